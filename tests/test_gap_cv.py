"""Cross-validated shrink: fit on one half of the record, score on the other, both ways."""

from types import SimpleNamespace
from typing import ClassVar

import numpy as np
import pytest

from skdelay.gap import Effect, diagnose_gap, get_effect
from skdelay.gap._diagnose import MIN_SHRINK
from skdelay.gap._effects import NotApplicable
from skdelay.gap._problem import GapProblem
from skdelay.systems import MackeyGlass

MG = MackeyGlass()
N = 12_000


def test_split_halves_share_seeds_and_runs():
    real = MG.simulate(N, random_state=7101)
    problem = GapProblem(real, MG, n_sims=3, random_state=0)
    first, second = problem.split()
    assert first.n_samples == second.n_samples == N // 2
    assert np.array_equal(first.real, real[: N // 2]) and np.array_equal(second.real,
                                                                         real[N // 2:])
    assert np.array_equal(second.base[1], problem.base[1][N // 2: N])
    assert list(first.sim_seeds) == list(problem.sim_seeds)
    # both halves search where the whole record's dip says, not where a half's noisier dip
    # would (its placement is a choice made on the whole record, as the lines are)
    assert first.dip is problem.dip and second.dip is problem.dip
    assert first.dip_spread == problem.dip_spread and second.dip_real == problem.dip_real


def test_drift_continues_its_ramp_on_the_held_out_half():
    drift = get_effect("parameter_drift")
    fit = {"parameter": "b", "start": 0.1, "end": 0.107}
    assert drift.transfer(fit, 5000, 5000) == {"parameter": "b", "start": 0.107,
                                               "end": pytest.approx(0.114)}
    const = {"parameter": "b", "start": 0.11, "end": 0.11}
    assert drift.transfer(const, 5000, 5000) == const
    # carried back over the samples before the fitted ones: the same line, earlier
    assert drift.transfer(fit, 5000, 2500, backward=True) == {
        "parameter": "b", "start": pytest.approx(0.0965), "end": 0.1}
    assert drift.transfer(const, 5000, 5000, backward=True) == const



@pytest.mark.parametrize("frequency, dt", [(0.1, 1.0), (5e-5, 1.0), (0.013, 0.25)])
def test_a_hum_carries_its_phase_over_to_the_held_out_half(frequency, dt):
    """The held-out half continues the sinusoid fitted on the first: a slow hum (1.5 cycles
    per half) restarted at its fitted phase ran against the record's."""
    eff = get_effect("periodic_interference")
    fit = {"frequency": frequency, "amplitude": 0.05, "phase": 0.4}
    h = 30_000
    whole = eff.apply(np.zeros(2 * h) + 1.0, fit, sample_dt=dt)
    moved = eff.transfer(fit, h, h, sample_dt=dt)
    assert moved["frequency"] == frequency and moved["amplitude"] == 0.05
    second = eff.apply(np.zeros(h) + 1.0, moved, sample_dt=dt)
    np.testing.assert_allclose(second, whole[h:], atol=1e-9)
    # fitted on the second half, carried back to the first: the same sinusoid
    back = eff.transfer(moved, h, h, sample_dt=dt, backward=True)
    first = eff.apply(np.zeros(h) + 1.0, back, sample_dt=dt)
    np.testing.assert_allclose(first, whole[:h], atol=1e-9)


class _Level(Effect):
    """A stationary effect whose fit on a part is that part's ``level`` (test double)."""

    name = "level_shift"
    bounds: ClassVar[dict] = {"level": (0.0, 10.0)}

    def initial(self, problem):
        return {"level": problem.level}

    def search(self, problem, guess, objective):
        return guess


class _AnchoredLevel(_Level):
    name = "anchored_level"
    anchored_at_start = True


class _OwnTransfer(_Level):
    name = "own_transfer"

    def transfer(self, params, n_fit, n_score):
        return dict(params)


class _Part:
    """A half of a record whose true level is ``truth``: gap 10 without the effect,
    10 |level - truth| with it; its clean runs' own gaps have median ``null``."""

    def __init__(self, truth, null):
        self.level, self.truth, self.n_samples, self.sample_dt = truth, truth, 100, 1.0
        self.simulator = None
        self.before = SimpleNamespace(gap=10.0)
        self.null_gaps = np.array([null])

    def evaluate(self, chain, tier="full"):
        level = sum(p["level"] for _, p in chain)
        return SimpleNamespace(gap=10.0 * abs(level - self.truth))


def test_cross_validation_pools_both_folds_unless_an_effect_is_anchored():
    """Each half fits, the other scores, and the held-out gaps are summed; an effect tied to
    the record's start whose search ignores a part's anchor, or with a forward-only
    ``transfer`` of its own, is scored on the forward fold alone."""
    from joblib import Parallel

    from skdelay.gap._diagnose import cross_validate

    parts = (_Part(1.0, 0.5), _Part(1.2, 0.25))
    effects = [_Level(), _AnchoredLevel(), _OwnTransfer()]
    before, scores, null = cross_validate(effects, parts, Parallel(n_jobs=1))
    assert before == 20.0 and null == 0.75
    after, params, b, n = scores["level_shift"]
    # fitted on the first half (1.0) and scored on the second (truth 1.2): 2; and back
    assert (after, b, n) == (pytest.approx(4.0), 20.0, 0.75)
    assert params == ({"level": 1.0}, {"level": 1.2})
    for name in ("anchored_level", "own_transfer"):
        after, params, b, n = scores[name]
        assert (after, b, n) == (pytest.approx(2.0), 10.0, 0.25)
        assert params == ({"level": 1.0}, None)


class _AnchoredRamp(_AnchoredLevel):
    """Fits a later part on a ramp through the record's start, as the built-in drift."""

    name = "anchored_ramp"
    fits_anchored_parts = True


def test_a_ramp_through_the_records_start_is_scored_on_the_backward_fold_alone():
    """Fitted on the first half a ramp sees the smaller part of the change, and its slope,
    continued over the second half, doubles its error there; fitted on the second half
    through the record's start and carried back, the error halves.  The forward fold
    refuted a true drift (benchmark seed 22.2e6: Mackey-Glass, b 0.1 -> 0.0966, the first
    half's slope took the second half's gap from 27.7 to 72.1), so such an effect is scored
    on the backward fold alone, and on the forward one only where no backward fold is live.
    """
    from joblib import Parallel

    from skdelay.gap._diagnose import _interpolates_backward, cross_validate

    parts = (_Part(1.0, 0.5), _Part(1.2, 0.25))
    _, scores, _ = cross_validate([_Level(), _AnchoredRamp()], parts, Parallel(n_jobs=1))
    after, params, b, n = scores["anchored_ramp"]
    # fitted on the second half (1.2) and scored on the first (truth 1.0) only
    assert (after, b, n) == (pytest.approx(2.0), 10.0, 0.5)
    assert params == (None, {"level": 1.2})
    assert scores["level_shift"][1] == ({"level": 1.0}, {"level": 1.2})  # both ways
    assert _interpolates_backward(get_effect("parameter_drift"))
    assert not _interpolates_backward(_AnchoredLevel())
    # on top of an effect that moves forward only, the backward fold is not live: the
    # forward fold tests the ramp
    chain = [(_OwnTransfer(), ({"level": 0.0}, {"level": 0.0}))]
    _, scores, _ = cross_validate([_AnchoredRamp()], parts, Parallel(n_jobs=1), chain=chain)
    assert scores["anchored_ramp"][1] == ({"level": 1.0}, None)


class _SimLevel(_Level):
    """The level as a change to the simulator: its runs are a new draw."""

    name = "sim_level"
    target = "simulation"


class _DrawnPart(_Part):
    """A half cut with an unlucky ensemble: gap 10 against it, ``fresh`` against new ones."""

    def __init__(self, truth, null, fresh):
        super().__init__(truth, null)
        self.fresh = fresh

    def reseeded(self, seed):
        return SimpleNamespace(evaluate=lambda chain, tier="full": SimpleNamespace(
            gap=self.fresh[seed - 1]))


def test_a_simulation_effect_is_scored_against_a_fresh_draw_of_the_held_out_half():
    """A simulation effect re-draws the simulator's runs, so its held-out gap is compared
    with the median of the half's own gap and REPLICATES fresh ones: it gets no credit for
    what a new draw alone removes (held-out-step benchmark seed 21.8e6: Ikeda at step 0.25,
    a half's gap 8.31 against fresh draws of 3.8-6.8, and dynamical noise of 1e-4 "removed"
    54 % of it).  An observation effect acts on the same runs and keeps the half's own."""
    from joblib import Parallel

    from skdelay.gap._diagnose import REPLICATES, cross_validate

    assert REPLICATES == 2
    parts = (_DrawnPart(1.0, 0.5, [4.0, 6.0]), _DrawnPart(1.2, 0.25, [3.0, 2.0]))
    before, scores, _ = cross_validate([_Level(), _SimLevel()], parts, Parallel(n_jobs=1))
    assert before == 20.0
    after_obs, _, b_obs, _ = scores["level_shift"]
    after_sim, _, b_sim, _ = scores["sim_level"]
    assert after_obs == after_sim == pytest.approx(4.0)  # the same fits, the same gaps
    assert b_obs == 20.0 and b_sim == pytest.approx(6.0 + 3.0)  # medians of (10, 4, 6), (10, 3, 2)


def test_a_drift_is_untested_when_one_half_holds_no_gap_of_its_own():
    """A half within its no-gap threshold while the other is far beyond it holds none of a
    discrepancy that builds up over the record: neither fold can test a drift (fitted there
    it extrapolates flat, scored there it has nothing to remove; held-out-step benchmark
    seed 21.1e6, a laser's beta 0.27 -> 0.107, first half 4.2 against 11.6, second 226),
    so it stays uncross-validated.  A stationary effect is still tested both ways, and a
    drift is tested as before when both halves show the gap.  When both are quiet the split
    tests nothing (a held-out half has nothing to remove beyond its runs' scatter)."""
    from joblib import Parallel

    from skdelay.gap._diagnose import cross_validate

    quiet, loud = _Part(1.0, 0.5), _Part(1.2, 0.25)
    quiet.before = SimpleNamespace(gap=1.0)

    class Counted(_AnchoredLevel):
        fits = 0

        def search(self, problem, guess, objective):
            Counted.fits += 1
            return guess

    effects = [_Level(), Counted()]
    _, scores, _ = cross_validate(effects, (quiet, loud), Parallel(n_jobs=1))
    assert "anchored_level" not in scores
    assert Counted.fits == 0  # a fold that cannot test the drift is not even fitted
    effects = [_Level(), _AnchoredLevel()]
    assert scores["level_shift"][1] == ({"level": 1.0}, {"level": 1.2})
    loud_pair = (_Part(1.0, 0.5), _Part(1.2, 0.25))
    _, scores, _ = cross_validate(effects, loud_pair, Parallel(n_jobs=1))
    assert scores["anchored_level"][1] == ({"level": 1.0}, None)
    quiet_pair = (quiet, _Part(1.2, 0.25))
    quiet_pair[1].before = quiet.before
    before, scores, null = cross_validate(effects, quiet_pair, Parallel(n_jobs=1))
    assert scores == {} and before == 2.0 and null == 0.75
    # ... but a second round's rest on top of a chain is tested as before
    _, scores, _ = cross_validate(effects, quiet_pair, Parallel(n_jobs=1),
                                  chain=[(_Level(), ({"level": 0.0}, {"level": 0.0}))])
    assert set(scores) == {"level_shift", "anchored_level"}


def test_a_drift_fits_a_later_part_on_the_ramp_through_the_records_start():
    """On the record's second half (``anchor`` 0.5-1) the drift's search scans ramps whose
    line passes through the simulator's value at the record's start, so carried back over
    the first half the fit starts there; the first half (and a whole record) is fitted as
    before.  Hence the drift is cross-validated both ways (``_moves_backward``), while an
    anchored effect whose search ignores the anchor stays forward only."""
    from skdelay.gap._diagnose import _moves_backward

    drift = get_effect("parameter_drift")
    v0, e_true = MG.params["a"], 0.23  # a drifting 0.2 -> 0.23 over the record
    seen = []

    def objective(p):  # the gap of the second half: least on the true line's second half
        seen.append(p)
        return 1e4 * ((p["start"] - 0.5 * (v0 + e_true)) ** 2 + (p["end"] - e_true) ** 2)

    part = SimpleNamespace(simulator=MG, anchor=(0.5, 1.0), pinned={drift.name: "a"})
    fit = drift.search(part, drift.initial(part), objective)
    assert fit["parameter"] == "a" and fit["end"] == pytest.approx(e_true, rel=0.02)
    for p in seen:  # every ramp tried lies on a line through v0 at the record's start (the
        # last is the constant mismatch, the same over the whole record)
        assert p["start"] == pytest.approx(0.5 * (v0 + p["end"])) or p["start"] == p["end"]
    assert sum(p["start"] == p["end"] for p in seen) == 1
    back = drift.transfer(fit, 3000, 3000, backward=True)
    assert back["start"] == pytest.approx(v0) and back["end"] == pytest.approx(fit["start"])
    # the first part (and a whole record: no anchor) starts at v0 itself
    first = SimpleNamespace(simulator=MG, anchor=(0.0, 0.5), pinned={drift.name: "a"})
    seen.clear()
    drift.search(first, drift.initial(first), objective)
    assert all(p["start"] == v0 for p in seen[:6])
    assert _moves_backward(drift) and not _moves_backward(_AnchoredLevel())


def test_a_later_part_of_a_drift_is_simulated_from_the_records_start():
    """The second half's ramp (on the line through the simulator's value at the record's
    start) is simulated with the first half as its history and cut off: the runs equal the
    second half of a whole-record run of the same ramp, bit for bit.  Started afresh at the
    half's first value, the CO2 laser can settle on another attractor (pump r 195 -> 129,
    held-out-style benchmark seed 19.4e6: the true ramp over the second half alone left
    that half's gap at 2701 against 544 with no drift; from the record's start the drift
    fitted on the second half is r 161 -> 127, cross-validated gap 4.2)."""
    from skdelay.gap._problem import run_simulator

    drift = get_effect("parameter_drift")
    v0, end, n = MG.params["b"], 0.115, 2000
    half = {"parameter": "b", "start": 0.5 * (v0 + end), "end": end}
    over = drift.overrides(half, MG)
    assert over["b"] == (pytest.approx(v0), end)
    run = run_simulator(MG, n, 1.0, 11, over)
    whole = MG.simulate(2 * n, random_state=11, b=(v0, end))
    assert run.size == n and np.array_equal(run, whole[n:])
    # a whole record's ramp (from v0) and a constant mismatch have no history
    assert drift.overrides({"parameter": "b", "start": v0, "end": end}, MG) == {"b": (v0, end)}
    assert drift.overrides({"parameter": "b", "start": 0.12, "end": 0.12}, MG) == {"b": 0.12}
    # a ramp moving back towards v0 is not on a line from it: no history
    assert drift.overrides({"parameter": "b", "start": 0.12, "end": 0.11}, MG) == {
        "b": (0.12, 0.11)}
    # a ramp far off v0 that barely moves gets at most one part's length of history
    far = drift.overrides({"parameter": "b", "start": 0.2, "end": 0.2001}, MG)
    assert far["b"] == (pytest.approx(0.1999), 0.2001)


def test_the_halves_know_where_they_lie():
    problem = GapProblem(MG.simulate(N, random_state=7103), MG, n_sims=3, random_state=0)
    first, second = problem.split()
    assert first.anchor == (0.0, 0.5) and second.anchor == (0.5, 1.0)
    assert not hasattr(problem, "anchor")


@pytest.fixture(scope="module")
def half_hum_report():
    """A hum in the first half of the record only: fitted in-sample it removes part of the
    whole record's gap, but what is fitted on the first half does not carry over."""
    x = MG.simulate(N, random_state=7202)
    t = np.arange(N)
    real = x + np.where(t < N // 2, 0.08 * x.std() * np.sin(2 * np.pi * 0.0831 * t), 0.0)
    return diagnose_gap(real, MG, random_state=0, n_jobs=2, combine=False,
                        effects=["periodic_interference", "measurement_noise"])


def test_cross_validated_columns_are_consistent(half_hum_report):
    t = half_hum_report.effects
    ok = t[t.status == "ok"]
    for col in ("gap_after_fit", "shrink_fit", "cv_gap_before", "cv_gap_after"):
        assert col in t.columns
    assert np.allclose(ok.shrink, 1 - ok.cv_gap_after.clip(lower=0) / ok.cv_gap_before)
    assert np.allclose(ok.gap_after, ok.gap_before * (1 - ok.shrink))
    assert list(ok.gap_after) == sorted(ok.gap_after)
    assert half_hum_report.info["cross_validated"]


def test_non_stationary_cause_does_not_carry_over(half_hum_report):
    rep = half_hum_report
    row = rep.effects.set_index("effect").loc["periodic_interference"]
    # in-sample, a hum of about half the amplitude removes enough of the whole record's gap
    # to be accepted (measured: 0.46) ...
    assert row.shrink_fit >= MIN_SHRINK
    # ... but the hum fitted on the first half does not help the second half (no hum)
    assert row.shrink < MIN_SHRINK <= row.shrink_fit
    assert rep.best_effect is None and rep.explained == "not explained"


def test_short_record_is_not_split():
    x = MG.simulate(3000, random_state=7303)
    real = x + 0.1 * x.std() * np.sin(2 * np.pi * 0.0831 * np.arange(3000))
    rep = diagnose_gap(real, MG, random_state=0, n_sims=3, combine=False,
                       effects=["periodic_interference"])
    assert not rep.info["cross_validated"]
    row = rep.effects.iloc[0]
    assert np.isnan(row.cv_gap_after) and row.shrink == pytest.approx(row.shrink_fit)


def test_halves_drift_the_parameter_chosen_on_the_whole_record():
    from types import SimpleNamespace

    from skdelay.gap._diagnose import pin_choices

    drift = get_effect("parameter_drift")
    parts = (SimpleNamespace(simulator=MG), SimpleNamespace(simulator=MG))
    whole = [SimpleNamespace(effect="parameter_drift", ok=True,
                             params={"parameter": "n", "start": 10.0, "end": 10.3}),
             SimpleNamespace(effect="lowpass", ok=True, params={"cutoff": 0.1})]
    free = drift.ranked(parts[0])
    assert set(free) == {"a", "b", "n"}
    pin_choices(parts, whole)
    assert parts[0].pinned == parts[1].pinned == {"parameter_drift": "n"}
    assert drift.ranked(parts[0]) == ["n"] and drift.ranked(parts[1]) == ["n"]
    # a failed whole-record fit pins nothing
    other = (SimpleNamespace(simulator=MG),)
    pin_choices(other, [SimpleNamespace(effect="parameter_drift", ok=False, params={})])
    assert other[0].pinned == {} and set(drift.ranked(other[0])) == {"a", "b", "n"}


def test_halves_fit_a_hum_on_the_line_chosen_on_the_whole_record(monkeypatch):
    """Which line a hum sits on is chosen on the whole record; a half only fits the
    hum's amplitude and phase there.  Chosen on a half, the second half of an Ikeda record
    (benchmark seed 12.8e6) put the hum on a line at 0.217 instead of the record's 0.408
    cycles per time unit, and the cross-validated shrink read -0.41 (in-sample 0.98)."""
    from skdelay.gap import PeriodicInterference
    from skdelay.gap._diagnose import pin_choices
    from skdelay.gap._lines import Line

    n = 3000
    real = MG.simulate(n, random_state=541)
    real = real + 0.2 * real.std() * np.sin(2 * np.pi * 0.2 * np.arange(n) + 1.0)

    def line(f):
        return Line(frequency=f, amplitude=0.1, phase=0.0, z=5.0, f_stat=50.0, p_value=1e-4,
                    bin_width=1.0 / n, half_width=3.0 / n)

    tried = []

    def objective(params):  # this half's reading prefers the other line
        tried.append(params["frequency"])
        return abs(params["frequency"] - 0.31)

    # the amplitude search after the choice of the starting line is not what is tested here
    monkeypatch.setattr(Effect, "search", lambda self, problem, guess, objective: guess)
    hum = PeriodicInterference()
    part = SimpleNamespace(real=real, lines=[line(0.2), line(0.31)], line_hints=[],
                           sample_dt=1.0)
    assert hum.search(part, hum.initial(part), objective)["frequency"] == pytest.approx(0.31)
    pin_choices((part,), [SimpleNamespace(effect="periodic_interference", ok=True,
                                          params={"frequency": 0.2, "amplitude": 0.2,
                                                  "phase": 1.0})])
    assert part.pinned == {"periodic_interference": 0.2}
    tried.clear()
    start = hum.initial(part)
    assert start["amplitude"] == pytest.approx(0.2, rel=0.15)  # read off the half itself
    assert hum.search(part, start, objective)["frequency"] == pytest.approx(0.2)
    assert tried == []  # no other line was tried


def test_a_half_fits_a_drift_with_the_whole_ensemble():
    """The first half's drift fit drives the held-out score: with two runs of half the
    record its search objective was too rough (Ikeda, mu 20 -> 25 over 6000 samples at step
    0.5: the first half ended at 21.6 instead of 22.5, held-out shrink 0.68)."""
    from skdelay.gap._diagnose import pin_choices
    from skdelay.gap._fit import fit_effect
    from skdelay.systems import Ikeda

    ikeda, dt = Ikeda(), 0.5
    real = ikeda.simulate(6000, sample_dt=dt, random_state=7404, mu=(20.0, 25.0))
    problem = GapProblem(real, ikeda, sample_dt=dt, random_state=7404)
    drift = get_effect("parameter_drift")
    whole = fit_effect(drift, problem)
    first, second = problem.split()
    assert first.search_sims == second.search_sims == len(problem.base)
    pin_choices((first, second), [whole])
    fit = fit_effect(drift, first, [], False).params
    assert fit["parameter"] == "mu" and fit["end"] == pytest.approx(22.5, abs=0.5)
    moved = drift.transfer(fit, first.n_samples, second.n_samples, sample_dt=dt)
    after = second.evaluate([(drift, moved)], "full").gap
    assert 1.0 - after / second.before.gap > 0.9


@pytest.mark.parametrize("cv_before, cv_after, shrink, tested", [
    (0.19, 0.28, 0.9, False),  # no gap in the held-out half, with or without the effect:
                               # it cannot test the effect, the in-sample share stands
    (0.19, 3.0, 1 - 3.0 / 0.19, True),  # the effect creates a gap there: refuted
    (4.0, 2.0, 0.5, True),     # a gap to explain there: the held-out share (4 -> 2)
    (4.0, 0.2, 0.9, True),     # ... never above the in-sample one (0.95 capped at 0.9)
    (4.0, 0.8, 0.9, True),     # left within the half's no-gap level: confirmed, and the
                               # null scatter (0.8) does not count against it (not 0.8)
    (4.0, 1.2, 0.7, True),     # left beyond it: the held-out share
])
def test_held_out_share_is_used_only_where_the_half_can_test_the_effect(cv_before, cv_after,
                                                                        shrink, tested):
    from skdelay.gap._diagnose import _table

    eff = get_effect("measurement_noise")
    res = SimpleNamespace(effect=eff.name, ok=True, gap_after=0.5, params={"noise": 0.01},
                          status="ok", reason="", target=eff.target, n_evals=1, seconds=0.0,
                          evaluation=None)
    problem = SimpleNamespace(real=np.arange(10.0), time_unit=None, sample_dt=1.0)
    # gaps summed over the held-out halves; their summed no-gap level: 1
    cv = (cv_before, {eff.name: (cv_after, ({}, {}), cv_before, 1.0)}, 1.0)
    table, _ = _table([res], 5.0, problem, {eff.name: eff}, cv)
    row = table.iloc[0]
    assert row["shrink"] == pytest.approx(shrink)
    assert row["shrink_fit"] == pytest.approx(0.9)
    assert bool(row["cross_validated"]) is tested


@pytest.mark.parametrize("seed, at, state", [
    # all three in the second half: the first has none to fit (the effect does not apply
    # there), and "failed on the held-out half" ranked the outliers last
    (7102, (3400, 4300, 5500), 5),
    # the mirror case: spikes added to the spike-free second half would raise its gap and
    # "refute" them, but a half holds none of three with probability 1/8
    (7103, (400, 1300, 2500), 6),
])
def test_spikes_all_in_one_half_leave_the_outliers_untested_not_failed(seed, at, state):
    """Three spikes in one half: the split cannot test the outliers, which keep their
    in-sample share."""
    x = MG.simulate(6000, random_state=seed)
    real = x.copy()
    for i, sign in zip(at, (1, -1, 1)):
        real[i] += sign * 4.0 * x.std()
    rep = diagnose_gap(real, MG, random_state=state, n_jobs=1,
                       effects=["outliers", "measurement_noise", "dynamical_noise"])
    assert rep.best_effect == "outliers", rep.effects[["effect", "shrink", "status"]]
    row = rep.effects.set_index("effect").loc["outliers"]
    assert not row["cross_validated"] and np.isnan(row["cv_gap_after"])
    assert row["shrink"] == row["shrink_fit"] > 0.9


def test_two_spikes_are_counted_and_measured_not_searched():
    """Two spikes (5 and 7 std) are read off the record: rate 2 / n and their median
    height.  Before, fewer than four detected spikes were searched from a default start,
    and the search matched the record's two with about eight smaller ones (benchmark
    seed 23.9e6, Mackey-Glass at step 0.5: rate 3.8 x and size 0.45 x the realised)."""
    from skdelay.gap import Outliers

    x = MG.simulate(6000, random_state=7110)
    real = x.copy()
    real[[1700, 4100]] += np.array([5.0, -7.0]) * x.std()
    guess = Outliers().guess(real, MG.simulate(6000, random_state=1)[None], 1.0)
    assert guess["detected"] and guess["measured"]
    assert guess["rate"] == pytest.approx(2 / 6000)
    rep = diagnose_gap(real, MG, random_state=3, n_jobs=1,
                       effects=["outliers", "measurement_noise", "dynamical_noise"])
    assert rep.best_effect == "outliers", rep.effects[["effect", "shrink", "status"]]
    fit = rep.effects.set_index("effect").loc["outliers", "params"]
    assert fit["rate"] == pytest.approx(2 / 6000)
    assert fit["size"] == pytest.approx(6.0, rel=0.2)


def test_a_clipped_end_reached_in_one_half_only_leaves_the_clipping_untested():
    """The electro-optic oscillator reaches its lowest values in the first half only
    (record seed 26): clipped just above the second half's minimum, its 40 piled-up
    samples all lie in the first half.  The second half cannot test a clipping (before, its
    fit clipped the top instead and both folds scored nothing, so the in-sample shrink was
    dropped); the clipping keeps its in-sample share and is named."""
    from skdelay.systems import ElectroOpticOscillator

    eo, dt = ElectroOpticOscillator(), 0.25
    x = eo.simulate(6000, sample_dt=dt, random_state=26)
    level = x[3000:].min()
    real = np.maximum(x, level)
    assert (real[:3000] == level).sum() >= 30 and (real[3000:] == level).sum() <= 1
    rep = diagnose_gap(real, eo, sample_dt=dt, random_state=3, n_jobs=1,
                       effects=["clipping", "measurement_noise", "lowpass"])
    assert rep.best_effect == "clipping", rep.effects[["effect", "shrink", "status"]]
    row = rep.effects.set_index("effect").loc["clipping"]
    assert not row["cross_validated"] and row["shrink"] > 0.9
    assert row["params"]["low"] == pytest.approx((level - x.mean()) / x.std(), abs=0.1)


def test_an_untested_candidate_ranks_by_its_in_sample_share_against_tested_ones():
    """Untested outliers (0.79 in-sample) go after a drift that removes 0.98 in-sample though
    only 0.62 held out, and before noise that removes 0.67 in-sample; an untested candidate
    that removes more in-sample than every tested one leads."""
    import pandas as pd

    from skdelay.gap._diagnose import _untested_in_place

    df = pd.DataFrame({
        "effect": ["outliers", "parameter_drift", "dynamical_noise", "clipping", "quantization"],
        "status": ["ok", "ok", "ok", "ok", "failed"],
        "shrink": [0.79, 0.62, 0.54, 0.05, np.nan],
        "shrink_fit": [0.79, 0.98, 0.67, 0.05, np.nan]})
    scores = {"parameter_drift": (27.1, {}), "dynamical_noise": (32.8, {})}
    order = _untested_in_place(df, scores)
    assert list(df.loc[order, "effect"]) == ["parameter_drift", "outliers", "dynamical_noise",
                                             "clipping", "quantization"]
    df.loc[0, ["shrink", "shrink_fit"]] = 0.995
    order = _untested_in_place(df, scores)
    assert df.loc[order, "effect"].iloc[0] == "outliers"


def test_untested_candidates_among_themselves_rank_by_their_in_sample_shares():
    """Benchmark seed 21.0e6: an electro-optic record clipped below, its clipped samples all
    in one half, so neither the clipping (0.89 in-sample) nor a drift (0.11, the other half
    quiet) could be tested; the drift was placed first and nothing was named."""
    import pandas as pd

    from skdelay.gap._diagnose import _untested_in_place

    df = pd.DataFrame({
        "effect": ["parameter_drift", "clipping", "dynamical_noise", "lowpass"],
        "status": ["ok", "ok", "ok", "ok"],
        "shrink": [0.113, 0.888, 0.027, 0.013],
        "shrink_fit": [0.113, 0.888, 0.027, 0.013]})
    order = _untested_in_place(df, {"dynamical_noise": (22.0, {}), "lowpass": (22.3, {})})
    assert list(df.loc[order, "effect"]) == ["clipping", "parameter_drift", "dynamical_noise",
                                             "lowpass"]


def test_halves_score_the_spikes_counted_on_the_whole_record():
    """Five spikes, one in the first half and four in the second (benchmark seed 15.0e6):
    each half measured its own, was scored on the other half's Poisson luck, and the
    cross-validated shrink read 0.29 against 0.997 in-sample, so nothing was named.  The
    halves now score the whole record's count and height; a half without a spike of its
    own keeps its own reading (it cannot test them)."""
    from skdelay.gap import Outliers
    from skdelay.gap._diagnose import pin_choices

    x = MG.simulate(6000, random_state=7104)
    real = x.copy()
    for i, sign in zip((1700, 3400, 4100, 4900, 5600), (1, -1, 1, -1, 1)):
        real[i] += sign * 4.9 * x.std()
    problem = GapProblem(real, MG, n_sims=3, random_state=1)
    first, second = problem.split()
    out = Outliers()
    assert out.counted(problem) and out.counted(first) and out.counted(second)  # 1 and 4
    whole = SimpleNamespace(effect="outliers", ok=True, params={"rate": 5 / 6000, "size": 4.9})
    pin_choices((first, second), [whole])  # without the whole record: nothing counted
    assert "outliers" not in first.pinned
    pin_choices((first, second), [whole], problem)
    assert first.pinned["outliers"] == second.pinned["outliers"] == whole.params
    for half in (first, second):
        start = out.initial(half)
        assert start["rate"] == pytest.approx(5 / 6000) and start["size"] == 4.9
        assert out.search_bounds(start, half) == {}  # scored as counted, not searched
    # a half without a spike of its own: outliers do not apply there, pinned or not
    clean = GapProblem(np.concatenate([x[:3000], real[3000:]]), MG, n_sims=3,
                       random_state=1).split()[0]
    pin_choices((clean,), [whole], problem)
    with pytest.raises(NotApplicable):
        out.initial(clean)

    rep = diagnose_gap(real, MG, random_state=2, n_jobs=1,
                       effects=["outliers", "measurement_noise", "dynamical_noise"])
    assert rep.best_effect == "outliers", rep.effects[["effect", "shrink", "status"]]
    row = rep.effects.set_index("effect").loc["outliers"]
    assert row["cross_validated"] and row["shrink"] > 0.5


def test_a_rough_half_without_the_counted_spikes_cannot_test_them():
    """Ikeda at step 0.25, four spikes all in the second half (benchmark seed 20.5e6:
    5.4-10 std; here 7-12, which this record needs for a significant gap).  The record
    is rough, so the spike-free first half does not
    refuse the outliers outright: it reads "spikes too small to be seen".  That reading,
    scored on the second half, failed (cross-validated shrink 0.15 against 0.93 in-sample)
    and nothing was named.  A half that holds none of the counted spikes cannot test them,
    so the outliers keep their in-sample share and lead."""
    from skdelay.gap import Outliers
    from skdelay.gap._diagnose import pin_choices
    from skdelay.systems import Ikeda

    ikeda, dt = Ikeda(), 0.25
    x = ikeda.simulate(6000, sample_dt=dt, random_state=7105)
    real = x.copy()
    for i, height in zip((3340, 3740, 4770, 5320), (8.0, 9.0, -7.0, 12.0)):
        real[i] += height * x.std()
    problem = GapProblem(real, ikeda, sample_dt=dt, n_sims=3, random_state=1)
    first, second = problem.split()
    out = Outliers()
    assert out.counted(problem) and out.counted(second)
    assert out.initial(first).get("unseen")  # its own reading: no NotApplicable there
    whole = SimpleNamespace(effect="outliers", ok=True, params={"rate": 4 / 6000, "size": 9.0})
    pin_choices((first, second), [whole], problem)
    with pytest.raises(NotApplicable, match="none of the spikes"):
        out.initial(first)
    assert out.initial(second)["rate"] == pytest.approx(4 / 6000)

    rep = diagnose_gap(real, ikeda, sample_dt=dt, random_state=2, n_jobs=1,
                       effects=["outliers", "measurement_noise", "dynamical_noise"])
    assert rep.best_effect == "outliers", rep.effects[["effect", "shrink", "status"]]
    row = rep.effects.set_index("effect").loc["outliers"]
    # 0.80 (0.88 while the runs drew a Poisson count of spikes: its scatter widened the
    # spread the record is judged against)
    assert not row["cross_validated"] and row["shrink"] == row["shrink_fit"] > 0.75


def test_a_half_searches_the_delay_near_the_whole_records():
    """``pin_choices`` pins the whole record's delay; a half searches within
    SEARCH_HALF_WIDTH samples of it (the window's search was two thirds of a 4e4-sample
    laser diagnosis) and still finds its own best there."""
    from skdelay.gap._diagnose import pin_choices

    delay = get_effect("delay_mismatch")
    parts = (SimpleNamespace(), SimpleNamespace())
    fit = SimpleNamespace(ok=True, effect="delay_mismatch", params={"tau": 16.3})
    pin_choices(parts, [fit])
    assert all(p.pinned == {"delay_mismatch": 16.3} for p in parts)

    class Objective:  # the half's own gap: least at 16.1
        def __init__(self):
            self.best, self.seen = (np.inf, None), []

        def __call__(self, p):
            self.seen.append(p["tau"])
            gap = 100.0 * (p["tau"] - 16.1) ** 2
            if gap < self.best[0]:
                self.best = (gap, dict(p))
            return gap

        precise = __call__

    half = SimpleNamespace(pinned=parts[0].pinned, sample_dt=0.5, simulator=MG, dip=None)
    objective = Objective()
    tau = delay.search(half, {"tau": 17.0}, objective)["tau"]
    assert tau == pytest.approx(16.1, abs=0.05)
    width = delay.SEARCH_HALF_WIDTH * 0.5
    assert min(objective.seen) >= 16.3 - width - 1e-9
    assert max(objective.seen) <= 16.3 + width + 1e-9


def test_costly_fits_are_handed_out_first_and_results_keep_the_candidates_order():
    """The diagnosis hands the simulation fits to its workers before the cheap ones, the
    longest first (a long fit queued last runs alone at the end), and returns every result
    in its task's place."""
    from skdelay.gap import EFFECTS
    from skdelay.gap._diagnose import _fit_cost, costly_first

    handed = []

    def parallel(tasks):
        out = []
        for name in tasks:
            handed.append(name)
            out.append(name.upper())
        return out

    tasks = ["hum", "noise", "delay", "clip", "drift"]
    costs = [_fit_cost(EFFECTS[name]()) for name in (
        "periodic_interference", "dynamical_noise", "delay_mismatch", "clipping",
        "parameter_drift")]
    assert costs == [0.0, 1.0, 1.0, 0.0, 2.0]

    class Odd:  # a registered effect's hint that is no number orders it as unset
        target, fit_cost = "simulation", "slow"

    assert _fit_cost(Odd()) == 1.0
    assert costly_first(parallel, tasks, costs) == ["HUM", "NOISE", "DELAY", "CLIP", "DRIFT"]
    assert handed == ["drift", "noise", "delay", "hum", "clip"]


def test_the_calling_process_works_while_the_tasks_run_and_gets_its_result():
    """``meanwhile`` runs once the fits are handed out (the workers fit while the calling
    process splits the record) and its result comes back beside the fits', which keep
    their order."""
    from skdelay.gap._diagnose import _Stages, costly_first

    events = []

    class Bar:
        total, n = None, 0

        def set_postfix_str(self, s):
            pass

        def update(self, n=1):
            pass

    stages = _Stages(Bar(), [("candidate fits", 3)], n_jobs=1, verbose=0)
    stages.start("candidate fits")

    def task(name):
        events.append(name)
        return name.upper()

    from joblib import delayed

    def meanwhile():
        events.append("meanwhile")
        return 42

    tasks = [delayed(task)(n) for n in ("hum", "drift", "clip", "noise")]
    out, extra = costly_first(stages, tasks, [0.0, 1.0, 0.0, 0.0], meanwhile=meanwhile)
    assert out == ["HUM", "DRIFT", "CLIP", "NOISE"] and extra == 42
    # handed out costly first; the calling process's work done once (one worker: before
    # the tasks, which a sequential joblib runs as their results are collected)
    assert [e for e in events if e != "meanwhile"] == ["drift", "hum", "clip", "noise"]
    assert events.count("meanwhile") == 1


def test_the_record_s_dip_scan_in_a_thread_gives_the_same_dip():
    """With more than one core the record's own dip scan runs in a thread beside the line
    scan; the curves and the dip are those of the scan in the calling process."""
    real = MG.simulate(6000, random_state=7105)
    one = GapProblem(real, MG, n_sims=3, random_state=0, n_jobs=1)
    two = GapProblem(real, MG, n_sims=3, random_state=0, n_jobs=2)
    for a, b in zip(one.dip_curves, two.dip_curves):
        np.testing.assert_array_equal(a, b)
    assert one.dip_real == two.dip_real and one.dip_spread == two.dip_spread
    assert one._start_real_scan(True, 1) is None and two._start_real_scan(True, 2) is not None
