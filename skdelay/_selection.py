"""Delay selection from the one-step forecast error sigma_m(tau): the public API.

:func:`forecast_error_curve` scans a series, :class:`DelaySelectorCV` scans a
lag matrix the scikit-learn way; both run the kernels of
:mod:`skdelay._scan` over a validated :class:`~skdelay._scan.ScanOptions` and
locate the dips with :func:`skdelay._dips.locate_dips` (re-exported here).

Scale: the series is rescaled by a power of two (``Standardiser``, exact) before
the scan, and sigma is normalised by the standard deviation, so the curve of
``s * 1e300`` or ``s * 1e-300`` is that of ``s``.
"""

from __future__ import annotations

import numbers
import warnings
from typing import ClassVar

import numpy as np
import pandas as pd
from joblib import Parallel, delayed
from scipy.stats import rankdata
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.model_selection import TimeSeriesSplit, check_cv
from sklearn.pipeline import Pipeline
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from skdelay._checks import check_params, check_positive_int, check_random_state, check_series
from skdelay._correlation import autocorrelation
from skdelay._dips import batch_table, locate_dips
from skdelay._embedding import TwoWindowEmbedding, required_lags, two_window_columns
from skdelay._local_linear import LocalLinearDelayMap
from skdelay._neighbours import Standardiser
from skdelay._scan import N_BATCHES, ScanOptions, cell_stats, scan_series
from skdelay._windows import series_from_lagged

__all__ = ["DelaySelectorCV", "NoDipWarning", "forecast_error_curve", "locate_dips"]

#: Window lengths scanned by default (the paper's m = 2..5); DelaySelectorCV keeps
#: those the lag matrix can hold.
DEFAULT_M = (2, 3, 4, 5)
#: Neighbourhood size of the default local linear model (the paper's choice for N ~ 10^5).
DEFAULT_NEIGHBOURS = 30
#: Fewest neighbours a default model is allowed to shrink to on short inputs: two
#: points define no local structure, three give a noisy but defined local mean/slope.
MIN_NEIGHBOURS = 3
#: A series whose spread relative to its level is below this differs only by rounding
#: (float64 has 2.2e-16 resolution): no dynamics can be read from it.
MIN_RELATIVE_SPREAD = 1e-13


class NoDipWarning(UserWarning):
    """No window length shows a significant forecast-error dip: the delay is unknown."""


def no_dip_message(dips, consequence):
    """The :class:`NoDipWarning` text: each m's reason (``dips["reason"]`` of
    :func:`locate_dips`), what follows (``consequence``) and what to try."""
    why = "; ".join(f"m={int(mm)}: {r}" for mm, r in dips["reason"].items())
    return (f"no window length shows a significant forecast-error dip ({why}), so "
            f"{consequence}. Try a longer record, a coarser sampling step (fewer samples per "
            "delay), less measurement noise, or a wider tau range around the expected delay.")


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
            raise ValueError(f"theiler_window must be 'auto' or an int >= 0, got "
                             f"{theiler_window!r}.")
        acf = autocorrelation(s, min(s.size - 1, 5000))
        below = np.flatnonzero(acf < np.exp(-1.0))
        return int(max(1, below[0] if below.size else acf.size))
    return check_positive_int(theiler_window, name="theiler_window", minimum=0)


def rescaled(s, name="series"):
    """``(z, std)``: ``s`` divided by a power of two near its rms, and the std of ``z``.

    Raises ValueError for a series that is constant up to rounding.
    """
    st = Standardiser.fit(s)
    if st.relative_spread < MIN_RELATIVE_SPREAD:
        raise ValueError(
            f"{name} is constant up to rounding (relative spread {st.relative_spread:.1e}); "
            "a delay cannot be read from it - check the recording channel or remove the offset."
        )
    z = st.forward(s)
    return z, float(z.std()), st.scale


def _frame(values, ms, taus):
    return pd.DataFrame(np.asarray(values).T, index=pd.Index(taus, name="tau"),
                        columns=pd.Index(ms, name="m"))


def _combine(res):
    """Mean over splits of the errors and the standard error of that mean."""
    n_split = res.error.shape[0]
    return res.error.mean(axis=0), np.sqrt(np.sum(res.se ** 2, axis=0)) / n_split


