"""Excursions of the real record beyond the range of the simulator runs.

Isolated spikes of a few standard deviations (outliers, detector glitches) are too
few to move a binned histogram: on Ikeda (step 0.5, 6000 samples) 31 spikes of 2-6
std raised the gap to 7.6 against a no-gap threshold of 7.9, and no bin lay more
than 4.5 spreads off.  Yet 12 of them lay beyond the range of all six simulator
runs, where one run beyond the other five's range went at most twice.

The same test on the record's *jumps* -- how far each sample lies off the midpoint of its
two neighbours (:func:`jumps`, :func:`jump_test`) -- sees spikes inside the range: a spike
of a few std sits on top of whatever the signal does there, and one sample off both of its
neighbours by that much is what a continuous signal, sampled finely enough to show its
dynamics, rarely does.  On Ikeda (step 0.5, 6000 samples; benchmark seed 16.0e6) 23
spikes of 3.4 std left the runs' range twice (p = 0.19) and the gap stayed at 2.4 against
a threshold of 6.8, so the record read "no gap"; their jumps left the runs' jump range 14
times, where no run left the others' once (p = 4e-16 at the runs' rate bound).

Guarantee: the test counts *excursions* (maximal groups of consecutive samples
beyond the range: a chaotic excursion lasts several samples, a spike one) and
calibrates their rate on the runs themselves (each run against the range of the
others), so it holds for any system and sampling step without a tuned level.  Six runs
bound a small rate poorly; where the test fires, or more runs could make it fire
(:func:`could_decide`), the diagnosis repeats it on its calibration runs (24 in all).  The
range is widened by the scatter of the runs' own extremes (:func:`_range_of`): a
record's extremes in standard units move with its spread.
"""

import numpy as np
from scipy import stats

from ._signature import zscore

#: a record is off when its excursion count has a Poisson tail probability below this
#: under the runs' own rate (at its upper confidence bound, :data:`RATE_CONFIDENCE`); one
#: test per record, beside the gap's, the line scan's and the dip's
RANGE_ALPHA = 1e-3
#: the runs' excursion rate enters at this one-sided upper confidence bound: six runs
#: estimate a rate of ~0.3 per record poorly, and a zero count does not mean a zero rate
RATE_CONFIDENCE = 0.95


def excursions(x, low, high):
    """Number of maximal groups of consecutive samples of ``x`` outside ``[low, high]``."""
    out = (np.asarray(x) > high) | (np.asarray(x) < low)
    if not out.any():
        return 0
    return int(out[0]) + int(np.count_nonzero(out[1:] & ~out[:-1]))


def _range_of(lows, highs):
    """The runs' range, widened on each side by the scatter of the runs' own extremes.

    Each record is z-scored, so its extremes in standard units move with its own mean
    and spread; where many samples sit near an extreme, the record whose extreme lies
    farthest out has all of them outside the others' bare range.  On the CO2 laser (tau
    150, 6000 samples, fresh no-effect records), whose intensity returns to its zero after
    every spike and whose spread moves with the number of spikes, one of six runs had
    61-84 excursions beyond the others' bare range and the rest 0-1, and three of ten
    records fired at p < 1e-32 (60-130 excursions).  Widened by the range of the runs'
    minima (maxima), the same records counted 0-1.  An isolated spike must clear that
    scatter (0.7-0.8 std on Ikeda at step 0.5): the price is power for spikes of ~3 std.
    """
    return (float(lows.min() - np.ptp(lows)), float(highs.max() + np.ptp(highs)))


