"""Delay selection from the one-step forecast error sigma_m(tau).

The scan works on the 1-D series: a row ``t`` of the database is the vector
``v_t(m, tau)`` (gathered from the series on the fly) with target ``s[t+1]``,
so nothing of size (n_rows, n_lags) is ever materialised.

Two neighbour searches are available:

* ``"exact"`` -- a plain k-d tree on the 2m-dimensional vectors, rebuilt for
  every ``(m, tau)``.
* ``"candidates"`` (default, much faster) -- the second window of row ``t``
  is the first window of row ``t - c`` (``c`` the window start), so one k-d
  tree per ``m`` on the m-dimensional windows serves every ``tau``: each
  needed time gets its ``K`` nearest windows once, and for each ``tau`` the
  candidates of a query ``q`` -- the neighbours of its first window and those
  of its second window, shifted by ``c`` -- are re-ranked by the exact
  2m-dimensional distance (numba).  Every point outside both lists is at
  least ``r_K(q)^2 + r_K(q - c)^2`` away, so when the ``k``-th re-ranked
  distance is below that bound the neighbours are provably the exact k-NN;
  otherwise they are the best ``k`` of the ``2K`` candidates
  (``exact_fraction`` in ``DataFrame.attrs``; about 2 % change of sigma in
  ``benchmarks/delay_scan.py``).  Taking candidates close in either window
  matters: with first-window candidates only, rare states get neighbours far
  away in the second window, and the extrapolated forecasts can turn the
  delay dip into a peak.
"""

from __future__ import annotations

import numbers

import numpy as np
import pandas as pd
from joblib import Parallel, delayed, effective_n_jobs
from numba import njit
from scipy.spatial import cKDTree
from scipy.stats import rankdata
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.model_selection import TimeSeriesSplit, check_cv
from sklearn.pipeline import Pipeline
from sklearn.utils.validation import check_is_fitted, validate_data

from skdelay._checks import check_positive_int, check_random_state, check_series
from skdelay._correlation import autocorrelation
from skdelay._dips import locate_dips
from skdelay._embedding import (
    TwoWindowEmbedding,
    _second_window_start,
    required_lags,
    two_window_columns,
)
from skdelay._local_linear import LocalLinearDelayMap
from skdelay._neighbours import RADIUS_CAP, chunk_slices, fit_from_series, tree_neighbours
from skdelay._windows import series_from_lagged

__all__ = ["DelaySelectorCV", "forecast_error_curve", "locate_dips"]


# ----------------------------------------------------------------------------- grids, options
def as_grid(values, name):
    """Sorted unique positive ints; an int ``v`` means ``1..v``."""
    if isinstance(values, numbers.Integral) and not isinstance(values, (bool, np.bool_)):
        values = range(1, int(values) + 1)
    try:
        arr = np.asarray(list(values))
    except TypeError:
        raise TypeError(f"{name} must be an int or a sequence of ints, got {values!r}.") from None
    if arr.size == 0:
        raise ValueError(f"{name} is empty; give at least one value.")
    if not np.issubdtype(arr.dtype, np.integer) or arr.min() < 1:
        raise ValueError(f"{name} must hold positive integers, got {values!r}.")
    return np.unique(arr.astype(np.int64))


def theiler_from(s, theiler_window):
    """``"auto"``: the 1/e decorrelation time of the series (>= 1 sample)."""
    if isinstance(theiler_window, str):
        if theiler_window != "auto":
            raise ValueError(f"theiler_window must be 'auto' or an int >= 0, got {theiler_window!r}.")
        acf = autocorrelation(s, min(s.size - 1, 5000))
        below = np.flatnonzero(acf < np.exp(-1.0))
        return int(max(1, below[0] if below.size else acf.size))
    return check_positive_int(theiler_window, name="theiler_window", minimum=0)


