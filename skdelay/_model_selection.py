"""Model settings from the data alone: time-series cross-validation of forecasts.

The Lyapunov spectrum of a local linear model depends on its neighbourhood
size and ridge: noise in the local Jacobians inflates the leading exponents,
over-smoothing deflates them.  Nothing outside the data may choose them (an
exact spectrum is never available for a recording), so
:func:`select_model_options` runs scikit-learn's ``GridSearchCV`` with a
``TimeSeriesSplit`` on the pipeline ``TwoWindowEmbedding -> LocalLinearDelayMap``
and scores each setting by two out-of-sample errors on the later folds:

* the **one-step** forecast error (what the fit is for), and
* the **iterated** error after ``horizon`` steps of the model's own free run
  from the true history -- it grows with the local Jacobians' errors, the
  quantity the spectrum is made of, so it tells over- from under-smoothing
  where the one-step error is flat.

Both are normalised by the series' standard deviation and summed, each relative
to its best value on the grid, so neither error alone can dominate.  The chosen
setting (``refit`` of ``GridSearchCV``) follows the one-standard-error rule: the
smoothest setting (most neighbours, then largest ridge) whose summed error lies
within one standard error over the test folds of the smallest (:func:`_pick`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from sklearn.model_selection import GridSearchCV, TimeSeriesSplit
from sklearn.pipeline import Pipeline

from ._checks import check_params, check_positive_int, check_series
from ._embedding import TwoWindowEmbedding, required_lags
from ._iterate import iterate
from ._local_linear import LocalLinearDelayMap
from ._model import ModelOptions
from ._neighbours import Standardiser
from ._windows import lagged_windows

__all__ = ["PER_PARAMETER_GRID", "RIDGE_GRID", "ModelSelection", "SpectrumModelSelection",
           "dominant_period", "select_model_options", "select_spectrum_model",
           "spectrum_of_selection"]

#: Neighbours per parameter of the local map (k = value * (2 m + 1)): from barely
#: overdetermined fits (2) to neighbourhoods spanning a sizeable part of a
#: low-dimensional attractor (32).
PER_PARAMETER_GRID = (2.0, 4.0, 8.0, 16.0, 32.0)
#: Relative ridges (fractions of the mean eigenvalue of the local covariance).
RIDGE_GRID = (1e-3, 1e-2, 1e-1)
#: Forecasts scored per fold and error (a subsample keeps the search to seconds).
N_SCORED = 600
#: Test folds of the TimeSeriesSplit.
N_SPLITS = 3


@dataclass(frozen=True)
class ModelSelection:
    """The chosen settings and the cross-validation table behind them."""

    options: ModelOptions
    table: pd.DataFrame
    horizon: int


def _unit_scale(s):
    """``s`` divided by the power of two nearest its root mean square (exact, see
    :class:`~skdelay._neighbours.Standardiser`).  The choices are scale free but the
    scorers divide errors by the series' standard deviation, which underflows to 0 for
    data at 1e-300 (a ZeroDivisionError) and overflows to inf at 1e300 (every score 0, an
    arbitrary choice)."""
    return s / Standardiser.fit(s).scale


def _rows(n, n_scored, seed, margin=0):
    rng = np.random.default_rng(seed)
    usable = max(n - margin, 1)
    return np.sort(rng.choice(usable, size=min(n_scored, usable), replace=False))


def _one_step_scorer(scale, n_scored, seed):
    def score(estimator, X, y):
        rows = _rows(len(X), n_scored, seed)
        err = estimator.predict(X[rows]) - y[rows]
        return -float(np.sqrt(np.mean(err ** 2))) / scale

    return score


def _iterated_scorer(scale, n_scored, seed, horizon):
    def score(estimator, X, y):
        # rows of a test fold are consecutive: X[i] holds the state (newest first) and
        # y[i : i + horizon] the true continuation
        rows = _rows(len(X), max(1, n_scored // 4), seed, margin=horizon)
        err = np.empty(rows.size)
        for j, i in enumerate(rows):
            run = iterate(estimator, X[i, ::-1], horizon, on_escape="ignore")
            # a run that escapes has forecast nothing: the error of a guess drawn from the
            # data's distribution, sqrt(2) standard deviations
            err[j] = run[-1] - y[i + horizon - 1] if run.size == horizon else np.sqrt(2) * scale
        return -float(np.sqrt(np.mean(err ** 2))) / scale

    return score


def _totals(cv_results):
    """Per test fold and setting, the sum of the two errors relative to each error's best
    mean on the grid; shape ``(n_splits, n_settings)``."""
    one = -np.asarray(cv_results["mean_test_one_step"])
    few = -np.asarray(cv_results["mean_test_iterated"])
    n_splits = sum(1 for key in cv_results
                   if key.startswith("split") and key.endswith("_test_one_step"))
    return np.array([-np.asarray(cv_results[f"split{i}_test_one_step"]) / np.min(one)
                     - np.asarray(cv_results[f"split{i}_test_iterated"]) / np.min(few)
                     for i in range(n_splits)])


def _one_se(cv_results):
    """``(total, se, within)``: each setting's mean relative error, the standard error of the
    best one's over the folds, and which settings lie within one standard error of it."""
    per_fold = _totals(cv_results)
    total = per_fold.mean(axis=0)
    best = int(np.argmin(total))
    se = float(per_fold[:, best].std(ddof=1) / np.sqrt(per_fold.shape[0]))
    return total, se, total <= total[best] + se


