"""Round 1's choice between two explanations of one discrepancy is re-checked with the
second cause in place (:func:`skdelay.gap._diagnose._better_first`)."""

import numpy as np
import pytest

from skdelay.gap import diagnose_gap, get_effect
from skdelay.systems import MackeyGlass

MG = MackeyGlass()
N = 4000
NOISES = ["measurement_noise", "dynamical_noise", "periodic_interference"]


def _hum(x, freq, amp, phase=0.4):
    return x + amp * x.std() * np.sin(2 * np.pi * freq * np.arange(x.size) + phase)


def _fake(name):
    """A stand-in effect the pair search fits one after the other (a simulation effect:
    never fitted in turn with another, see JOINT_ROUNDS)."""
    from types import SimpleNamespace

    return SimpleNamespace(name=name, target="simulation", signature=())


def _found(rep):
    return [rep.best_effect] + (rep.combined["effects"][1:] if rep.combined else [])


@pytest.mark.parametrize("seed", [614, 615])
def test_measurement_noise_under_a_strong_hum_is_not_dynamical_noise(seed):
    """White noise (3.5 % of the std) + a 0.35-std hum at 57 cycles per record: alone,
    dynamical noise absorbs part of the hum's autocorrelation and ranked first (shrink
    0.965-0.973 vs 0.951-0.966); with the hum in place the measurement noise leaves no
    indicator off, the dynamical noise leaves the spectrum off."""
    x = MG.simulate(N, random_state=seed)
    noise = 0.035 * x.std() * np.random.default_rng(seed).standard_normal(N)
    real = _hum(x, 0.0143, 0.35) + noise
    rep = diagnose_gap(real, MG, random_state=1, n_jobs=1, cross_validated=False,
                       effects=NOISES)
    assert _found(rep) == ["measurement_noise", "periodic_interference"], rep.effects
    assert rep.combined["params"][0]["noise"] == pytest.approx(0.035, rel=0.15)



@pytest.mark.parametrize("seed", [614, 615])
def test_measurement_noise_under_a_hum_of_0_8_std_is_not_dynamical_noise(seed):
    """The same noise under a 0.8-std hum: dynamical noise leads round 1 far ahead (shrink
    0.91-0.93 vs 0.72-0.75), beyond any slack a near-tie rule would give; its pair with the
    hum leaves indicators off, so the runner-up is paired and the true pair wins."""
    x = MG.simulate(N, random_state=seed)
    noise = 0.035 * x.std() * np.random.default_rng(seed).standard_normal(N)
    real = _hum(x, 0.0143, 0.8) + noise
    rep = diagnose_gap(real, MG, random_state=1, n_jobs=1, cross_validated=False,
                       effects=NOISES)
    assert set(_found(rep)) == {"measurement_noise", "periodic_interference"}, rep.effects
    fitted = dict(zip(rep.combined["effects"], rep.combined["params"], strict=True))
    assert fitted["measurement_noise"]["noise"] == pytest.approx(0.035, rel=0.2)
    assert fitted["periodic_interference"]["frequency"] == pytest.approx(0.0143,
                                                                         abs=0.5 / N)

def test_dynamical_noise_under_a_hum_stays_dynamical_noise():
    """The control: the true dynamical noise pairs better with the hum; no swap."""
    x = MG.simulate(N, random_state=621, dynamical_noise=0.005)
    rep = diagnose_gap(_hum(x, 0.2, 0.1), MG, random_state=1, n_jobs=1,
                       cross_validated=False, effects=NOISES)
    assert _found(rep) == ["dynamical_noise", "periodic_interference"], rep.effects


def test_hum_starts_from_the_line_that_explains_most_of_the_gap():
    """Dynamical noise raises weak lines that rank above a strong slow hum by their
    excess over the runs; the hum was fitted at one of them (0.032, amplitude 0.05) and
    missed.  Every found line is tried as the hum's start."""
    n = 6000
    x = MG.simulate(n, random_state=702, dynamical_noise=0.0046)
    rep = diagnose_gap(_hum(x, 0.0143, 0.38), MG, random_state=1, n_jobs=1,
                       cross_validated=False, effects=NOISES)
    assert _found(rep) == ["dynamical_noise", "periodic_interference"], rep.effects
    hum = rep.effects.set_index("effect").loc["periodic_interference", "params"]
    assert hum["frequency"] == pytest.approx(0.0143, abs=0.5 / n)  # within half a bin
    assert hum["amplitude"] == pytest.approx(0.38, rel=0.2)