# ----------------------------------------------------------------------------- forecast_error_curve
def forecast_error_curve(series, m=(2, 3, 4, 5), tau=range(1, 101), *, n_neighbors=30, order=1,
                         ridge=1e-3, radius=None, n_queries=None, equal_neighbourhood=False,
                         theiler_window="auto", search="auto", n_candidates=None,
                         refine=True, centre_error="batches", progress=False, random_state=None,
                         n_jobs=None, verbose=0):
    """Normalised one-step forecast error sigma_m(tau) of local linear two-window models.

    For every ``(m, tau)`` and every query time ``t`` the local linear map is
    fitted on the ``n_neighbors`` nearest two-window vectors ``v_j(m, tau)``
    of the same series, excluding ``|j - t| <= theiler_window``, and predicts
    ``s[t+1]``; sigma is the rms error divided by the series' standard
    deviation (Buenner et al., Sec. III).  Its dip locates the delay
    (:func:`locate_dips`, which reads the standard errors in ``attrs["se"]``).

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Scalar series sampled at step 1 (any scale: it is rescaled exactly).
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
        Radius neighbourhoods (units of ``series``) with k-NN fallback instead of k-NN.
    n_queries : int, default=None
        Queries of the coarse pass: forecast this many random times per cell
        (the database stays complete); None uses every time (no coarse cells).
    equal_neighbourhood : {False, True, "segment", "radius"}, default=False
        The paper's equal neighbourhood size for every ``m``: ``True`` /
        ``"segment"`` uses for each smaller ``m`` the most recent segment of
        the series whose mean ``k``-th neighbour distance (at the median
        ``tau``) matches that of the largest ``m`` on the whole series;
        ``"radius"`` uses that distance as a common neighbourhood radius.
    theiler_window : int or "auto", default="auto"
        Temporal exclusion of neighbours; "auto" is the 1/e decorrelation time.
    search : {"auto", "tree", "candidates", "exact"}, default="auto"
        Neighbour search (see :mod:`skdelay._scan`): "tree" is the exact
        k-NN from a k-d tree per tau on the leading principal components of
        both windows, refined by the full distance; "candidates" re-ranks fixed
        candidate lists built once per ``m`` (approximate: it can miss true
        neighbours, ``attrs["exact_fraction"]`` says how often it is provably
        exact); "auto" uses "tree" unless a measured cost model expects the
        lists to cost less than half of it: "tree" for every cell of a
        full-precision scan, for refined cells and most coarse passes,
        "candidates" for a coarse pass with few queries on a long record
        (10^4 queries on 10^6 rows);
        "exact" rebuilds a plain k-d tree on the 2m-dimensional vectors per
        ``(m, tau)`` (the reference).
    n_candidates : int, default=None
        Candidates per window and query for ``search="candidates"`` (default
        ``max(8 k, 64)``, fewer for records so long that the lists of one ``m``
        would exceed 256 MB, see :func:`skdelay._scan.default_n_candidates`).
    refine : bool, default=True
        With ``n_queries``: recompute the taus around each dip with 4x more
        queries per round (up to all) until every dip centre's standard error
        is below 0.2 samples; then, under ``search="auto"``, recompute the taus
        around each significant dip that the candidate lists approximated with
        the exact tree search (same queries), so that a dip is read off exact
        neighbourhoods.  False keeps the coarse pass (full precision:
        ``n_queries=None``).
    centre_error : {"batches", "redraws"}, default="batches"
        The dip centre's standard error that the refinement targets: from
        resampling the query batches (as :func:`locate_dips` reports it), or
        from independent redraws of each cell, which overstates it where the
        curve has several valleys and refines far more cells (on a wide scan
        of clean Mackey-Glass tau = 17, 3x the time for the same centres).
    progress : bool, default=False
        Show a tqdm progress bar (with ETA) over the scan's tasks.
    random_state : int, RandomState or Generator, default=None
        Seeds the query subset and the neighbourhood-size probes.
    n_jobs : int, default=None
        joblib workers (tasks: one ``m`` and a chunk of ``tau``).
    verbose : int, default=0
        joblib verbosity.

    Returns
    -------
    pandas.DataFrame
        Index ``tau``, one column per ``m``.  ``attrs`` holds ``se``
        (standard errors of the cells, same shape), ``coarse`` (bool, cells
        left at the coarse query subset), ``queries`` (queries per cell),
        ``n_queries`` (coarse queries per ``m``), ``segment_length`` (per
        ``m``), ``theiler_window``, ``radius``, ``exact`` (fraction of the
        queries of each cell whose neighbours are provably the exact k-NN,
        same shape), ``exact_fraction`` (its mean over ``tau``, per ``m``) and
        ``batch_msq`` (each cell's mean squared error per query batch, for the
        bootstrap of the dip centre, :func:`skdelay._dips.batch_table`).

    Raises
    ------
    ValueError
        Bad options (negative ridge, radius <= 0, order not 0/1, n_candidates <
        n_neighbors, a Theiler window leaving no neighbours), a series too
        short for the grid, or a constant series.

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
    >>> bool(sigma.attrs["se"].loc[7, 2] < 0.1 * sigma.loc[7, 2])
    True
    """
    s = check_series(series, name="series")
    n_jobs = check_params(n_jobs=n_jobs)
    z, z_std, scale = rescaled(s)
    ms, taus = as_grid(m, "m"), as_grid(tau, "tau")
    n_lags = required_lags(int(ms[-1]), int(taus[-1]))
    k = check_positive_int(n_neighbors, name="n_neighbors")
    if s.size < n_lags + k + 2:
        raise ValueError(
            f"series has {s.size} samples but m={int(ms[-1])}, tau={int(taus[-1])} needs "
            f"{n_lags} lags plus at least n_neighbors + 2 = {k + 2} rows; use a longer "
            "series or a smaller tau/m range."
        )
    w = theiler_from(z, theiler_window)
    opts = ScanOptions(k=k, order=order, ridge=ridge,
                       radius=None if radius is None else _scaled_radius(radius, scale),
                       theiler=w, search=search, n_candidates=n_candidates,
                       neighbourhood=equal_neighbourhood, n_queries=n_queries, refine=refine,
                       centre_error=centre_error)
    db_t = np.arange(n_lags - 1, s.size - 1)
    opts.check_rows(db_t.size)
    res = scan_series(z, ms, taus, [(db_t, None)], opts, random_state=random_state,
                      n_jobs=n_jobs, verbose=verbose, progress=progress)
    err, se = _combine(res)
    out = _frame(err / z_std, ms, taus)
    out.attrs.update(
        se=_frame(se / z_std, ms, taus), coarse=_frame(res.coarse, ms, taus),
        batch_msq=batch_table(res.batch_msq / z_std ** 2, ms, taus),
        queries=_frame(res.n_queries[0], ms, taus), exact=_frame(res.exact[0], ms, taus),
        n_queries={int(mm): int(res.n_queries[0, j].min()) for j, mm in enumerate(ms)},
        segment_length=res.segment_length, theiler_window=w,
        radius=None if res.radius is None else float(res.radius) * scale,
        exact_fraction={int(mm): float(res.exact[0, j].mean()) for j, mm in enumerate(ms)},
    )
    return out