def _pick(cv_results):
    """Index of the chosen setting (``GridSearchCV`` refit): the one-standard-error rule --
    of the settings whose summed relative error lies within one standard error (over the
    test folds) of the smallest, the smoothest: most neighbours, then largest ridge.

    Why: the local Jacobians, of which the free runs and the spectrum are made, are noisier
    than the forecasts show, and settings within one standard error are a tie the data
    cannot break (Hastie, Tibshirani & Friedman, *The Elements of Statistical Learning*,
    sec. 7.10).  Mackey-Glass tau = 17 with 1 % noise (10^5 samples, noise-reduced, seed
    2024 of benchmarks/faithful_noise.py): the smallest error took 2 points per parameter
    for m = 2, whose lambda_1 (0.0067 per step) sat 34 % above the m = 5 model's (0.0050;
    clean data 0.0050); the rule takes 4 (0.0051).  Over tau = 17, 23, 30 with clean, 1 %
    and 5 % noise, m_d read 2/4/none, 2/2/2, 2/2/2 with the rule against 2/4/none, 2/2/2,
    2/2/2 without at that seed, and 2/2/none, 2/2/2, 2/2/2 against 2/3/none, 2/2/3, 2/2/2
    at seed 7.
    """
    _total, _se, within = _one_se(cv_results)
    k = np.asarray(cv_results["param_model__n_neighbors"], dtype=float)
    ridge = np.asarray(cv_results["param_model__ridge"], dtype=float)
    idx = np.flatnonzero(within)
    return int(idx[np.lexsort((ridge[idx], k[idx]))[-1]])