@pytest.mark.parametrize(("seed", "cutoff", "noise"), [(631, 0.06, 0.03), (632, 0.09, 0.025)])
def test_lowpass_under_measurement_noise_is_found_as_a_pair(seed, cutoff, noise):
    """A detector low-pass under white noise added after it.  Two failures of the
    sequential fit: the low-pass search on top of the noise started from a roll-off that
    read no filter (the noise floor flattens the record's high end) and stopped at its
    bound, 0.17 for 0.09 (seed 632); and where dynamical noise led round 1 and nothing
    took a share of its significant rest, no runner-up was paired (seed 631: "dynamical
    noise, partly")."""
    x = MG.simulate(N, random_state=seed)
    y = get_effect("lowpass").apply(x, {"cutoff": cutoff})
    y = y + noise * y.std() * np.random.default_rng(seed).standard_normal(N)
    rep = diagnose_gap(y, MG, random_state=1, n_jobs=1, cross_validated=False,
                       effects=["measurement_noise", "dynamical_noise", "lowpass"])
    assert _found(rep) == ["measurement_noise", "lowpass"], rep.effects
    assert rep.explained == "fully"
    fitted = dict(zip(rep.combined["effects"], rep.combined["params"], strict=True))
    assert fitted["lowpass"]["cutoff"] == pytest.approx(cutoff, rel=0.1)
    assert fitted["measurement_noise"]["noise"] == pytest.approx(noise, rel=0.15)


def test_a_runner_up_is_paired_with_effects_the_best_round_two_ranked_low(monkeypatch):
    """What the best effect absorbed can sit low in its round 2: Ikeda (step 0.5, noise 0.60
    + a 0.37-std hum, benchmark seed 10 326 000) led with a timebase factor; on top of it
    the noise came fifth.  The runner-up hum must still be tried with the noise."""
    from types import SimpleNamespace

    import pandas as pd
    from joblib import Parallel

    from skdelay.gap import _diagnose

    table = pd.DataFrame({"effect": ["timebase_mismatch", "periodic_interference",
                                     "measurement_noise"],
                          "shrink": [0.55, 0.52, 0.25], "status": ["ok"] * 3,
                          "params": [{}] * 3, "consistent": [True, None, None]})
    second = pd.DataFrame({"effect": ["periodic_interference", "outliers", "delay_mismatch",
                                      "measurement_noise"], "status": ["ok"] * 4})
    by_name = {name: _fake(name) for name in
               ["timebase_mismatch", "periodic_interference", "measurement_noise",
                "outliers", "delay_mismatch"]}
    best_pair = SimpleNamespace(gap=4.7)

    def fake_fit(effect, problem, chain, *args):
        first = chain[0][0].name
        good = {first, effect.name} == {"periodic_interference", "measurement_noise"}
        return SimpleNamespace(ok=True, spread=False, gap_after=0.5 if good else 4.0)

    monkeypatch.setattr(_diagnose, "off_indicators", lambda problem, ev: {"band_spectrum": 1})
    monkeypatch.setattr(_diagnose, "fit_effect", fake_fit)
    pick = _diagnose._better_first(None, table, [object()] * 3, by_name, second,
                                   [best_pair], Parallel(n_jobs=1))
    assert pick == (1, None, None)  # the hum: its pair with the noise leaves 0.5 vs 4.7


