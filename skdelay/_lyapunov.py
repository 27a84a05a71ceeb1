"""Lyapunov spectrum of a fitted two-window model (data-driven tangent dynamics).

The tangent map of the delay map is the shift plus one new row holding the
gradient ``a_n`` of the local linear map at ``v_n``; the Jacobians come from
:meth:`LocalLinearDelayMap.local_maps` (batched, leave-one-out along the
data) and the QR iteration from :mod:`skdelay._tangent`.
"""

from __future__ import annotations

import os
import time
import warnings
import weakref
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from ._checks import check_params, check_positive_int, check_series
from ._iterate import (
    OffSupportWarning,
    check_finite,
    check_tau,
    off_support_fraction,
    progress_bar,
    stage_timer,
    support_guard,
)
from ._model import resolve_model, self_query_index
from ._neighbours import fit_neighbourhood, fit_scratch
from ._spectrum import LyapunovSpectrum
from ._tangent import exponents_from_logs, tangent_qr
from ._windows import lagged_windows

__all__ = ["covering_spectrum", "lyapunov_spectrum"]

#: Rows of Jacobians computed per batch on the fallback path (radius neighbourhoods or a
#: duck-typed map: ``local_maps``; bounds its (rows, k, 2m) neighbour gather).
CHUNK_ROWS = 1 << 16
#: Rows per task of the k-NN + compiled local fit: 0.3-0.8 s of work each at k = 100 in
#: 10 dimensions (laser, tau = 400: 70-200 us per row on one loaded core, 2026-11-23),
#: small enough for an even split over threads and a progress bar that moves.
TASK_ROWS = 4096
#: Leaf size of the rotated k-d tree (see :class:`RotatedIndex`: 48 and unbalanced was the
#: fastest of 16/48 x balanced/not for k = 105 in 10 dimensions).
INDEX_LEAF_SIZE = 48
#: Cached rotated indexes of fitted maps (building one costs a covariance and a tree).
_INDEXES = weakref.WeakKeyDictionary()
#: Largest fraction of a foreign series' vectors allowed off the model's support before a
#: warning: a model run stays within it by construction (escapes are cut), so anything
#: beyond a few per cent is a different signal (shifted, rescaled, another system).
OFF_SUPPORT_LIMIT = 0.05


