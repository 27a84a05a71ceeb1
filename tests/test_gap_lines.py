"""Spectral lines anywhere from a few cycles per record to Nyquist (the paper's own hum)."""

import numpy as np
import pytest

from skdelay.gap import _lines, diagnose_gap
from skdelay.gap._lines import find_lines
from skdelay.gap._units import format_frequency, parse_sample_dt
from skdelay.systems import MackeyGlass

MG = MackeyGlass()


def hum(x, freq, amp, dt=1.0, phase=0.4):
    t = np.arange(x.size) * dt
    return x + amp * x.std() * np.sin(2 * np.pi * freq * t + phase)


@pytest.fixture(scope="module")
def sims_4e4():
    return [MG.simulate(40_000, random_state=s) for s in (501, 502, 503, 504)]


@pytest.mark.parametrize("cycles, amp", [(3.0, 0.05), (3324.0, 0.01), (18_000.0, 0.01),
                                         (19_990.5, 0.01)])
def test_line_found_from_a_few_cycles_to_nyquist(sims_4e4, cycles, amp):
    n = 40_000
    real = hum(MG.simulate(n, random_state=511), cycles / n, amp)
    lines = find_lines(real, sims_4e4, 1.0)
    assert len(lines) == 1
    # within one bin (1 / n); the amplitude within 10 %
    assert abs(lines[0].frequency - cycles / n) < 1.0 / n
    assert lines[0].amplitude == pytest.approx(amp, rel=0.1)


def test_only_the_reported_peaks_are_refined(sims_4e4, monkeypatch):
    """The refined frequency costs 33 tapered DFTs of the whole record (about 1 s at 4e5
    samples), so it is made for the lines and the hints reported, not for every sub-threshold
    cluster: a hum under 5 % noise leaves 13 gated clusters, of which three are hints."""
    x = MG.simulate(40_000, random_state=511)
    rng = np.random.default_rng(511)
    real = hum(x + 0.05 * x.std() * rng.standard_normal(x.size), 0.013, 0.02)
    calls = []
    refine = _lines._refine
    monkeypatch.setattr(_lines, "_refine", lambda *a, **k: calls.append(a) or refine(*a, **k))
    lines, hints, start = _lines.line_scan(real, sims_4e4, 1.0)
    assert len(hints) == _lines.MAX_HINTS
    # one per reported line, hint and start, and those hints that fell beside a line
    assert len(calls) <= 3 * len(lines) + len(hints) + (start is not None)


def test_no_line_in_clean_runs(sims_4e4):
    for seed in (521, 522, 523):
        assert find_lines(MG.simulate(40_000, random_state=seed), sims_4e4, 1.0) == []


def test_mains_hum_at_1_mhz_a_few_tens_of_cycles():
    """50 Hz at 1 MHz: period 20 000 samples, 20 cycles in 0.4 s, 3 % of the std."""
    n = 400_000
    sims = [MG.simulate(n, random_state=s) for s in (531, 532, 533)]
    real = hum(MG.simulate(n, random_state=534), 50.0, 0.03, dt=1e-6)
    lines = find_lines(real, sims, 1e-6)
    assert len(lines) == 1 and abs(lines[0].frequency - 50.0) < 1.0 / (n * 1e-6)
    assert format_frequency(lines[0].frequency, "s") == "50 Hz"


def test_units_parsing():
    assert parse_sample_dt("1 us") == (1.0, "us")
    assert parse_sample_dt((2.0, "ms")) == (2.0, "ms")
    assert parse_sample_dt(0.5, "s") == (0.5, "s")
    assert format_frequency(5e-5, "us") == "50 Hz"
    assert format_frequency(0.25, None) == "0.25 cycles per time unit"
    with pytest.raises(ValueError, match="unknown time unit"):
        parse_sample_dt("1 parsec")
    with pytest.raises(ValueError, match="positive"):
        parse_sample_dt(-1.0)