def test_a_runner_up_far_behind_is_paired_when_the_best_pair_leaves_indicators_off(
        monkeypatch):
    """A strong hum lifts the wrong noise type far ahead in round 1 (Mackey-Glass, noise
    0.034 + a 0.78-std hum, benchmark seed 10 312 000: dynamical noise 0.84 against 0.62);
    the margin is no evidence, so the runner-up is paired all the same.  A candidate
    below MIN_SHRINK is not."""
    from types import SimpleNamespace

    import pandas as pd
    from joblib import Parallel

    from skdelay.gap import _diagnose

    table = pd.DataFrame({"effect": ["dynamical_noise", "measurement_noise",
                                     "periodic_interference", "clipping"],
                          "shrink": [0.84, 0.62, 0.46, 0.14], "status": ["ok"] * 4,
                          "params": [{}] * 4, "consistent": [None] * 4})
    second = pd.DataFrame({"effect": ["periodic_interference", "lowpass",
                                      "measurement_noise", "clipping"],
                           "status": ["ok"] * 4})
    by_name = {name: _fake(name) for name in
               ["dynamical_noise", "measurement_noise", "periodic_interference",
                "clipping", "lowpass"]}
    tried = []

    def fake_fit(effect, problem, chain, *args):
        first = chain[0][0].name
        tried.append(first)
        good = {first, effect.name} == {"measurement_noise", "periodic_interference"}
        return SimpleNamespace(ok=True, spread=False, gap_after=16.5 if good else 150.0)

    monkeypatch.setattr(_diagnose, "off_indicators", lambda problem, ev: {"band_spectrum": 1})
    monkeypatch.setattr(_diagnose, "fit_effect", fake_fit)
    pick = _diagnose._better_first(None, table, [object()] * 4, by_name, second,
                                   [SimpleNamespace(gap=165.0)], Parallel(n_jobs=1))
    assert pick == (1, None, None)  # measurement noise + the hum leave 16.5 against 165
    assert "clipping" not in tried  # removes 14 % alone: below MIN_SHRINK, never paired

    # a pair that explains the record is not reconsidered
    monkeypatch.setattr(_diagnose, "off_indicators", lambda problem, ev: {})
    tried.clear()
    assert _diagnose._better_first(None, table, [object()] * 4, by_name, second,
                                   [SimpleNamespace(gap=165.0)], Parallel(n_jobs=1)) is None
    assert not tried


def test_without_a_second_effect_every_effect_is_tried_on_each_runner_up(monkeypatch):
    """The best found no second effect (``second`` None): each eligible runner-up gets every
    other effect on top, and one whose pair leaves at most PAIR_RATIO of what the best
    leaves alone replaces it."""
    from types import SimpleNamespace

    import pandas as pd
    from joblib import Parallel

    from skdelay.gap import _diagnose

    table = pd.DataFrame({"effect": ["dynamical_noise", "measurement_noise", "lowpass"],
                          "shrink": [0.94, 0.93, 0.05], "status": ["ok"] * 3,
                          "params": [{}] * 3, "consistent": [None] * 3})
    by_name = {name: _fake(name) for name in table["effect"]}
    tried = []

    def fake_fit(effect, problem, chain, *args):
        tried.append((chain[0][0].name, effect.name))
        good = (chain[0][0].name, effect.name) == ("measurement_noise", "lowpass")
        return SimpleNamespace(ok=True, spread=False, gap_after=0.3 if good else 100.0)

    monkeypatch.setattr(_diagnose, "off_indicators", lambda problem, ev: {"band_spectrum": 1})
    monkeypatch.setattr(_diagnose, "fit_effect", fake_fit)
    alone = [SimpleNamespace(gap=114.0)]
    assert _diagnose._better_first(None, table, [object()] * 3, by_name, None, alone,
                                   Parallel(n_jobs=1)) == (1, None, None)
    assert sorted(tried) == [("measurement_noise", "dynamical_noise"),
                             ("measurement_noise", "lowpass")]  # lowpass: below MIN_SHRINK
    tried.clear()
    monkeypatch.setattr(_diagnose, "fit_effect",
                        lambda e, p, c, *a: SimpleNamespace(ok=True, spread=False, gap_after=60.0))
    assert _diagnose._better_first(None, table, [object()] * 3, by_name, None, alone,
                                   Parallel(n_jobs=1)) is None  # 60 > PAIR_RATIO * 114


