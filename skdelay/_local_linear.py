"""Local linear (Farmer-Sidorowich) regression with batched neighbourhood fits.

Every query point gets its own affine map ``y = b + a . v`` fitted by
least squares on its neighbourhood.  All fits of a chunk of queries are done
at once: neighbours are gathered into a (chunk, k, p) array, centred, and the
(chunk, p, p) stacked normal equations are solved by one ``np.linalg.solve``
call -- there is no Python loop over points.
"""

from __future__ import annotations

import numbers

import numpy as np
from numba import njit
from scipy.spatial import cKDTree
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, validate_data

__all__ = ["LocalLinearDelayMap"]

_RADIUS_CAP = 10  # radius neighbourhoods hold at most this many times n_neighbors points
_CHUNK_VALUES = 1 << 21  # size of the (chunk, k, p) gather that one batch may hold


@njit(cache=True)
def _centred_moments(Vn, yn, w):
    """Weighted means and centred normal equations of every neighbourhood (one pass)."""
    n, k, p = Vn.shape
    mu = np.zeros((n, p))
    ybar = np.zeros(n)
    G = np.zeros((n, p, p))
    rhs = np.zeros((n, p))
    wsum = np.zeros(n)
    d = np.empty(p)
    for i in range(n):
        ws = 0.0
        for j in range(k):
            wj = w[i, j]
            if wj != 0.0:
                ws += wj
                ybar[i] += wj * yn[i, j]
                for a in range(p):
                    mu[i, a] += wj * Vn[i, j, a]
        wsum[i] = ws
        if ws == 0.0:
            continue
        ybar[i] /= ws
        for a in range(p):
            mu[i, a] /= ws
        for j in range(k):
            wj = w[i, j]
            if wj == 0.0:
                continue
            dy = wj * (yn[i, j] - ybar[i])
            for a in range(p):
                d[a] = Vn[i, j, a] - mu[i, a]
            for a in range(p):
                rhs[i, a] += d[a] * dy
                wa = wj * d[a]
                for b in range(a + 1):
                    G[i, a, b] += wa * d[b]
        for a in range(p):
            for b in range(a):
                G[i, b, a] = G[i, a, b]
    return mu, ybar, G, rhs, wsum


def local_affine(Vq, Vn, yn, weight, *, order=1, ridge=1e-3, fallback=0.0):
    """Fit one affine map per query on its neighbourhood (batched).

    Parameters
    ----------
    Vq : ndarray (n, p)
        Query vectors.
    Vn : ndarray (n, k, p)
        Neighbour vectors of each query.
    yn : ndarray (n, k)
        Neighbour targets.
    weight : ndarray (n, k) of bool or float
        Neighbour weights (0 = unused slot).
    order : {0, 1}
        0 = neighbourhood mean, 1 = local linear.
    ridge : float
        Ridge on the centred normal equations, relative to their mean
        eigenvalue ``trace(G) / p`` (scale free); a tiny floor keeps
        degenerate neighbourhoods solvable.
    fallback : float
        Prediction for queries without any neighbour.

    Returns
    -------
    A : ndarray (n, p)
    b : ndarray (n,)
    pred : ndarray (n,)
        ``b + A . Vq`` evaluated in the centred, better conditioned form.
    """
    moments = _centred_moments(np.ascontiguousarray(Vn, dtype=np.float64),
                               np.ascontiguousarray(yn, dtype=np.float64),
                               np.ascontiguousarray(weight, dtype=np.float64))
    return solve_moments(Vq, *moments, order=order, ridge=ridge, fallback=fallback)


def solve_moments(Vq, mu, ybar, G, rhs, wsum, *, order=1, ridge=1e-3, fallback=0.0):
    """Affine maps from centred neighbourhood moments (see :func:`local_affine`).

    Solves the stacked, ridge-regularised normal equations ``G a = rhs`` of a
    whole batch with one ``np.linalg.solve`` call; modifies ``G`` and ``ybar``.
    """
    n, p = mu.shape
    empty = wsum == 0
    ybar[empty] = fallback
    A = np.zeros((n, p))
    if order == 0 or p == 0:
        return A, ybar, ybar.copy()
    scale = np.trace(G, axis1=1, axis2=2) / p
    lam = max(float(ridge), 1e-12) * scale
    lam[~(scale > 0)] = 1.0  # all neighbours coincide: rhs is 0, so a = 0
    diag = np.arange(p)
    G[:, diag, diag] += lam[:, None]
    A = np.linalg.solve(G, rhs[..., None])[..., 0]
    A[empty] = 0.0
    b = ybar - np.einsum("np,np->n", A, mu)
    pred = ybar + np.einsum("np,np->n", A, Vq - mu)
    return A, b, pred