@pytest.fixture(scope="module")
def mains_report():
    """A 50 Hz hum at 1 MHz (3 cycles in 60 ms, 5 % of the std) in Mackey-Glass data whose
    time unit is the microsecond."""
    n = 60_000
    real = hum(MG.simulate(n, random_state=541), 50.0, 0.05, dt=1e-6)
    return diagnose_gap(real, MG, sample_dt="1 us", random_state=0, n_jobs=2,
                        effects=["periodic_interference", "measurement_noise", "lowpass",
                                 "parameter_drift", "clipping"])


def test_mains_hum_found_reported_in_hz_and_on_top_of_where(mains_report):
    rep = mains_report
    assert rep.best_effect == "periodic_interference"
    p = rep.effects.set_index("effect").loc["periodic_interference", "params"]
    bin_hz = 1.0 / (60_000 * 1e-6)
    assert abs(p["frequency"] * 1e6 - 50.0) < bin_hz  # cycles per us -> Hz
    assert p["amplitude"] == pytest.approx(0.05, rel=0.2)
    # held out too: the hum continues into the second half with its phase carried over (1.5
    # cycles per half; restarted at the fitted phase it left 0.55 of that half's gap)
    row = rep.effects.set_index("effect").loc["periodic_interference"]
    assert row["cross_validated"] and row["shrink"] > 0.9
    top = rep.where.iloc[0]
    assert top.indicator == "spectrum" and top.feature == "spectral line"
    assert top.unit == "Hz" and top.low <= 50.0 <= top.high
    assert abs(top.peak - 50.0) < bin_hz
    assert "line at 50" in rep.summary() and "Hz" in rep.summary()


def test_noise_does_not_mask_a_hum():
    """Noise and a hum of a few % each: both found, the hum in the second round."""
    n = 20_000
    x = MG.simulate(n, random_state=551)
    real = hum(x, 0.1123, 0.04) + 0.04 * x.std() * np.random.default_rng(5).standard_normal(n)
    rep = diagnose_gap(real, MG, random_state=1, n_jobs=2,
                       effects=["measurement_noise", "periodic_interference", "lowpass",
                                "outliers", "quantization"])
    found = {rep.best_effect} | set(rep.combined["effects"] if rep.combined else [])
    assert found == {"measurement_noise", "periodic_interference"}, rep.effects
    params = (rep.combined["params"][rep.combined["effects"].index("periodic_interference")])
    assert abs(params["frequency"] - 0.1123) < 1.0 / n


def test_sub_threshold_candidates_pass_the_gates_and_keep_clear_of_the_lines():
    """Hints (starting points of a hum fit) pass both gates but not the family-wise test,
    stay more than a line's width away from every line, and are at most MAX_HINTS; a 1 %
    hum under 2 % noise is a line, not a hint."""

    n = 8000
    sims = [MG.simulate(n, random_state=s) for s in (531, 532, 533, 534)]
    real = hum(MG.simulate(n, random_state=535), 2400.0 / n, 0.01)
    real = real + 0.02 * real.std() * np.random.default_rng(536).standard_normal(n)
    lines, hints, _ = _lines.line_scan(real, sims, 1.0)
    assert lines == find_lines(real, sims, 1.0)
    assert len(lines) == 1 and abs(lines[0].frequency - 2400.0 / n) < 1.0 / n
    assert hints  # on this record a noise bin at 1194 cycles passes the gates
    assert len(hints) <= _lines.MAX_HINTS
    for h in hints:
        assert h.p_value < _lines.F_GATE  # (its cluster's best F; z passed at some bin)
        assert abs(h.frequency - lines[0].frequency) > 2 * _lines.NW / n


def test_hum_fit_starts_from_a_hint_when_no_line_is_found():
    from types import SimpleNamespace

    from skdelay.gap import PeriodicInterference
    from skdelay.gap._lines import Line

    n = 4000
    real = hum(MG.simulate(n, random_state=541), 0.3, 0.2)
    hint = Line(frequency=0.3, amplitude=0.1, phase=0.0, z=3.0, f_stat=20.0, p_value=3e-3,
                bin_width=1.0 / n, half_width=3.0 / n)
    problem = SimpleNamespace(real=real, lines=[], line_hints=[hint], sample_dt=1.0)
    start = PeriodicInterference().initial(problem)
    assert start["frequency"] == pytest.approx(0.3)
    assert start["amplitude"] == pytest.approx(0.2, rel=0.15)  # read off the record