def test_a_second_cause_is_sought_only_for_a_significant_or_localised_rest():
    """What the best effect leaves must itself be a finding: above the significance threshold,
    or a localised mark.  A broadband indicator off with the whole rest under the threshold
    is the best fit's own error (benchmark seed 14.8e6: Mackey-Glass dynamical noise left
    2.02 against 5.71 with the band spectrum off, and a low-pass filter was named on top)."""
    from types import SimpleNamespace

    from skdelay.gap import _diagnose

    problem = SimpleNamespace(null_by_indicator={"band_spectrum": [0.1] * 6,
                                                 "spectral_line": [0.1] * 6})
    broad = np.full(24, 2.0)  # mean z^2 4: off by the family-wise test, no bin far off

    def after(band, line, gap):
        z = {"band_spectrum": band, "spectral_line": np.array([line])}
        return SimpleNamespace(z=z, gap=gap, gaps={k: float(np.mean(v ** 2) - 1.0)
                                                   for k, v in z.items()})

    left = _diagnose._residual_left
    small = after(broad, 0.5, 3.0)
    assert set(_diagnose.off_indicators(problem, small)) == {"band_spectrum"}
    assert not left(problem, small, threshold=6.0, gap_before=1000.0)
    assert left(problem, after(broad, 0.5, 9.0), threshold=6.0, gap_before=1000.0)
    # a significant rest with nothing off must be a share of the gap
    quiet = np.full(24, 0.5)
    assert not left(problem, after(quiet, 0.5, 9.0), threshold=6.0, gap_before=1000.0)
    assert left(problem, after(quiet, 0.5, 9.0), threshold=6.0, gap_before=100.0)
    # a line the best effect leaves: sought however small the rest
    assert left(problem, after(np.zeros(24), 4.5, 1.0), threshold=6.0, gap_before=1000.0)
    # one bin Z_LOCAL spreads off
    spike = np.zeros(24)
    spike[3] = _diagnose.Z_LOCAL + 1
    assert left(problem, after(spike, 0.5, 3.0), threshold=6.0, gap_before=1000.0)


def test_a_spectrum_off_beside_a_fitted_hum_calls_for_a_second_cause():
    """A hum changes the spectrum only at its own frequency: a band still off away from
    it after the hum fit is no fit error of the hum but a second cause (held-out-step
    seeds 20.1e6-20.7e6: Ikeda noise under a hum, the two top bands off, nothing sought).
    The same bands off after a broadband effect, or off only where the hum sits, are not."""
    from types import SimpleNamespace

    from skdelay.gap import _diagnose
    from skdelay.gap._indicators import BandSpectrum

    rng = np.random.default_rng(0)
    band = BandSpectrum()
    band.setup(rng.standard_normal(6000), rng.standard_normal((2, 6000)), 0.25, None)
    lo, hi = band.bounds()
    problem = SimpleNamespace(indicators={"band_spectrum": band},
                              null_by_indicator={"band_spectrum": [0.1] * 6})
    hum = get_effect("periodic_interference")
    line = 0.5 * (lo[-4] + hi[-4])  # inside the fourth band from the top
    chain = [(hum, {"frequency": line, "amplitude": 0.1, "phase": 0.0})]
    noise = [(get_effect("measurement_noise"), {"noise": 0.1})]

    def after(z):
        z = {"band_spectrum": np.asarray(z, dtype=float)}
        return SimpleNamespace(z=z, gap=3.0, gaps={k: float(np.mean(v ** 2) - 1.0)
                                                   for k, v in z.items()})

    top = np.zeros(lo.size)
    top[-2:] = [3.5, 5.0]  # the top two bands: off by the family-wise test, no bin far off
    at_line = np.zeros(lo.size)
    at_line[-4] = 6.0
    assert _diagnose._line_freqs(chain) == [line]
    assert _diagnose._line_freqs(noise) is None
    assert _diagnose._off_beside_lines(problem, after(top), [line]) == {"band_spectrum"}
    assert _diagnose._off_beside_lines(problem, after(at_line), [line]) == set()
    left = _diagnose._residual_left
    assert left(problem, after(top), threshold=6.0, gap_before=1000.0, chain=chain)
    assert not left(problem, after(top), threshold=6.0, gap_before=1000.0, chain=noise)
    assert not left(problem, after(at_line), threshold=6.0, gap_before=1000.0, chain=chain)
    # off only once the bands the line reaches are left out: not off (benchmark seed 20.8e6,
    # electro-optic hum at 0.112: the whole band spectrum at p = 0.0072, the rest 0.0035)
    seen = [-0.4, -0.7, -0.7, 0.5, 0.1, 0.4, 1.8, 3.0, -0.0, -1.1, 0.2, 1.6, 0.3, 3.5, 1.3]
    assert lo.size == len(seen)
    assert _diagnose._off_beside_lines(problem, after(seen), [0.1116]) == set()
    # the second effect must take the bands beside the line back, and remove MIN_SHRINK
    import pandas as pd

    table = pd.DataFrame({"effect": ["lowpass", "measurement_noise"], "status": ["ok"] * 2,
                          "shrink": [0.8, 0.9], "consistent": [None] * 2})
    evals = [after(top), after(np.zeros(lo.size))]
    off = _diagnose.off_indicators(problem, after(top))
    pick = _diagnose._second_choice(problem, off, table, evals, rest_significant=False,
                                    beside={"band_spectrum"}, freqs=[line])
    assert pick == 1
    small = table.assign(shrink=[0.8, 0.2])
    assert _diagnose._second_choice(problem, off, small, evals, rest_significant=False,
                                    beside={"band_spectrum"}, freqs=[line]) is None


