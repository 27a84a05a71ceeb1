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
