"""Classic (Takens-style) nonlinear time-series tools, TISEAN flavoured.

Used to cross-check the two-window analysis when the dynamics is low
dimensional (paper Sec. III): delay embedding, Poincaré section, local
projective noise reduction, correlation dimension D2, Kantz's maximal
Lyapunov exponent and false nearest neighbours.  Everything is vectorised
numpy on top of :class:`scipy.spatial.cKDTree`, sized for 1e5-1e6 points
(queries are subsampled with ``n_reference`` where the cost is quadratic).

Convention: row ``i`` of a delay embedding is
``(s[i], s[i+lag], ..., s[i+(dim-1)*lag])`` (TISEAN / nolds order), so row
``i + k`` is row ``i`` advanced by ``k`` samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from numba import njit
from scipy.signal import find_peaks
from scipy.spatial import cKDTree

from ._checks import (
    Options,
    check_interval,
    check_params,
    check_positive_int,
    check_random_state,
    check_series,
    standardise,
)
from ._iterate import progress_bar

__all__ = [
    "CorrelationDimension",
    "MaximalLyapunovExponent",
    "correlation_dimension",
    "correlation_sum",
    "delay_embedding",
    "false_nearest_neighbors",
    "maximal_lyapunov_exponent",
    "noise_reduction",
    "poincare_section",
]


def _check_pair(name, value):
    """Rule for a (low, high) range of radii or times: None or finite, 0 <= low < high."""
    return check_interval(name, value, nonnegative=True)


def _check_theiler(theiler_window, n_vectors):
    w = check_positive_int(theiler_window, name="theiler_window", minimum=0)
    if 2 * w + 2 > n_vectors:
        raise ValueError(
            f"theiler_window={w} excludes every pair of the {n_vectors} embedded vectors; "
            "use a smaller Theiler window (a few autocorrelation times) or a longer series."
        )
    return w


def _reference_points(n, n_reference, rng):
    if n_reference is None or n_reference >= n:
        return np.arange(n)
    n_reference = check_positive_int(n_reference, name="n_reference")
    return np.sort(rng.choice(n, size=n_reference, replace=False))


def delay_embedding(series, dim, lag=1):
    """Takens delay vectors as a read-only, zero-copy view.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Scalar time series.
    dim : int
        Embedding dimension.
    lag : int, default=1
        Delay between coordinates, in samples.

    Returns
    -------
    ndarray of shape (n_samples - (dim - 1) * lag, dim)
        ``X[i] = (s[i], s[i + lag], ..., s[i + (dim - 1) * lag])``; a strided view
        of ``series`` (no copy when it already is a contiguous float64 array).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.classic import delay_embedding
    >>> delay_embedding(np.arange(6.0), dim=3, lag=2)
    array([[0., 2., 4.],
           [1., 3., 5.]])
    """
    dim = check_positive_int(dim, name="dim")
    lag = check_positive_int(lag, name="lag")
    span = (dim - 1) * lag + 1
    s = check_series(series, min_length=span + 1, allow_constant=True)
    return np.lib.stride_tricks.sliding_window_view(s, span)[:, ::lag]


def poincare_section(series, *, sample_dt=1.0, kind="maxima", prominence=None):
    """Poincaré section in the plane ``ds/dt = 0``: the local extrema of a flow.

    Each extremum is refined by a parabola through the three samples around
    it, which removes the sampling jitter of the raw maximum (the paper's
    Fig. 8a collects the maxima of the laser intensity this way).

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Sampled flow.
    sample_dt : float, default=1.0
        Sampling step, so that the returned times are in time units.
    kind : {"maxima", "minima"}, default="maxima"
    prominence : float, optional
        Ignore extrema less prominent than this (in the units of ``series``);
        useful to skip noise wiggles.  Flat tops (quantised data) count once.

    Returns
    -------
    times : ndarray
        Interpolated times of the extrema (time units, origin at sample 0).
    values : ndarray
        Interpolated extreme values; ``values[k]`` vs ``values[k+1]`` is the
        return map.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.classic import poincare_section
    >>> t = np.arange(0, 20, 0.1)
    >>> times, values = poincare_section(np.sin(t), sample_dt=0.1)
    >>> np.round(values[:2], 4), np.round(times[:2], 2)
    (array([1., 1.]), array([1.57, 7.85]))
    """
    s = check_series(series, min_length=3)
    sample_dt, kind, prominence = check_params(
        sample_dt=sample_dt, kind=(kind, Options("maxima", "minima")), prominence=prominence)
    sign = 1.0 if kind == "maxima" else -1.0
    peaks, _ = find_peaks(sign * s, prominence=prominence)
    peaks = peaks[(peaks > 0) & (peaks < s.size - 1)]
    y0, y1, y2 = s[peaks - 1], s[peaks], s[peaks + 1]
    curv = y0 - 2.0 * y1 + y2
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(curv != 0.0, 0.5 * (y0 - y2) / curv, 0.0)
    delta = np.clip(delta, -0.5, 0.5)
    values = y1 - 0.25 * (y0 - y2) * delta
    return (peaks + delta) * float(sample_dt), values


@njit(cache=True)
def _local_projection(X, rows, idx, w, weights, n_normal):
    """Correction of each delay vector towards its local q-dimensional manifold.

    In the metric ``weights`` (large at both ends), the neighbourhood
    covariance ``Gamma = R C R`` is diagonalised; the component of ``R (x - centre)``
    along the ``n_normal`` least-variance directions is removed.
    """
    n, k = idx.shape
    dim = X.shape[1]
    theta = np.zeros((n, dim))
    centre = np.empty(dim)
    gamma = np.empty((dim, dim))
    dev = np.empty(dim)
    z = np.empty(dim)
    for a in range(n):
        tot = 0.0
        centre[:] = 0.0
        for b in range(k):
            wb = w[a, b]
            if wb > 0.0:
                tot += wb
                for c in range(dim):
                    centre[c] += wb * X[idx[a, b], c]
        for c in range(dim):
            centre[c] /= tot
        gamma[:, :] = 0.0
        for b in range(k):
            wb = w[a, b]
            if wb > 0.0:
                for c in range(dim):
                    dev[c] = (X[idx[a, b], c] - centre[c]) * weights[c]
                for c in range(dim):
                    for e in range(c + 1):
                        gamma[c, e] += wb * dev[c] * dev[e]
        for c in range(dim):
            for e in range(c):
                gamma[e, c] = gamma[c, e]
        _, vecs = np.linalg.eigh(gamma)  # ascending eigenvalues
        for c in range(dim):
            z[c] = (X[rows[a], c] - centre[c]) * weights[c]
        for v in range(n_normal):
            proj = 0.0
            for c in range(dim):
                proj += vecs[c, v] * z[c]
            for c in range(dim):
                theta[a, c] -= proj * vecs[c, v] / weights[c]
    return theta


def noise_reduction(series, *, dim=7, q=2, lag=1, n_neighbors=30, radius=None,
                    iterations=3, end_weight=1000.0, chunk_size=20_000, workers=1):
    """Local projective noise reduction (Grassberger et al. 1993, TISEAN ``ghkss``).

    In a ``dim``-dimensional delay embedding, the clean dynamics lies close
    to a ``q``-dimensional manifold.  For every delay vector the covariance of
    its neighbourhood is computed in a metric that makes corrections of the
    first and last coordinates expensive (weight ``end_weight``), so the
    middle coordinates are corrected.  The vector is projected onto the
    ``q`` leading local directions (through the neighbourhood's centre of
    mass); each sample receives the average of the corrections of all delay
    vectors that contain it.  Repeated ``iterations`` times.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
    dim : int, default=7
        Embedding dimension (must exceed ``q``; ghkss uses 5-10).
    q : int, default=2
        Dimension of the local manifold kept (Hénon: 2).
    lag : int, default=1
    n_neighbors : int, default=30
        Neighbourhood size (k nearest neighbours, the point itself included).
    radius : float, optional
        If given, only neighbours within ``radius`` (max-norm, units of the
        series) are used, at most ``n_neighbors``; vectors with fewer than
        ``dim + 1`` such neighbours are left unchanged.
    iterations : int, default=3
    end_weight : float, default=1000.0
        Penalty for corrections of the first and last coordinate.
    chunk_size : int, default=20000
        Vectors whose neighbours are searched at once (memory ~ chunk_size * n_neighbors).
    workers : int, default=1
        Threads for the kd-tree queries (-1 = all cores).

    Returns
    -------
    ndarray of shape (n_samples,)
        The cleaned series.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.datasets import henon
    >>> from skdelay.classic import noise_reduction
    >>> clean = henon(5000, random_state=0)
    >>> noisy = clean + 0.05 * clean.std() * np.random.default_rng(0).normal(size=clean.size)
    >>> cleaned = noise_reduction(noisy, dim=7, q=2, iterations=3, n_neighbors=15)
    >>> bool(np.std(cleaned - clean) < 0.5 * np.std(noisy - clean))
    True
    """
    dim = check_positive_int(dim, name="dim", minimum=2)
    q = check_positive_int(q, name="q", maximum=dim - 1)
    lag = check_positive_int(lag, name="lag")
    k = check_positive_int(n_neighbors, name="n_neighbors", minimum=dim + 1)
    iterations = check_positive_int(iterations, name="iterations")
    s = check_series(series, min_length=(dim - 1) * lag + k + 1).copy()
    radius, end_weight, workers = check_params(radius=radius, end_weight=end_weight,
                                               workers=workers)
    chunk_size = check_positive_int(chunk_size, name="chunk_size")
    # local covariances square the data: standardise (the projection is equivariant
    # under x -> a x + b) so that 1e200 or 1e-200 data neither overflow nor underflow
    s, centre, unit = standardise(s)
    radius = None if radius is None else radius / unit
    weights = np.ones(dim)
    weights[0] = weights[-1] = float(end_weight)
    n_chunks = -(-(s.size - (dim - 1) * lag) // chunk_size)
    # a bar inside ``skdelay analyze`` (progress_bars): 2e5 samples take ~30 s on 2 cores
    with progress_bar(iterations * n_chunks, "noise reduction", unit="chunk") as bar:
        for _ in range(iterations):
            s = _projection_pass(s, dim, lag, k, radius, weights, q, chunk_size, workers, bar)
    return s * unit + centre


def _projection_pass(s, dim, lag, k, radius, weights, q, chunk_size, workers, bar):
    """One pass of local projective noise reduction (see :func:`noise_reduction`)."""
    offsets = np.arange(dim) * lag
    X = delay_embedding(s, dim, lag)
    tree = cKDTree(X)
    total = np.zeros(s.size)
    hits = np.zeros(s.size)
    for start in range(0, X.shape[0], chunk_size):
        bar.update(1)
        rows = np.arange(start, min(start + chunk_size, X.shape[0]))
        dist, idx = tree.query(X[rows], k=k, p=np.inf, workers=workers)
        w = np.ones(dist.shape) if radius is None else (dist <= radius).astype(float)
        count = w.sum(axis=1)
        ok = count >= dim + 1
        if not ok.any():
            continue
        rows, idx, w = rows[ok], idx[ok], w[ok]
        theta = _local_projection(X, rows, idx, w, weights, dim - q)
        target = rows[:, None] + offsets[None, :]
        total += np.bincount(target.ravel(), theta.ravel(), minlength=s.size)
        hits += np.bincount(target.ravel(), minlength=s.size)
    return s + np.divide(total, hits, out=np.zeros_like(total), where=hits > 0)


def _pair_sample_c(X, ref, radii, w, n_pairs, rng):
    """C(r) from random (reference, any) pairs: cheap, accurate where C is not small."""
    i = rng.choice(ref, size=n_pairs)
    j = rng.randint(0, X.shape[0], size=n_pairs)
    keep = np.abs(i - j) > w
    d = np.sort(np.max(np.abs(X[i[keep]] - X[j[keep]]), axis=1))
    return np.searchsorted(d, radii, side="right") / max(d.size, 1)


_NBOX = 1024
#: range / largest radius above which box indices lose integer precision (2**53)
_MAX_BOXES_PER_RANGE = 1e15


@njit(cache=True)
def _box_counts(X, ref, sub, radii, w):
    """Pairs (i in ref, j in sub, |i-j| > w) with max-norm distance <= each radius.

    Box-assisted search (TISEAN): boxes of size radii[-1] in the first and
    last coordinate, wrapped modulo _NBOX; only the 3x3 neighbouring boxes
    are scanned, so the cost is proportional to the close pairs.
    """
    r_top = radii[-1]
    dim = X.shape[1]
    last = dim - 1
    mask = _NBOX - 1
    n_sub = sub.size
    key = np.empty(n_sub, dtype=np.int64)
    head = np.zeros(_NBOX * _NBOX + 1, dtype=np.int64)
    for a in range(n_sub):
        j = sub[a]
        bx = np.int64(np.floor(X[j, 0] / r_top)) & mask
        by = np.int64(np.floor(X[j, last] / r_top)) & mask
        key[a] = bx * _NBOX + by
        head[key[a] + 1] += 1
    for b in range(_NBOX * _NBOX):
        head[b + 1] += head[b]
    order = np.empty(n_sub, dtype=np.int64)
    fill = head[:-1].copy()
    for a in range(n_sub):
        order[fill[key[a]]] = sub[a]
        fill[key[a]] += 1
    hist = np.zeros(radii.size + 1, dtype=np.int64)
    for i in ref:
        bx0 = np.int64(np.floor(X[i, 0] / r_top))
        by0 = np.int64(np.floor(X[i, last] / r_top))
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                b = ((bx0 + dx) & mask) * _NBOX + ((by0 + dy) & mask)
                for p in range(head[b], head[b + 1]):
                    j = order[p]
                    if abs(i - j) <= w:
                        continue
                    d = 0.0
                    for c in range(dim):
                        e = abs(X[i, c] - X[j, c])
                        if e > d:
                            d = e
                            if d > r_top:
                                break
                    if d <= r_top:
                        hist[np.searchsorted(radii, d)] += 1
    return np.cumsum(hist)[: radii.size].astype(np.float64)


def correlation_sum(series, dim, lag=1, radii=None, *, theiler_window=0, n_reference=5000,
                    max_pairs=1_000_000, random_state=None, workers=1):
    """Grassberger–Procaccia correlation sum ``C(r)`` with a Theiler window.

    ``C(r)`` is the fraction of pairs ``(i, j)``, ``|i - j| > theiler_window``,
    of delay vectors closer than ``r`` in the maximum norm.  The ``i`` run
    over ``n_reference`` random reference vectors.  Like TISEAN ``d2`` the
    pair budget is capped per radius: at small ``r`` every vector ``j`` is
    used (exact kd-tree counts), at large ``r``, where ``C`` is large, a
    random subset of the ``j`` just big enough to count about ``max_pairs``
    close pairs — so the cost stays near-linear in the series length.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
    dim : int
        Embedding dimension.
    lag : int, default=1
    radii : array-like of float, optional
        Increasing radii (units of the series).  Default: 40 values
        log-spaced from ``1e-3`` to 1 times the range of the series.
    theiler_window : int, default=0
        Pairs closer than this in time are not counted (use a few
        autocorrelation times for flows).
    n_reference : int or None, default=5000
        Number of reference vectors (None = all).
    max_pairs : int or None, default=1_000_000
        Pair budget per radius (None = count every pair: exact, quadratic).
    random_state : int, RandomState or None
    workers : int, default=1
        Threads for the kd-tree queries (-1 = all cores).

    Returns
    -------
    radii : ndarray
    C : ndarray, same shape as ``radii``

    Examples
    --------
    >>> from skdelay.datasets import henon
    >>> from skdelay.classic import correlation_sum
    >>> r, c = correlation_sum(henon(2000, random_state=0), 2, radii=[0.01, 0.1])
    >>> bool(c[0] < c[1])
    True
    """
    s = check_series(series, min_length=(dim - 1) * lag + 3)
    # distances do not change under a shift; from the minimum the box indices of the
    # search stay small even for data with a large offset (1e200 + O(1) signals)
    s = s - s.min()
    X = delay_embedding(s, dim, lag)
    n = X.shape[0]
    w = _check_theiler(theiler_window, n)
    if radii is None:
        radii = np.ptp(s) * np.geomspace(1e-3, 1.0, 40)
    try:
        radii = np.asarray(radii, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise TypeError(f"radii must be an array of numbers (in the units of the series), "
                        f"got {radii!r}.") from None
    # NaN compares False with everything, so test finiteness explicitly
    if (radii.size == 0 or not np.all(np.isfinite(radii)) or np.any(radii <= 0)
            or np.any(np.diff(radii) <= 0)):
        raise ValueError(f"radii must be finite, positive and strictly increasing (in the "
                         f"units of the series), got {radii!r}.")
    random_state, workers = check_params(random_state=random_state, workers=workers)
    if np.ptp(s) / radii[-1] > _MAX_BOXES_PER_RANGE:
        raise ValueError(
            f"the largest radius {radii[-1]:.3g} is below {1 / _MAX_BOXES_PER_RANGE:.0e} times "
            f"the range {np.ptp(s):.3g} of the series, beyond float64 resolution; pass radii in "
            "the units of the series (the default spans 1e-3..1 times its range)."
        )
    rng = check_random_state(random_state)
    ref = _reference_points(n, n_reference, rng)
    level = np.zeros(radii.size, dtype=int)
    if max_pairs is not None:
        pilot = _pair_sample_c(X, ref, radii, w, 200_000, rng)
        wanted = max_pairs / (ref.size * np.maximum(pilot, 1e-300))
        level = np.clip(np.floor(np.log(n / np.maximum(wanted, 1.0)) / np.log(4.0)), 0, None)
        level = np.minimum(level, np.floor(np.log(n / 256.0) / np.log(4.0))).astype(int)
        level = np.maximum(level, 0)
    out = np.empty(radii.size)
    for lev in np.unique(level):
        sel = np.flatnonzero(level == lev)
        member = np.ones(n, dtype=bool)
        if lev > 0:
            member[:] = False
            member[rng.choice(n, size=n // 4 ** lev, replace=False)] = True
        sub = np.flatnonzero(member)
        counts = _box_counts(X, ref, sub, radii[sel], w)
        # pairs inside the Theiler window (including i == j) are not pairs at all
        cs = np.concatenate(([0], np.cumsum(member)))
        in_window = cs[np.minimum(ref + w, n - 1) + 1] - cs[np.maximum(ref - w, 0)]
        out[sel] = counts / (ref.size * sub.size - in_window.sum())
    return radii, out


@dataclass(frozen=True)
class CorrelationDimension:
    """Result of :func:`correlation_dimension`.

    Attributes
    ----------
    dimension : float
        D2: mean local slope over ``scaling_range`` and the ``n_converged``
        largest embedding dimensions.
    spread : float
        Standard deviation of those local slopes (small = clear plateau).
    scaling_range : tuple of float
        ``(r_low, r_high)`` in the units of the series.
    correlation_sum : pandas.DataFrame
        ``C(r)``, index ``radius``, one column per embedding dimension.
    local_slopes : pandas.DataFrame
        ``d log C / d log r``, same layout.
    """

    dimension: float
    spread: float
    scaling_range: tuple
    correlation_sum: pd.DataFrame
    local_slopes: pd.DataFrame


def correlation_dimension(series, dims=range(1, 9), lag=1, *, radii=None, theiler_window=0,
                          n_reference=5000, scaling_range=None, n_converged=3,
                          window=8, min_pairs=500, random_state=None):
    """Correlation dimension D2 from the local slopes of ``C(r)`` in a scaling range.

    For each embedding dimension the local slope ``d log C / d log r`` is
    computed; D2 is its mean over a scaling range and over the
    ``n_converged`` largest dimensions (where the slopes should agree).  If
    ``scaling_range`` is not given, the range of ``window`` consecutive radii
    where those slopes are the flattest and most consistent (smallest
    standard deviation) is chosen, among radii with at least ``min_pairs``
    counted pairs at the largest dimension (below that the statistics is
    dominated by counting noise) and ``C < 0.5`` (above: finite-size of the
    attractor).  Inspect ``local_slopes`` (or plot it with
    :func:`skdelay.plotting.plot_correlation_dimension`) before trusting it.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
    dims : sequence of int, default=range(1, 9)
    lag : int, default=1
    radii : array-like of float, optional
        Default: 48 radii log-spaced from ``1e-3`` to 1 times the range.
    theiler_window : int, default=0
    n_reference : int or None, default=5000
    scaling_range : (float, float), optional
        Fixed ``(r_low, r_high)`` instead of the automatic choice.
    n_converged : int, default=3
        Number of largest dimensions averaged (clipped to ``len(dims)``).
    window : int, default=8
        Number of consecutive radii in the automatic scaling range.
    min_pairs : int, default=500
    random_state : int, RandomState or None

    Returns
    -------
    CorrelationDimension

    Examples
    --------
    >>> from skdelay.datasets import henon
    >>> from skdelay.classic import correlation_dimension
    >>> res = correlation_dimension(henon(5000, random_state=0), dims=[1, 2, 3, 4],
    ...                             random_state=0)
    >>> 1.1 < res.dimension < 1.35
    True
    """
    dims = [check_positive_int(d, name="dims") for d in np.atleast_1d(dims)]
    n_converged = min(check_positive_int(n_converged, name="n_converged"), len(dims))
    min_pairs, random_state = check_params(min_pairs=min_pairs, random_state=random_state)
    scaling_range = check_params(scaling_range=(scaling_range, _check_pair))
    s = check_series(series, min_length=(max(dims) - 1) * lag + 3)
    if radii is None:
        radii = np.ptp(s) * np.geomspace(1e-3, 1.0, 48)
    curves = {}
    n_ref = None
    for d in dims:
        r, c = correlation_sum(s, d, lag, radii, theiler_window=theiler_window,
                               n_reference=n_reference, random_state=random_state)
        curves[d] = c
        n_ref = min(n_reference or np.inf, s.size - (d - 1) * lag)
    C = pd.DataFrame(curves, index=pd.Index(r, name="radius"))
    C.columns.name = "dim"
    with np.errstate(divide="ignore", invalid="ignore"):
        logc = np.log(C.to_numpy())
        slopes = np.gradient(logc, np.log(r), axis=0)
    slopes[~np.isfinite(slopes)] = np.nan
    S = pd.DataFrame(slopes, index=C.index, columns=C.columns)
    top = slopes[:, -n_converged:]
    if scaling_range is None:
        n_pairs = C.iloc[:, -1].to_numpy() * n_ref * (s.size - (max(dims) - 1) * lag)
        usable = (n_pairs >= min_pairs) & (C.iloc[:, -1].to_numpy() < 0.5)
        usable &= np.all(np.isfinite(top), axis=1)
        window = min(check_positive_int(window, name="window", minimum=2), r.size)
        best, best_score = None, np.inf
        for a in range(r.size - window + 1):
            if usable[a:a + window].all():
                score = np.std(top[a:a + window])
                if score < best_score:
                    best, best_score = a, score
        if best is None:
            raise ValueError(
                "no scaling range found: too few pairs at small radii. Use a longer series, "
                "larger n_reference, smaller dims, or pass scaling_range=(r_low, r_high)."
            )
        sel = np.arange(best, best + window)
    else:
        lo, hi = scaling_range
        sel = np.flatnonzero((r >= lo) & (r <= hi))
        if sel.size < 2:
            raise ValueError(f"scaling_range={scaling_range} contains fewer than 2 radii; widen "
                             "it or pass denser radii.")
    vals = top[sel]
    return CorrelationDimension(
        dimension=float(np.nanmean(vals)),
        spread=float(np.nanstd(vals)),
        scaling_range=(float(r[sel[0]]), float(r[sel[-1]])),
        correlation_sum=C,
        local_slopes=S,
    )


@dataclass(frozen=True)
class MaximalLyapunovExponent:
    """Result of :func:`maximal_lyapunov_exponent`.

    Attributes
    ----------
    exponent : float
        Maximal Lyapunov exponent per time unit (natural log).
    divergence : pandas.Series
        ``S(t)``: mean log distance of neighbouring segments after time ``t``
        (index ``time`` in time units).
    fit_range : tuple of float
        ``(t_start, t_stop)`` of the linear fit, time units.
    intercept : float
        Intercept of the fit (for plotting the line).
    """

    exponent: float
    divergence: pd.Series
    fit_range: tuple
    intercept: float


def _auto_fit_range(t, S, fraction=0.4, saturation=0.8):
    """Linear range of the divergence curve: its straightest stretch before saturation.

    Between the initial transient (curved: neighbours align with the unstable
    direction) and the saturation at the attractor size, ``S(t)`` is a
    straight line.  Among the stretches covering ``fraction`` of the curve up
    to ``saturation`` of its total rise, keep the one whose straight-line fit
    has the smallest rms residual relative to the rise it explains.
    """
    rise = S - S[0]
    top = np.nanmax(rise)
    if not top > 0:
        raise ValueError("the divergence curve does not grow: no positive exponent is visible "
                         "(increase max_steps, or the data are not chaotic).")
    end = max(int(np.argmax(rise >= saturation * top)) + 1, 5)
    length = max(4, round(fraction * end))
    best, best_score = (0, min(end, t.size)), np.inf
    for a in range(max(1, end - length + 1)):
        tt, ss = t[a:a + length], S[a:a + length]
        slope, icpt = np.polyfit(tt, ss, 1)
        if not slope > 0:
            continue
        resid = ss - (slope * tt + icpt)
        score = np.sqrt(np.mean(resid ** 2)) / (slope * (tt[-1] - tt[0]))
        if score < best_score:
            best, best_score = (a, a + length), score
    return t[best[0]], t[best[1] - 1]


@njit(cache=True)
def _divergence(X, ref, nbrs, max_steps):
    """S(dn) = mean_i ln(mean_j ||x_{i+dn} - x_{j+dn}||) over rows with a positive mean."""
    out = np.empty(max_steps + 1)
    dim = X.shape[1]
    for dn in range(max_steps + 1):
        acc = 0.0
        used = 0
        for a in range(ref.size):
            i = ref[a] + dn
            tot = 0.0
            cnt = 0
            for b in range(nbrs.shape[1]):
                j = nbrs[a, b]
                if j < 0:
                    break
                j += dn
                d2 = 0.0
                for c in range(dim):
                    e = X[i, c] - X[j, c]
                    d2 += e * e
                tot += np.sqrt(d2)
                cnt += 1
            if cnt > 0 and tot > 0.0:
                acc += np.log(tot / cnt)
                used += 1
        out[dn] = acc / used if used > 0 else np.nan
    return out


def maximal_lyapunov_exponent(series, *, dim, lag=1, theiler_window=0, sample_dt=1.0,
                              max_steps=100, n_neighbors=20, radius=None, n_reference=2000,
                              fit_range=None, random_state=None, workers=1):
    """Maximal Lyapunov exponent by Kantz's method (Kantz 1994, TISEAN ``lyap_k``).

    For reference vectors ``x_i`` and their neighbours ``x_j`` (``|i - j| >
    theiler_window``) the average log-divergence

        ``S(dn) = < ln( mean_j || x_{i+dn} - x_{j+dn} || ) >_i``

    grows as ``S(0) + lambda_1 * dn * sample_dt`` in a linear range between an
    initial transient and saturation at the attractor size.  The slope there
    is the exponent.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
    dim, lag : int
        Delay embedding.
    theiler_window : int, default=0
        Temporal exclusion in samples (a few autocorrelation times for flows).
    sample_dt : float, default=1.0
        Sampling step; the exponent is returned per time unit.
    max_steps : int, default=100
        Largest ``dn`` (samples).
    n_neighbors : int, default=20
        Neighbours per reference vector (at most this many if ``radius``).
    radius : float, optional
        Use only neighbours within this Euclidean distance (Kantz's epsilon).
    n_reference : int or None, default=2000
        Number of random reference vectors.
    fit_range : (float, float), optional
        ``(t_start, t_stop)`` in time units; default: automatic (the
        straightest stretch, 40 % of the curve below 80 % of its rise, i.e.
        after the transient and before saturation) — check it on the curve
        (:func:`skdelay.plotting.plot_divergence`).
    random_state : int, RandomState or None
    workers : int, default=1
        Threads for the kd-tree query.

    Returns
    -------
    MaximalLyapunovExponent

    Examples
    --------
    >>> from skdelay.datasets import henon
    >>> from skdelay.classic import maximal_lyapunov_exponent
    >>> res = maximal_lyapunov_exponent(henon(5000, random_state=0), dim=2, max_steps=12,
    ...                                 fit_range=(0, 5), random_state=0)
    >>> 0.3 < res.exponent < 0.5   # exact value 0.419
    True
    """
    dim = check_positive_int(dim, name="dim")
    lag = check_positive_int(lag, name="lag")
    max_steps = check_positive_int(max_steps, name="max_steps")
    k = check_positive_int(n_neighbors, name="n_neighbors")
    sample_dt, radius, random_state, workers = check_params(
        sample_dt=sample_dt, radius=radius, random_state=random_state, workers=workers)
    fit_range = check_params(fit_range=(fit_range, _check_pair))
    s = check_series(series, min_length=(dim - 1) * lag + max_steps + 10)
    # the k-d tree squares distances (overflow at 1e200): work in units of the std; the
    # divergence S = <ln distance> then shifts by ln(std), the slope does not change
    s, _, unit = standardise(s)
    radius = None if radius is None else radius / unit
    X = delay_embedding(s, dim, lag)
    usable = X.shape[0] - max_steps
    w = _check_theiler(theiler_window, usable)
    rng = check_random_state(random_state)
    ref = _reference_points(usable, n_reference, rng)
    tree = cKDTree(X[:usable])
    kq = min(k + 2 * w + 1, usable)
    dist, idx = tree.query(X[ref], k=kq, workers=workers)
    dist, idx = dist.reshape(ref.size, -1), idx.reshape(ref.size, -1)
    valid = np.abs(idx - ref[:, None]) > w
    if radius is not None:
        valid &= dist <= radius
    valid &= np.cumsum(valid, axis=1) <= k
    has = valid.any(axis=1)
    if not has.any():
        raise ValueError("no reference vector has a neighbour (radius too small or Theiler "
                         "window too large); increase radius or n_neighbors.")
    ref, idx, valid = ref[has], idx[has], valid[has]
    # compact the neighbour lists to (n_ref, k), -1 = no neighbour
    pos = np.cumsum(valid, axis=1) - 1
    nbrs = -np.ones((ref.size, k), dtype=np.int64)
    rows = np.broadcast_to(np.arange(ref.size)[:, None], idx.shape)
    nbrs[rows[valid], pos[valid]] = idx[valid]
    S = _divergence(X, ref.astype(np.int64), nbrs, max_steps) + np.log(unit)
    t = np.arange(max_steps + 1) * float(sample_dt)
    if fit_range is None:
        fit_range = _auto_fit_range(t, S)
    sel = (t >= fit_range[0] - 1e-12) & (t <= fit_range[1] + 1e-12)
    if sel.sum() < 2:
        raise ValueError(f"fit_range={fit_range} holds fewer than 2 steps; widen it (time units).")
    slope, icpt = np.polyfit(t[sel], S[sel], 1)
    return MaximalLyapunovExponent(
        exponent=float(slope),
        divergence=pd.Series(S, index=pd.Index(t, name="time"), name="S"),
        fit_range=(float(fit_range[0]), float(fit_range[1])),
        intercept=float(icpt),
    )


def false_nearest_neighbors(series, *, max_dim=10, lag=1, rtol=10.0, atol=2.0,
                            theiler_window=0, n_reference=None, random_state=None, workers=1):
    """Fraction of false nearest neighbours versus embedding dimension (Kennel et al. 1992).

    The nearest neighbour ``j`` of ``x_i`` in dimension ``d`` is *false* if
    adding the coordinate ``d + 1`` separates them: ``|s_{i+d*lag} -
    s_{j+d*lag}| / R_d > rtol`` or ``R_{d+1} / std(s) > atol``.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
    max_dim : int, default=10
    lag : int, default=1
    rtol, atol : float, default=10.0, 2.0
    theiler_window : int, default=0
    n_reference : int or None
        Random subsample of reference vectors (None = all).
    random_state : int, RandomState or None
    workers : int, default=1

    Returns
    -------
    pandas.DataFrame
        Index ``dim`` (1..max_dim), column ``fraction``.

    Examples
    --------
    >>> from skdelay.datasets import henon
    >>> from skdelay.classic import false_nearest_neighbors
    >>> fnn = false_nearest_neighbors(henon(3000, random_state=0), max_dim=3)
    >>> bool(fnn.loc[1, "fraction"] > 0.5 and fnn.loc[2, "fraction"] < 0.05)
    True
    """
    max_dim = check_positive_int(max_dim, name="max_dim")
    lag = check_positive_int(lag, name="lag")
    rtol, atol, random_state, workers = check_params(
        rtol=rtol, atol=atol, random_state=random_state, workers=workers)
    s = check_series(series, min_length=max_dim * lag + 10)
    # both criteria are ratios of distances: standardising changes nothing but keeps the
    # k-d tree's squared distances finite for data of any scale
    s = standardise(s)[0]
    ra = 1.0
    rng = check_random_state(random_state)
    out = []
    for d in range(1, max_dim + 1):
        X1 = delay_embedding(s, d + 1, lag)
        n = X1.shape[0]
        w = _check_theiler(theiler_window, n)
        Xd = X1[:, :d]
        ref = _reference_points(n, n_reference, rng)
        kq = min(2 * w + 2 + 8, n)
        dist, idx = cKDTree(Xd).query(Xd[ref], k=kq, workers=workers)
        valid = (np.abs(idx - ref[:, None]) > w) & (dist > 0)
        first = np.argmax(valid, axis=1)
        has = valid[np.arange(ref.size), first]
        r_d = dist[np.arange(ref.size), first][has]
        i, j = ref[has], idx[np.arange(ref.size), first][has]
        extra = np.abs(X1[i, d] - X1[j, d])
        r_next = np.sqrt(r_d ** 2 + extra ** 2)
        false = (extra / r_d > rtol) | (r_next / ra > atol)
        out.append((d, float(false.mean()) if false.size else np.nan))
    return pd.DataFrame(out, columns=["dim", "fraction"]).set_index("dim")
