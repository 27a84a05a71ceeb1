"""Unpack a fitted two-window model into its embedding parameters and local map."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.pipeline import Pipeline, make_pipeline
from sklearn.utils.validation import check_is_fitted

from ._embedding import TwoWindowEmbedding, required_lags, two_window_columns
from ._local_linear import LocalLinearDelayMap
from ._windows import lagged_windows


@dataclass(frozen=True)
class DelayModel:
    """A fitted two-window model: ``(m, tau)`` of its embedding and its regressor."""

    embedding: TwoWindowEmbedding
    regressor: object
    m: int
    tau: int

    def lags(self, tau=None):
        """Lags read by ``v_n`` when iterated with delay ``tau`` (default: fitted)."""
        return two_window_columns(self.m, self.tau if tau is None else tau)

    def state_dim(self, tau=None):
        """Dimension of the iterated map's state (= number of Lyapunov exponents)."""
        return required_lags(self.m, self.tau if tau is None else tau)


def resolve_model(model):
    """Return a :class:`DelayModel` for a fitted Pipeline, ``(embedding, map)`` pair or search.

    Accepted: ``Pipeline([TwoWindowEmbedding, LocalLinearDelayMap])``, a tuple
    ``(embedding, fitted map)``, or anything with a ``best_estimator_`` that
    is one of those (e.g. a fitted ``DelaySelectorCV``).
    """
    if hasattr(model, "best_estimator_"):
        model = model.best_estimator_
    if isinstance(model, Pipeline):
        steps = [step for _, step in model.steps if step not in (None, "passthrough")]
    elif isinstance(model, (tuple, list)):
        steps = list(model)
    else:
        raise TypeError(
            "model must be a fitted Pipeline(TwoWindowEmbedding, LocalLinearDelayMap) or an "
            f"(embedding, map) pair, got {type(model).__name__}."
        )
    if (len(steps) != 2 or not isinstance(steps[0], TwoWindowEmbedding)
            or not hasattr(steps[1], "local_maps")):
        names = [type(s).__name__ for s in steps]
        raise TypeError(
            "model must consist of exactly a TwoWindowEmbedding followed by a local map with "
            f"local_maps() (e.g. LocalLinearDelayMap); got steps {names}."
        )
    emb, reg = steps
    check_is_fitted(reg, ["fit_X_", "fit_y_"])
    m, tau = int(emb.m), int(emb.tau)
    if reg.fit_X_.shape[1] != 2 * m:
        raise ValueError(
            f"the map was fitted on {reg.fit_X_.shape[1]} features but TwoWindowEmbedding(m={m}) "
            f"gives {2 * m}; fit the embedding and the map together."
        )
    return DelayModel(emb, reg, m, tau)


def self_query_index(reg, V, *, n_probe=16, random_state=0):
    """Rows of ``reg.fit_X_`` that the rows of ``V`` are, if ``V`` is (a shift of) them.

    Returns ``offset + arange(len(V))`` when ``V[i] == fit_X_[i + offset]`` on
    random probes (the model was fitted on the same series, possibly with
    more lag columns), else ``None``.
    """
    data = reg.fit_X_
    n = V.shape[0]
    if n == 0 or data.shape[1] != V.shape[1]:
        return None
    rng = np.random.default_rng(random_state)
    j0 = n // 2
    hits = np.flatnonzero(np.all(data == V[j0], axis=1))
    probe = rng.integers(0, n, size=n_probe)
    for hit in hits[:8]:
        offset = int(hit) - j0
        rows = probe + offset
        ok = (rows >= 0) & (rows < data.shape[0])
        if ok.sum() >= n_probe // 2 and np.array_equal(data[rows[ok]], V[probe[ok]]):
            return np.arange(n) + offset
    return None


@dataclass(frozen=True)
class ModelOptions:
    """Settings of the local linear delay models that an analysis fits.

    ``n_neighbors=None`` means ``per_parameter * (2 m + 1)`` points per
    neighbourhood (the local affine map has ``2 m + 1`` parameters), so one
    setting serves every ``m``.  The default 4 points per parameter averages
    measurement noise out of the fit while keeping the neighbourhood local;
    :func:`~skdelay._model_selection.select_model_options` chooses
    ``per_parameter`` and ``ridge`` by time-series cross-validation instead.
    """

    n_neighbors: int | None = None
    ridge: float = 1e-3
    theiler_window: int = 2
    per_parameter: float = 4.0

    def neighbours(self, m):
        """Neighbourhood size for window length ``m``."""
        if self.n_neighbors is not None:
            return int(self.n_neighbors)
        return max(2 * m + 2, round(self.per_parameter * (2 * m + 1)))


def fit_delay_model(series, m, tau, options=None):
    """Fit ``Pipeline(TwoWindowEmbedding(m, tau), LocalLinearDelayMap)`` on one series.

    The one place where the analysis, the faithful-model search and the demo
    fit their models (so each ``(m, tau)`` model is fitted once per analysis).
    """
    options = ModelOptions() if options is None else options
    X, y = lagged_windows(series, required_lags(m, tau))
    model = make_pipeline(
        TwoWindowEmbedding(m=m, tau=tau),
        LocalLinearDelayMap(n_neighbors=options.neighbours(m), ridge=options.ridge,
                            theiler_window=options.theiler_window),
    )
    return model.fit(X, y)
