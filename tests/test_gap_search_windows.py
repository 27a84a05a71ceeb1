"""Where a simulation-side effect is searched follows what the forecast-error dips say.

* A timebase factor starts at the ratio of the model's dip to the real data's and is
  searched within the consistency check's tolerance: the gap against the factor is a
  notch ~0.01 wide on a fast chaotic system, narrower than the default grid's spacing.
* A delay mismatch whose real dip cannot be placed against the model's keeps the
  model's delay as its start and is searched over the whole dip window: the shift of
  an unplaceable dip is no evidence (a Mackey-Glass record taken out of the chaotic
  regime by its shorter delay has a flat curve with minima anywhere).
* A parameter drift extends every parameter whose gap still falls at the coarse scan's
  edge before the parameters are compared.
"""

from itertools import pairwise
from types import SimpleNamespace

import numpy as np
import pytest

from skdelay.gap import TimebaseMismatch, diagnose_gap, get_effect
from skdelay.gap._where import TB_TOL, dip_factor
from skdelay.systems import CO2LaserFeedback, ElectroOpticOscillator, MackeyGlass


def _dips(real, sim, spread, comparable=True):
    dip = SimpleNamespace(significant=comparable, depth=0.3, baseline=1.0)
    return SimpleNamespace(dip=dip, dip_real=real, dip_sim=sim, dip_spread=spread,
                           sim_dips=[SimpleNamespace(depth=0.3, baseline=1.0)],
                           real=None, base=[], sample_dt=1.0)


@pytest.mark.parametrize("spread, half", [
    (0.01, TB_TOL),      # a well placed dip: the consistency tolerance's floor
    (1.0, 3 * 1.0 * 0.98 / 50.0),  # DIP_Z standard errors of the ratio
])
def test_timebase_starts_at_the_dips_ratio_and_stays_within_their_tolerance(spread, half):
    ctx = _dips(real=50.0, sim=49.0, spread=spread)
    factor, tol = dip_factor(ctx)
    assert factor == pytest.approx(0.98)
    assert tol == pytest.approx(max(TB_TOL, half))
    eff = TimebaseMismatch()
    assert eff.initial(ctx)["factor"] == pytest.approx(0.98)
    lo, hi = eff.search_bounds({"factor": 0.98}, ctx)["factor"]
    assert (lo, hi) == (pytest.approx(0.98 - tol), pytest.approx(0.98 + tol))


def test_timebase_search_keeps_its_default_width_without_comparable_dips():
    ctx = _dips(real=50.0, sim=49.0, spread=0.01, comparable=False)
    assert dip_factor(ctx) is None
    lo, hi = TimebaseMismatch().search_bounds({"factor": 1.0}, ctx)["factor"]
    assert (lo, hi) == (pytest.approx(0.88), pytest.approx(1.12))


def test_a_two_percent_timebase_on_a_fast_chaotic_system_is_found():
    """Electro-optic oscillator (step 0.25, 80 samples per delay) read with a clock 2 %
    fast: the dip moves by 1.6 samples.  (On one benchmark record of this kind the
    default +-0.12 grid, spacing 0.04, let the cross-validated fit miss the notch and a
    delay change ranked first; on this record the old search found it too, so this test
    guards the capability, the two above the mechanism.)"""
    eo = ElectroOpticOscillator()
    x = eo.simulate(int(6000 * 0.98) + 4, sample_dt=0.25, random_state=7301)
    real = get_effect("timebase_mismatch").apply(x, {"factor": 0.98})[:6000]
    rep = diagnose_gap(real, eo, sample_dt=0.25, random_state=3, n_jobs=1,
                       effects=["timebase_mismatch", "delay_mismatch", "dynamical_noise"])
    assert rep.best_effect == "timebase_mismatch", rep.effects[["effect", "shrink"]]
    factor = rep.effects.set_index("effect").loc["timebase_mismatch", "params"]["factor"]
    assert factor == pytest.approx(0.98, abs=0.004)
    assert rep.shrink > 0.7


