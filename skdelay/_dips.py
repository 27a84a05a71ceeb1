"""The forecast-error dip: where it is, how wide, and whether it is there at all.

One locator for every caller (the delay scan, :class:`~skdelay.DelaySelectorCV`,
the analysis, the faithful-model search and the gap diagnosis):

* **centre** -- the depth-weighted centroid of the contiguous run of delays
  around the minimum where ``sigma <= L = min + level * (rim - min)``
  (crossings interpolated linearly).  ``rim`` is the median of the scanned
  curve -- or, where the run below that median's level would span several
  valleys, the lower of the dip's two shoulders (:func:`_rim`): walking out of
  the dip, the highest error before the curve falls back significantly.  A
  wide scan of a record whose error grows with ``tau`` (Mackey-Glass scanned
  to 20 times its delay, as its autocorrelation's strongest revival asks) has
  a median far above the dip's rim: on clean Mackey-Glass tau = 17 (2*10^4
  samples, 12 bit, tau = 1..300, grid minimum at 17) the median's level gave
  centres of 28-37 with half-widths of 27-39 samples, the shoulders 16.5-16.7
  with 1.1-3.2.  A single valley keeps the median's level (its centre is what
  the gap diagnosis's delay and timebase searches were calibrated on).
  A delay dip is lopsided -- a gentle flank on the short-``tau``
  side, a cliff on the long side -- so the run is taken in the lower third
  and weighted towards its bottom, where the windows holding the delayed pair
  lie.  For odd ``m >= 3`` that plateau is centred half a sample after the
  delay (the centred second window has one more newer sample, see
  :class:`~skdelay.TwoWindowEmbedding`), so callers pass ``shift=-0.5``.
* **half-width** -- half the run's width, at least half a sample.
* **significance** -- the depth ``baseline - min`` in standard errors of the
  curve (``se``: from the spread of the squared errors over the queries, or,
  without it, from the curve's own roughness) against the Bonferroni
  threshold over the scanned delays, plus a minimum relative depth and an
  interior minimum.  A curve without a significant dip has no delay.
* **centre standard error** -- from bootstrap replicates of the curve
  (``random_state``); ``error`` combines it with the half-width.  Where the
  scan kept the per-batch mean squared errors (``attrs["batch_msq"]``, see
  :func:`batch_table`), a replicate resamples the query batches -- the same
  batches at every delay, so the whole curve moves as it would with another
  set of queries: every cell of a scan forecasts the same query times, and
  their errors at neighbouring delays are strongly correlated; the spread is
  read robustly (:func:`_robust_spread`).  Otherwise
  (and for curves from other sources) each cell is redrawn independently
  within its standard error, which roughens a smooth curve and overstates the
  centre's error (their plain standard deviation, which the scan's refinement
  and the gap's dip tests were calibrated on): on clean Mackey-Glass tau = 17
  (2*10^4 samples, 12 bit, tau = 1..384) independent redraws gave centre
  errors of 8-68 samples for centres within 0.5 of the delay.
* **best delay** -- the grid delay next to the centre with the lowest error:
  the integer delay a model should use (rounding the centre can pick the
  worse neighbour of a lopsided dip).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import norm

__all__ = ["DIP_ALPHA", "MIN_RELATIVE_DEPTH", "Dip", "batch_table", "locate_dip", "locate_dips"]

#: Family-wise false-dip rate of the significance test.  The minimum of ``n`` noisy
#: cells lies ~sqrt(2 ln n) standard errors below their mean by chance alone, so the
#: threshold is Bonferroni's ``isf(DIP_ALPHA / n)`` (4.1 standard errors for 500 delays).
DIP_ALPHA = 0.01
#: Smallest depth, relative to the baseline, that counts as a dip.  With every point a
#: query the standard errors shrink to a fraction of a percent, and the few-percent
#: undulations of sigma_m(tau) that the second window's changing geometry gives any record
#: would become "significant".  The delay dips of this project's tests are far deeper
#: (Mackey-Glass and the laser: 20-90 %; flat curves of an oversampled record: < 5 %);
#: the value is not yet calibrated on a population of records without a delay.
MIN_RELATIVE_DEPTH = 0.1
#: A dip's shoulder (:func:`_shoulder`) is where the curve, walking out of the dip, falls
#: back below its highest value so far by more than this many combined standard errors of
#: the two cells (a fall within the noise is no shoulder: 3 standard errors are exceeded by
#: chance in 0.1 % of the steps) ...
SHOULDER_SE = 3.0
#: ... and by more than this fraction of that highest value's height above the dip's
#: minimum (the few-percent undulations of a smooth curve, see MIN_RELATIVE_DEPTH, are
#: no shoulder either).
SHOULDER_FALL = 0.1
#: Bootstrap replicates for the standard error of the centre.
N_BOOTSTRAP = 200
#: Scale factor of the median absolute deviation to a Gaussian standard deviation.
_MAD_TO_SD = 1.4826


@dataclass(frozen=True)
class Dip:
    """The dip of one forecast-error curve (delays in the curve's index units).

    ``significant`` False means the curve has no dip it can vouch for;
    ``reason`` then says why.  ``error`` is the error bar of ``centre``:
    ``sqrt(half_width**2 + centre_se**2)``.
    """

    centre: float
    half_width: float
    centre_se: float
    tau_min: int
    tau_best: int
    min_error: float
    baseline: float
    depth: float
    z: float
    threshold: float
    significant: bool
    reason: str = ""

    @property
    def error(self):
        """Error bar of the centre: half-width and centre standard error combined."""
        return float(math.hypot(self.half_width, self.centre_se))


def _shoulder(c, se, i0, step, fall_se=None):
    """The dip's shoulder on one side (``step`` -1: shorter delays, +1: longer), or None.

    Walks from the minimum ``i0`` outwards, keeping the highest error met so far;
    the shoulder is that highest value once the curve falls back below it by more
    than :data:`SHOULDER_SE` standard errors of the fall and :data:`SHOULDER_FALL` of
    its height above the minimum.  None when the curve never falls back before the
    edge of the scan: the dip is open on that side.  The fall's standard error is
    ``fall_se(i, j)`` where given (paired over query batches, :func:`_paired_fall_se`),
    else the two cells' standard errors combined as if independent.
    """
    top = c[i0]
    itop = i0
    j = i0 + step
    while 0 <= j < c.size:
        if c[j] > top:
            top, itop = c[j], j
        else:
            fall = top - c[j]
            noise = None if fall_se is None else fall_se(itop, j)
            if noise is None:
                noise = math.hypot(se[itop], se[j])
            if fall > SHOULDER_SE * noise and fall > SHOULDER_FALL * (top - c[i0]):
                return float(top)
        j += step
    return None


def _rim(c, se, i0, fall_se=None):
    """The level a dip is measured from: the median of the curve, or the lower shoulder
    where that lies below it (the median's run would cross into the next valley).  An
    open side (no shoulder before the edge) does not count: a minimum in a valley that
    runs to the end of the scan still reaches it, and no dip is located."""
    median = float(np.median(c))
    if se is None or not np.all(np.isfinite(se)):
        return median
    closed = [v for v in (_shoulder(c, se, i0, -1, fall_se), _shoulder(c, se, i0, +1, fall_se))
              if v is not None]
    return min([median] + closed)


def _run_around_minimum(taus, c, level, se=None, fall_se=None):
    """Centre, half-width and edge flag of the run below ``level`` around the minimum
    (``level`` a fraction of the way from the minimum to :func:`_rim`)."""
    i0 = int(np.argmin(c))
    lo = c[i0]
    lev = lo + level * (_rim(c, se, i0, fall_se) - lo)
    left = i0
    while left > 0 and c[left - 1] <= lev:
        left -= 1
    right = i0
    while right < c.size - 1 and c[right + 1] <= lev:
        right += 1

    def cross(a, b):  # crossing of the level between grid points a (inside) and b (outside)
        if c[b] == c[a]:
            return taus[a]
        return taus[a] + (lev - c[a]) / (c[b] - c[a]) * (taus[b] - taus[a])

    t_left = taus[left] if left == 0 else cross(left, left - 1)
    t_right = taus[right] if right == c.size - 1 else cross(right, right + 1)
    depth = lev - c[left:right + 1]
    if depth.sum() > 0:
        centre = float(np.sum(taus[left:right + 1] * depth) / depth.sum())
    else:
        centre = float(taus[i0])
    at_edge = left == 0 or right == c.size - 1
    return centre, max(0.5 * (t_right - t_left), 0.5), i0, at_edge


def batch_table(batch_msq, ms, taus):
    """The per-batch mean squared errors of a scan as a table for ``attrs["batch_msq"]``.

    ``batch_msq`` ``(n_splits, n_m, n_tau, n_batches)`` (NaN: a batch without
    queries); returns a DataFrame with index ``tau`` and columns ``(m, split,
    batch)``, so that row and column selections of the forecast-error table
    can select the same cells here.
    """
    bm = np.asarray(batch_msq, dtype=np.float64)
    n_split, _, n_tau, n_b = bm.shape
    cols = pd.MultiIndex.from_product([list(ms), range(n_split), range(n_b)],
                                      names=["m", "split", "batch"])
    return pd.DataFrame(bm.transpose(2, 1, 0, 3).reshape(n_tau, -1),
                        index=pd.Index(taus, name="tau"), columns=cols)


def _batch_replicates(c, batch_msq, n_draws, rng):
    """Bootstrap replicates ``(n_draws, n)`` of the curve ``c`` from its per-batch mean
    squared errors ``(n_splits, n, n_batches)`` (each split's batches resampled with
    replacement, the same draw at every delay), or None when a cell lacks two batches
    or the batches' holes differ between cells.

    A replicate is ``c`` plus the deviation of the resampled curve from the curve of
    all batches (unweighted), so unequal batch sizes do not bias it."""
    bm = np.asarray(batch_msq, dtype=np.float64)
    if bm.ndim != 3 or bm.shape[1] != c.size:
        return None
    dev = np.zeros((n_draws, c.size))
    for split in bm:  # (n, n_batches)
        used = np.all(np.isfinite(split), axis=0)
        if used.sum() < 2 or np.any(np.isfinite(split[:, ~used])):
            return None
        b = split[:, used]
        n_b = b.shape[1]
        counts = rng.multinomial(n_b, np.full(n_b, 1.0 / n_b), size=n_draws)
        rep = np.sqrt(np.maximum(counts @ b.T, 0.0) / n_b)
        dev += rep - np.sqrt(b.mean(axis=1))
    return c + dev / bm.shape[0]


def _paired_fall_se(batch_msq, c):
    """Standard error of ``c[i] - c[j]`` from the two cells' per-batch mean squared
    errors ``(n_splits, n, n_batches)``, paired batch by batch, as a function
    ``(i, j) -> se`` (None where fewer than two batches are shared), or None.

    The cells of a scan forecast the same queries, so their errors rise and fall
    together and the fall between two cells is known far better than the two
    standard errors combined as independent say.  On clean Mackey-Glass tau = 17
    (2*10^4 samples, m = 2, 500 coarse queries, tau = 1..300, seed 5) the rim at
    tau = 19 (1.09e-3, standard error 1.0e-4) falls to 0.86e-3 at tau = 20: 1.9
    independent standard errors, no shoulder, and the dip's run took in the whole
    valley to tau = 48 (centre 24.3 +- 21.1).  The (m, split, batch) cells of a
    delay scan share their batches' query times except where refinement added
    queries; a batch difference is a valid paired sample either way (batches
    are independent of each other), only less tight."""
    bm = np.asarray(batch_msq, dtype=np.float64)
    if bm.ndim != 3 or bm.shape[1] != c.size or bm.shape[2] < 2:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a cell without any batch
        rms = np.sqrt(np.nanmean(bm, axis=2))
    cache = {}

    def fall_se(i, j):
        key = (min(i, j), max(i, j))
        if key not in cache:
            var = 0.0
            for split, r in zip(bm, rms):
                d = split[i] - split[j]
                d = d[np.isfinite(d)]
                if d.size < 2 or not r[i] + r[j] > 0:
                    var = None
                    break
                var += (float(np.std(d, ddof=1)) / math.sqrt(d.size) / (r[i] + r[j])) ** 2
            cache[key] = None if var is None else math.sqrt(var) / bm.shape[0]
        return cache[key]

    return fall_se


def _robust_spread(values):
    """Half the central 68 % range: the standard deviation of a Gaussian spread.

    A few replicates whose minimum falls into another valley (Mackey-Glass's dips at
    twice and three times its delay are almost as deep as the first on a noisy record)
    do not set it: on Mackey-Glass tau = 17 with 2 % noise (2*10^4 samples, m = 5,
    tau = 1..384) 95 % of 200 batch replicates put the centre within 17.6-20.6 and 3 %
    at 38-60, a standard deviation of 9.0 samples against 0.2 here.  When jumps are
    frequent (more than one replicate in six), they widen it."""
    lo, hi = np.percentile(np.asarray(values, dtype=np.float64), [15.87, 84.13])
    return float(0.5 * (hi - lo))


def _roughness_se(c):
    """Standard error of single cells from the curve's second differences (robust)."""
    if c.size < 5:
        return np.full(c.size, np.nan)
    d2 = np.diff(c, 2)
    # a second difference of independent errors has variance 6 se^2
    sd = _MAD_TO_SD * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0)
    return np.full(c.size, sd)


def locate_dip(taus, values, *, se=None, level=1 / 3, shift=0.0, alpha=DIP_ALPHA,
               min_relative_depth=MIN_RELATIVE_DEPTH, batch_msq=None, random_state=0):
    """Locate the dip of one forecast-error curve and test it (see the module notes).

    Parameters
    ----------
    taus : array-like of shape (n,)
        Scanned delays (increasing).
    values : array-like of shape (n,)
        The error at each delay (NaN cells are not allowed).
    se : array-like of shape (n,), default=None
        Standard error of each value; None estimates it from the curve's
        roughness (second differences), which suits curves of independent cells.
    level : float, default=1/3
        Fraction of the depth (0 < level <= 1) that delimits the dip.
    shift : float, default=0.0
        Added to the centre (-0.5 for odd ``m >= 3``, see the module notes).
    alpha : float, default=DIP_ALPHA
        Family-wise false-dip rate (Bonferroni over the ``n`` delays).
    min_relative_depth : float, default=MIN_RELATIVE_DEPTH
        Smallest ``depth / baseline`` that counts as a dip.
    batch_msq : array-like of shape (n_splits, n, n_batches), default=None
        Per-batch mean squared errors of the cells (the scan's query batches, the
        squares of ``values``' units; the curve is the mean over splits of the
        rms): the centre's standard error then comes from resampling the batches.
        None (or batches with holes) redraws each cell within ``se``.
    random_state : int, default=0
        Seed of the bootstrap for the centre's standard error.

    Returns
    -------
    Dip

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._dips import locate_dip
    >>> taus = np.arange(10, 31)
    >>> curve = 1 - 0.6 * np.exp(-0.5 * ((taus - 20.3) / 1.5) ** 2)
    >>> dip = locate_dip(taus, curve, se=np.full(21, 0.01))
    >>> dip.significant, round(dip.centre, 1), dip.tau_best
    (True, 20.3, 20)
    >>> locate_dip(taus, 1 + 0.01 * np.sin(taus), se=np.full(21, 0.01)).significant
    False
    """
    taus = np.asarray(taus, dtype=np.float64)
    c = np.asarray(values, dtype=np.float64)
    if c.ndim != 1 or taus.shape != c.shape:
        raise ValueError(f"taus and values must be 1-D of the same length, got {taus.shape} "
                         f"and {c.shape}.")
    if c.size == 0:
        raise ValueError("the forecast-error curve is empty; scan at least 5 delays.")
    if batch_msq is not None:
        shape = np.shape(batch_msq)
        if len(shape) != 3 or shape[1] != c.size:
            raise ValueError(f"batch_msq must have shape (n_splits, {c.size}, n_batches) for "
                             f"{c.size} delays, got {shape}; pass the scan's per-batch mean "
                             "squared errors of these cells, or None.")
    if np.any(np.diff(taus) <= 0):
        # the dip's run and flanks are read along the array: unsorted delays misplace them
        raise ValueError("the delays tau must be strictly increasing (one value each); sort "
                         "the curve by tau first (DataFrame.sort_index()).")
    if not np.all(np.isfinite(c)):
        bad = taus[~np.isfinite(c)]
        raise ValueError(f"the forecast error is NaN or infinite at tau = {bad[:5].tolist()}; "
                         "a dip cannot be located on an incomplete curve (rescan those delays).")
    if not 0 < level <= 1:
        raise ValueError(f"level must lie in (0, 1], got {level!r}.")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha!r}.")
    if c.size < 3:  # no flanks: the minimum is all there is, and it proves nothing
        i0 = int(np.argmin(c))
        return Dip(centre=float(taus[i0] + shift), half_width=0.5, centre_se=0.0,
                   tau_min=int(taus[i0]), tau_best=int(taus[i0]), min_error=float(c[i0]),
                   baseline=float(np.median(c)), depth=0.0, z=math.nan, threshold=math.nan,
                   significant=False, reason=f"only {c.size} delay(s) scanned; scan at least 5")
    se = _roughness_se(c) if se is None else np.asarray(se, dtype=np.float64)
    if se.shape != c.shape:
        raise ValueError(f"se must have the shape of values {c.shape}, got {se.shape}.")
    fall_se = None if batch_msq is None else _paired_fall_se(batch_msq, c)
    centre, half, i0, at_edge = _run_around_minimum(taus, c, level, se, fall_se)
    baseline = float(np.median(c))
    depth = baseline - float(c[i0])
    noise = math.hypot(float(se[i0]), float(np.median(se))) if np.all(np.isfinite(se)) \
        else math.nan
    if math.isnan(noise):
        z = math.nan
    else:
        z = depth / noise if noise > 0 else (math.inf if depth > 0 else 0.0)
    threshold = float(norm.isf(alpha / c.size))
    reason = ""
    if at_edge and taus[i0] <= 1:
        # a delay of one sample is no delay: nothing lies below it to scan
        reason = ("the error is lowest at the shortest delay (1 sample): no delayed "
                  "feedback shows in the forecasts")
    elif at_edge:
        reason = ("the lowest error lies at the edge of the scanned delays; scan delays on "
                  "both sides of it")
    elif math.isnan(z):
        reason = "too few delays to estimate the noise of the curve; scan at least 5"
    elif not z >= threshold:
        reason = (f"the dip is {z:.1f} standard errors deep, below the {threshold:.1f} needed "
                  f"over {c.size} delays")
    elif baseline > 0 and depth / baseline < min_relative_depth:
        reason = (f"the dip is {100 * depth / baseline:.1f} % of the baseline error, "
                  f"shallower than {100 * min_relative_depth:.0f} %")
    centre_se = 0.0
    rng = np.random.default_rng(random_state)
    draws = None if batch_msq is None else _batch_replicates(c, batch_msq, N_BOOTSTRAP, rng)
    if draws is not None:
        centre_se = _robust_spread([_run_around_minimum(taus, d, level, se, fall_se)[0]
                                    for d in draws])
    elif np.all(np.isfinite(se)) and np.any(se > 0):
        # independent redraws keep the plain standard deviation: the scan's refinement
        # target (TARGET_CENTRE_SE) and the gap's dip tests (dip_difference_se) were
        # calibrated on it, and it errs on the safe side
        draws = c + se * rng.standard_normal((N_BOOTSTRAP, c.size))
        centre_se = float(np.std([_run_around_minimum(taus, d, level, se)[0] for d in draws],
                                 ddof=1))
    centre += shift
    near = np.flatnonzero(np.abs(taus - centre) < 1.0)
    if near.size == 0:
        near = np.array([int(np.argmin(np.abs(taus - centre)))])
    best = int(taus[near[np.argmin(c[near])]])
    return Dip(centre=float(centre), half_width=float(half), centre_se=centre_se,
               tau_min=int(taus[i0]), tau_best=best, min_error=float(c[i0]),
               baseline=baseline, depth=float(depth), z=float(z), threshold=threshold,
               significant=not reason, reason=reason)