def test_line_feature_leaves_a_continuum_trough_unscaled():
    """A run prefix (a multiple of LENGTH_STEP) rescales a line's excess to the record's
    length; a trough of the continuum (ratio < 1: 13 cycles per 6000-sample Mackey-Glass
    record, where the continuum is ~10x below its flanks) is not an excess and keeps its
    value.  Rescaled as one, a clean run's ratio 0.06 went through zero to the floor
    (log10 = -3), and the inflated spread hid a real hum from the line indicator."""
    from skdelay.gap._lines import LENGTH_STEP, line_feature

    n = 6000
    freq = 13.3 / n
    floor_hits = []
    for seed in (561, 562, 563, 564, 565, 566):
        z = MG.simulate(n, random_state=seed)
        z = (z - z.mean()) / z.std()
        prefix = (n // LENGTH_STEP) * LENGTH_STEP
        own = line_feature(z[:prefix], freq, 1.0, prefix)  # no rescaling at n_ref = n
        scaled = line_feature(z, freq, 1.0, n)             # prefix of 5632, rescaled to 6000
        if own < 0:
            assert scaled == own  # a trough stays a trough
        floor_hits.append(scaled <= -2.99)
        assert own < 0.5  # the clean runs have no line here
    assert not any(floor_hits)
    # a line's excess is rescaled: a 5 % hum at that frequency reads above the clean runs
    z = hum(MG.simulate(n, random_state=561), freq, 0.05)
    z = (z - z.mean()) / z.std()
    assert line_feature(z, freq, 1.0, n) > 0.5


def test_a_slow_hum_under_noise_survives_into_the_second_round():
    """13 cycles per record (the paper's mains hum in a short record) at 5 % of the std
    under 3.4 % white noise: the noise explains almost all of the gap, the hum's line must
    still be fitted on top (the benchmark miss of seed 9.1e6, here on other seeds)."""
    n = 6000
    x = MG.simulate(n, random_state=571)
    real = hum(x, 13.3 / n, 0.05) + 0.034 * x.std() * np.random.default_rng(572).standard_normal(n)
    rep = diagnose_gap(real, MG, random_state=573, n_jobs=2,
                       effects=["measurement_noise", "dynamical_noise", "periodic_interference",
                                "lowpass", "parameter_drift"])
    found = [rep.best_effect] + (list(rep.combined["effects"][1:]) if rep.combined else [])
    assert set(found) == {"measurement_noise", "periodic_interference"}, rep.effects
    params = rep.combined["params"][rep.combined["effects"].index("periodic_interference")]
    assert abs(params["frequency"] - 13.3 / n) < 1.0 / n
    # on top of the noise the amplitude is fitted through the gap, where a 13-cycle line is
    # weakly tied to it: 0.079, 0.068, 0.052 on seeds 571/581/591 (the record's own line
    # estimate, round 1's start, was within 5 % on all three) -- a known looseness
    assert 0.5 * 0.05 < params["amplitude"] < 2.0 * 0.05
    assert rep.combined["gap_after"] < rep.significance["threshold"]


def test_a_slow_hum_over_a_strong_low_frequency_continuum_is_found_on_top_of_the_noise():
    """Electro-optic oscillator (step 0.25, 6000 samples): a 0.4-std hum of 5.1 cycles per
    record under 3 % noise.  Over the oscillator's strong low-frequency continuum its narrow
    excess is only a sub-threshold candidate (a hint); the low band's test of the power
    itself makes it a line (z 2.9 against the runs' power, p_F 1.6e-4).  Before either, the
    noise was the whole answer (the benchmark miss of seed 13.0e6, where a drift took the
    hum's place).  A hint alone still marks the hum for the second round
    (Effect.has_local_mark)."""
    from types import SimpleNamespace

    from skdelay.gap import PeriodicInterference, get_effect
    from skdelay.gap._lines import line_scan
    from skdelay.systems import ElectroOpticOscillator

    eo, dt, n, seed = ElectroOpticOscillator(), 0.25, 6000, 803
    rng = np.random.default_rng(seed)
    cycles = rng.uniform(4, 6)  # 5.09
    x = eo.simulate(n, sample_dt=dt, random_state=seed)
    y = PeriodicInterference().apply(
        x, {"frequency": cycles / (n * dt), "amplitude": 0.4, "phase": rng.uniform(0, 2 * np.pi)},
        sample_dt=dt)
    real = get_effect("measurement_noise").apply(y, {"noise": 0.03}, sample_dt=dt,
                                                 random_state=seed + 1)
    sims = [eo.simulate(n, sample_dt=dt, random_state=seed + 100 + j) for j in range(6)]
    lines = line_scan(real, sims, dt)[0]
    assert len(lines) == 1 and abs(lines[0].frequency * n * dt - cycles) < 1.0
    hint = SimpleNamespace(lines=[], line_hints=[lines[0]])
    assert PeriodicInterference().has_local_mark(hint)
    assert not PeriodicInterference().has_local_mark(SimpleNamespace(lines=[], line_hints=[]))
    rep = diagnose_gap(real, eo, sample_dt=dt, random_state=seed + 7, n_jobs=2,
                       effects=["measurement_noise", "periodic_interference", "parameter_drift"])
    found = [rep.best_effect] + (list(rep.combined["effects"][1:]) if rep.combined else [])
    assert found == ["measurement_noise", "periodic_interference"], rep.effects
    params = rep.combined["params"][1]
    assert abs(params["frequency"] * n * dt - cycles) < 1.0  # within one bin
    assert 0.5 * 0.4 < params["amplitude"] < 2.0 * 0.4  # fitted 0.52


def test_a_sub_threshold_line_calls_for_nothing_once_the_rest_is_at_the_runs_level():
    """A mark no indicator measures (a hint) is followed only while what the best effect
    leaves exceeds every gap of the runs among themselves: an electro-optic delay fit left
    0.15 (runs 1.32), and a 2.3 %-std hum at a hint removed 97 % of that and was named as a
    second cause (benchmark seed 17.3e6); an Ikeda clipping left 1.32 among runs' gaps of
    0-1.9 (median 1.27), and a hum at the dynamics' main frequency was named on top
    (benchmark seed 21.5e6)."""
    from types import SimpleNamespace

    from skdelay.gap._diagnose import _marked

    problem = SimpleNamespace(null_gaps=[0.9, 1.2, 1.32, 1.4, 2.4, 1.1])
    hum = SimpleNamespace(name="periodic_interference", has_local_mark=lambda p: True)
    noise = SimpleNamespace(name="measurement_noise", has_local_mark=lambda p: False)
    best = SimpleNamespace(name="delay_mismatch", has_local_mark=lambda p: True)
    cands = [hum, noise, best]
    assert _marked(problem, cands, "delay_mismatch", SimpleNamespace(gap=0.15)) == set()
    # above the median (1.26) but within the runs' own gaps
    assert _marked(problem, cands, "clipping", SimpleNamespace(gap=1.32)) == set()
    assert _marked(problem, cands, "delay_mismatch", SimpleNamespace(gap=3.0)) == {
        "periodic_interference"}


def test_a_weak_hum_that_noise_leaves_standing_is_fitted_on_top():
    """A 0.4 %-std hum at 0.14 cycles per sample under 3.4 % noise (6000 samples): with the
    noise fitted the record's line still stands out of the runs (one question per line, not
    one among all indicators), so the hum is fitted on top.  Judged among all indicators it
    fell under their family bound and the noise alone "explained" the record (the benchmark
    miss of seed 10.5e6, here on another seed)."""
    n = 6000
    x = MG.simulate(n, random_state=615)
    noise = 0.034 * x.std() * np.random.default_rng(615).standard_normal(n)
    real = hum(x, 0.14, 0.004) + noise
    rep = diagnose_gap(real, MG, random_state=1, n_jobs=1, cross_validated=False,
                       effects=["measurement_noise", "dynamical_noise", "periodic_interference"])
    found = [rep.best_effect] + (list(rep.combined["effects"][1:]) if rep.combined else [])
    assert found == ["measurement_noise", "periodic_interference"], rep.effects
    params = rep.combined["params"][1]
    assert abs(params["frequency"] - 0.14) < 0.5 / n


def test_a_hum_on_the_dynamics_own_peak_is_fitted_from_the_most_coherent_bin():
    """A hum at Mackey-Glass' subharmonic peak (0.01 cycles per sample) lifts that bin only
    slightly above the runs' (under every z gate), so no line or hint is found; it is the
    record's most coherent bin, its power far beyond the runs' there, and the hum fit starts
    there too.  Of 60 such records (amplitude 0.3-0.7 std, seeds 100-159) 20 had no line; 11
    of them got the start, all on the hum.  Before it, this record was "not explained" (the
    hum fitted at 0.25, removing nothing)."""
    from skdelay.gap import PeriodicInterference
    from skdelay.gap._lines import line_scan

    n = 6000
    real = PeriodicInterference().apply(MG.simulate(n, random_state=119), {
        "frequency": 0.01, "amplitude": 0.3596, "phase": 4.389})
    sims = [MG.simulate(n, random_state=900 + j) for j in range(6)]
    lines, hints, start = line_scan(real, sims, 1.0)
    assert lines == [] and hints == []
    assert abs(start.frequency - 0.01) < 1.0 / n and start.z < 2.0  # under the z gate
    rep = diagnose_gap(real, MG, random_state=119,
                       effects=["periodic_interference", "measurement_noise"])
    assert rep.best_effect == "periodic_interference"
    assert abs(rep.effects.iloc[0]["params"]["frequency"] - 0.01) < 0.2 / n


def test_no_hum_start_on_records_without_a_hum():
    """The most coherent bin of a clean record is one of the dynamics' own peaks, whose power
    the runs share: no start is offered (0 of 30 clean Mackey-Glass records, seeds 300-329)."""
    from skdelay.gap._lines import line_scan

    n = 6000
    sims = [MG.simulate(n, random_state=900 + j) for j in range(6)]
    for seed in (300, 301, 302):
        assert line_scan(MG.simulate(n, random_state=seed), sims, 1.0)[2] is None


def test_a_slow_hum_where_the_runs_low_frequency_power_varies_is_found_by_the_low_band():
    """On the electro-optic oscillator the band-pass's low cut-off makes the runs' power
    below ~36 cycles per record vary from run to run, so a slow hum's narrow excess has no
    contrast; its power against the runs' with the F-test finds it (the low band's own
    family).  Of 30 hums of 0.2-0.5 std at 3-36 cycles per record (seeds 700-729, runs
    5000 + 10 j + k) the scan found 22 before and 27 with the low band (Ikeda 25 -> 27,
    Mackey-Glass 30 -> 30), and none of the 90 clean records got a line either way.
    This record (seed 712, 8.4 cycles, 0.375 std) had none before."""
    from skdelay.gap import PeriodicInterference
    from skdelay.gap._lines import line_scan
    from skdelay.systems import ElectroOpticOscillator

    eo, n, dt = ElectroOpticOscillator(), 6000, 0.25
    f = 8.4345 / (n * dt)
    clean = eo.simulate(n, sample_dt=dt, random_state=712)
    real = PeriodicInterference().apply(clean, {"frequency": f, "amplitude": 0.3752,
                                                "phase": 8.4}, sample_dt=dt)
    sims = [eo.simulate(n, sample_dt=dt, random_state=5120 + k) for k in range(6)]
    lines = line_scan(real, sims, dt)[0]
    assert len(lines) == 1 and abs(lines[0].frequency - f) < 1.0 / (n * dt)
    assert abs(lines[0].amplitude - 0.3752) < 0.2 * 0.3752
    assert line_scan(clean, sims, dt)[0] == []


def test_the_low_band_keeps_its_false_line_rate_on_clean_records():
    """The low band is a family of its own at LINE_ALPHA = 1 % per record: on 60 clean
    records of the three systems (seeds 761-780) at most 2 get a line below 36 cycles per
    record (one does: Mackey-Glass seed 763, 29.9 cycles, z 3.1, p_F 5e-3; on 300 other
    clean records, seeds 70 000+, one did).  A test that flagged any coherent bin of a
    varying low band would flag most of them."""
    from skdelay.gap._lines import line_scan
    from skdelay.systems import ElectroOpticOscillator, Ikeda

    n, hits = 6000, 0
    for system, dt in ((MG, 1.0), (Ikeda(), 0.5), (ElectroOpticOscillator(), 0.25)):
        sims = [system.simulate(n, sample_dt=dt, random_state=5500 + k) for k in range(6)]
        for seed in range(761, 781):
            lines = line_scan(system.simulate(n, sample_dt=dt, random_state=seed), sims, dt)[0]
            hits += any(line.frequency * n * dt < 36 for line in lines)
    assert hits <= 2


def _white(seed, n=6000):
    return np.random.default_rng(seed).standard_normal(n)


def _sine(freq, amp, n=6000, phase=0.3):
    return amp * np.sin(2 * np.pi * freq * np.arange(n) + phase)


def test_a_runs_own_line_calibrates_the_tests_only_near_its_frequency():
    """One run with a line of its own (the laser's delay-loop mode) says how far the
    simulator can stick out near that frequency, not everywhere: a hum two octaves away is
    still found, a line where the run has one is not."""
    runs = [_white(s) for s in range(1, 7)]
    runs[0] = runs[0] + _sine(0.45, 0.5)
    # a whole-band calibration (run 0's z ~ 9 everywhere) missed this hum (z 5)
    lines = _lines.line_scan(_white(10) + _sine(0.08, 0.2), runs, 1.0)[0]
    assert [round(line.frequency, 3) for line in lines] == [0.08]
    # without the runs' calibration a record with the same line reads z 4.7 and 6.6: found
    for amp in (0.3, 0.5):
        assert _lines.line_scan(_white(11) + _sine(0.45, amp), runs, 1.0)[0] == []
    for seed in (12, 13):
        assert _lines.line_scan(_white(seed), runs, 1.0)[0] == []


def test_more_calibration_runs_are_drawn_only_when_the_runs_null_can_decide():
    """The runs' null only matters where some bin of the record passes the Bonferroni bounds,
    or where some run alone passes them: only then are runs drawn up to CALIBRATION_RUNS,
    and the prediction bound of their extremes judges the record."""
    calls = []

    def more(k):
        calls.append(k)
        return [_white(100 + s) for s in range(k)]

    plain = [_white(s) for s in range(1, 7)]
    assert _lines.line_scan(_white(10), plain, 1.0, more_runs=more)[0] == []
    assert calls == []
    lines = _lines.line_scan(_white(10) + _sine(0.08, 0.2), plain, 1.0, more_runs=more)[0]
    assert calls == [_lines.CALIBRATION_RUNS - 6]
    assert [round(line.frequency, 3) for line in lines] == [0.08]
    outrun = [plain[0] + _sine(0.45, 0.5)] + plain[1:]
    assert _lines.line_scan(_white(10), outrun, 1.0, more_runs=more)[0] == []
    assert calls == [_lines.CALIBRATION_RUNS - 6] * 2


def test_threads_give_the_same_scan_to_the_last_bit():
    """The runs' spectra and their leave-one-out nulls on threads are the same numbers as
    one by one: the same lines, hints and start, and the same calibration arrays."""
    plain = [_white(s) + _sine(0.2 + 0.01 * s, 0.05) for s in range(1, 7)]
    extra = [_white(100 + s) for s in range(_lines.CALIBRATION_RUNS - 6)]
    real = _white(10) + _sine(0.08, 0.2) + _sine(0.31, 0.04)
    scans = [_lines.line_scan(real, plain, 1.0, more_runs=lambda k: extra[:k], threads=t)
             for t in (1, 2, 5)]
    assert scans[0][0] and scans[1] == scans[0] and scans[2] == scans[0]
    runs = [_lines.zscore(x) for x in plain + extra]
    serial = _lines._run_spectra(runs, runs[0].size)
    threaded = _lines._run_spectra(runs, runs[0].size, threads=3)
    assert all(np.array_equal(a, b) for a, b in zip(serial, threaded, strict=True))
    bins = np.arange(8, serial[2].shape[1] - _lines.PAD)
    nulls = [_lines._run_nulls(bins, serial[2], serial[1], threads=t) for t in (1, 2)]
    assert all(np.array_equal(a, b) for a, b in zip(*nulls, strict=True))
    assert nulls[0][0].shape == (len(runs), bins.size) and np.any(nulls[0][0] > 0)


def test_peaks_of_the_dynamics_moved_by_a_timebase_are_not_lines():
    """A clock 6 % off moves every sharp peak of Mackey-Glass' spectrum by 6 %: the record
    has peaks where the runs have none and lacks theirs next to them.  Judged bin by bin,
    each moved peak passed the line tests (2 and 5 lines on these seeds before); read as
    moves by one common factor they are not lines, and a hum on top still is."""
    from skdelay.gap import get_effect
    from skdelay.gap._lines import line_scan

    n = 6000
    sims = [MG.simulate(n, random_state=5600 + k) for k in range(30)]

    def more(k):
        return sims[6:6 + k]

    for seed in (31, 32):
        x = MG.simulate(int(n * 1.1), random_state=seed)
        real = get_effect("timebase_mismatch").apply(x, {"factor": 1.06})[:n]
        assert line_scan(real, sims[:6], 1.0, more_runs=more)[0] == []
        lines = line_scan(hum(real, 0.1, 0.3), sims[:6], 1.0, more_runs=more)[0]
        assert [round(line.frequency, 3) for line in lines] == [0.1]


def test_the_runs_nulls_spread_over_their_spans_as_entry_by_entry():
    """:func:`_lines._spread` (a sparse table over the entries) gives, bin by bin, what
    reducing each entry's value over its span does, NaN included."""
    rng = np.random.default_rng(5)
    for trial in range(200):
        nb = int(rng.integers(1, 300))
        bins = np.sort(rng.choice(np.arange(1, 3000), size=nb, replace=False))
        at = np.sort(rng.choice(nb, size=int(rng.integers(0, nb + 1)), replace=False))
        values = rng.normal(size=at.size)
        if trial % 5 == 0 and at.size:
            values[rng.integers(at.size)] = np.nan
        for op in (np.maximum, np.minimum):
            want = np.zeros(nb)
            for v, h in zip(values, at, strict=True):
                lo, hi = _lines._span(bins, bins[h])
                want[lo:hi] = op(want[lo:hi], v)
            assert np.array_equal(_lines._spread(bins, at, values, op), want, equal_nan=True)


def test_a_hum_on_the_lasers_comb_of_harmonics_is_not_read_as_moved():
    """The CO2 laser's spectrum is a comb of the delay loop's harmonics: within 15 % of any
    bin lie several, and two candidates of a noisy record find a common "move" by chance.
    Read as moved only when the runs' whole comb, moved by that factor, fits the record
    better, a 0.15-std hum under 6 % noise is a line (before: read as moved, no line)."""
    from skdelay.gap._lines import line_scan
    from skdelay.systems import CO2LaserFeedback

    laser = CO2LaserFeedback(tau=150.0)
    n = 6000
    sims = [np.asarray(laser.simulate(n, random_state=900 + k), dtype=float) for k in range(24)]
    x = np.asarray(laser.simulate(n, random_state=5), dtype=float)
    rng = np.random.default_rng(5)
    real = (x + 0.06 * x.std() * rng.standard_normal(n)
            + 0.15 * x.std() * np.sin(2 * np.pi * 0.072 * np.arange(n) + 0.5))
    lines = line_scan(real, sims[:6], 1.0, more_runs=lambda k: sims[6:6 + k])[0]
    assert [round(line.frequency, 4) for line in lines] == [0.072]