def test_a_delay_that_leaves_the_chaotic_regime_is_searched_over_the_dip_window():
    """Mackey-Glass with delay 16.2 instead of 17 is periodic: its forecast-error curve is
    flat within ~15 % with minima at 17 and 22, so its dip cannot be placed.  Started from
    the deeper minimum the delay search ran to 22.9 and left a larger gap than before."""
    real = MackeyGlass(tau=16.2).simulate(6000, random_state=7302)
    rep = diagnose_gap(real, MackeyGlass(), random_state=3, n_jobs=1,
                       effects=["delay_mismatch", "timebase_mismatch", "parameter_drift"])
    assert rep.best_effect == "delay_mismatch", rep.effects[["effect", "shrink"]]
    tau = rep.effects.set_index("effect").loc["delay_mismatch", "params"]["tau"]
    assert tau == pytest.approx(16.2, abs=1.0)  # within one sample


def test_drift_extends_every_parameter_at_the_scan_edge_before_comparing():
    """A parameter whose gap still falls at the coarse scan's edge is extended before the
    parameters are compared: its edge point is not its best.  Here ``a`` falls to its
    minimum at -30 % (gap 7 there, 34 at the -12 % edge) while ``b`` has an interior
    minimum of 23 at -5 % (on the electro-optic oscillator with beta drifting by -29 %,
    eps scattered to 23 and was fitted, shrink 0.18, beta never extended)."""
    from skdelay.gap import ParameterDrift

    sim = SimpleNamespace(params={"tau": 10.0, "a": 5.0, "b": 0.02})
    problem = SimpleNamespace(simulator=sim)

    def objective(p):
        rel = p["end"] / sim.params[p["parameter"]] - 1.0
        if p["start"] != sim.params[p["parameter"]]:
            return 1e3  # a constant offset does not fit this record
        if p["parameter"] == "a":
            return 7.0 + 833.0 * (rel + 0.30) ** 2  # 34 at -12 %, 15 at -20 %
        return 23.0 if abs(rel + 0.05) < 1e-9 else 60.0

    fit = ParameterDrift().search(problem, {}, objective)
    assert fit["parameter"] == "a"
    assert fit["end"] / 5.0 - 1.0 == pytest.approx(-0.30, abs=0.03)


@pytest.mark.parametrize("key, end, seed", [("r", 126.0, 4211), ("b0", 0.117, 4221),
                                            ("r", 252.0, 4232)])
def test_drift_ranks_the_drifting_laser_parameter_among_those_it_scans(key, end, seed):
    # the laser has 12 parameters and only ParameterDrift.max_scanned = 3 are scanned.  One
    # +10 % sensitivity run ranked the drifting one 4th or lower on 7 of 9 such records
    # (seeds 4201-4223: beta 0.27 -> 0.42, r 195 -> 126, b0 0.0975 -> 0.117), here among
    # the first three on all nine: r answers a fall of 20-30 % but hardly one of 10 %.
    # A rise of r (195 -> 252) is seen only by a ramp probe: with constant probes alone it
    # ranked 4th, 9th, 8th and 1st on seeds 4231-4234, with ramps too 1st on all four
    from skdelay.gap._problem import GapProblem

    laser = CO2LaserFeedback(tau=150.0)
    real = laser.simulate(6000, random_state=seed, **{key: (laser.params[key], end)})
    problem = GapProblem(real, laser, random_state=seed % 97, n_jobs=1)
    drift = get_effect("parameter_drift")
    assert key in drift.ranked(problem)[: drift.max_scanned]