@pytest.mark.parametrize("seed", [7201])
def test_noise_under_a_hum_is_found_beside_the_line(seed):
    """Ikeda at step 0.25 (the held-out step), white noise of 0.2 std and a 0.13-std hum at
    1.03 cycles per time unit: the hum leads, and what it leaves lies under the no-gap
    threshold with the band spectrum off in its top bands, away from the line.  Before
    :func:`skdelay.gap._diagnose._off_beside_lines` no second cause was sought (held-out-step
    seeds 20.1e6, 20.5e6, 20.7e6; this record too, and record 7202); the noise is found on
    top of the hum."""
    from skdelay.systems import Ikeda

    ik = Ikeda()
    x = ik.simulate(6000, sample_dt=0.25, random_state=seed)
    y = get_effect("measurement_noise").apply(x, {"noise": 0.2}, random_state=seed + 1)
    real = get_effect("periodic_interference").apply(
        y, {"frequency": 1.03, "amplitude": 0.13, "phase": 0.7}, sample_dt=0.25)
    rep = diagnose_gap(real, ik, sample_dt=0.25, random_state=1, n_jobs=1)
    assert set(_found(rep)) == {"periodic_interference", "measurement_noise"}, rep.effects
    fitted = dict(zip(rep.combined["effects"], rep.combined["params"], strict=True))
    assert fitted["periodic_interference"]["frequency"] == pytest.approx(1.03, abs=0.005)
    assert fitted["measurement_noise"]["noise"] == pytest.approx(0.2, rel=0.3)


def test_a_second_effect_must_answer_the_rest_that_called_for_it(monkeypatch):
    """A share of a rest within the threshold, or a broadband indicator brought back, names
    no second cause; the localised mark that made the rest worth a second round does
    (benchmark seed 14.9e6: drifts on top of an outlier fit and of a low-pass fit)."""
    import pandas as pd

    from skdelay.gap import _diagnose

    table = pd.DataFrame({"effect": ["parameter_drift", "periodic_interference", "lowpass"],
                          "status": ["ok"] * 3, "shrink": [0.45, 0.26, 0.1],
                          "consistent": [None] * 3})
    leaves = {"parameter_drift": {"spectral_line": (3.4, 2.1)},
              "periodic_interference": {},
              "lowpass": {"spectral_line": (3.5, 2.1)}}
    evaluations = list(table["effect"])
    monkeypatch.setattr(_diagnose, "off_indicators", lambda problem, ev: leaves[ev])
    line_off = {"spectral_line": (3.5, 2.1), "autocorrelation": (1.0, 2.8)}
    choose = _diagnose._second_choice
    # a significant rest: the top row's share decides
    assert choose(None, line_off, table, evaluations, rest_significant=True) == 0
    # a rest within the threshold, called for by its line: the row that takes the line back
    assert choose(None, line_off, table, evaluations, rest_significant=False) == 1
    # only broadband indicators off: a small share that takes one back is no second cause
    broad = {"cross_prediction": (3.4, 5.5), "segment": (8.9, 7.5)}
    leaves.update({"parameter_drift": {"segment": (8.9, 7.5)},
                   "periodic_interference": broad, "lowpass": broad})
    small = table.assign(shrink=[0.1, 0.0, -0.1])
    assert choose(None, broad, small, evaluations, rest_significant=True) is None
    # ... but a bin Z_LOCAL spreads off is a localised mark
    spike = {"cross_prediction": (3.4, 5.5), "segment": (8.9, _diagnose.Z_LOCAL + 1)}
    leaves["parameter_drift"] = {"cross_prediction": (3.4, 5.5)}
    assert choose(None, spike, small, evaluations, rest_significant=True) == 0