def tree_neighbours(tree, Xq, n_neighbors, *, radius=None, query_ids=None, fit_ids=None,
                    theiler_window=0, workers=1):
    """Neighbour positions and weights for a chunk of queries.

    k-NN, or all points within ``radius`` (at most ``_RADIUS_CAP * k`` of the
    nearest) with a k-NN fallback when fewer than ``k`` lie inside.  With
    ``query_ids``, points whose id (``fit_ids``, default: tree position) lies
    within ``theiler_window`` of the query's id are excluded.

    Returns
    -------
    pos : ndarray (n, kk) of int
        Positions in the tree's data.
    weight : ndarray (n, kk) of bool
        Which slots are used.
    """
    n_fit = tree.n
    k = min(int(n_neighbors), n_fit)
    excl = 0 if query_ids is None else 2 * int(theiler_window) + 1
    kq = min(n_fit, (k if radius is None else _RADIUS_CAP * k) + excl)
    dist, pos = tree.query(Xq, k=kq, workers=workers)
    dist = dist.reshape(len(Xq), kq)
    pos = pos.reshape(len(Xq), kq)
    valid = np.ones(pos.shape, dtype=bool)
    if query_ids is not None:
        ids = pos if fit_ids is None else fit_ids[pos]
        valid = np.abs(ids - np.asarray(query_ids)[:, None]) > theiler_window
    if radius is None:
        keep = np.argsort(~valid, axis=1, kind="stable")[:, :k]
        return np.take_along_axis(pos, keep, 1), np.take_along_axis(valid, keep, 1)
    rank = np.cumsum(valid, axis=1)
    weight = valid & ((dist <= radius) | (rank <= k))
    used = np.flatnonzero(weight.any(axis=0))
    last = used[-1] + 1 if used.size else 1
    return pos[:, :last], weight[:, :last]


def _check_params(est):
    k = est.n_neighbors
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, numbers.Integral) or k < 1:
        raise ValueError(f"n_neighbors must be a positive integer, got {k!r}.")
    if est.order not in (0, 1):
        raise ValueError(f"order must be 0 (local constant) or 1 (local linear), got {est.order!r}.")
    if not isinstance(est.ridge, numbers.Real) or not est.ridge >= 0:
        raise ValueError(f"ridge must be a non-negative number, got {est.ridge!r}.")
    if est.radius is not None and (not isinstance(est.radius, numbers.Real) or not est.radius > 0):
        raise ValueError(f"radius must be None or a positive number, got {est.radius!r}.")
    w = est.theiler_window
    if isinstance(w, (bool, np.bool_)) or not isinstance(w, numbers.Integral) or w < 0:
        raise ValueError(f"theiler_window must be a non-negative integer, got {w!r}.")


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
        _check_params(self)
        X, y = validate_data(self, X, y, y_numeric=True, dtype=np.float64)
        self.fit_X_ = X
        self.fit_y_ = np.asarray(y, dtype=np.float64)
        self._tree = cKDTree(X)
        self._y_mean = float(self.fit_y_.mean())
        return self

    def _maps(self, X, query_index):
        check_is_fitted(self)
        _check_params(self)
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
        k_cap = min(self.n_neighbors * (_RADIUS_CAP if self.radius else 1), self._tree.n)
        chunk = max(1, _CHUNK_VALUES // max(1, k_cap * max(p, 1)))
        A = np.empty((n, p))
        b = np.empty(n)
        pred = np.empty(n)
        for lo in range(0, n, chunk):
            sl = slice(lo, min(n, lo + chunk))
            pos, weight = tree_neighbours(
                self._tree, X[sl], self.n_neighbors, radius=self.radius,
                query_ids=None if query_index is None else query_index[sl],
                theiler_window=self.theiler_window, workers=_workers(self.n_jobs))
            A[sl], b[sl], pred[sl] = local_affine(
                X[sl], self.fit_X_[pos], self.fit_y_[pos], weight, order=self.order,
                ridge=self.ridge, fallback=self._y_mean)
        return A, b, pred

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

    def local_maps(self, X, *, query_index=None):
        """Local affine maps at the query points.

        Parameters
        ----------
        X : array-like of shape (n, p)
            Query vectors.
        query_index : array-like of int, shape (n,), default=None
            As in :meth:`predict`.

        Returns
        -------
        A : ndarray of shape (n, p)
            Local gradients (zeros for ``order=0``).
        b : ndarray of shape (n,)
            Offsets; the forecast is ``b + (A * X).sum(1)``.
        """
        A, b, _ = self._maps(X, query_index)
        return A, b