# ----------------------------------------------------------------------------- kernels
@njit(cache=True)
def _kth_smallest(a, k):
    """k-th smallest (0-based) value of ``a``, reordering ``a`` in place (quickselect)."""
    lo, hi = 0, a.size - 1
    while lo < hi:
        pivot = a[(lo + hi) // 2]
        i, j = lo, hi
        while i <= j:
            while a[i] < pivot:
                i += 1
            while a[j] > pivot:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return a[k]


@njit(cache=True)
def _union_rerank(s, q_t, lists, ldist, rk2, row_of, u_min, start, m, k, radius2, is_db,
                  nb_t, weight, reach, bound):
    """Exact two-window distances over the union of each query's two candidate lists.

    Candidates of query ``q`` are its first-window neighbours ``lists[q]`` and
    its second-window neighbours ``lists[q - start] + start``; ``ldist`` holds
    their list distances (one window), so only the other window is read from
    the series.  Duplicates are skipped with a small per-query hash set.  The
    ``k`` nearest (or, with ``radius2 > 0``, every candidate within
    ``max(radius2, k-th distance)``) go to ``nb_t``/``weight``; ``reach`` is the
    squared distance covered and ``bound = rk2[q] + rk2[q - start]`` a lower
    bound of the squared distance of every point outside both lists, so
    ``reach <= bound`` certifies the exact k-NN.
    """
    n = q_t.size
    kk = lists.shape[1]
    width = nb_t.shape[1]
    cand = np.empty(2 * kk, dtype=np.int64)
    dist = np.empty(2 * kk)
    scratch = np.empty(2 * kk)
    size = 1
    while size < 4 * kk:
        size *= 2
    table = np.empty(size, dtype=np.int64)
    n_max = is_db.size
    for i in range(n):
        q = q_t[i]
        r1 = row_of[q - u_min]
        r2 = row_of[q - start - u_min]
        table[:] = -1
        nc = 0
        for part in range(2):
            row = r1 if part == 0 else r2
            shift = 0 if part == 0 else start
            for c in range(kk):
                j = np.int64(lists[row, c])
                if j < 0:
                    continue
                j += shift
                if j >= n_max or not is_db[j]:
                    continue
                h = (j * 2654435761) & (size - 1)
                while table[h] != -1 and table[h] != j:
                    h = (h + 1) & (size - 1)
                if table[h] == j:
                    continue
                table[h] = j
                acc = np.float64(ldist[row, c])  # the list's window ...
                qa = q - (start if part == 0 else 0)  # ... plus the other one
                ja = j - (start if part == 0 else 0)
                for lag in range(m):
                    d = s[qa - lag] - s[ja - lag]
                    acc += d * d
                cand[nc] = j
                dist[nc] = acc
                nc += 1
        bound[i] = rk2[r1] + rk2[r2]
        if nc == 0:
            reach[i] = np.inf
            for c in range(width):
                nb_t[i, c] = q
                weight[i, c] = False
            continue
        scratch[:nc] = dist[:nc]
        r = max(_kth_smallest(scratch[:nc], min(k, nc) - 1), radius2)
        reach[i] = r
        used = 0
        for c in range(nc):
            if dist[c] <= r and used < width:
                nb_t[i, used] = cand[c]
                weight[i, used] = True
                used += 1
        for c in range(used, width):
            nb_t[i, c] = q
            weight[i, c] = False


def _gather(s, t, cols):
    return s[t[..., None] - cols]


def _fit_errors(s, q_t, nb_t, weight, cols, order, ridge, fallback):
    """Squared one-step errors of the local fits for queries q_t with neighbours nb_t."""
    pred = fit_from_series(s, q_t, nb_t, weight, cols, float(ridge), int(order), fallback)
    return (pred - s[q_t + 1]) ** 2


_chunks = chunk_slices


def _errors_exact(s, m, taus, db_t, q_t, *, k, order, ridge, radius, theiler, workers):
    sq = np.zeros(len(taus))
    exact = np.ones(len(taus))
    fallback = float(s[db_t + 1].mean())
    for i, tau in enumerate(taus):
        cols = two_window_columns(m, tau)
        tree = cKDTree(_gather(s, db_t, cols))
        Vq = _gather(s, q_t, cols)
        kk = k * (RADIUS_CAP if radius else 1)
        for sl in _chunks(q_t.size, kk * 2 * m):
            pos, weight = tree_neighbours(
                tree, Vq[sl], k, radius=radius,
                query_ids=None if theiler is None else q_t[sl], fit_ids=db_t,
                theiler_window=0 if theiler is None else theiler, workers=workers)
            sq[i] += _fit_errors(s, q_t[sl], db_t[pos], weight, cols, order, ridge,
                                 fallback).sum()
    return np.sqrt(sq / q_t.size), exact


def _candidate_lists(s, m, members, needed, n_list, theiler, workers):
    """``n_list`` nearest first-window neighbours (times, -1 = none) of every needed time.

    Neighbours come from ``members`` (times); with ``theiler``, members within
    ``theiler`` samples of the needed time are dropped (from ``n_list`` plus a
    margin of nearest, so fewer may remain).  ``ldist`` holds their
    squared first-window distances (float32) and ``rk2`` the squared distance
    of the last neighbour queried: every member outside a list is at least that
    far away.
    """
    first = np.arange(m)
    tree = cKDTree(_gather(s, members, first))
    # query a margin for the Theiler-excluded times; on long records the temporal
    # neighbours are rarely among the nearest, so the margin is capped (a list may then
    # hold fewer than n_list valid entries, and the bound stays valid)
    excl = 0 if theiler is None else min(2 * theiler + 1, max(n_list // 2, 1))
    kq = min(members.size, n_list + excl)
    lists = np.full((needed.size, n_list), -1, dtype=np.int32)
    ldist = np.full((needed.size, n_list), np.inf, dtype=np.float32)
    rk2 = np.empty(needed.size)
    for sl in _chunks(needed.size, 3 * kq):
        d, pos = tree.query(_gather(s, needed[sl], first), k=kq, workers=workers)
        d, pos = d.reshape(-1, kq), pos.reshape(-1, kq)
        rk2[sl] = d[:, -1] ** 2 if kq < members.size else np.inf
        times = members[pos]
        keep = np.ones(times.shape, dtype=bool)
        if theiler is not None:
            keep = np.abs(times - needed[sl, None]) > theiler
        order = np.argsort(~keep, axis=1, kind="stable")[:, :n_list]
        kept = np.take_along_axis(keep, order, 1)
        width = order.shape[1]
        lists[sl, :width] = np.where(kept, np.take_along_axis(times, order, 1), -1)
        ldist[sl, :width] = np.where(kept, np.take_along_axis(d, order, 1) ** 2, np.inf)
    return lists, ldist, rk2


def _errors_candidates(s, m, taus, db_t, q_t, *, k, order, ridge, radius, theiler, workers,
                       n_candidates, max_start=None):
    k = min(k, db_t.size)
    starts = np.array([_second_window_start(m, int(tau)) for tau in taus])
    reach_back = int(starts.max()) if max_start is None else int(max_start)
    members = np.arange(max(m - 1, int(db_t.min()) - reach_back), int(db_t.max()) + 1)
    needed = np.unique(np.concatenate([q_t, (q_t[:, None] - np.unique(starts)[None, :]).ravel()]))
    u_min = int(needed[0])
    row_of = np.full(int(needed[-1]) - u_min + 1, -1, dtype=np.int64)
    row_of[needed - u_min] = np.arange(needed.size)
    lists, ldist, rk2 = _candidate_lists(s, m, members, needed, n_candidates, theiler, workers)
    is_db = np.zeros(s.size, dtype=np.bool_)
    is_db[db_t] = True
    fallback = float(s[db_t + 1].mean())
    width = k if radius is None else 2 * n_candidates
    nb_t = np.empty((q_t.size, width), dtype=np.int64)
    weight = np.empty((q_t.size, width), dtype=np.bool_)
    reach = np.empty(q_t.size)
    bound = np.empty(q_t.size)
    radius2 = 0.0 if radius is None else float(radius) ** 2
    sq = np.zeros(len(taus))
    exact = np.zeros(len(taus))
    for i, tau in enumerate(taus):
        cols = two_window_columns(m, tau)
        _union_rerank(s, q_t, lists, ldist, rk2, row_of, u_min, int(starts[i]), m, k, radius2,
                      is_db, nb_t, weight, reach, bound)
        exact[i] = np.mean(reach <= bound)
        for sl in _chunks(q_t.size, width * 2 * m):
            sq[i] += _fit_errors(s, q_t[sl], nb_t[sl], weight[sl], cols, order, ridge,
                                 fallback).sum()
    return np.sqrt(sq / q_t.size), exact


def _errors_job(s, m, taus, db_t, q_t, opts):
    if opts["search"] == "exact":
        return _errors_exact(s, m, taus, db_t, q_t, k=opts["k"], order=opts["order"],
                             ridge=opts["ridge"], radius=opts["radius"],
                             theiler=opts["theiler"], workers=1)
    return _errors_candidates(s, m, taus, db_t, q_t, k=opts["k"], order=opts["order"],
                              ridge=opts["ridge"], radius=opts["radius"],
                              theiler=opts["theiler"], workers=1,
                              n_candidates=opts["n_candidates"],
                              max_start=_second_window_start(m, int(opts["max_tau"])))


# ----------------------------------------------------------------------------- equal neighbourhoods
def _mean_kth_distance(s, m, tau, db_t, k, theiler, rng, n_probe=1000):
    cols = two_window_columns(m, tau)
    V = _gather(s, db_t, cols)
    probes = rng.choice(db_t.size, size=min(n_probe, db_t.size), replace=False)
    pos, weight = tree_neighbours(cKDTree(V), V[probes], k, query_ids=db_t[probes],
                                  fit_ids=db_t, theiler_window=theiler)
    dist = np.linalg.norm(V[pos] - V[probes][:, None, :], axis=2)
    return float(np.where(weight, dist, 0.0).max(axis=1).mean())


def _segment_length(s, m, tau, db_t, k, theiler, d_ref, rng, n_min):
    """Length of the (last) database segment whose mean k-th distance is d_ref."""
    n_hi, d_hi = db_t.size, _mean_kth_distance(s, m, tau, db_t, k, theiler, rng)
    if d_hi >= d_ref:
        return n_hi
    while True:
        n_lo = max(n_min, n_hi // 2)
        d_lo = _mean_kth_distance(s, m, tau, db_t[-n_lo:], k, theiler, rng)
        if d_lo >= d_ref or n_lo == n_min:
            break
        n_hi, d_hi = n_lo, d_lo
    if d_lo < d_ref or d_lo == d_hi:
        return n_lo
    frac = (np.log(d_ref) - np.log(d_hi)) / (np.log(d_lo) - np.log(d_hi))
    return round(float(np.exp(np.log(n_hi) + frac * (np.log(n_lo) - np.log(n_hi)))))


# ----------------------------------------------------------------------------- driver
def scan_series(s, ms, taus, splits, *, k, order, ridge, radius, theiler, n_queries,
                equal_neighbourhood, search, n_candidates, random_state, n_jobs, verbose):
    """Forecast errors (n_splits, n_m, n_tau) (not normalised) plus metadata.

    ``splits`` is a list of ``(db_t, test_t)``; ``test_t=None`` means the
    in-sample, Theiler-excluded error over the database itself.
    """
    if search not in ("candidates", "exact"):
        raise ValueError(f"search must be 'candidates' or 'exact', got {search!r}.")
    if equal_neighbourhood not in (False, True, "segment", "radius"):
        raise ValueError(
            "equal_neighbourhood must be False, True/'segment' (shorter series for smaller m) "
            f"or 'radius' (one neighbourhood radius for every m), got {equal_neighbourhood!r}."
        )
    rng = check_random_state(random_state)
    k = check_positive_int(k, name="n_neighbors")
    n_candidates = (max(2 * k, 32) if n_candidates is None
                    else check_positive_int(n_candidates, name="n_candidates"))
    # one job per (split, m): the candidate lists of an m are built once per job, so
    # blocks of tau are only split off when there are fewer (split, m) pairs than workers
    n_workers = max(1, effective_n_jobs(n_jobs))
    n_chunks = max(1, min(len(taus), -(-n_workers // (len(splits) * len(ms)))))
    tau_chunks = [c for c in np.array_split(np.asarray(taus), n_chunks) if c.size]
    jobs, meta = [], {"segment_length": {}, "n_queries": {}, "radius": radius}
    for split, (db_t, test_t) in enumerate(splits):
        w = theiler if test_t is None else None
        seg = {int(m): db_t.size for m in ms}
        rad = radius
        if equal_neighbourhood and len(ms) > 1:
            tau_ref = int(np.median(taus))
            n_min = min(db_t.size, max(4 * k + 2 * (w or 0) + 2, 50))
            d_ref = _mean_kth_distance(s, int(ms[-1]), tau_ref, db_t, k, w or 0, rng)
            if equal_neighbourhood == "radius":
                rad = d_ref
                meta["radius"] = d_ref
            else:
                for m in ms[:-1]:
                    seg[int(m)] = _segment_length(s, int(m), tau_ref, db_t, k, w or 0, d_ref,
                                                  rng, n_min)
        shared = None  # one query set for every m unless the database differs per m
        for m in ms[::-1]:  # costliest (largest m) first: better load balance
            db_m = db_t[-seg[int(m)]:]
            pool = db_m if test_t is None else test_t
            if n_queries is None or n_queries >= pool.size:
                q_t = pool
            elif shared is not None and db_m.size == db_t.size:
                q_t = shared
            else:
                q_t = np.sort(rng.choice(pool, size=n_queries, replace=False))
                if db_m.size == db_t.size:
                    shared = q_t
            meta["segment_length"][int(m)] = int(db_m.size)
            meta["n_queries"][int(m)] = int(q_t.size)
            opts = {"k": k, "order": order, "ridge": ridge, "radius": rad, "theiler": w,
                    "search": search, "n_candidates": n_candidates, "max_tau": int(taus[-1])}
            for chunk in tau_chunks:
                jobs.append(((split, int(m), chunk), delayed(_errors_job)(s, int(m), chunk,
                                                                          db_m, q_t, opts)))
    results = Parallel(n_jobs=n_jobs, verbose=verbose)(job for _, job in jobs)
    m_pos = {int(m): j for j, m in enumerate(ms)}
    tau_pos = {int(t): j for j, t in enumerate(taus)}
    err = np.empty((len(splits), len(ms), len(taus)))
    exact = np.empty_like(err)
    for ((split, m, chunk), _), (e, x) in zip(jobs, results):
        cols = [tau_pos[int(t)] for t in chunk]
        err[split, m_pos[m], cols] = e
        exact[split, m_pos[m], cols] = x
    meta["exact_fraction"] = exact
    return err, meta


def forecast_error_curve(series, m=(2, 3, 4, 5), tau=range(1, 101), *, n_neighbors=30, order=1,
                         ridge=1e-3, radius=None, n_queries=None, equal_neighbourhood=False,
                         theiler_window="auto", search="candidates", n_candidates=None,
                         random_state=None, n_jobs=None, verbose=0):
    """Normalised one-step forecast error sigma_m(tau) of local linear two-window models.

    For every ``(m, tau)`` and every query time ``t`` the local linear map is
    fitted on the ``n_neighbors`` nearest two-window vectors ``v_j(m, tau)``
    of the same series, excluding ``|j - t| <= theiler_window``, and predicts
    ``s[t+1]``; sigma is the rms error divided by the series' standard
    deviation (Buenner et al., Sec. III).  Its dip locates the delay
    (:func:`locate_dips`).

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Scalar series sampled at step 1.
    m : int or sequence of int, default=(2, 3, 4, 5)
        Window lengths (an int ``v`` means ``1..v``).
    tau : int or sequence of int, default=range(1, 101)
        Delays in samples (an int ``v`` means ``1..v``).
    n_neighbors : int, default=30
        Neighbourhood size ``k``.
    order : {1, 0}, default=1
        Local linear or local constant fits.
    ridge : float, default=1e-3
        Relative ridge of the local fits (see :class:`LocalLinearDelayMap`).
    radius : float, default=None
        Radius neighbourhoods with k-NN fallback instead of k-NN.
    n_queries : int, default=None
        Forecast only this many random times (the database stays complete);
        None uses every time.
    equal_neighbourhood : {False, True, "segment", "radius"}, default=False
        The paper's equal neighbourhood size for every ``m``: ``True`` /
        ``"segment"`` uses for each smaller ``m`` the most recent segment of
        the series whose mean ``k``-th neighbour distance (at the median
        ``tau``) matches that of the largest ``m`` on the whole series;
        ``"radius"`` uses that distance as a common neighbourhood radius.
    theiler_window : int or "auto", default="auto"
        Temporal exclusion of neighbours; "auto" is the 1/e decorrelation time.
    search : {"candidates", "exact"}, default="candidates"
        Neighbour search (see module docs); "exact" rebuilds a k-d tree per
        ``(m, tau)``.
    n_candidates : int, default=None
        Candidates per query for ``search="candidates"`` (default ``max(8k, 64)``).
    random_state : int, RandomState or Generator, default=None
        Seeds the query subset and the neighbourhood-size probes.
    n_jobs : int, default=None
        joblib workers (one job per ``m`` and block of ``tau``).
    verbose : int, default=0
        joblib verbosity.

    Returns
    -------
    pandas.DataFrame
        Index ``tau``, one column per ``m``.  ``attrs`` holds
        ``segment_length`` and ``n_queries`` (per ``m``), ``theiler_window``,
        ``radius`` and ``exact_fraction`` (fraction of queries whose
        neighbours are provably the exact k-NN, per ``m``, mean over ``tau``).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import forecast_error_curve
    >>> rng = np.random.default_rng(0)
    >>> s = np.zeros(3000)
    >>> s[:9] = rng.uniform(size=9)
    >>> for t in range(8, 2999):   # delay 7: s[t+1] depends on s[t+1-7] and s[t-7]
    ...     d = np.sin(3 * s[t - 6]) + np.sin(3 * s[t - 7])
    ...     s[t + 1] = 0.5 * s[t] + 0.5 * d + 0.01 * rng.normal()
    >>> sigma = forecast_error_curve(s, m=(2,), tau=range(1, 15), random_state=0)
    >>> int(sigma[2].idxmin())
    7
    """
    s = check_series(series, name="series")
    ms, taus = as_grid(m, "m"), as_grid(tau, "tau")
    n_lags = required_lags(int(ms[-1]), int(taus[-1]))
    k = check_positive_int(n_neighbors, name="n_neighbors")
    if s.size < n_lags + k + 2:
        raise ValueError(
            f"series has {s.size} samples but m={int(ms[-1])}, tau={int(taus[-1])} needs "
            f"{n_lags} lags plus at least n_neighbors + 2 = {k + 2} rows; use a longer "
            "series or a smaller tau/m range."
        )
    if n_queries is not None:
        n_queries = check_positive_int(n_queries, name="n_queries")
    w = theiler_from(s, theiler_window)
    db_t = np.arange(n_lags - 1, s.size - 1)
    err, meta = scan_series(s, ms, taus, [(db_t, None)], k=k, order=order, ridge=ridge,
                            radius=radius, theiler=w, n_queries=n_queries,
                            equal_neighbourhood=equal_neighbourhood, search=search,
                            n_candidates=n_candidates, random_state=random_state,
                            n_jobs=n_jobs, verbose=verbose)
    out = pd.DataFrame(err[0].T / s.std(), index=pd.Index(taus, name="tau"),
                       columns=pd.Index(ms, name="m"))
    out.attrs.update(
        segment_length=meta["segment_length"], n_queries=meta["n_queries"], theiler_window=w,
        radius=meta["radius"],
        exact_fraction={int(mm): float(meta["exact_fraction"][0, j].mean())
                        for j, mm in enumerate(ms)},
    )
    return out


# ----------------------------------------------------------------------------- DelaySelectorCV
def _columns_job(Xc, y, train, queries, estimator, theiler):
    """Fallback for X that is not a lag matrix: one candidate's (n, 2m) columns."""
    model = clone(estimator)
    if theiler is not None:  # in-sample, Theiler-excluded
        model.set_params(theiler_window=theiler).fit(Xc, y)
        pred = model.predict(Xc[queries], query_index=queries)
    else:
        model.fit(Xc[train], y[train])
        pred = model.predict(Xc[queries])
    return float(np.sqrt(np.mean((pred - y[queries]) ** 2)))


class DelaySelectorCV(RegressorMixin, BaseEstimator):
    """Find the feedback delay and window length by scanning sigma_m(tau).

    ``fit(X, y)`` takes the lag matrix and next values from
    :func:`~skdelay.lagged_windows` (``n_lags >= required_lags(max m, max
    tau)``), computes the normalised one-step forecast error of
    ``Pipeline(TwoWindowEmbedding(m, tau), estimator)`` for every ``(m, tau)``
    of the grid, and locates the dip of each ``sigma_m(tau)``
    (:func:`locate_dips`).  The scan never materialises ``X[train]``: the
    1-D series is recovered from ``X`` (first row + first column, checked
    against all of ``X``) and workers receive the series and row indices; if
    ``X`` is not a consistent lag matrix, each candidate gets only its
    ``(n, 2m)`` columns.

    With ``cv=None`` the error is the paper's: in-sample, each forecast made
    without the neighbours within ``theiler_window`` of the query.  With a
    splitter (an int means ``TimeSeriesSplit(n_splits=cv)``) it is the
    out-of-sample error on the test folds.

    Parameters
    ----------
    estimator : LocalLinearDelayMap or regressor, default=None
        Model fitted on the two-window vectors (default
        ``LocalLinearDelayMap()``).  Other regressors need a ``cv`` splitter.
    m : int or sequence of int, default=(2, 3, 4, 5)
        Window lengths (an int ``v`` means ``1..v``).
    tau : int or sequence of int, default=100
        Delays in samples (an int ``v`` means ``1..v``).
    cv : None, int, or CV splitter, default=None
        None: in-sample Theiler-excluded error; otherwise the test error.
    n_queries : int, default=None
        Forecast only this many random rows per fold (the neighbour database
        stays complete); None uses all.
    theiler_window : int or "auto", default="auto"
        Temporal exclusion for ``cv=None`` ("auto": the 1/e decorrelation time).
    equal_neighbourhood : {False, True, "segment", "radius"}, default=False
        Equal neighbourhood size for every ``m`` (see
        :func:`forecast_error_curve`); needs ``X`` from ``lagged_windows``.
    search : {"candidates", "exact"}, default="candidates"
        Neighbour search of the scan (see :func:`forecast_error_curve`).
    n_candidates : int, default=None
        Candidates per query for ``search="candidates"``.
    dip_level : float, default=1/3
        Fraction of the dip depth delimiting the dip (:func:`locate_dips`).
    random_state : int, RandomState or Generator, default=None
        Seeds the query subsets.
    n_jobs : int, default=None
        joblib workers (works under ``joblib.parallel_config(backend="dask")``).
    verbose : int, default=0
        joblib verbosity.

    Attributes
    ----------
    forecast_error_ : pandas.DataFrame
        sigma_m(tau) normalised by the series' standard deviation (mean over
        folds); index ``tau``, one column per ``m``.
    delay_by_m_ : pandas.DataFrame
        Dip of every ``m`` (:func:`locate_dips`): ``delay``, ``half_width``,
        ``tau_min``, ``min_error``.
    delay_ : float
        Dip centre (samples) of the best ``m`` (lowest minimum error).
    delay_error_ : float
        Half-width of that dip.
    best_params_ : dict
        ``{"m": best m, "tau": grid delay nearest to delay_}``.
    best_index_ : int
        Index of ``best_params_`` in ``cv_results_["params"]``.
    best_score_ : float
        Its ``mean_test_score``.
    best_estimator_ : Pipeline
        ``Pipeline([("embedding", TwoWindowEmbedding(**best_params_)),
        ("model", estimator)])`` refitted on all rows.
    cv_results_ : dict of ndarray
        As ``GridSearchCV``: ``params``, ``param_m``, ``param_tau``,
        ``split<i>_test_score``, ``mean_test_score``, ``std_test_score``,
        ``rank_test_score``; scores are minus the normalised error.
    n_splits_ : int
        Number of folds (1 for ``cv=None``).
    n_features_in_ : int
        Number of lag columns.

    See Also
    --------
    forecast_error_curve : the same scan straight from a series.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import DelaySelectorCV, lagged_windows
    >>> rng = np.random.default_rng(0)
    >>> s = np.zeros(3000)
    >>> s[:9] = rng.uniform(size=9)
    >>> for t in range(8, 2999):   # delay 7: s[t+1] depends on s[t+1-7] and s[t-7]
    ...     d = np.sin(3 * s[t - 6]) + np.sin(3 * s[t - 7])
    ...     s[t + 1] = 0.5 * s[t] + 0.5 * d + 0.01 * rng.normal()
    >>> X, y = lagged_windows(s, n_lags=16)
    >>> sel = DelaySelectorCV(m=(2, 3), tau=14, random_state=0).fit(X, y)
    >>> sel.best_params_
    {'m': 2, 'tau': 7}
    >>> bool(abs(sel.delay_ - 7) <= 1)
    True
    """

    def __init__(self, estimator=None, *, m=(2, 3, 4, 5), tau=100, cv=None, n_queries=None,
                 theiler_window="auto", equal_neighbourhood=False, search="candidates",
                 n_candidates=None, dip_level=1 / 3, random_state=None, n_jobs=None, verbose=0):
        self.estimator = estimator
        self.m = m
        self.tau = tau
        self.cv = cv
        self.n_queries = n_queries
        self.theiler_window = theiler_window
        self.equal_neighbourhood = equal_neighbourhood
        self.search = search
        self.n_candidates = n_candidates
        self.dip_level = dip_level
        self.random_state = random_state
        self.n_jobs = n_jobs
        self.verbose = verbose

    def _splits(self, X, y):
        if self.cv is None:
            return [(np.arange(X.shape[0]), None)]
        cv = self.cv
        if isinstance(cv, numbers.Integral) and not isinstance(cv, (bool, np.bool_)):
            cv = TimeSeriesSplit(n_splits=int(cv))
        else:
            cv = check_cv(cv, y)
        return [(np.asarray(tr), np.asarray(te)) for tr, te in cv.split(X, y)]

    def fit(self, X, y):
        """Scan the ``(m, tau)`` grid and refit the best pipeline.

        Parameters
        ----------
        X : array-like of shape (n_rows, n_lags)
            Lag matrix (``lagged_windows``).
        y : array-like of shape (n_rows,)
            Next values.

        Returns
        -------
        self : DelaySelectorCV
        """
        X, y = validate_data(self, X, y, y_numeric=True, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        est = LocalLinearDelayMap() if self.estimator is None else self.estimator
        ms, taus = as_grid(self.m, "m"), as_grid(self.tau, "tau")
        n, n_lags = X.shape
        need = required_lags(int(ms[-1]), int(taus[-1]))
        if n_lags < need:
            raise ValueError(
                f"X has {n_lags} feature(s) (lag columns) but m={int(ms[-1])}, "
                f"tau={int(taus[-1])} needs {need}; build X with lagged_windows(series, "
                f"n_lags={need}) or scan smaller m/tau."
            )
        if n < 3:
            raise ValueError(f"X has {n} sample(s) but DelaySelectorCV needs at least 3 rows.")
        if self.n_queries is not None:
            check_positive_int(self.n_queries, name="n_queries")
        local = isinstance(est, LocalLinearDelayMap)
        if self.cv is None and not local:
            raise ValueError(
                "cv=None (in-sample, Theiler-excluded error) needs a LocalLinearDelayMap "
                f"estimator, got {type(est).__name__}; pass cv=5 (TimeSeriesSplit) or a splitter."
            )
        splits = self._splits(X, y)
        s = series_from_lagged(X, y) if local else None
        if s is not None and np.ptp(s) > 0:
            w = theiler_from(s, self.theiler_window)
            err, meta = scan_series(
                s, ms, taus, [(tr + n_lags - 1, None if te is None else te + n_lags - 1)
                              for tr, te in splits],
                k=est.n_neighbors, order=est.order, ridge=est.ridge, radius=est.radius,
                theiler=w, n_queries=self.n_queries,
                equal_neighbourhood=self.equal_neighbourhood, search=self.search,
                n_candidates=self.n_candidates, random_state=self.random_state,
                n_jobs=self.n_jobs, verbose=self.verbose)
            scale = s.std()
            attrs = {"segment_length": meta["segment_length"], "n_queries": meta["n_queries"],
                     "theiler_window": w}
        else:
            if self.equal_neighbourhood:
                raise ValueError(
                    "equal_neighbourhood needs X and y from lagged_windows (consecutive rows of "
                    "one series); set equal_neighbourhood=False for other inputs."
                )
            w = (0 if np.ptp(y) == 0 else theiler_from(y, self.theiler_window)) \
                if self.cv is None else None
            err = self._scan_columns(X, y, ms, taus, splits, est, w)
            scale = y.std()
            attrs = {"theiler_window": w}
        err = err / (scale if scale > 0 else 1.0)
        self._store(err, ms, taus, attrs)
        best = self.best_params_
        self.best_estimator_ = Pipeline([
            ("embedding", TwoWindowEmbedding(m=best["m"], tau=best["tau"])),
            ("model", clone(est)),
        ]).fit(X, y)
        return self

    def _scan_columns(self, X, y, ms, taus, splits, est, w):
        rng = check_random_state(self.random_state)
        plans = []
        for tr, te in splits:
            pool = tr if te is None else te
            if self.n_queries is not None and self.n_queries < pool.size:
                pool = np.sort(rng.choice(pool, size=self.n_queries, replace=False))
            plans.append((tr, pool))
        jobs = (delayed(_columns_job)(X[:, two_window_columns(int(m), int(t))], y, tr, q, est, w)
                for tr, q in plans for m in ms for t in taus)
        res = Parallel(n_jobs=self.n_jobs, verbose=self.verbose)(jobs)
        return np.asarray(res).reshape(len(splits), len(ms), len(taus))

    def _store(self, err, ms, taus, attrs):
        n_splits = err.shape[0]
        self.n_splits_ = n_splits
        fe = pd.DataFrame(err.mean(axis=0).T, index=pd.Index(taus, name="tau"),
                          columns=pd.Index(ms, name="m"))
        fe.attrs.update(attrs)
        self.forecast_error_ = fe
        self.delay_by_m_ = locate_dips(fe, level=self.dip_level)
        scores = -err.reshape(n_splits, -1)  # candidate order: m outer, tau inner
        params = [{"m": int(mm), "tau": int(tt)} for mm in ms for tt in taus]
        results = {
            "params": params,
            "param_m": np.array([p["m"] for p in params]),
            "param_tau": np.array([p["tau"] for p in params]),
        }
        for i in range(n_splits):
            results[f"split{i}_test_score"] = scores[i]
        results["mean_test_score"] = scores.mean(axis=0)
        results["std_test_score"] = scores.std(axis=0)
        results["rank_test_score"] = rankdata(-results["mean_test_score"],
                                              method="min").astype(np.int32)
        self.cv_results_ = results
        best_m = int(fe.min(axis=0).idxmin())
        self.delay_ = float(self.delay_by_m_.loc[best_m, "delay"])
        self.delay_error_ = float(self.delay_by_m_.loc[best_m, "half_width"])
        best_tau = int(taus[np.argmin(np.abs(taus - self.delay_))])
        self.best_params_ = {"m": best_m, "tau": best_tau}
        self.best_index_ = params.index(self.best_params_)
        self.best_score_ = float(results["mean_test_score"][self.best_index_])

    def predict(self, X):
        """Forecasts of ``best_estimator_``.

        Parameters
        ----------
        X : array-like of shape (n_rows, n_lags)
            Lag matrix with the columns seen in ``fit``.

        Returns
        -------
        y_pred : ndarray of shape (n_rows,)
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, reset=False)
        return self.best_estimator_.predict(X)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        # the refitted model only sees the 2m selected lag columns, so on generic
        # regression data (one informative feature among many) its R^2 may be low
        tags.regressor_tags.poor_score = True
        return tags