def _lowpass_noise(system, seed, cutoff, noise, dt, n=6000):
    """``(system, record)``: a run of ``system`` behind a low-pass, under white noise."""
    x = system.simulate(n, sample_dt=dt, random_state=seed)
    y = get_effect("lowpass").apply(x, {"cutoff": cutoff}, sample_dt=dt)
    return system, get_effect("measurement_noise").apply(y, {"noise": noise},
                                                         random_state=seed + 1)


def _ikeda_lowpass_noise(seed, cutoff, noise, dt=0.5, n=6000):
    from skdelay.systems import Ikeda

    return _lowpass_noise(Ikeda(), seed, cutoff, noise, dt, n)


@pytest.mark.parametrize(("seed", "cutoff", "noise"), [(641, 0.068, 0.56), (642, 0.05, 0.4)])
def test_a_lowpass_under_strong_noise_is_fitted_in_turn_with_it(seed, cutoff, noise):
    """Ikeda at step 0.5 behind a low-pass, under white noise of about half its std: the
    low-pass fitted alone compromises with the noise's white floor (0.53 for 0.068 on the
    record of benchmark seed 19.3e6), and the noise fitted on top of that compromise
    leaves most of the gap.  Fitted in turn (JOINT_ROUNDS), both come out right and the
    pair leaves a tenth of what the one-after-the-other pair leaves."""
    from skdelay.gap._diagnose import _joint_pair
    from skdelay.gap._fit import fit_effect
    from skdelay.gap._problem import GapProblem

    ik, real = _ikeda_lowpass_noise(seed, cutoff, noise)
    problem = GapProblem(real, ik, sample_dt=0.5, random_state=1, n_jobs=1)
    lowpass, measurement_noise = get_effect("lowpass"), get_effect("measurement_noise")
    alone = fit_effect(lowpass, problem)
    plain = fit_effect(measurement_noise, problem, [(lowpass, alone.params)])
    params, pair = _joint_pair(problem, lowpass, alone.params, measurement_noise)
    assert params["cutoff"] == pytest.approx(cutoff, rel=0.15)
    assert pair.params["noise"] == pytest.approx(noise, rel=0.1)
    assert pair.gap_after < 0.1 * plain.gap_after, (alone.params, plain.gap_after)


@pytest.mark.parametrize(("seed", "cutoff", "noise"), [(661, 0.09, 0.7), (662, 0.12, 0.65)])
def test_a_lowpass_under_very_strong_noise_is_reached_from_spread_starts(seed, cutoff, noise):
    """Under noise of about 0.7 std the low-pass alone reads "no filter" (0.9-2), the noise
    on top of it finds little to add, and the turns from there stay put (the pair keeps
    most of the gap).  From the best of the low-pass's spread starts (Lowpass.starts, noise
    fitted on top of each) the turns reach the truth."""
    from skdelay.gap._diagnose import _joint_pair
    from skdelay.gap._fit import fit_effect
    from skdelay.gap._problem import GapProblem

    ik, real = _ikeda_lowpass_noise(seed, cutoff, noise)
    problem = GapProblem(real, ik, sample_dt=0.5, random_state=1, n_jobs=1)
    lowpass, measurement_noise = get_effect("lowpass"), get_effect("measurement_noise")
    alone = fit_effect(lowpass, problem)
    stuck, stuck_pair = _joint_pair(problem, lowpass, alone.params, measurement_noise,
                                    spread=False)
    params, pair = _joint_pair(problem, lowpass, alone.params, measurement_noise)
    assert stuck["cutoff"] > 5 * cutoff  # the failure the starts are for
    assert stuck_pair.gap_after > 0.5 * problem.before.gap
    assert params["cutoff"] == pytest.approx(cutoff, rel=0.2)
    assert pair.params["noise"] == pytest.approx(noise, rel=0.1)
    assert pair.gap_after < 0.1 * stuck_pair.gap_after