def test_drift_extends_each_edge_where_the_gap_still_falls():
    """Both edges of the scan fall outward and the lower one leads nowhere: Ikeda, mu
    20 -> 24.9 (benchmark seed 17.2e6), gaps 16.7 at -12 % and 21.3 at +12 % (44 at +5 %),
    114 at -20 % and 0.1 at +20 %; only the lower edge was extended, and mu was fitted at
    -12 %, the wrong way."""
    from skdelay.gap import ParameterDrift

    sim = SimpleNamespace(params={"tau": 5.0, "mu": 20.0})
    problem = SimpleNamespace(simulator=sim)
    table = {-0.12: 16.7, -0.05: 98.6, -0.02: 80.0, 0.02: 70.0, 0.05: 44.3, 0.12: 21.3,
             -0.2: 113.9, 0.2: 0.1, 0.3: 13.8}

    def objective(p):
        rel = p["end"] / 20.0 - 1.0
        if p["start"] != 20.0:
            return 1e3  # a constant offset does not fit this record
        near = min(table, key=lambda r: abs(r - rel))
        return table[near] + 100.0 * abs(rel - near)  # between the points: worse

    fit = ParameterDrift().search(problem, {}, objective)
    assert fit["end"] / 20.0 - 1.0 == pytest.approx(0.2, abs=0.03)


def test_drift_tries_one_step_beyond_an_edge_that_does_not_fall():
    """A laser answers a fall of its pump r only beyond ~15 %: on the record of r 195 -> 133
    (held-out-style benchmark seed 19.1e6) the scan's -12 % edge was no lower than -5 %
    (113.0 against 112.4), r was never extended, and k1, falling steadily to -65 %, was
    fitted (its ramp, continued over the record's other half, made the gap 2015).  The
    gaps here are that record's."""
    from skdelay.gap import ParameterDrift

    sim = SimpleNamespace(params={"tau": 150.0, "k1": 4.5556, "r": 195.0})
    problem = SimpleNamespace(simulator=sim)
    tables = {
        "r": {-0.45: 37.7, -0.3: 1.3, -0.2: 10.6, -0.12: 113.0, -0.05: 112.4, -0.02: 155.2,
              0.02: 143.6, 0.05: 131.5, 0.12: 118.8, 0.2: 128.8},
        "k1": {-0.9: 140.4, -0.65: 22.6, -0.45: 24.1, -0.3: 95.8, -0.2: 115.4, -0.12: 119.9,
               -0.05: 143.8, -0.02: 153.5, 0.02: 160.2, 0.05: 168.1, 0.12: 175.4,
               0.2: 180.0},
    }

    def objective(p):
        key = p["parameter"]
        if p["start"] != sim.params[key]:
            return 1e3  # a constant offset does not fit this record
        rel = p["end"] / sim.params[key] - 1.0
        table = tables[key]
        near = min(table, key=lambda r: abs(r - rel))
        return table[near] + 100.0 * abs(rel - near)  # between the points: worse

    fit = ParameterDrift().search(problem, {}, objective)
    assert fit["parameter"] == "r"
    assert fit["end"] / 195.0 - 1.0 == pytest.approx(-0.3, abs=0.05)


class _RoughGap:
    """A drift's gap with its minimum at +8 %: smooth on every run of the ensemble
    (``precise``), rough on the scan's two runs (``__call__``: the half steps, where the
    refinement looks, scatter by +-2)."""

    def __init__(self, v0):
        self.v0, self.precise_calls = v0, 0

    def exact(self, p):
        if p["start"] != self.v0:
            return 1e3  # a constant offset does not fit this record
        return 1.0 + 400.0 * (p["end"] / self.v0 - 1.08) ** 2

    def __call__(self, p):
        rel = p["end"] / self.v0 - 1.0
        on_grid = min(abs(rel - r) for r in (-0.12, -0.05, -0.02, 0.02, 0.05, 0.12)) < 1e-9
        return self.exact(p) + (0.0 if on_grid else 2.0 * np.sign(np.sin(977.0 * rel)))

    def precise(self, p):
        self.precise_calls += 1
        return self.exact(p)


