"""Local linear (Farmer-Sidorowich) regression: the scikit-learn estimator.

A thin estimator over :mod:`skdelay._neighbours` (k-d tree queries, Theiler
exclusion, centred moments and the ridge solve live there, shared with the
delay scan and the compiled free-run loop).  Vectors and targets are
rescaled internally (:class:`~skdelay._neighbours.Standardiser`), so the
fitted maps and forecasts do not depend on the data's units or scale.
"""

from __future__ import annotations

import numbers
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils._param_validation import Interval, Options
from sklearn.utils.validation import check_is_fitted, validate_data

from ._checks import check_params
from ._neighbours import RADIUS_CAP, Standardiser, chunk_slices, fit_gathered, tree_neighbours

__all__ = ["LocalLinearDelayMap"]

#: Relative spread below which the training vectors differ only by rounding: neighbour
#: distances are then ties decided by the last bits, so no neighbourhood means anything.
MIN_RELATIVE_SPREAD = 1e-12


def _workers(n_jobs):
    return 1 if n_jobs is None else int(n_jobs)


class LocalLinearDelayMap(RegressorMixin, BaseEstimator):
    """Local linear (or local constant) regressor for delay vectors.

    For each query ``v`` the map ``y = b + a . v`` is fitted by least
    squares on the neighbourhood of ``v`` among the training vectors (the
    Farmer-Sidorowich local linear predictor used by Buenner et al.).  Fits
    are centred on the neighbourhood mean and ridge-regularised relative to
    the neighbourhood's own scale, so degenerate neighbourhoods (duplicated
    columns, a flat patch, fewer points than dimensions) never fail.

    Parameters
    ----------
    n_neighbors : int, default=30
        Neighbourhood size ``k`` (clipped to the number of training rows).
    radius : float, default=None
        If given, use every training point within this Euclidean distance
        (at most ``10 * n_neighbors`` of the nearest) and fall back to the
        ``n_neighbors`` nearest when fewer lie inside.
    order : {1, 0}, default=1
        1: local linear; 0: local constant (neighbourhood mean, ``A = 0``).
    ridge : float, default=1e-3
        Ridge parameter relative to the mean eigenvalue of the centred
        neighbourhood covariance.
    theiler_window : int, default=0
        When ``query_index`` is passed to ``predict``/``local_maps``,
        training rows ``j`` with ``|j - query_index[i]| <= theiler_window`` are
        not used for query ``i`` (0 = leave-one-out).
    n_jobs : int, default=None
        Threads of the k-d tree queries (``cKDTree(..., workers=n_jobs)``);
        None means 1, -1 all cores.

    Attributes
    ----------
    n_features_in_ : int
        Dimension ``p`` of the training vectors.
    fit_X_ : ndarray of shape (n_rows, p)
        Training vectors (the neighbour database).
    fit_y_ : ndarray of shape (n_rows,)
        Training targets.
    x_scaler_, y_scaler_ : Standardiser
        Power-of-two rescaling of the vectors and of the targets; the fits run
        on rescaled values, so results do not depend on the data's scale.

    See Also
    --------
    TwoWindowEmbedding : builds the vectors ``v`` from a lag matrix.
    DelaySelectorCV : scans ``(m, tau)`` with this model.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import LocalLinearDelayMap
    >>> rng = np.random.default_rng(0)
    >>> V = rng.uniform(-1, 1, size=(500, 2))
    >>> y = np.sin(V[:, 0]) + V[:, 1] ** 2
    >>> model = LocalLinearDelayMap(n_neighbors=20).fit(V, y)
    >>> bool(np.abs(model.predict(V[:5]) - y[:5]).max() < 0.02)
    True
    >>> A, b = model.local_maps(V[:1])
    >>> A.shape, b.shape
    ((1, 2), (1,))
    """

    _parameter_constraints: ClassVar[dict] = {
        "n_neighbors": [Interval(numbers.Integral, 1, None, closed="left")],
        "radius": [Interval(numbers.Real, 0, None, closed="neither"), None],
        "order": [Options(numbers.Integral, {0, 1})],
        "ridge": [Interval(numbers.Real, 0, None, closed="left")],
        "theiler_window": [Interval(numbers.Integral, 0, None, closed="left")],
        # 0 is refused by check_params (with what to pass instead)
        "n_jobs": [numbers.Integral, None],
    }

    def __init__(self, n_neighbors=30, *, radius=None, order=1, ridge=1e-3, theiler_window=0,
                 n_jobs=None):
        self.n_neighbors = n_neighbors
        self.radius = radius
        self.order = order
        self.ridge = ridge
        self.theiler_window = theiler_window
        self.n_jobs = n_jobs

    def fit(self, X, y):
        """Store the training vectors and build the k-d tree.

        Parameters
        ----------
        X : array-like of shape (n_rows, p)
            Training vectors (e.g. ``TwoWindowEmbedding().fit_transform(X)``).
        y : array-like of shape (n_rows,)
            Next values.

        Returns
        -------
        self : LocalLinearDelayMap
        """
        self._validate_params()
        check_params(n_jobs=self.n_jobs)
        X, y = validate_data(self, X, y, y_numeric=True, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        self.fit_X_ = X
        self.fit_y_ = y
        self.x_scaler_ = Standardiser.fit(X)
        self.y_scaler_ = Standardiser.fit(y)
        if 0 < self.x_scaler_.relative_spread < MIN_RELATIVE_SPREAD:
            raise ValueError(
                "the training vectors differ only in their last bits (relative spread "
                f"{self.x_scaler_.relative_spread:.1e}): neighbours cannot be told apart. "
                "Remove the offset (subtract the mean) before fitting."
            )
        self._Xs = np.ascontiguousarray(self.x_scaler_.forward(X))
        self._ys = self.y_scaler_.forward(y)
        self._tree = cKDTree(self._Xs)
        return self

    def database(self):
        """The neighbour database in rescaled units: ``(vectors, targets)``.

        Both in the units of the rescaled *vectors* (``x_scaler_``), so a
        delay map can be iterated on rescaled values of one series.
        """
        check_is_fitted(self)
        return self._Xs, np.ascontiguousarray(self.x_scaler_.forward(self.fit_y_))

    def _maps(self, X, query_index, n_jobs=None):
        check_is_fitted(self)
        self._validate_params()  # set_params may have changed them since fit
        X = validate_data(self, X, dtype=np.float64, reset=False)
        n, p = X.shape
        if query_index is not None:
            query_index = np.asarray(query_index)
            if query_index.shape != (n,) or not np.issubdtype(query_index.dtype, np.integer):
                raise ValueError(
                    f"query_index must be an integer array of shape ({n},) giving each query's "
                    f"row in the training data, got shape {query_index.shape} and dtype "
                    f"{query_index.dtype}."
                )
        sx, sy = self.x_scaler_, self.y_scaler_
        Xs = sx.forward(X)
        radius = None if self.radius is None else self.radius / sx.scale
        k_cap = min(self.n_neighbors * (RADIUS_CAP if self.radius else 1), self._tree.n)
        A = np.empty((n, p))
        b = np.empty(n)
        pred = np.empty(n)
        for sl in chunk_slices(n, k_cap * max(p, 1)):
            pos, weight = tree_neighbours(
                self._tree, Xs[sl], self.n_neighbors, radius=radius,
                query_ids=None if query_index is None else query_index[sl],
                theiler_window=self.theiler_window,
                workers=_workers(self.n_jobs if n_jobs is None else n_jobs))
            # C order whatever the caller's layout: one compiled signature, not one per layout
            A[sl], b[sl], pred[sl] = fit_gathered(
                np.ascontiguousarray(Xs[sl]), self._Xs[pos], self._ys[pos],
                weight.astype(np.float64),
                float(self.ridge), int(self.order), 0.0)
        # back to the original units (exact: both scales are powers of two)
        return A * (sy.scale / sx.scale), sy.inverse(b), sy.inverse(pred)

    def predict(self, X, *, query_index=None):
        """One-step forecasts ``b_i + a_i . v_i``.

        Parameters
        ----------
        X : array-like of shape (n, p)
            Query vectors.
        query_index : array-like of int, shape (n,), default=None
            Row of each query in the training data; enables the Theiler
            exclusion (in-sample forecasts without the point itself).

        Returns
        -------
        y_pred : ndarray of shape (n,)
        """
        return self._maps(X, query_index)[2]

    def local_maps(self, X, *, query_index=None, n_jobs=None):
        """Local affine maps at the query points.

        Parameters
        ----------
        X : array-like of shape (n, p)
            Query vectors.
        query_index : array-like of int, shape (n,), default=None
            As in :meth:`predict`.
        n_jobs : int, default=None
            Threads of the neighbour queries for this call (default: the
            estimator's ``n_jobs``).

        Returns
        -------
        A : ndarray of shape (n, p)
            Local gradients (zeros for ``order=0``).
        b : ndarray of shape (n,)
            Offsets; the forecast is ``b + (A * X).sum(1)``.
        """
        A, b, _ = self._maps(X, query_index, n_jobs)
        return A, b