def test_a_pair_fitted_in_turn_is_cross_validated_and_reported_as_a_pair():
    """End to end, held out: the runner-up low-pass is refitted in turn with the noise on
    the whole record and on each half; the report names both and says the low-pass
    explains the gap together with the noise, whatever it does alone."""
    ik, real = _ikeda_lowpass_noise(641, 0.068, 0.56)
    rep = diagnose_gap(real, ik, sample_dt=0.5, random_state=1, n_jobs=1,
                       effects=["measurement_noise", "lowpass", "timebase_mismatch"])
    assert set(_found(rep)) == {"lowpass", "measurement_noise"}, rep.effects
    assert rep.explained == "fully"
    fitted = dict(zip(rep.combined["effects"], rep.combined["params"], strict=True))
    assert fitted["lowpass"]["cutoff"] == pytest.approx(0.068, rel=0.15)
    assert fitted["measurement_noise"]["noise"] == pytest.approx(0.56, rel=0.1)
    assert rep.shrink > 0.9  # held out: the halves fit the pair in turn too
    assert rep.combined["joint"] and rep.best_effect == "lowpass"
    assert rep.effects.iloc[0]["shrink"] < 0  # alone the low-pass at 0.065 widens the gap
    assert ("fitted in turn with measurement_noise, it explains the gap together with it"
            in rep.summary())
    # the first screen names both fitted values
    assert "explain it: cutoff = " in rep.summary()
    assert f"; noise = {fitted['measurement_noise']['noise']:.4g} x signal std." in rep.summary()


def test_an_electro_optic_lowpass_under_noise_keeps_its_own_cutoff():
    """The electro-optic oscillator at step 0.25 behind a low-pass at 0.054, under noise of
    0.034 std.  Fitted one after the other, the low-pass read 0.15-0.17 (three records,
    seeds 651-653) and the pair removed 88-90 %, "partly"; fitted in turn, 0.050-0.060 and
    98-100 %.  (The benchmark's record of this kind, seed 19.7e6 with --pairs, named
    nothing at all: there no effect removed MIN_SHRINK alone.)"""
    from skdelay.systems import ElectroOpticOscillator

    eo, y = _lowpass_noise(ElectroOpticOscillator(), 651, 0.054, 0.034, dt=0.25)
    rep = diagnose_gap(y, eo, sample_dt=0.25, random_state=1, n_jobs=1,
                       effects=["measurement_noise", "lowpass", "timebase_mismatch",
                                "dynamical_noise"])
    assert set(_found(rep)) == {"lowpass", "measurement_noise"}, rep.effects
    assert rep.explained == "fully"
    fitted = dict(zip(rep.combined["effects"], rep.combined["params"], strict=True))
    assert fitted["lowpass"]["cutoff"] == pytest.approx(0.054, rel=0.15)
    assert fitted["measurement_noise"]["noise"] == pytest.approx(0.034, rel=0.1)


def test_where_nothing_removes_min_shrink_alone_a_pair_fitted_in_turn_may(monkeypatch):
    """The electro-optic oscillator at step 0.25 behind a low-pass at 0.054, under noise of
    0.05 std: alone, no effect removes MIN_SHRINK (the best, a delay change, 17 %; the
    low-pass 16 %, the noise 4 %), so round 1 names nothing.  The pairs fitted in turn are
    then tried on the whole gap, and the noise with the low-pass explains it."""
    from skdelay.gap import _diagnose
    from skdelay.systems import ElectroOpticOscillator

    calls = []
    better_first = _diagnose._better_first

    def spy(problem, table, evaluations, by_name, second, second_evals, parallel):
        pick = better_first(problem, table, evaluations, by_name, second, second_evals,
                            parallel)
        calls.append((second is None and second_evals[0] is problem.before,
                      float(table["shrink"].max()), pick))
        return pick

    monkeypatch.setattr(_diagnose, "_better_first", spy)
    eo, y = _lowpass_noise(ElectroOpticOscillator(), 672, 0.054, 0.05, dt=0.25)
    rep = diagnose_gap(y, eo, sample_dt=0.25, random_state=1, n_jobs=1,
                       effects=["lowpass", "measurement_noise", "timebase_mismatch",
                                "delay_mismatch"])
    rescue = [c for c in calls if c[0]]
    assert rescue and rescue[0][1] < _diagnose.MIN_SHRINK  # the path this test is for
    assert rescue[0][2] is not None and rescue[0][2][1] is not None  # a pair fitted in turn
    assert set(_found(rep)) == {"lowpass", "measurement_noise"}, rep.effects
    assert rep.explained == "fully" and rep.combined["joint"]
    fitted = dict(zip(rep.combined["effects"], rep.combined["params"], strict=True))
    assert fitted["lowpass"]["cutoff"] == pytest.approx(0.054, rel=0.25)
    assert fitted["measurement_noise"]["noise"] == pytest.approx(0.05, rel=0.1)