def test_drift_refinement_compares_on_the_whole_ensemble():
    """The coarse scan places the bracket; the refinement compares its points on every run
    (the objective's ``precise``), so the two runs' scatter cannot move the end value."""
    from skdelay.gap import ParameterDrift

    sim = SimpleNamespace(params={"tau": 10.0, "mu": 20.0})
    gap = _RoughGap(20.0)
    fit = ParameterDrift().search(SimpleNamespace(simulator=sim), {}, gap)
    assert fit["parameter"] == "mu" and fit["start"] == 20.0
    assert fit["end"] / 20.0 - 1.0 == pytest.approx(0.08, abs=0.005)
    assert gap.precise_calls >= 5
    # a plain callable (a user's objective) still works: it is its own precise gap
    plain = ParameterDrift().search(SimpleNamespace(simulator=sim), {}, gap.exact)
    assert plain["end"] / 20.0 - 1.0 == pytest.approx(0.08, abs=0.005)


def test_the_drifting_parameter_is_chosen_on_the_whole_ensemble():
    """The scan's two runs rank two parameters that both nearly explain the record by their
    scatter; the best two are refined on every run and the lower is kept.  Mackey-Glass,
    a 0.2 -> 0.2095 (benchmark seed 21.2e6): scan minima 13.2 for ``a`` (at +5 %) and 9.6
    for ``n`` (+5 %); with ``n`` alone refined (5.9) the record was read as a drift of n."""
    from skdelay.gap import ParameterDrift

    sim = SimpleNamespace(params={"tau": 17.0, "a": 0.2, "n": 10.0})
    truth = {"a": (0.0475, 0.0), "n": (0.05, 5.9)}  # relative end and floor of each

    class Gap:
        def __init__(self, rough):
            self.rough = rough

        def __call__(self, p):
            key = p["parameter"]
            rel = p["end"] / sim.params[key] - 1.0
            if p["start"] != sim.params[key]:
                return 1e3  # a constant offset does not fit this record
            best, floor = truth[key]
            # the scan's runs: a's floor reads 13, n's 4 (their scatter)
            lift = {"a": 13.0, "n": -2.0}[key] if self.rough else 0.0
            return floor + lift + 4e4 * (rel - best) ** 2

        def precise(self, p):
            return Gap(False)(p)

    fit = ParameterDrift().search(SimpleNamespace(simulator=sim), {}, Gap(True))
    assert fit["parameter"] == "a"
    assert fit["end"] / 0.2 - 1.0 == pytest.approx(0.0475, abs=0.01)
    assert "also" not in fit  # n's best leaves 5.9: no tie
    # within the ensemble's scatter of each other the scan's order stands, and the report
    # names the other parameter: the record cannot tell which one changed
    truth["a"] = (0.0475, 5.8)
    tie = ParameterDrift().search(SimpleNamespace(simulator=sim), {}, Gap(True))
    assert tie["parameter"] == "n" and tie["also"].startswith("a from 0.2 to 0.209")
    text = ParameterDrift().describe(tie)
    assert text.startswith("n drifts from 10 to 10.5 over the record; a from 0.2 to 0.209")
    assert "cannot tell which parameter changed" in text


def test_a_flat_bottomed_drift_gap_is_fitted_at_the_middle_of_its_floor():
    """Gaps within the runs' own scatter read 0: a floor of equally good end values.  Its
    middle is the estimate, not its lower edge (nor a parabola's vertex left of it)."""
    from skdelay.gap import ParameterDrift

    sim = SimpleNamespace(params={"tau": 10.0, "mu": 20.0})

    def gap(p):
        if p["start"] != 20.0:
            return 1e3
        rel = p["end"] / 20.0 - 1.0
        # 0 on +8 .. +13 %, gentle below (the record's seed 7404: 0.7 at +5 %), steep above
        return 20.0 * max(0.08 - rel, 0.0) + 100.0 * max(rel - 0.13, 0.0)

    fit = ParameterDrift().search(SimpleNamespace(simulator=sim), {}, gap)
    # the floor's points compared are +8.5 and +12 %: their middle
    assert fit["end"] / 20.0 - 1.0 == pytest.approx(0.1025, abs=0.003)


