"""A record whose gap is its only evidence is compared again with fresh ensembles of
simulator runs (:data:`skdelay.gap._diagnose.REPLICATES`): one ensemble is one draw."""

import copy
import dataclasses

import pytest

from skdelay.gap import get_effect
from skdelay.gap._diagnose import REPLICATES, _fresh_gap, _fresh_gaps, significance
from skdelay.gap._problem import GapProblem
from skdelay.systems import MackeyGlass

MG = MackeyGlass()
N = 3000


def test_a_gap_that_one_ensemble_drew_is_not_significant():
    """The same clean record against an ensemble that happened to lie far from it (its
    gap set to twice the threshold): the fresh ensembles put it back within the threshold,
    and nothing is called significant."""
    problem = GapProblem(MG.simulate(N, random_state=811), MG, n_sims=6, random_state=3,
                         n_jobs=1)
    sig = significance(problem)
    assert not sig["significant"]
    assert sig["replicated"] is None  # within the threshold: nothing to replicate
    drawn = copy.copy(problem)
    drawn.before = dataclasses.replace(problem.before, gap=2.0 * sig["threshold"])
    again = significance(drawn)
    assert len(again["replicated"]) == REPLICATES + 1
    assert again["replicated"][0] == pytest.approx(2.0 * sig["threshold"])
    assert max(again["replicated"][1:]) < sig["threshold"]
    assert not again["significant"]


def test_a_discrepancy_in_the_record_stays_with_it():
    """A low-pass in the record leaves about the same gap against fresh ensembles."""
    x = get_effect("lowpass").apply(MG.simulate(N, random_state=812), {"cutoff": 0.12})
    problem = GapProblem(x, MG, n_sims=6, random_state=3, n_jobs=1)
    sig = significance(problem)
    assert sig["significant"]
    for k in range(1, REPLICATES + 1):
        fresh = _fresh_gap(problem, k)
        assert fresh > sig["threshold"]
        assert fresh == pytest.approx(sig["gap_before"], rel=0.5)


def test_the_halves_fresh_ensembles_are_drawn_once_for_both():
    """The two halves of a split share the record's seeds and length, so a replicate's
    fresh ensemble is the same runs for both: drawn together in one task, the second half
    finds all of them in the run cache, and each half's gap is the one drawn alone."""
    x = get_effect("lowpass").apply(MG.simulate(2 * N, random_state=813), {"cutoff": 0.12})
    problem = GapProblem(x, MG, n_sims=4, random_state=3, n_jobs=1, scan_dips=False)
    halves = problem.split()
    chain = [(get_effect("lowpass"), {"cutoff": 0.12})]
    misses = problem.run_cache.misses
    together = _fresh_gaps([(halves[1], chain), (halves[0], ())], 1)
    assert problem.run_cache.misses - misses == 4  # one fresh ensemble of four runs
    alone = [_fresh_gap(halves[1], 1, chain), _fresh_gap(halves[0], 1)]
    assert together == alone and together[0] < together[1]


def test_the_report_says_why_a_gap_above_the_threshold_is_no_gap():
    """The text follows the numbers: a gap above the threshold is not "within" it."""
    import pandas as pd

    from skdelay.gap import GapReport

    sig = {"threshold": 8.52, "null_median": 1.17, "significant": False,
           "replicated": [10.24, 0.318, 1.17]}
    rep = GapReport(best_effect=None, effects=pd.DataFrame(), where=pd.DataFrame(),
                    gap_before=10.24, gap_after=10.24, shrink=0.0, significance=sig)
    text = rep.headline()
    assert "within the no-gap threshold" not in text
    assert "10.2 exceeds the no-gap threshold 8.52" in text
    assert "0.318 and 1.17 (median with the first runs' 1.17)" in text
    low = GapReport(best_effect=None, effects=pd.DataFrame(), where=pd.DataFrame(),
                    gap_before=3.0, gap_after=3.0, shrink=0.0,
                    significance=dict(sig, replicated=None))
    assert "the gap 3 is within the no-gap threshold 8.52" in low.headline()


def test_a_far_off_bin_that_six_runs_drew_is_not_significant():
    """A no-effect CO2-laser record (delay 150) with one autocorrelation lag more than
    Z_LOCAL spreads from its six clean runs: against the calibration runs that lag lies
    within Z_LOCAL, and nothing else is off, so the record shows no gap."""
    from skdelay.gap._diagnose import Z_LOCAL
    from skdelay.systems import CO2LaserFeedback

    laser = CO2LaserFeedback(tau=150.0)
    real = laser.simulate(6000, random_state=13 * 7919 + 13)
    problem = GapProblem(real, laser, random_state=13, n_jobs=1)
    sig = significance(problem)
    assert sig["max_z"] > Z_LOCAL  # six runs: one lag far off ...
    assert sig["far_z_calibrated"] < Z_LOCAL / 1.5  # ... not against the calibration runs
    assert not sig["far_bin"] and not sig["lines"] and not sig["significant"]


@pytest.mark.parametrize("effect, params", [
    ("quantization", {"step": 0.06, "phase": 0.6}),
    ("clipping", {"low": -float("inf"), "high": 1.5}),
])
def test_a_far_off_bin_of_the_record_stays_far_off(effect, params):
    """A coarse ADC step (the record's value levels) and a clipped end (its pile-up) leave
    bins far off the six runs; the calibration runs, clean as the six, keep them far off."""
    from skdelay.gap._diagnose import Z_LOCAL, _far_bin_kept

    x = get_effect(effect).apply(MG.simulate(N, random_state=814), params)
    problem = GapProblem(x, MG, n_sims=6, random_state=3, n_jobs=1)
    assert significance(problem)["max_z"] > Z_LOCAL
    kept, z = _far_bin_kept(problem)
    assert kept and z > 2 * Z_LOCAL