@pytest.mark.parametrize("spread", [True, False])
def test_a_pair_from_a_spread_start_must_leave_a_quarter_of_the_best_pair(monkeypatch, spread):
    """Beneath true outliers (Mackey-Glass, benchmark seed 20.3e6) a low-pass that alone
    removed 1 % of the gap, started from one of its spread cutoffs, left 12.2 with the
    outliers where the outliers alone left 31.1: under PAIR_RATIO, but not under
    SPREAD_RATIO, so the outliers stay the answer.  From the low-pass's own fit the same
    gap would take the lead."""
    from types import SimpleNamespace

    import pandas as pd
    from joblib import Parallel

    from skdelay.gap import _diagnose

    table = pd.DataFrame({"effect": ["outliers", "lowpass"], "shrink": [0.987, 0.01],
                          "status": ["ok"] * 2, "params": [{}, {"cutoff": 0.72}],
                          "consistent": [None, None]})
    by_name = {name: get_effect(name) for name in ("outliers", "lowpass")}

    def fake_joint(problem, first, first_params, second, final=True, spread_=True):
        if first.name == "lowpass":
            return {"cutoff": 0.068}, SimpleNamespace(ok=True, gap_after=12.2, spread=spread)
        return dict(first_params), SimpleNamespace(ok=True, gap_after=30.9, spread=False)

    monkeypatch.setattr(_diagnose, "off_indicators", lambda problem, ev: {"spectrum": 1})
    monkeypatch.setattr(_diagnose, "_joint_pair", fake_joint)
    pick = _diagnose._better_first(None, table, [object()] * 2, by_name, None,
                                   [SimpleNamespace(gap=31.1)], Parallel(n_jobs=1))
    assert 12.2 < _diagnose.PAIR_RATIO * 31.1 and 12.2 > _diagnose.SPREAD_RATIO * 31.1
    assert pick == (None if spread else (1, {"cutoff": 0.068}, "outliers"))


def test_a_hum_under_a_lowpass_is_cross_validated_with_the_lowpass_refitted_beneath_it():
    """Round 2 scores the second effect on the half it was not fitted on with the pair
    fitted in turn on the other half, as on the whole record.  Ikeda at step 0.25 (6000
    samples), a 1.38-std hum of 23.5 cycles per record under a low-pass at 0.068: each half
    fitted the low-pass alone far below its cutoff (it absorbed the hum), the hum on top of
    that compromise removed nothing held out, and dynamical noise was named as the second
    cause, the record "partly explained"."""
    from skdelay.systems import Ikeda

    ik, dt, n = Ikeda(), 0.25, 6000
    x = ik.simulate(n, sample_dt=dt, random_state=7)
    hum = {"frequency": 23.5 / (n * dt), "amplitude": 1.38, "phase": 4.45}
    real = get_effect("lowpass").apply(
        get_effect("periodic_interference").apply(x, hum, sample_dt=dt), {"cutoff": 0.068},
        sample_dt=dt)
    rep = diagnose_gap(real, ik, sample_dt=dt, random_state=1, n_jobs=2,
                       effects=["lowpass", "periodic_interference", "dynamical_noise"])
    assert _found(rep) == ["lowpass", "periodic_interference"], rep.effects
    assert rep.explained == "fully"
    fitted = dict(zip(rep.combined["effects"], rep.combined["params"], strict=True))
    assert fitted["periodic_interference"]["frequency"] == pytest.approx(
        hum["frequency"], abs=0.5 / (n * dt))  # within half a bin of the record
    assert fitted["lowpass"]["cutoff"] == pytest.approx(0.068, rel=0.2)
    assert rep.combined["shrink"] > 0.9  # held out