class _Valley:
    """A gap that is flat (975) except in a notch 0.3 samples wide around ``centre``, like
    Mackey-Glass's near tau = 16 (14 at 16.0 and 16.1, 133 at 16.2, 420 at 15.8)."""

    def __init__(self, centre):
        self.centre, self.best, self.calls = centre, (float("inf"), None), []
        self.width = 0.3

    def __call__(self, params):
        tau = params["tau"]
        self.calls.append(tau)
        gap = 1.0 + 974.0 * min(1.0, abs(tau - self.centre) / self.width)
        if gap < self.best[0]:
            self.best = (gap, dict(params))
        return gap


@pytest.mark.parametrize("centre", [16.05, 19.71, 12.4])
def test_a_delay_search_over_the_dip_window_cannot_step_over_a_narrow_notch(centre):
    """Five grid points 3 samples apart over 11..23 and a few Brent steps missed such a
    notch (the fit ended at 16.29 for a real 16.05); the grid's spacing is now at most half
    the delay tolerance and Brent refines between the best point's neighbours."""
    from skdelay.gap import DelayMismatch
    from skdelay.gap._where import DELAY_TOL

    ctx = _dips(real=21.7, sim=16.4, spread=6.5, comparable=False)
    ctx.delay_samples, ctx.simulator = 17.0, SimpleNamespace(params={"tau": 17.0})
    eff = DelayMismatch()
    lo, hi = eff.search_bounds({"tau": 17.0}, ctx)["tau"]
    assert (lo, hi) == (pytest.approx(11.0), pytest.approx(23.0))
    objective = _Valley(centre)
    fit = eff.search(ctx, {"tau": 17.0}, objective)
    assert fit["tau"] == pytest.approx(centre, abs=0.05)
    # the calls: the guess, the grid (in order), then Brent between two grid points
    step = eff.GRID_STEP * DELAY_TOL
    n_grid = round((hi - lo) / step) + 1
    grid = objective.calls[1:1 + n_grid]
    assert grid[0] == pytest.approx(lo) and grid[-1] == pytest.approx(hi)
    assert max(b - a for a, b in pairwise(grid)) <= step + 1e-9


def test_a_delay_near_the_edge_of_chaos_is_fitted_to_a_tenth_of_a_sample():
    """Mackey-Glass with delay 16.05 against the model's 17: the gap is a notch in the delay
    (see above), and both the whole record and each half are searched over the whole dip
    window (the whole record's dip cannot be placed; a half's own dip seemed to, at 20)."""
    real = MackeyGlass(tau=16.05).simulate(6000, random_state=7303)
    rep = diagnose_gap(real, MackeyGlass(), random_state=4, n_jobs=1,
                       effects=["delay_mismatch", "timebase_mismatch", "parameter_drift"])
    row = rep.effects.set_index("effect").loc["delay_mismatch"]
    assert rep.best_effect == "delay_mismatch", rep.effects[["effect", "shrink"]]
    assert row["params"]["tau"] == pytest.approx(16.05, abs=0.1)
    assert row["cross_validated"] and row["shrink"] > 0.9
    # nothing is left over, but the shallow dip cannot confirm the delay: the headline says
    # so instead of placing a rest outside the library
    assert rep.explained == "partly" and len(rep.reasons) == 1
    assert "too shallow" in rep.reasons[0]
    head = rep.headline()
    assert "does not confirm the fitted values" in head and "outside" not in head


