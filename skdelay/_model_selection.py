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

Both are normalised by the series' standard deviation; the chosen setting
minimises their sum relative to each error's best value on the grid
(``refit`` of ``GridSearchCV``), so neither error alone can dominate.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from sklearn.model_selection import GridSearchCV, TimeSeriesSplit
from sklearn.pipeline import Pipeline

from ._checks import check_positive_int, check_series
from ._embedding import TwoWindowEmbedding, required_lags
from ._iterate import iterate
from ._local_linear import LocalLinearDelayMap
from ._model import ModelOptions
from ._windows import lagged_windows

__all__ = ["PER_PARAMETER_GRID", "RIDGE_GRID", "ModelSelection", "select_model_options"]

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


def _pick(cv_results):
    """Index of the setting with the smallest sum of relative errors (GridSearchCV refit)."""
    one = -np.asarray(cv_results["mean_test_one_step"])
    few = -np.asarray(cv_results["mean_test_iterated"])
    total = one / np.min(one) + few / np.min(few)
    return int(np.argmin(total))


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
        ``one_step``, ``iterated``, ``chosen``) and ``horizon``.

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
    s = check_series(series, name="series", min_length=200)
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
    table["chosen"] = np.arange(len(table)) == search.best_index_
    best = table.loc[search.best_index_]
    options = replace(base, n_neighbors=None, per_parameter=float(best["per_parameter"]),
                      ridge=float(best["ridge"]))
    return ModelSelection(options=options, table=table, horizon=horizon)