def lyapunov_spectrum(model, series, *, n_exponents=None, n_steps=None, sample_dt=1.0,
                      tau=None, n_transient=None, qr_interval=None, n_blocks=10,
                      exclude_self="auto", flow=False, random_state=0, n_jobs=None,
                      progress=None):
    """Lyapunov spectrum of a fitted two-window model along a trajectory.

    The tangent map of the delay map is the shift plus one new row,
    ``delta s_{n+1} = a_n . delta v_n``, with ``a_n`` the gradient of the
    local linear map at ``v_n`` (from :meth:`LocalLinearDelayMap.local_maps`,
    batched).  ``n_exponents`` tangent vectors are propagated at O(m) cost
    per vector and step and re-orthonormalised (Householder QR) every
    ``qr_interval`` steps; the exponents are the time-averaged
    ``log |R_jj|`` (Benettin / Eckmann-Ruelle).

    Parameters
    ----------
    model : Pipeline or (TwoWindowEmbedding, LocalLinearDelayMap) or DelaySelectorCV
        A fitted local *linear* two-window model (``order=1``).
    series : array-like of shape (n_samples,)
        The trajectory along which the Jacobians are taken: the data (then
        each point's own row is left out of its neighbourhood, see
        ``exclude_self``) or a model run from :func:`iterate`.
    n_exponents : int, default=None
        How many of the largest exponents; at most (and by default) the state
        dimension ``D = required_lags(m, tau)``.  For long delays ask for
        fewer: the cost grows as ``n_exponents**2`` per step.
    n_steps : int, default=None
        Use only the first ``n_steps`` steps of ``series`` (default: all).
    sample_dt : float, default=1.0
        Time between samples; exponents are returned per time unit
        (``per step / sample_dt``), as the exact spectra of the simulators.
    tau : int, default=None
        Delay of the second window along ``series``; default the fitted one
        (set it to analyse a model transplanted to another delay).
    n_transient : int, default=None
        Steps discarded while the tangent vectors align
        (default ``min(max(2 D, 1000), n // 5)``).
    qr_interval : int, default=None
        Steps between QRs (default ``max(1, min(D // 2, 200))``); a QR is
        also taken early if a tangent vector grows by 10^6.
    n_blocks : int, default=10
        Blocks for the standard error (``spread``) of each exponent.
    exclude_self : {"auto", True, False}, default="auto"
        Leave each data point (and the model's ``theiler_window`` around it)
        out of its own neighbourhood.  "auto": when ``series`` is the data
        the model was fitted on (detected by matching its vectors).
    flow : bool, default=False
        ``series`` samples a continuous-time flow (a delay *differential*
        equation), whose spectrum holds an exact zero (the direction along
        the flow).  Its data-driven estimate is only noise, yet it decides
        whether it enters the Kaplan-Yorke sum and the count of positive
        exponents; with ``flow=True`` the exponent closest to zero is set to
        exactly 0 (its estimate is kept in ``extra["zero_exponent"]``) --
        unless all computed exponents are positive (the zero is then beyond
        ``n_exponents``; ``extra["zero_exponent"]`` is None).
    random_state : int, Generator or None, default=0
        Initial tangent vectors.
    n_jobs : int, default=None
        Threads of the neighbour queries and local fits behind the Jacobians
        (-1: all cores; None: the model's own ``n_jobs``).
    progress : bool, default=None
        Show a tqdm progress bar (with ETA) over the Jacobians; None: only
        inside :func:`~skdelay._iterate.progress_bars` (``skdelay analyze``).

    Returns
    -------
    LyapunovSpectrum
        ``exponents`` (per time unit, descending), ``spread`` (standard
        error over blocks), ``sample_dt``, ``n_steps``; per-step values are
        ``.per_step``; ``.extra`` holds ``m``, ``tau``, ``state_dim``,
        ``exclude_self``, ``n_transient``, ``qr_interval`` and ``seconds`` (wall
        time of the two parts: ``jacobians``, ``tangent_qr``).

    Raises
    ------
    ValueError
        If ``n_exponents`` exceeds the state dimension, the series is too
        short for ``m`` and ``tau``, or the model is local constant.

    Notes
    -----
    *Sampling.*  The delay must be a whole number of samples and the map
    ``s_n -> s_{n+1}`` smooth: about 10 or more samples per characteristic
    period (Mackey-Glass at ``sample_dt = 1``, the CO2 laser at 1 us).  The
    exponents are those of the sampled map divided by ``sample_dt``.

    *Settings.*  Measured against exact spectra (``benchmarks/lyapunov.py``,
    ``benchmarks/paper_table.py``): ``m = 3..5``, ``n_neighbors`` about 3-4
    times the ``2 m + 1`` parameters.  Noise in the local Jacobians inflates
    the leading exponents (a product of noisy matrices grows faster), the
    ridge shrinks them: ``ridge = 1e-3`` is right for low-dimensional
    attractors (Mackey-Glass ``tau <= 100``, 1e5 samples, 0.5 % noise:
    ``lambda_1`` within 10 %, ``D_KY`` within 5 %), high-dimensional noisy
    data (the laser, ``D_KY`` 10-70 from 1e5 samples) needs ``k ~ 100`` and
    ``ridge ~ 3e-2``.  For flows use ``flow=True``.  ``D_KY`` needs enough
    exponents for the Kaplan-Yorke sum to turn negative (otherwise it is
    returned as ``n_exponents``, a lower bound).

    Examples
    --------
    >>> from sklearn.pipeline import make_pipeline
    >>> from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows
    >>> from skdelay.dynamics import lyapunov_spectrum
    >>> from skdelay.systems import MackeyGlass
    >>> x = MackeyGlass(tau=17.0).simulate(20000, random_state=0)
    >>> X, y = lagged_windows(x, n_lags=18)
    >>> model = make_pipeline(TwoWindowEmbedding(m=2, tau=17),
    ...                       LocalLinearDelayMap(n_neighbors=20)).fit(X, y)
    >>> spec = lyapunov_spectrum(model, x, n_exponents=4)
    >>> spec.exponents.shape, bool(0.002 < spec.exponents[0] < 0.009)
    ((4,), True)
    """
    return _spectrum(model, series, n_exponents=n_exponents, n_steps=n_steps,
                     sample_dt=sample_dt, tau=tau, n_transient=n_transient,
                     qr_interval=qr_interval, n_blocks=n_blocks, exclude_self=exclude_self,
                     flow=flow, random_state=random_state, n_jobs=n_jobs, progress=progress)