def test_a_long_delays_window_is_searched_with_a_bounded_number_of_points():
    """A delay of 400 samples whose dip cannot be placed: a window of +-100 samples is not
    searched at half a sample (401 simulations) but on MAX_GRID points plus Brent."""
    from skdelay.gap import DelayMismatch

    ctx = _dips(real=300.0, sim=400.0, spread=30.0, comparable=False)
    ctx.delay_samples, ctx.simulator = 400.0, SimpleNamespace(params={"tau": 400.0})
    eff = DelayMismatch()
    objective = _Valley(371.3)
    objective.width = 3.0
    fit = eff.search(ctx, {"tau": 400.0}, objective)
    assert len(objective.calls) <= 1 + eff.MAX_GRID + eff.REFINE + 2
    assert fit["tau"] == pytest.approx(371.3, abs=0.5)


def test_dynamical_noise_is_polished_on_every_run():
    """The search of a simulation effect re-simulates two runs per evaluation, while
    measurement noise is scored on all of them; the dynamical noise is polished on every
    run so the two compete at the same reading.  Electro-optic oscillator at step 0.25
    with dynamical noise 0.11: the default search ended at 0.123 (gap 0.97 on every run);
    polished, the gap falls below a third of that, the intensity within 15 % of the truth."""
    from skdelay.gap._fit import fit_effect
    from skdelay.gap._problem import GapProblem
    from skdelay.gap._simulation import DynamicalNoise

    eo, dt = ElectroOpticOscillator(), 0.25
    real = eo.simulate(6000, sample_dt=dt, random_state=5182, dynamical_noise=0.11)
    problem = GapProblem(real, eo, sample_dt=dt, random_state=5182, n_jobs=1)
    polished = fit_effect(DynamicalNoise(), problem)

    class Unpolished(DynamicalNoise):
        POLISH_FINEST = 2.0  # above POLISH_STEP: the default search alone

    plain = fit_effect(Unpolished(), problem)
    assert polished.gap_after < plain.gap_after / 3, (polished.params, plain.params)
    assert polished.params["dynamical_noise"] == pytest.approx(0.11, rel=0.15)


@pytest.mark.parametrize("gaps, lo, hi", [
    # Ikeda step 0.25 (held-out-style seed 19.1e6): one run's fluctuation beyond the
    # target at 1e-4 must not stop the ladder; the crossing lies between 0.1 and 1
    ((0.57, 3.15, 0.79, 0.03, 0.12, 9.5), 0.1, 1.0),
    # a plain monotone ladder: the crossing between the last level below and the first beyond
    ((0.1, 0.5, 5.0, 40.0), 1e-4, 1e-3),
    # the last level alone beyond the target counts (nothing left to confirm it)
    ((0.1, 0.2, 0.3, 0.4, 0.5, 9.0), 0.1, 1.0),
])
def test_the_dynamical_noise_ladder_crosses_where_the_next_level_confirms(gaps, lo, hi):
    from skdelay.gap._simulation import DynamicalNoise

    levels = DynamicalNoise.ladder[: len(gaps)]
    d = DynamicalNoise._crossing(levels, gaps, 2.77)
    assert lo < d < hi
    assert DynamicalNoise._crossing(levels, [0.1] * len(gaps), 2.77) == levels[-1]


@pytest.mark.parametrize("seed", [10, 11, 21, 29])
def test_ikeda_dynamical_noise_is_found_past_a_fluctuating_ladder(seed):
    """Records whose ladder fluctuated (see CONFIRM): stopped at the first level beyond
    the target, the fit started at 1e-5 .. 2e-3 and ended there (intensities 1e-5, 3e-3,
    5e-3, 1e-5; gaps of 2.9 to 6.4 left).  Now the intensity comes out within a factor 2
    of the truth and most of the gap is explained.  (Ikeda, step 0.25, 6000 samples,
    intensity 0.9: 8 of the records of seeds 7..40 started four decades too low before;
    with the ladder also read on the noise's own indicators, 30 of the 34 fits leave at
    most a tenth of the gap, against 29 on every fast indicator.)"""
    from skdelay.gap._fit import fit_effect
    from skdelay.gap._problem import GapProblem
    from skdelay.gap._simulation import DynamicalNoise
    from skdelay.systems import Ikeda

    ik, dt, d = Ikeda(), 0.25, 0.9
    real = ik.simulate(6000, sample_dt=dt, random_state=seed, dynamical_noise=d)
    problem = GapProblem(real, ik, sample_dt=dt, random_state=seed + 1, n_jobs=1)
    fit = fit_effect(DynamicalNoise(), problem)
    assert d / 2 < fit.params["dynamical_noise"] < 2 * d
    assert fit.gap_after < 0.4 * problem.before.gap