def locate_dips(forecast_error, *, level=1 / 3, se=None, alpha=DIP_ALPHA,
                min_relative_depth=MIN_RELATIVE_DEPTH, batch_msq=None, random_state=0):
    """Dip of every column of a forecast-error table (:func:`locate_dip` per ``m``).

    Parameters
    ----------
    forecast_error : pandas.DataFrame
        Index ``tau``, one column per ``m`` (as from :func:`forecast_error_curve`).
    level : float, default=1/3
        Fraction of the dip depth (0 < level <= 1) that delimits the dip.
    se : pandas.DataFrame, default=None
        Standard errors of the cells (same shape); default: ``forecast_error.attrs["se"]``
        when present, else estimated from each curve's roughness.
    batch_msq : pandas.DataFrame, default=None
        Per-batch mean squared errors (:func:`batch_table`: index ``tau``, columns
        ``(m, split, batch)``); default: ``forecast_error.attrs["batch_msq"]`` when
        present.  A column ``m`` without them, or whose delays they do not cover,
        gets the centre error from independent redraws within ``se``.
    alpha, min_relative_depth, random_state
        As in :func:`locate_dip`.

    Returns
    -------
    pandas.DataFrame
        Index ``m``; columns ``delay`` (centre), ``half_width``, ``tau_min``
        (grid minimum), ``min_error``, ``centre_se``, ``delay_error``
        (half-width and centre error combined), ``tau_best`` (the grid delay
        a model should use), ``depth``, ``z`` (depth in standard errors),
        ``threshold``, ``significant`` and ``reason`` (why not, if not).

    Examples
    --------
    >>> import pandas as pd
    >>> curve = pd.DataFrame({2: [9.0, 8, 7, 4, 2, 3, 9, 9, 9]},
    ...                      index=pd.Index(range(10, 19), name="tau"))
    >>> row = locate_dips(curve, level=0.5).loc[2]
    >>> round(float(row["delay"]), 2), round(float(row["half_width"]), 2), int(row["tau_min"])
    (14.17, 1.33, 14)
    """
    if not isinstance(forecast_error, pd.DataFrame):
        raise TypeError(
            f"forecast_error must be a pandas DataFrame (index tau, one column per m), got "
            f"{type(forecast_error).__name__}; pass the table of forecast_error_curve(series, "
            f"m=..., tau=...), or pd.DataFrame({{m: errors}}, index=taus) for one curve.")
    if se is not None and not isinstance(se, pd.DataFrame):
        raise TypeError(f"se must be a pandas DataFrame shaped like forecast_error, got "
                        f"{type(se).__name__}.")
    if forecast_error.shape[1] == 0:
        raise ValueError("forecast_error has no columns; give one column of errors per m.")
    if se is None:
        se = forecast_error.attrs.get("se")
    if batch_msq is None:
        batch_msq = forecast_error.attrs.get("batch_msq")
    elif not (isinstance(batch_msq, pd.DataFrame) and batch_msq.columns.nlevels == 3):
        raise TypeError(f"batch_msq must be a DataFrame with columns (m, split, batch) as "
                        f"skdelay._dips.batch_table builds it, got {type(batch_msq).__name__}; "
                        "or leave it None to use forecast_error.attrs['batch_msq'].")
    try:
        taus = np.asarray(forecast_error.index, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"forecast_error's index must hold the delays tau (numbers), got "
                         f"{forecast_error.index[:3].tolist()}...; set it with "
                         "df.set_index('tau') or pd.DataFrame(..., index=taus).") from None
    rows = {}
    for m in forecast_error.columns:
        shift = -0.5 if isinstance(m, (int, np.integer)) and m >= 3 and m % 2 else 0.0
        dip = locate_dip(taus, forecast_error[m], se=None if se is None else se[m],
                         level=level, shift=shift, alpha=alpha,
                         min_relative_depth=min_relative_depth,
                         batch_msq=_batches_of(batch_msq, m, forecast_error.index),
                         random_state=random_state)
        rows[m] = {"delay": dip.centre, "half_width": dip.half_width, "tau_min": dip.tau_min,
                   "min_error": dip.min_error, "centre_se": dip.centre_se,
                   "delay_error": dip.error, "tau_best": dip.tau_best, "depth": dip.depth,
                   "z": dip.z, "threshold": dip.threshold, "significant": dip.significant,
                   "reason": dip.reason}
    out = pd.DataFrame.from_dict(rows, orient="index")
    out.index.name = "m"
    return out.astype({"tau_min": int, "tau_best": int, "significant": bool})


def _batches_of(table, m, index):
    """``(n_splits, n_tau, n_batches)`` of column ``m`` on the delays ``index``, or None."""
    if not isinstance(table, pd.DataFrame) or not isinstance(table.columns, pd.MultiIndex):
        return None
    try:
        block = table[m].reindex(index)
    except (KeyError, TypeError, ValueError):
        return None
    cols = block.columns
    if cols.nlevels != 2 or block.shape[0] != len(index):
        return None
    n_split = cols.get_level_values(0).nunique()
    n_b = cols.get_level_values(1).nunique()
    if block.shape[1] != n_split * n_b or block.isna().all(axis=1).any():
        return None
    return block.to_numpy().reshape(len(index), n_split, n_b).transpose(1, 0, 2)