def _spectrum(model, series, *, n_exponents, n_steps, sample_dt, tau, n_transient,
              qr_interval, n_blocks, exclude_self, flow, random_state, n_jobs, progress,
              cache=None):
    """:func:`lyapunov_spectrum`; a dict ``cache`` keeps the Jacobians for the next call
    with the same model, series and steps (they do not depend on ``n_exponents``)."""
    mdl = resolve_model(model)
    tau = check_tau(tau, mdl)
    dim = mdl.state_dim(tau)
    if n_exponents is None:
        n_exponents = dim
    n_exponents = check_positive_int(n_exponents, name="n_exponents")
    if n_exponents > dim:
        raise ValueError(
            f"n_exponents={n_exponents} exceeds the state dimension {dim} of the model "
            f"(m={mdl.m}, tau={tau}): a delay map with this state has only {dim} exponents; "
            f"ask for at most {dim} or use a larger tau / m."
        )
    if getattr(mdl.regressor, "order", 1) == 0:
        raise ValueError("the Lyapunov spectrum needs a local linear model (order=1); a local "
                         "constant model (order=0) has no Jacobian.")
    sample_dt = check_finite(sample_dt, "sample_dt", minimum=0.0, strict=True)
    n_blocks = check_positive_int(n_blocks, name="n_blocks", minimum=2)
    if n_transient is not None:
        n_transient = check_positive_int(n_transient, name="n_transient", minimum=0)
    if qr_interval is not None:
        qr_interval = check_positive_int(qr_interval, name="qr_interval")
    min_steps = 4 * n_blocks
    s = check_series(series, name="series", min_length=dim + 1 + min_steps)
    n_jobs = check_params(n_jobs=n_jobs)
    X, _ = lagged_windows(s, dim)
    if n_steps is not None:
        n_steps = check_positive_int(n_steps, name="n_steps", minimum=min_steps)
        X = X[:n_steps]
    n = X.shape[0]
    if n < max(min_steps, 2 * dim):
        raise ValueError(
            f"series gives only {n} steps for m={mdl.m}, tau={tau} (state dimension {dim}); "
            f"at least {max(min_steps, 2 * dim)} are needed, better >> 10 * {dim}: pass a "
            "longer series."
        )
    V = np.ascontiguousarray(X[:, mdl.lags(tau)])
    qidx = None
    if exclude_self not in ("auto", True, False):
        raise ValueError(f"exclude_self must be 'auto', True or False, got {exclude_self!r}.")
    if exclude_self is not False:
        qidx = self_query_index(mdl.regressor, V)
        if qidx is None and exclude_self is True:
            raise ValueError("exclude_self=True but series is not the data the model was "
                             "fitted on (its vectors do not match the model's database).")
    if qidx is None and hasattr(mdl.regressor, "database"):
        guard = support_guard(mdl.regressor, distance_factor=5.0, range_margin=0.25)
        off = off_support_fraction(guard, V)
        if off > OFF_SUPPORT_LIMIT:
            warnings.warn(
                f"{100 * off:.0f} % of the series' vectors lie outside the support of the "
                "model's data (farther from every database vector than a free run may go): "
                "the local maps there are extrapolations and the exponents are not the "
                "model's. Pass the data the model was fitted on, or a run of the model.",
                OffSupportWarning, stacklevel=2)
    with stage_timer("spectra"):
        t0 = time.perf_counter()
        if cache is not None and "jac" in cache:
            jac = cache["jac"]
        else:
            jac = local_gradients(mdl.regressor, V, qidx, n_jobs=n_jobs, progress=progress,
                                  desc=f"spectrum m={mdl.m}, tau={tau}: Jacobians")
            if cache is not None:
                cache["jac"] = jac
        if not np.all(np.isfinite(jac)):
            raise ValueError("the local maps contain NaN/inf; the model or series is "
                             "degenerate.")
        if n_transient is None:
            n_transient = min(max(2 * dim, 1000), n // 5)
        if qr_interval is None:
            qr_interval = max(1, min(dim // 2, 200))
        t1 = time.perf_counter()
        logs, ends = tangent_qr(jac, mdl.lags(tau), dim, n_exponents, interval=qr_interval,
                                random_state=random_state)
        t2 = time.perf_counter()
    lam, spread, n_used = exponents_from_logs(logs, ends, n_transient=n_transient,
                                              n_blocks=n_blocks)
    extra = {"m": mdl.m, "tau": tau, "state_dim": dim, "exclude_self": qidx is not None,
                 "n_transient": int(n_transient), "qr_interval": int(qr_interval),
                 "seconds": {"jacobians": t1 - t0, "tangent_qr": t2 - t1}}
    if flow:
        extra["zero_exponent"] = None
        if lam.min() < 0 or n_exponents == dim:  # the zero lies within the computed range
            i0 = int(np.argmin(np.abs(lam)))
            extra["zero_exponent"] = float(lam[i0] / sample_dt)
            lam = lam.copy()
            lam[i0] = 0.0
    return LyapunovSpectrum(lam / sample_dt, spread / sample_dt, sample_dt=sample_dt,
                            n_steps=n_used, extra=extra)


def covering_spectrum(model, series, *, n_exponents, n_steps=None, sample_dt=1.0,
                      max_doublings=1, flow=False, n_jobs=None, progress=None):
    """Lyapunov spectrum with enough exponents to close the Kaplan-Yorke sum (if affordable).

    Starts with ``n_exponents`` and doubles (at most ``max_doublings`` times)
    while every partial sum is still positive; ``extra["ky_closed"]`` says
    whether the Kaplan-Yorke dimension is a value or only a lower bound.  The
    Jacobians are computed once (only the tangent QR is repeated).  Other
    arguments as in :func:`lyapunov_spectrum`.
    """
    dim = resolve_model(model).state_dim()
    n_exp = min(dim, int(n_exponents))
    cache = {}  # the Jacobians, computed once for all attempts
    for attempt in range(max_doublings + 1):
        spec = _spectrum(model, series, n_exponents=n_exp, n_steps=n_steps,
                         sample_dt=sample_dt, tau=None, n_transient=None, qr_interval=None,
                         n_blocks=10, exclude_self="auto", flow=flow, random_state=0,
                         n_jobs=n_jobs, progress=progress, cache=cache)
        closed = spec.kaplan_yorke_dimension < n_exp - 1e-9 or n_exp >= dim
        if closed or attempt == max_doublings:
            spec.extra["ky_closed"] = bool(closed)
            return spec
        n_exp = min(dim, 2 * n_exp)
    return spec  # pragma: no cover - the loop always returns


def thread_count(n_jobs):
    """Threads for ``n_jobs`` (joblib's convention: None 1, -1 all cores, -2 all but one)."""
    cpus = os.cpu_count() or 1
    if n_jobs is None:
        return 1
    n_jobs = int(n_jobs)
    return max(1, cpus + 1 + n_jobs) if n_jobs < 0 else max(1, min(n_jobs, cpus))


class RotatedIndex:
    """k-NN index of a database in its principal axes (exact Euclidean neighbours).

    Delay vectors have strongly correlated coordinates (successive samples);
    in the axes of their covariance the k-d tree's boxes fit the data and
    prune far better.  A rotation keeps distances (up to rounding: only exact
    ties may be broken differently).  Measured on the laser at tau = 400
    (m = 5, 1e5 rows, k = 105, 1e4 queries, 2026-11-23, load ~9 on 2 cores):
    scipy's default tree 1.9 s, rotated 1.2 s, rotated with ``leafsize=48,
    balanced_tree=False`` 1.1 s (:data:`INDEX_LEAF_SIZE`).
    """

    def __init__(self, data):
        data = np.asarray(data, dtype=np.float64)
        self.n = data.shape[0]
        self.mean = data.mean(axis=0)
        cov = (np.atleast_2d(np.cov(data, rowvar=False)) if self.n > 1
               else np.zeros((data.shape[1], data.shape[1])))
        if not np.all(np.isfinite(cov)):  # no usable axes: keep the coordinates
            cov = np.zeros_like(cov)
        _, vecs = np.linalg.eigh(cov)
        self.rotation = np.ascontiguousarray(vecs[:, ::-1])
        self.tree = cKDTree(self.rotate(data), leafsize=INDEX_LEAF_SIZE, balanced_tree=False)

    def rotate(self, X):
        """Rows of ``X`` in the principal axes (centred)."""
        return (np.asarray(X, dtype=np.float64) - self.mean) @ self.rotation

    def query(self, X, k):
        """Positions (n, k) of the ``k`` nearest database rows, nearest first (``n``: none)."""
        _, pos = self.tree.query(self.rotate(X), k=k)
        return np.asarray(pos, dtype=np.int64).reshape(len(X), k)


def rotated_index(reg):
    """The (cached) :class:`RotatedIndex` of a fitted map's database."""
    data, _ = reg.database()
    key = (id(data), data.shape, data[0].tobytes(), data[-1].tobytes())
    try:
        cached = _INDEXES.get(reg)
    except TypeError:  # not weak-referenceable
        cached = None
    if cached is not None and cached[0] == key:
        return cached[1]
    index = RotatedIndex(data)
    try:
        _INDEXES[reg] = (key, index)
    except TypeError:
        pass
    return index


@njit(nogil=True, cache=True)
def _fit_rows(data, targets, V, pos, qidx, lo, k, theiler, ridge, out):
    """Local gradients ``out[lo + i]`` at ``V[lo + i]`` from the neighbour positions ``pos[i]``.

    The same neighbourhoods as :meth:`LocalLinearDelayMap.local_maps`: the
    first ``k`` of ``pos[i]`` (nearest first) that exist and lie farther than
    ``theiler`` rows from the query's own row ``qidx[lo + i]`` (when ``qidx``
    is not empty); the same ridge-regularised local linear fit.
    """
    n_fit, p = data.shape
    nb_x = np.zeros((k, p))
    nb_y = np.zeros(k)
    nb_w = np.zeros(k)
    scratch = fit_scratch(p, k)
    for i in range(pos.shape[0]):
        row_q = lo + i
        used = 0
        for j in range(pos.shape[1]):
            if used == k:
                break
            row = pos[i, j]
            if row >= n_fit or (qidx.size > 0 and abs(row - qidx[row_q]) <= theiler):
                continue
            nb_w[used] = 1.0
            nb_y[used] = targets[row]
            for f in range(p):
                nb_x[used, f] = data[row, f]
            used += 1
        for j in range(used, k):
            nb_w[j] = 0.0
        fit_neighbourhood(nb_x, nb_y, nb_w, V[row_q], ridge, 1, 0.0, scratch, out[row_q])


def local_gradients(reg, V, query_index=None, *, n_jobs=None, progress=None, desc="Jacobians"):
    """Gradients ``a_n`` of the local linear maps at the rows of ``V`` (data units).

    What ``reg.local_maps(V, query_index=...)[0]`` returns: per task of
    :data:`TASK_ROWS` rows one k-NN query on the map's :class:`RotatedIndex`
    and one compiled loop of Theiler exclusion and local fits reading the
    database in place (no gathered neighbour arrays), ``thread_count(n_jobs)``
    tasks at once (both release the GIL).  Radius neighbourhoods and
    duck-typed maps take ``local_maps``.
    """
    n = V.shape[0]
    if n_jobs is None:
        n_jobs = getattr(reg, "n_jobs", None)
    if (getattr(reg, "radius", None) is not None or not hasattr(reg, "database")
            or getattr(reg, "order", 1) != 1):
        jac = np.empty_like(V, dtype=np.float64)
        with progress_bar(n, desc, progress) as bar:
            for lo in range(0, n, CHUNK_ROWS):
                sl = slice(lo, min(n, lo + CHUNK_ROWS))
                jac[sl], _ = reg.local_maps(
                    V[sl], query_index=None if query_index is None else query_index[sl],
                    n_jobs=n_jobs)
                bar.update(sl.stop - sl.start)
        return jac
    data, targets = reg.database()  # rescaled units (targets too: gradients need no rescaling)
    index = rotated_index(reg)
    Vs = np.ascontiguousarray(reg.x_scaler_.forward(V))
    qidx = (np.zeros(0, dtype=np.int64) if query_index is None
            else np.ascontiguousarray(query_index, dtype=np.int64))
    k = min(int(reg.n_neighbors), index.n)
    theiler = int(reg.theiler_window or 0)
    kq = min(index.n, k + (0 if query_index is None else 2 * theiler + 1))
    jac = np.empty((n, V.shape[1]))
    bounds = [(lo, min(n, lo + TASK_ROWS)) for lo in range(0, n, TASK_ROWS)]

    def task(lohi):
        lo, hi = lohi
        _fit_rows(data, targets, Vs, index.query(Vs[lo:hi], kq), qidx, lo, k, theiler,
                  float(reg.ridge), jac)
        return hi - lo

    threads = min(thread_count(n_jobs), len(bounds))
    with progress_bar(n, desc, progress) as bar:
        if threads == 1:
            for b in bounds:
                bar.update(task(b))
        else:
            with ThreadPoolExecutor(max_workers=threads) as pool:
                for done in pool.map(task, bounds):
                    bar.update(done)
    return jac