def select_model_options(series, m, tau, *, base=None, per_parameter=PER_PARAMETER_GRID,
                         ridge=RIDGE_GRID, horizon=None, n_scored=N_SCORED, random_state=0,
                         n_jobs=None):
    """Neighbourhood size and ridge of the delay models by time-series cross-validation.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        The data (sampling step 1).
    m, tau : int
        Window length and delay of the model that is cross-validated (the
        largest ``m`` of an analysis: the one whose spectrum is reported).
    base : ModelOptions, default=None
        Settings kept (the Theiler window); ``per_parameter`` and ``ridge`` are
        replaced by the chosen ones.
    per_parameter, ridge : sequence of float
        The grid: neighbours per parameter (``k = per_parameter * (2 m + 1)``)
        and relative ridges.
    horizon : int, default=None
        Steps of the iterated forecast (default ``min(max(2, tau // 4), 50)``: a
        fraction of a delay loop, so the errors of the local Jacobians have
        grown through the map but the feedback has not yet closed the loop).
    n_scored : int, default=600
        One-step forecasts scored per fold (a quarter as many iterated ones).
    random_state : int, default=0
        Seeds the scored subsets.
    n_jobs : int, default=None
        joblib workers of ``GridSearchCV``.

    Returns
    -------
    ModelSelection
        ``options`` (a :class:`~skdelay._model.ModelOptions`), ``table`` (one
        row per setting: ``per_parameter``, ``ridge``, ``n_neighbors``,
        ``one_step``, ``iterated``, ``total`` (their sum, each relative to its
        best on the grid), ``within_one_se`` (``total`` within one standard
        error of the smallest; the standard error in ``table.attrs["se"]``),
        ``chosen``) and ``horizon``.

    Examples
    --------
    >>> from skdelay._model_selection import select_model_options
    >>> from skdelay.systems import MackeyGlass, measure
    >>> x = measure(MackeyGlass(tau=17.0).simulate(8000, random_state=0), noise=0.01,
    ...             random_state=1)
    >>> sel = select_model_options(x, 2, 17, per_parameter=(2, 8), ridge=(1e-3,), n_scored=200)
    >>> sel.options.per_parameter in (2, 8), int(sel.table["chosen"].sum())
    (True, 1)
    """
    s = _unit_scale(check_series(series, name="series", min_length=200))
    n_jobs = check_params(n_jobs=n_jobs)
    m = check_positive_int(m, name="m")
    tau = check_positive_int(tau, name="tau")
    horizon = min(max(2, tau // 4), 50) if horizon is None else check_positive_int(horizon,
                                                                           name="horizon")
    base = ModelOptions() if base is None else base
    X, y = lagged_windows(s, required_lags(m, tau))
    p = 2 * m + 1
    grid = {"model__n_neighbors": sorted({max(p + 1, round(c * p)) for c in per_parameter}),
            "model__ridge": list(ridge)}
    pipe = Pipeline([("embedding", TwoWindowEmbedding(m=m, tau=tau)),
                     ("model", LocalLinearDelayMap(theiler_window=base.theiler_window))])
    scale = float(s.std())
    search = GridSearchCV(
        pipe, grid, cv=TimeSeriesSplit(n_splits=N_SPLITS),
        scoring={"one_step": _one_step_scorer(scale, n_scored, random_state),
                 "iterated": _iterated_scorer(scale, n_scored, random_state, horizon)},
        refit=_pick, n_jobs=n_jobs, error_score="raise")
    search.fit(X, y)
    res = search.cv_results_
    k = np.asarray(res["param_model__n_neighbors"], dtype=int)
    table = pd.DataFrame({
        "per_parameter": k / p, "ridge": np.asarray(res["param_model__ridge"], dtype=float),
        "n_neighbors": k, "one_step": -np.asarray(res["mean_test_one_step"]),
        "iterated": -np.asarray(res["mean_test_iterated"])})
    table["total"], se, table["within_one_se"] = _one_se(res)
    table.attrs["se"] = se  # of the smallest total, over the test folds
    table["chosen"] = np.arange(len(table)) == search.best_index_
    best = table.loc[search.best_index_]
    options = replace(base, n_neighbors=None, per_parameter=float(best["per_parameter"]),
                      ridge=float(best["ridge"]))
    return ModelSelection(options=options, table=table, horizon=horizon)


# --------------------------------------------------------------------------------------
# The model behind the reported spectrum: time scale, window span, neighbours and ridge
# --------------------------------------------------------------------------------------

#: Evolution times (samples per model step) tried for the spectrum model.  A local linear
#: map of a flow sampled far above its fastest time scale is nearly the identity: its
#: Jacobian's information sits in high-order differences that are mostly noise.  Larger
#: steps let the window reach back further with the same number of coordinates.
STEP_GRID = (1, 2, 3, 4)
#: Window spans (``m * step``) in units of the dominant period of the series (the lag of
#: the first autocorrelation maximum after its first minimum).  Evidence (embedded laser,
#: tau0 = 50 us, 1e5 samples, k = 150, 2026-11-25): with a window spanning ~0.7 periods
#: (18 us) lambda_max is 4.7-5.3 /ms at every step; spanning ~1.1 periods (27-28 us) it is
#: 2.4-2.7 /ms (exact 2.29): the state in the off-phase between spikes is visible only to a
#: window reaching back over the previous pulse.  The grid brackets both sides.
SPAN_GRID = (0.75, 1.0, 1.25, 1.5)
#: Largest window length tried (2 m coordinates per neighbourhood fit).
MAX_WINDOW = 14
#: Neighbourhood sizes of the spectrum model's grid.
NEIGHBOUR_GRID = (50, 100, 200)
#: Relative ridges of the spectrum model's grid.
SPECTRUM_RIDGE_GRID = (1e-3, 1e-2)
#: Relative ridges of the second stage of :func:`select_spectrum_model_staged`: one
#: decade beyond the full grid's, because with the one-delay horizon below the best
#: ridge on the embedded laser lies inside this range (0.1 beat 0.01, 0.3 and 1 at
#: 50 us: benchmarks/out/spectrum_staged.txt).
STAGED_RIDGE_GRID = (1e-3, 1e-2, 1e-1)
#: Neighbours and ridge of the first stage of :func:`select_spectrum_model_staged`
#: (step and window span): mid-grid values.
STAGE1_MODEL = (100, 1e-2)
#: Horizon of the scored free runs, in delays (see :func:`select_spectrum_model`).  A
#: free run's RMS error rewards a damped model once the runs have lost the data's
#: phase: the best point forecast of an unpredictable future is the conditional mean,
#: smoother than any trajectory.  Scored over four delays, the largest ridge of every
#: grid won at 50 and 150 us on the embedded laser (0.1, the grid's edge; the errors
#: 0.33 std on average, 0.17-0.25 std already after 5 us of the pulses' timing); over
#: one delay the errors stay at 0.14-0.20 std and the ridge has an optimum inside the
#: grid (0.3 and 1 lose to 0.1), the mark of a criterion that no longer rewards damping.
HORIZON_DELAYS = 1.0
#: Fractions of the horizon at which the free run's error is scored.
HORIZON_FRACTIONS = (0.25, 0.5, 0.75, 1.0)
#: Free runs scored per test fold.
N_RUNS_SCORED = 100


def dominant_period(series, max_lag):
    """Lag (samples) of the first autocorrelation maximum after its first minimum.

    The period of the fastest oscillation that dominates the series (for the
    laser: the ~25 us relaxation oscillation of the feedback loop); ``None``
    when the autocorrelation has no such maximum within ``max_lag``.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._model_selection import dominant_period
    >>> t = np.arange(5000)
    >>> dominant_period(np.sin(2 * np.pi * t / 25.0), 100)
    25
    """
    from ._correlation import autocorrelation

    s = check_series(series, name="series", min_length=8)
    max_lag = int(min(max_lag, s.size // 2))
    acf = autocorrelation(s, max_lag)
    d = np.diff(acf)
    rising = np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0))  # first minimum
    if rising.size == 0:
        return None
    lo = int(rising[0]) + 1
    falling = np.flatnonzero((d[lo:-1] > 0) & (d[lo + 1:] <= 0))
    return None if falling.size == 0 else int(lo + falling[0] + 1)


@dataclass(frozen=True)
class SpectrumModelSelection:
    """The cross-validated model behind the reported spectrum.

    ``step`` (samples per model step), ``m`` (window length in model steps),
    ``tau`` (delay in model steps), ``options`` (neighbours and ridge),
    ``horizon`` (scored free-run length, samples), ``period`` (dominant
    period, samples) and ``table`` (one row per setting: ``step``, ``m``,
    ``span``, ``n_neighbors``, ``ridge``, ``error``, ``error_se`` (the
    standard error of ``error`` from the spread over the folds), ``chosen``).
    """

    step: int
    m: int
    tau: int
    options: ModelOptions
    horizon: int
    period: int | None
    table: pd.DataFrame

    def describe(self):
        """One sentence: the chosen settings, in samples of the series."""
        return (f"step {self.step}, window m = {self.m} (spanning {self.m * self.step} "
                f"samples), delay {self.tau * self.step} samples, k = "
                f"{self.options.n_neighbors}, ridge {self.options.ridge:g}; chosen by "
                f"time-series cross-validation of free runs over {self.horizon} samples")


def _tracking_scorer(scale, n_runs, seed, steps):
    """Negative RMS error of free runs from the true history at ``steps`` (model steps)."""
    steps = np.asarray(steps, dtype=int)

    def score(estimator, X, y):
        rows = _rows(len(X), n_runs, seed, margin=int(steps.max()))
        err = np.empty((rows.size, steps.size))
        for j, i in enumerate(rows):
            run = iterate(estimator, X[i, ::-1], int(steps.max()), on_escape="ignore")
            for q, st in enumerate(steps):
                # an escaped run has forecast nothing: a guess from the data's distribution
                err[j, q] = (run[st - 1] - y[i + st - 1] if run.size >= st
                             else np.sqrt(2) * scale)
        return -float(np.sqrt(np.mean(err ** 2))) / scale

    return score


def select_spectrum_model(series, delay, *, steps=STEP_GRID, spans=SPAN_GRID,
                          n_neighbors=NEIGHBOUR_GRID, ridge=SPECTRUM_RIDGE_GRID,
                          horizon=None, max_window=MAX_WINDOW, n_runs=N_RUNS_SCORED,
                          theiler_window=2, random_state=0, n_jobs=None):
    """Time scale, window, neighbours and ridge of the spectrum model, from the data alone.

    The Lyapunov exponents of a local linear delay model depend on how well
    its local Jacobians reproduce the growth of small differences.  One-step
    forecasts hardly test that (they are made from the true state), so each
    setting is scored by its **free runs from the true history** on the later
    folds of a ``TimeSeriesSplit``: the RMS error at a quarter, half, three
    quarters and all of ``horizon`` samples, normalised by the series' std.
    Errors of the local Jacobians compound along such a run, so a model whose
    Jacobians stretch too much (or too little) drifts away from the data
    sooner.  Settings of different ``step`` are scored at the same horizons in
    samples, hence comparable.  For each ``step``, scikit-learn's
    ``GridSearchCV`` runs on the pipeline ``TwoWindowEmbedding ->
    LocalLinearDelayMap`` of the series sampled every ``step`` samples (grid:
    window length ``m`` for each span, ``n_neighbors``, ``ridge``); the best
    over all steps is returned.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
    delay : int
        Feedback delay in samples (the dip of the delay scan).
    steps : sequence of int
        Samples per model step.
    spans : sequence of float
        Window spans ``m * step`` in units of the dominant period
        (:func:`dominant_period`; in units of ``delay / 2`` when there is none).
    n_neighbors, ridge : sequence
        Neighbourhood sizes and relative ridges.
    horizon : int, default=None
        Samples of the scored free runs (default ``HORIZON_DELAYS`` delays: the
        errors of the Jacobians have been fed back through the delay loop
        once, and the runs still follow the data's phase, where an RMS error
        does not yet reward a damped model).
    max_window : int
        Largest ``m``.
    n_runs : int
        Free runs scored per test fold.
    theiler_window : int
    random_state : int
        Seeds the scored start points.
    n_jobs : int, default=None
        joblib workers of ``GridSearchCV``.

    Returns
    -------
    SpectrumModelSelection
    """
    s = _unit_scale(check_series(series, name="series", min_length=200))
    n_jobs = check_params(n_jobs=n_jobs)
    delay = check_positive_int(delay, name="delay")
    horizon = (round(HORIZON_DELAYS * delay) if horizon is None
               else check_positive_int(horizon, name="horizon"))
    period = dominant_period(s, max(2 * delay, 50))
    unit = period if period is not None else max(1, delay // 2)
    scale = float(s.std())
    rows, best, best_score = [], None, -np.inf
    for h in sorted({check_positive_int(v, name="step") for v in steps}):
        tau_h = max(1, round(delay / h))
        ms = sorted({min(max_window, max(2, round(w * unit / h))) for w in spans})
        s_h = s[::h]
        n_lags = max(required_lags(mm, tau_h) for mm in ms)
        # free-run steps of the scored horizons (at least one model step each)
        st = sorted({max(1, round(f * horizon / h)) for f in HORIZON_FRACTIONS})
        if s_h.size < 4 * (n_lags + st[-1]) + 100:
            continue
        X, y = lagged_windows(s_h, n_lags)
        pipe = Pipeline([("embedding", TwoWindowEmbedding(m=ms[0], tau=tau_h)),
                         ("model", LocalLinearDelayMap(theiler_window=theiler_window))])
        grid = {"embedding__m": ms, "model__n_neighbors": [int(k) for k in n_neighbors],
                "model__ridge": [float(r) for r in ridge]}
        search = GridSearchCV(
            pipe, grid, cv=TimeSeriesSplit(n_splits=N_SPLITS),
            scoring=_tracking_scorer(scale, n_runs, random_state, st), refit=False,
            n_jobs=n_jobs, error_score="raise")
        search.fit(X, y)
        res = search.cv_results_
        for j in range(len(res["params"])):
            p = res["params"][j]
            score = float(res["mean_test_score"][j])
            rows.append({"step": h, "m": int(p["embedding__m"]),
                         "span": h * int(p["embedding__m"]),
                         "n_neighbors": int(p["model__n_neighbors"]),
                         "ridge": float(p["model__ridge"]), "error": -score,
                         # spread of the folds' errors over sqrt(folds)
                         "error_se": float(res["std_test_score"][j]) / np.sqrt(N_SPLITS)})
            if score > best_score:
                best_score, best = score, (h, tau_h, p)
    if best is None:
        raise ValueError(f"series of {s.size} samples is too short to cross-validate free "
                         f"runs over {horizon} samples; pass a longer series or a shorter "
                         "horizon.")
    table = pd.DataFrame(rows)
    h, tau_h, p = best
    table["chosen"] = ((table["step"] == h) & (table["m"] == p["embedding__m"])
                       & (table["n_neighbors"] == p["model__n_neighbors"])
                       & (table["ridge"] == p["model__ridge"]))
    options = ModelOptions(n_neighbors=int(p["model__n_neighbors"]),
                           ridge=float(p["model__ridge"]), theiler_window=theiler_window)
    return SpectrumModelSelection(step=h, m=int(p["embedding__m"]), tau=tau_h,
                                  options=options, horizon=horizon, period=period,
                                  table=table)


def spectrum_of_selection(series, selection, *, n_exponents=20, n_steps=None, sample_dt=1.0,
                          flow=False, random_state=0, n_jobs=None):
    """Fit the selected model on the whole series and return its Lyapunov spectrum.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        The series the selection was made on (sampling step ``sample_dt``).
    selection : SpectrumModelSelection
        From :func:`select_spectrum_model`.
    n_exponents : int, default=20
        Exponents computed (at most the model's state dimension).
    n_steps : int, default=None
        Model steps along the series used (default: all).
    sample_dt : float, default=1.0
        Sampling interval of ``series``; exponents are per its time unit (the
        model's step is ``selection.step * sample_dt``).
    flow : bool, default=False
        Pin the exponent nearest zero (see :func:`skdelay.dynamics.lyapunov_spectrum`).
    random_state : int, default=0
    n_jobs : int, default=None

    Returns
    -------
    LyapunovSpectrum
    """
    from ._lyapunov import lyapunov_spectrum
    from ._model import fit_delay_model

    s = check_series(series, name="series")[::selection.step]
    model = fit_delay_model(s, selection.m, selection.tau, selection.options)
    n_exp = min(int(n_exponents), required_lags(selection.m, selection.tau))
    return lyapunov_spectrum(model, s, n_exponents=n_exp, n_steps=n_steps,
                             sample_dt=sample_dt * selection.step, flow=flow,
                             random_state=random_state, n_jobs=n_jobs)


def select_spectrum_model_staged(series, delay, *, steps=STEP_GRID, spans=SPAN_GRID,
                                 n_neighbors=NEIGHBOUR_GRID, ridge=STAGED_RIDGE_GRID,
                                 first=STAGE1_MODEL, horizon=None, n_runs=N_RUNS_SCORED,
                                 random_state=0, n_jobs=None, progress=None):
    """:func:`select_spectrum_model` in two stages: the time scale, then the fit.

    Stage 1 scores every model step and window span at one neighbourhood
    size and ridge (``first``); stage 2 scores ``n_neighbors`` x ``ridge``
    at the chosen step and span.  The full grid costs the product of both
    (8-30 minutes per delay on the embedded laser, 2 cores); the stages cost
    their sum (15-100 s).  The returned table holds both stages' rows
    (column ``stage``), the chosen one marked.

    Parameters
    ----------
    series, delay, steps, spans, n_neighbors, ridge, horizon, n_runs, random_state, n_jobs
        As in :func:`select_spectrum_model` (``ridge`` defaults to
        :data:`STAGED_RIDGE_GRID`).
    first : (int, float)
        Neighbours and ridge of stage 1.
    progress : callable, default=None
        Called with a one-line message before each stage.

    Returns
    -------
    SpectrumModelSelection

    Examples
    --------
    >>> from skdelay.model_selection import select_spectrum_model_staged
    >>> from skdelay.systems import MackeyGlass
    >>> s = MackeyGlass(tau=17.0).simulate(4000, random_state=0)
    >>> sel = select_spectrum_model_staged(s, 17, steps=(1, 2), spans=(1.0,),
    ...                                    n_neighbors=(20, 40), ridge=(1e-3, 1e-1),
    ...                                    first=(20, 1e-3), n_runs=10)
    >>> sel.step in (1, 2), sel.options.n_neighbors in (20, 40), sorted(set(sel.table.stage))
    (True, True, [1, 2])
    """
    say = progress or (lambda _msg: None)
    try:
        k1, r1 = first
    except (TypeError, ValueError):
        raise ValueError(f"first must be (n_neighbors, ridge) of stage 1, e.g. (100, 0.01); "
                         f"got {first!r}.") from None
    say(f"spectrum model, stage 1 of 2: model step and window span (k = {k1}, ridge {r1:g}), "
        f"{n_runs} free runs per fold and setting")
    one = select_spectrum_model(series, delay, steps=steps, spans=spans, n_neighbors=(k1,),
                                ridge=(r1,), horizon=horizon, n_runs=n_runs,
                                random_state=random_state, n_jobs=n_jobs)
    unit = one.period if one.period is not None else max(1, int(delay) // 2)
    say(f"spectrum model, stage 2 of 2: neighbours and ridge at step {one.step}, window "
        f"m = {one.m}")
    two = select_spectrum_model(series, delay, steps=(one.step,),
                                spans=(one.m * one.step / unit,), n_neighbors=n_neighbors,
                                ridge=ridge, horizon=horizon, n_runs=n_runs,
                                random_state=random_state, n_jobs=n_jobs)
    first_rows = one.table.assign(stage=1, chosen=False)
    table = pd.concat([first_rows, two.table.assign(stage=2)], ignore_index=True)
    return SpectrumModelSelection(step=two.step, m=two.m, tau=two.tau, options=two.options,
                                  horizon=two.horizon, period=two.period, table=table)
