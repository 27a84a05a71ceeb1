"""Unpack a fitted two-window model into its embedding parameters and local map."""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
from sklearn.pipeline import Pipeline
from sklearn.utils.validation import check_is_fitted

from ._embedding import TwoWindowEmbedding, required_lags, two_window_columns

_GUARDS = weakref.WeakKeyDictionary()


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


def support_guard(reg, *, distance_factor, range_margin):
    """The (cached) :class:`~skdelay._iterate.SupportGuard` of a fitted map."""
    from ._iterate import SupportGuard

    data = reg.fit_X_
    key = (id(data), data.shape, data[0].tobytes(), data[-1].tobytes(),
           float(distance_factor), float(range_margin))
    try:
        cached = _GUARDS.get(reg)
    except TypeError:  # not weak-referenceable
        cached = None
    if cached is not None and cached[0] == key:
        return cached[1]
    if hasattr(reg, "database"):
        data, targets = reg.database()
        scaler = reg.x_scaler_
    else:  # a duck-typed local map without standardisation
        data, targets, scaler = reg.fit_X_, reg.fit_y_, None
    guard = SupportGuard(data, targets, distance_factor=distance_factor,
                         range_margin=range_margin, scaler=scaler)
    try:
        _GUARDS[reg] = (key, guard)
    except TypeError:
        pass
    return guard