def range_test(real, runs):
    """Does ``real`` leave the range of the simulator ``runs`` more often than they do?

    Returns ``{"count", "null_counts", "rate_bound", "p_value", "off"}``: the real
    record's excursions beyond the range of all runs (z-scored, first ``n`` samples;
    the range widened as :func:`_range_of` says), each run's excursions beyond the range
    of the others, the upper confidence bound of the runs' rate (per record, against one
    fewer run than the real record faces: the bound is conservative) and the Poisson
    tail probability of the real count under it.
    """
    z = zscore(np.asarray(real, dtype=float))
    n = z.size
    zs = [zscore(np.asarray(r, dtype=float)[:n]) for r in runs]
    k = len(zs)
    if k < 2:
        return {"count": 0, "null_counts": [], "rate_bound": np.nan, "p_value": 1.0,
                "off": False}
    lows = np.array([r.min() for r in zs])
    highs = np.array([r.max() for r in zs])
    null = []
    for j in range(k):
        others = np.arange(k) != j
        null.append(excursions(zs[j], *_range_of(lows[others], highs[others])))
    count = excursions(z, *_range_of(lows, highs))
    # sum of k Poisson(rate) counts: exact (Garwood) upper bound of the rate
    rate = float(stats.chi2.ppf(RATE_CONFIDENCE, 2 * (sum(null) + 1)) / (2 * k))
    p = float(stats.poisson.sf(count - 1, rate)) if count > 0 else 1.0
    return {"count": count, "null_counts": null, "rate_bound": rate, "p_value": p,
            "off": bool(p < RANGE_ALPHA)}


def could_decide(result, n_runs):
    """Could ``n_runs`` runs make a :func:`range_test` result that is not off significant?

    Only when the record left the range at all, and its count would be significant if the
    further runs left the others' range no more often than the present ones did (their
    rate bound then falls as ``1 / n_runs``).  Six runs with no excursion bound the rate at
    0.5 per record, so three excursions give p = 0.014 however far out they lie; with 24
    runs the same count gives p = 3e-4.  Ikeda (step 0.25, 6000 samples; held-out benchmark
    seed 22.3e6): six spikes of 3-9 std put three excursions beyond the runs' range and three
    beyond their jumps' (p = 0.046 and 0.014), the gap stayed at 2.05 against a threshold of
    8.3, and the record read "no gap".
    """
    if result["off"] or result["count"] == 0 or n_runs <= len(result["null_counts"]):
        return False
    rate = float(stats.chi2.ppf(RATE_CONFIDENCE, 2 * (sum(result["null_counts"]) + 1))
                 / (2 * n_runs))
    return bool(stats.poisson.sf(result["count"] - 1, rate) < RANGE_ALPHA)


def jumps(x):
    """``x[t] - (x[t - 1] + x[t + 1]) / 2`` for ``t = 1 .. n - 2``: how far each sample lies
    off the midpoint of its neighbours (a spike of height ``h`` gives ``h`` there and
    ``-h / 2`` beside it: one excursion)."""
    x = np.asarray(x, dtype=float)
    return x[1:-1] - 0.5 * (x[:-2] + x[2:])


def jump_test(real, runs):
    """:func:`range_test` of the :func:`jumps` of ``real`` against those of the ``runs``
    (cut to the record's length): isolated spikes within the runs' range of values."""
    n = len(real)
    return range_test(jumps(real), [jumps(np.asarray(r, dtype=float)[:n]) for r in runs])


def excursion_tests(real, runs, calibration=None, n_calibration=0):
    """``(beyond, jumps, n_runs)``: :func:`range_test` and :func:`jump_test` of ``real``,
    repeated against ``calibration()`` (all ``n_calibration`` runs, ``runs`` among them)
    where either fires or could fire with that many runs (:func:`could_decide`), and the
    number of runs the returned results were calibrated on.

    Six runs cannot bound a small excursion rate (three excursions give p = 0.014 however
    far out they lie), nor the scatter of the runs' extremes: on fresh no-effect records of
    the CO2 laser (tau 150, 6000 samples) the z-scored zero level left the six runs'
    widened range in 5 of 150 records (70-88 excursions each), in none against 24 runs
    (benchmarks/range_calibration.py).
    """
    beyond, jumps_ = range_test(real, runs), jump_test(real, runs)
    if calibration is not None and (
            beyond["off"] or jumps_["off"] or could_decide(beyond, n_calibration)
            or could_decide(jumps_, n_calibration)):
        runs = calibration()
        beyond, jumps_ = range_test(real, runs), jump_test(real, runs)
    return beyond, jumps_, len(runs)