def _scaled_radius(radius, scale):
    if isinstance(radius, numbers.Real) and not isinstance(radius, (bool, np.bool_)) \
            and radius > 0 and np.isfinite(radius):
        return float(radius) / scale
    return radius  # ScanOptions says what is wrong with it


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
    e2 = (pred - y[queries]) ** 2
    n_b = min(N_BATCHES, e2.size)
    sq = np.bincount((np.arange(e2.size) * n_b) // e2.size, e2, minlength=n_b)[None, :]
    rms, se = cell_stats(sq, e2.size)
    return float(rms[0]), float(se[0])


def _no_dip_rows(ms, reason):
    rows = {int(mm): {"delay": np.nan, "half_width": np.nan, "tau_min": -1,
                      "min_error": np.nan, "centre_se": np.nan, "delay_error": np.nan,
                      "tau_best": -1, "depth": np.nan, "z": np.nan, "threshold": np.nan,
                      "significant": False, "reason": reason} for mm in ms}
    out = pd.DataFrame.from_dict(rows, orient="index")
    out.index.name = "m"
    return out


class DelaySelectorCV(RegressorMixin, BaseEstimator):
    """Find the feedback delay and window length by scanning sigma_m(tau).

    ``fit(X, y)`` takes the lag matrix and next values from
    :func:`~skdelay.lagged_windows`, computes the normalised one-step forecast
    error of ``Pipeline(TwoWindowEmbedding(m, tau), estimator)`` for every
    ``(m, tau)`` of the grid with its standard error, and locates and tests
    the dip of each ``sigma_m(tau)`` (:func:`locate_dips`).  The scan never
    materialises ``X[train]``: the 1-D series is recovered from ``X`` (first
    row + first column, checked against all of ``X``) and workers receive the
    series and row indices; if ``X`` is not a consistent lag matrix, each
    candidate gets only its ``(n, 2m)`` columns.

    With ``cv=None`` the error is the paper's: in-sample, each forecast made
    without the neighbours within ``theiler_window`` of the query.  With a
    splitter (an int means ``TimeSeriesSplit(n_splits=cv)``) it is the
    out-of-sample error on the test folds.

    Parameters
    ----------
    estimator : LocalLinearDelayMap or regressor, default=None
        Model fitted on the two-window vectors.  None: ``LocalLinearDelayMap``
        with 30 neighbours, fewer (down to 3) when ``X`` has too few rows.
        Other regressors need a ``cv`` splitter.
    m : int or sequence of int, default=None
        Window lengths (an int ``v`` means ``1..v``).  None: those of
        ``(2, 3, 4, 5)`` that the lag columns of ``X`` can hold.
    tau : int or sequence of int, default=None
        Delays in samples (an int ``v`` means ``1..v``).  None: every delay the
        lag columns hold for the largest ``m``, ``1..n_lags - max(m) // 2``
        (``required_lags(m, tau) <= n_lags``), so ``lagged_windows(s, L)``
        scans delays up to about ``L``.
    cv : None, int, or CV splitter, default=None
        None: in-sample Theiler-excluded error; otherwise the test error.
    n_queries : int, default=None
        Forecast this many random rows per fold in the coarse pass (the
        neighbour database stays complete); None uses all.
    theiler_window : int or "auto", default="auto"
        Temporal exclusion for ``cv=None`` ("auto": the 1/e decorrelation time).
    equal_neighbourhood : {False, True, "segment", "radius"}, default=False
        Equal neighbourhood size for every ``m`` (see
        :func:`forecast_error_curve`); needs ``X`` from ``lagged_windows``.
    search : {"auto", "tree", "candidates", "exact"}, default="auto"
        Neighbour search of the scan (see :func:`forecast_error_curve`).
    n_candidates : int, default=None
        Candidates per window and query for ``search="candidates"``.
    refine : bool, default=True
        Refine the dips with more queries (see :func:`forecast_error_curve`).
    dip_level : float, default=1/3
        Fraction of the dip depth delimiting the dip (:func:`locate_dips`).
    progress : bool, default=False
        tqdm progress bar over the scan's tasks.
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
        folds); index ``tau``, one column per ``m``; ``attrs["se"]`` holds the
        standard errors of the cells.
    delay_by_m_ : pandas.DataFrame
        Dip of every ``m`` (:func:`locate_dips`): ``delay``, ``half_width``,
        ``centre_se``, ``delay_error``, ``tau_best``, ``z``, ``threshold``,
        ``significant``, ``reason``, ...
    delay_ : float
        Dip centre (samples) of the best ``m``: among the ``m`` with a
        significant dip, the one with the lowest minimum error.  NaN when no
        ``m`` has a significant dip (a :class:`NoDipWarning` says why).
    delay_error_ : float
        Error bar of ``delay_`` (half-width and centre standard error), or NaN.
    best_params_ : dict
        ``{"m": best m, "tau": its tau_best}``; without a significant dip the
        grid cell of lowest error (so ``best_estimator_`` always exists).
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
    >>> bool(abs(sel.delay_ - 7) <= 1), bool(sel.delay_by_m_.loc[2, "significant"])
    (True, True)
    """

    _parameter_constraints: ClassVar[dict] = {
        "estimator": [HasMethods(["fit", "predict"]), None],
        # the grids' contents (positive integers) are checked by as_grid
        "m": [Interval(numbers.Integral, 1, None, closed="left"), "array-like", None],
        "tau": [Interval(numbers.Integral, 1, None, closed="left"), "array-like", None],
        "cv": ["cv_object", None],
        "n_queries": [Interval(numbers.Integral, 1, None, closed="left"), None],
        "theiler_window": [StrOptions({"auto"}), Interval(numbers.Integral, 0, None,
                                                          closed="left")],
        "equal_neighbourhood": ["boolean", StrOptions({"none", "segment", "radius"})],
        "search": [StrOptions({"auto", "tree", "candidates", "exact"})],
        "n_candidates": [Interval(numbers.Integral, 1, None, closed="left"), None],
        "refine": ["boolean"],
        "dip_level": [Interval(numbers.Real, 0, 1, closed="right")],
        "progress": ["boolean"],
        "random_state": ["random_state", np.random.Generator],
        # 0 is refused by check_params (with what to pass instead)
        "n_jobs": [numbers.Integral, None],
        "verbose": ["verbose"],
    }

    def __init__(self, estimator=None, *, m=None, tau=None, cv=None, n_queries=None,
                 theiler_window="auto", equal_neighbourhood=False, search="auto",
                 n_candidates=None, refine=True, dip_level=1 / 3, progress=False,
                 random_state=None, n_jobs=None, verbose=0):
        self.estimator = estimator
        self.m = m
        self.tau = tau
        self.cv = cv
        self.n_queries = n_queries
        self.theiler_window = theiler_window
        self.equal_neighbourhood = equal_neighbourhood
        self.search = search
        self.n_candidates = n_candidates
        self.refine = refine
        self.dip_level = dip_level
        self.progress = progress
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

    def _grid(self, n_lags):
        """The (m, tau) grid, the defaults adapted to the lag columns of X."""
        if self.m is None:
            ms = np.array([mm for mm in DEFAULT_M if mm <= n_lags], dtype=np.int64)
            if ms.size == 0:
                raise ValueError(
                    f"X has {n_lags} feature(s) (lag columns) but the smallest default window "
                    f"m={DEFAULT_M[0]} needs {DEFAULT_M[0]}; build X with "
                    "lagged_windows(series, n_lags) for n_lags > the delays to scan."
                )
        else:
            ms = as_grid(self.m, "m")
        if self.tau is None:
            top = n_lags - int(ms[-1]) // 2
            if n_lags < int(ms[-1]) or top < 1:
                raise ValueError(
                    f"X has {n_lags} feature(s) (lag columns) but m={int(ms[-1])} needs at "
                    f"least {required_lags(int(ms[-1]), 1)}; build X with "
                    "lagged_windows(series, n_lags) for n_lags > the delays to scan."
                )
            taus = np.arange(1, top + 1, dtype=np.int64)
        else:
            taus = as_grid(self.tau, "tau")
        need = required_lags(int(ms[-1]), int(taus[-1]))
        if n_lags < need:
            raise ValueError(
                f"X has {n_lags} feature(s) (lag columns) but m={int(ms[-1])}, "
                f"tau={int(taus[-1])} needs {need}; build X with lagged_windows(series, "
                f"n_lags={need}) or scan smaller m/tau."
            )
        return ms, taus

    def _model(self, n_rows, theiler, splits):
        """The estimator; the default one shrinks its neighbourhood to short inputs."""
        fewest = min((tr.size for tr, _ in splits), default=n_rows)
        free = fewest - (2 * theiler + 1 if self.cv is None else 0)
        if self.estimator is not None:
            est = self.estimator
            k = getattr(est, "n_neighbors", None)
            if isinstance(est, LocalLinearDelayMap) and isinstance(k, numbers.Integral) \
                    and k > free:
                raise ValueError(
                    f"n_neighbors={k} but X has {n_rows} rows, of which {max(free, 0)} can be "
                    f"neighbours of a query (theiler_window={theiler}, smallest training fold "
                    f"{fewest} rows); use n_neighbors <= {max(free, 1)} or a longer series."
                )
            return est
        if free < MIN_NEIGHBOURS:
            raise ValueError(
                f"X has {n_rows} rows, too few for a delay scan: at most {max(free, 0)} can be "
                f"neighbours of a query (theiler_window={theiler}), and a local model needs "
                f"at least {MIN_NEIGHBOURS}; use a longer series (hundreds of rows or more)."
            )
        return LocalLinearDelayMap(n_neighbors=min(DEFAULT_NEIGHBOURS, free))

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

        Warns
        -----
        NoDipWarning
            When no ``m`` has a significant dip (``delay_`` is then NaN).
        """
        self._validate_params()
        check_params(n_jobs=self.n_jobs)
        X, y = validate_data(self, X, y, y_numeric=True, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        n, n_lags = X.shape
        ms, taus = self._grid(n_lags)
        if n < 3:
            raise ValueError(f"X has {n} sample(s) but DelaySelectorCV needs at least 3 rows; "
                             "use a longer series.")
        if np.ptp(X) == 0:
            raise ValueError(f"X is constant (every value equals {float(X.flat[0])!r}); a delay "
                             "cannot be read from a constant signal - check the recording channel.")
        if self.estimator is not None and self.cv is None \
                and not isinstance(self.estimator, LocalLinearDelayMap):
            raise ValueError(
                "cv=None (in-sample, Theiler-excluded error) needs a LocalLinearDelayMap "
                f"estimator, got {type(self.estimator).__name__}; pass cv=5 (TimeSeriesSplit) "
                "or a splitter."
            )
        splits = self._splits(X, y)
        local = self.estimator is None or isinstance(self.estimator, LocalLinearDelayMap)
        s = series_from_lagged(X, y) if local else None
        if s is not None:
            z, scale, unit = rescaled(s, name="the series behind X")
            w = theiler_from(z, self.theiler_window) if self.cv is None else 0
            est = self._model(n, w, splits)
            opts = ScanOptions(
                k=est.n_neighbors, order=est.order, ridge=est.ridge,
                radius=None if est.radius is None else _scaled_radius(est.radius, unit),
                theiler=w, search=self.search, n_candidates=self.n_candidates,
                neighbourhood=self.equal_neighbourhood, n_queries=self.n_queries,
                refine=self.refine)
            res = scan_series(
                z, ms, taus, [(tr + n_lags - 1, None if te is None else te + n_lags - 1)
                              for tr, te in splits], opts,
                random_state=self.random_state, n_jobs=self.n_jobs, verbose=self.verbose,
                progress=self.progress)
            err, se, bm = res.error, res.se, res.batch_msq
            attrs = {"segment_length": res.segment_length,
                     "queries": _frame(res.n_queries[0], ms, taus),
                     "coarse": _frame(res.coarse, ms, taus),
                     "theiler_window": w if self.cv is None else None}
        else:
            if self.equal_neighbourhood:
                raise ValueError(
                    "equal_neighbourhood needs X and y from lagged_windows (consecutive rows of "
                    "one series); set equal_neighbourhood=False for other inputs."
                )
            w = (0 if np.ptp(y) == 0 else theiler_from(y, self.theiler_window)) \
                if self.cv is None else None
            est = self._model(n, w or 0, splits)
            err, se = self._scan_columns(X, y, ms, taus, splits, est, w)
            bm = None  # an estimator's own fits: no query batches
            scale = y.std()
            attrs = {"theiler_window": w}
        scale = scale if scale > 0 else 1.0
        if bm is not None:
            attrs["batch_msq"] = batch_table(bm / scale ** 2, ms, taus)
        self._store(err / scale, se / scale, ms, taus, attrs)
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
        res = np.asarray(Parallel(n_jobs=self.n_jobs, verbose=self.verbose)(jobs))
        shape = (len(splits), len(ms), len(taus))
        return res[:, 0].reshape(shape), res[:, 1].reshape(shape)

    def _store(self, err, se, ms, taus, attrs):
        n_splits = err.shape[0]
        self.n_splits_ = n_splits
        fe = _frame(err.mean(axis=0), ms, taus)
        fe.attrs.update(attrs)
        fe.attrs["se"] = _frame(np.sqrt(np.sum(se ** 2, axis=0)) / n_splits, ms, taus)
        self.forecast_error_ = fe
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
        if len(taus) < 3:
            dips = _no_dip_rows(ms, f"only {len(taus)} delay(s) scanned; a dip needs at least 3")
        elif not np.all(np.isfinite(fe.to_numpy())):
            dips = _no_dip_rows(ms, "the forecast error is not finite everywhere")
        else:
            dips = locate_dips(fe, level=self.dip_level)
        self.delay_by_m_ = dips
        good = dips[dips["significant"]]
        if len(good):
            best_m = int(good["min_error"].idxmin())
            row = dips.loc[best_m]
            self.delay_ = float(row["delay"])
            self.delay_error_ = float(row["delay_error"])
            self.best_params_ = {"m": best_m, "tau": int(row["tau_best"])}
        else:
            self.delay_ = float("nan")
            self.delay_error_ = float("nan")
            j, i = np.unravel_index(np.argmin(fe.to_numpy().T), (len(ms), len(taus)))
            self.best_params_ = {"m": int(ms[j]), "tau": int(taus[i])}
            warnings.warn(no_dip_message(dips, "the delay is unknown (delay_ = NaN)"),
                          NoDipWarning, stacklevel=3)
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