@pytest.mark.parametrize("left, wide_left, expected", [
    (0.05, 0.01, "dip"),    # the dip's delay explains 95 %: the window is not searched
    (0.60, 0.015, "wide"),  # Mackey-Glass, delay 15.57 against 17 (benchmark seed 14.1e6)
    (0.60, 0.45, "dip"),    # elsewhere not even halved: the dip's delay stays
    (0.80, 0.70, "wide"),   # beyond ESCAPE_LEFT, as before: the window's best
    # ... unless it leaves more (Ikeda with dynamical noise, held-out-step benchmark seed
    # 23.0e6, case seed 23 030 000:
    # the window's best 5.90 left 1.37 of the gap, the dip's 4.875 left 0.93)
    (0.93, 1.37, "dip"),
])
def test_a_delay_that_explains_part_of_the_gap_is_checked_against_the_window(
        monkeypatch, left, wide_left, expected):
    from skdelay.gap._simulation import DelayMismatch

    delay = DelayMismatch()
    problem = _dips(17.5, 17.0, 0.2)
    problem.simulator = SimpleNamespace(params={"tau": 17.0})
    problem.delay_samples, problem.dip_only = 17.0, False
    calls = []

    def grid(self, problem_, guess, objective, lo, hi):
        calls.append((lo, hi))
        return {"tau": 17.5} if len(calls) == 1 else {"tau": 15.6}

    monkeypatch.setattr(DelayMismatch, "_grid", grid)
    gaps = {17.0: 100.0, 17.5: 100.0 * left, 15.6: 100.0 * wide_left}  # shares of the gap at 17
    objective = SimpleNamespace(precise=lambda p: gaps[p["tau"]])
    best = delay.search(problem, {"tau": 17.5}, objective)
    assert best["tau"] == (17.5 if expected == "dip" else 15.6)
    assert len(calls) == (1 if left <= DelayMismatch.ESCAPE_SETTLED else 2)


@pytest.mark.parametrize("off, searched", [
    (None, True),                                   # nothing judged the record: as before
    (frozenset({"spectrum", "histogram"}), False),  # a hum or noise: no delay's marks
    (frozenset({"spectrum", "forecast_error"}), True),
])
def test_the_dip_window_is_searched_only_where_a_delay_has_left_its_marks(
        monkeypatch, off, searched):
    """The periodic Mackey-Glass record whose delay lies outside the dip's window (benchmark
    seed 14.1e6) has its forecast error, autocorrelation and cross-prediction off before
    any effect; a record whose only marks are spectral and distributional is not searched
    beyond the delays its dip allows, however little those explain."""
    from skdelay.gap._simulation import DelayMismatch

    problem = _dips(17.5, 17.0, 0.2)
    problem.simulator = SimpleNamespace(params={"tau": 17.0})
    problem.delay_samples, problem.dip_only = 17.0, False
    if off is not None:
        problem.off_before = off
    calls = []

    def grid(self, problem_, guess, objective, lo, hi):
        calls.append((lo, hi))
        return {"tau": 17.5} if len(calls) == 1 else {"tau": 15.6}

    monkeypatch.setattr(DelayMismatch, "_grid", grid)
    gaps = {17.0: 100.0, 17.5: 90.0, 15.6: 1.0}
    objective = SimpleNamespace(precise=lambda p: gaps[p["tau"]])
    best = DelayMismatch().search(problem, {"tau": 17.5}, objective)
    assert len(calls) == (2 if searched else 1)
    assert best["tau"] == (15.6 if searched else 17.5)
