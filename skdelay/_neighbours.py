"""Neighbourhoods and local affine fits: the one home of the Farmer-Sidorowich fit.

Every local linear (or local constant) forecast in skdelay -- the estimator
:class:`~skdelay.LocalLinearDelayMap`, the sigma_m(tau) delay scan, the
compiled free runs and the Jacobians of the Lyapunov spectra -- goes through
the compiled kernels of this module:

* :func:`neighbourhood_moments` -- weighted mean and *centred* normal
  equations of one neighbourhood (two passes: the centring keeps the normal
  equations well conditioned when the data sit far from the origin);
* :func:`ridge_solve` -- the ridge rule (``max(ridge, RIDGE_FLOOR) * trace(G) / p``,
  relative to the neighbourhood's own scale, so it is unit free) and an
  in-place Cholesky solve;
* :func:`fit_neighbourhood` -- both, plus the forecast ``ybar + a . (v - mu)``;
* :func:`fit_gathered` / :func:`fit_from_series` -- a batch of fits on
  gathered neighbour arrays, or read straight from a 1-D series at given lag
  columns (the scan never builds the ``(n, k, 2m)`` neighbour array);
* :func:`tree_neighbours` -- k-NN / radius neighbourhoods from a scipy k-d
  tree with the Theiler exclusion (:func:`theiler_keep`).

Guarantees: for the same neighbours the four entry points give the same
affine map to rounding (one code path); a neighbourhood without any point
gives the ``fallback`` prediction and ``a = 0``; a neighbourhood whose points
coincide gives ``a = 0`` (its covariance has no scale to regularise against).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "CHUNK_VALUES",
    "RADIUS_CAP",
    "RIDGE_FLOOR",
    "Standardiser",
    "chunk_slices",
    "fit_from_series",
    "fit_gathered",
    "fit_neighbourhood",
    "neighbourhood_moments",
    "ridge_solve",
    "theiler_keep",
    "tree_neighbours",
]

#: Radius neighbourhoods hold at most this many times ``n_neighbors`` points: a radius
#: chosen for the sparse parts of an attractor would otherwise pull in tens of thousands
#: of points in its dense parts (cost and memory grow with the neighbourhood).
RADIUS_CAP = 10
#: Values one gathered batch of neighbours may hold (``chunk * k * p``): 2**21 doubles
#: = 16 MB keeps a batch in the last-level cache of common CPUs and memory flat.
CHUNK_VALUES = 1 << 21
#: Smallest relative ridge: keeps the normal equations of a neighbourhood with
#: fewer points than dimensions (or duplicated columns) positive definite.
RIDGE_FLOOR = 1e-12


def chunk_slices(n, per_row):
    """Slices of ``range(n)`` whose rows hold at most :data:`CHUNK_VALUES` values each."""
    step = max(1, CHUNK_VALUES // max(1, int(per_row)))
    return [slice(lo, min(n, lo + step)) for lo in range(0, n, step)]


#: Floating-point licence of the moment sums: reassociation lets LLVM vectorise the dot
#: products over the neighbours (and contract them into fused multiply-adds); NaN and
#: infinity keep their IEEE semantics.  Against the previous single pass that updated the
#: whole triangle per neighbour, 50 exponents of the tau = 400 laser model (k = 100,
#: p = 10) took 6.51 s instead of 7.47 s with one worker and 3.61 s instead of 4.83 s with
#: two, same exponents (``python benchmarks/lyapunov_speed.py --baseline b52e4ec``,
#: benchmarks/out/lyapunov_speed.txt).
_SUMS = {"reassoc", "contract"}


@njit(cache=True, fastmath=_SUMS)
def neighbourhood_moments(Vn, yn, w, scratch):
    """Weighted mean and centred normal equations of one neighbourhood.

    ``Vn`` (k, p) neighbour vectors, ``yn`` (k,) targets, ``w`` (k,) weights
    (``>= 0``; 0 = unused slot, whose row is ignored whatever it holds).
    ``scratch`` = :func:`fit_scratch` ``(mu, G, rhs, D)``: fills ``mu`` (p,),
    the lower triangle and diagonal of ``G`` (p, p) and ``rhs`` (p,); ``D``
    (p + 1, >= k) receives the centred, ``sqrt(w)``-weighted neighbours
    (transposed, so that every entry of ``G`` is one contiguous dot product).
    Returns ``(ybar, weight_sum)``.
    """
    mu, G, rhs, D = scratch
    k, p = Vn.shape
    ws = 0.0
    ybar = 0.0
    for a in range(p):
        mu[a] = 0.0
    for j in range(k):
        wj = w[j]
        if wj != 0.0:
            ws += wj
            ybar += wj * yn[j]
            for a in range(p):
                mu[a] += wj * Vn[j, a]
    if ws == 0.0:
        return 0.0, 0.0
    ybar /= ws
    for a in range(p):
        mu[a] /= ws
    for j in range(k):
        wj = w[j]
        if wj == 0.0:
            for a in range(p + 1):
                D[a, j] = 0.0
            continue
        sw = np.sqrt(wj)
        for a in range(p):
            D[a, j] = sw * (Vn[j, a] - mu[a])
        D[p, j] = sw * (yn[j] - ybar)
    for a in range(p):
        acc = 0.0
        for j in range(k):
            acc += D[a, j] * D[p, j]
        rhs[a] = acc
        for b in range(a + 1):
            acc = 0.0
            for j in range(k):
                acc += D[a, j] * D[b, j]
            G[a, b] = acc
    return ybar, ws


@njit(cache=True)
def ridge_solve(G, rhs, ridge, a_out):
    """Solve ``(G + lam I) a = rhs`` in place (lower triangle of ``G`` used, overwritten).

    ``lam = max(ridge, RIDGE_FLOOR) * trace(G) / p``; when ``trace(G) == 0``
    (all neighbours coincide, so ``rhs == 0``) ``a = 0``.
    """
    p = rhs.size
    scale = 0.0
    for f in range(p):
        scale += G[f, f]
    scale /= max(p, 1)
    if not scale > 0.0:
        for f in range(p):
            a_out[f] = 0.0
        return
    lam = max(ridge, RIDGE_FLOOR) * scale
    for f in range(p):  # Cholesky of the lower triangle, in place
        G[f, f] += lam
        for h in range(f + 1):
            acc = G[f, h]
            for c in range(h):
                acc -= G[f, c] * G[h, c]
            if h == f:
                G[f, f] = np.sqrt(acc)
            else:
                G[f, h] = acc / G[h, h]
    for f in range(p):  # forward ...
        acc = rhs[f]
        for c in range(f):
            acc -= G[f, c] * a_out[c]
        a_out[f] = acc / G[f, f]
    for f in range(p - 1, -1, -1):  # ... and backward substitution
        acc = a_out[f]
        for c in range(f + 1, p):
            acc -= G[c, f] * a_out[c]
        a_out[f] = acc / G[f, f]


@njit(cache=True)
def fit_scratch(p, k):
    """``(mu, G, rhs, D)``: the scratch of :func:`fit_neighbourhood` for neighbourhoods of
    at most ``k`` rows of ``p`` features."""
    return np.empty(p), np.empty((p, p)), np.empty(p), np.empty((p + 1, k))


@njit(cache=True)
def neighbourhood_buffers(k, p):
    """``(Vn, yn, w, vq, scratch, a)``: one neighbourhood of ``k`` rows of ``p`` features,
    its query, the scratch of :func:`fit_neighbourhood` and its gradient output."""
    return (np.empty((k, p)), np.empty(k), np.empty(k), np.empty(p), fit_scratch(p, k),
            np.empty(p))


@njit(cache=True)
def fit_neighbourhood(Vn, yn, w, vq, ridge, order, fallback, scratch, a_out):
    """One local affine fit and its forecast at ``vq``.

    Returns ``(b, pred)`` with the gradient in ``a_out`` (zeros for
    ``order=0`` or an empty neighbourhood); ``scratch`` is :func:`fit_scratch`'s
    (its ``mu`` holds the neighbourhood's mean afterwards).
    """
    p = vq.size
    ybar, ws = neighbourhood_moments(Vn, yn, w, scratch)
    mu, G, rhs, _ = scratch
    if ws == 0.0:
        for f in range(p):
            a_out[f] = 0.0
        return fallback, fallback
    if order == 0 or p == 0:
        for f in range(p):
            a_out[f] = 0.0
        return ybar, ybar
    ridge_solve(G, rhs, ridge, a_out)
    b = ybar
    pred = ybar
    for f in range(p):
        b -= a_out[f] * mu[f]
        pred += a_out[f] * (vq[f] - mu[f])
    return b, pred


@njit(cache=True)
def fit_gathered(Vq, Vn, yn, w, ridge, order, fallback):
    """Fits of a batch: ``Vq`` (n, p), ``Vn`` (n, k, p), ``yn`` and ``w`` (n, k).

    Returns ``A`` (n, p), ``b`` (n,), ``pred`` (n,).
    """
    n, p = Vq.shape
    A = np.zeros((n, p))
    b = np.empty(n)
    pred = np.empty(n)
    scratch = fit_scratch(p, Vn.shape[1])
    for i in range(n):
        b[i], pred[i] = fit_neighbourhood(Vn[i], yn[i], w[i], Vq[i], ridge, order, fallback,
                                          scratch, A[i])
    return A, b, pred


@njit(cache=True, nogil=True)  # the exact scan's tasks may run in threads
def fit_from_series(s, q_t, nb_t, weight, cols, ridge, order, fallback):
    """Forecasts ``pred`` (n,) of ``s[q_t + 1]`` from neighbours read off the series.

    The vector of time ``t`` is ``s[t - cols]`` and its target ``s[t + 1]``;
    ``nb_t`` (n, k) neighbour times, ``weight`` (n, k) bool.  Same fit as
    :func:`fit_gathered` on ``Vn = s[nb_t[..., None] - cols]``, without
    building that array.
    """
    n, k = nb_t.shape
    p = cols.size
    pred = np.empty(n)
    Vn, yn, w, vq, scratch, a = neighbourhood_buffers(k, p)
    for i in range(n):
        for f in range(p):
            vq[f] = s[q_t[i] - cols[f]]
        for j in range(k):
            w[j] = 1.0 if weight[i, j] else 0.0
            t = nb_t[i, j]
            yn[j] = s[t + 1]
            for f in range(p):
                Vn[j, f] = s[t - cols[f]]
        _, pred[i] = fit_neighbourhood(Vn, yn, w, vq, ridge, order, fallback, scratch, a)
    return pred


def theiler_keep(ids, query_ids, theiler_window):
    """Boolean mask of candidate ``ids`` (n, k) farther than the window from their query."""
    return np.abs(ids - np.asarray(query_ids)[:, None]) > theiler_window


def tree_neighbours(tree, Xq, n_neighbors, *, radius=None, query_ids=None, fit_ids=None,
                    theiler_window=0, workers=1):
    """Neighbour positions and weights for a chunk of queries.

    k-NN, or all points within ``radius`` (at most ``RADIUS_CAP * k`` of the
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
    kq = min(n_fit, (k if radius is None else RADIUS_CAP * k) + excl)
    dist, pos = tree.query(Xq, k=kq, workers=workers)
    dist = dist.reshape(len(Xq), kq)
    pos = pos.reshape(len(Xq), kq)
    valid = pos < n_fit  # scipy marks missing neighbours with index n
    if query_ids is not None:
        ids = pos if fit_ids is None else fit_ids[np.minimum(pos, n_fit - 1)]
        valid &= theiler_keep(ids, query_ids, theiler_window)
    pos = np.minimum(pos, n_fit - 1)
    if radius is None:
        keep = np.argsort(~valid, axis=1, kind="stable")[:, :k]
        return np.take_along_axis(pos, keep, 1), np.take_along_axis(valid, keep, 1)
    rank = np.cumsum(valid, axis=1)
    weight = valid & ((dist <= radius) | (rank <= k))
    used = np.flatnonzero(weight.any(axis=0))
    last = used[-1] + 1 if used.size else 1
    return pos[:, :last], weight[:, :last]


class Standardiser:
    """Rescaling by a power of two fitted on some values: ``z = x / scale``.

    Neighbour searches, moment sums and QR run on rescaled values so that data
    at any scale (1e-300 .. 1e300) give the answer of unit-scale data: the
    squared distances of raw values at 1e200 overflow, at 1e-160 they
    underflow.  ``scale`` is the power of two nearest the values' root mean
    square, so the rescaling is exact (no rounding) and results are those of
    the same data at unit scale.  Nothing is subtracted: a location shift
    would round away the small-scale structure of records that span many
    orders of magnitude (a growing or decaying transient), and every local
    fit is centred on its own neighbourhood anyway.  One scalar for all
    columns keeps Euclidean distances isotropic.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._neighbours import Standardiser
    >>> st = Standardiser.fit(np.array([1e300, -3e300]))
    >>> z = st.forward(np.array([1e300, -3e300]))
    >>> bool(0.5 <= np.sqrt(np.mean(z ** 2)) <= 2), bool(np.all(st.inverse(z) == [1e300, -3e300]))
    (True, True)
    """

    __slots__ = ("relative_spread", "scale")

    def __init__(self, scale=1.0, relative_spread=1.0):
        self.scale = float(scale)
        self.relative_spread = float(relative_spread)

    @classmethod
    def fit(cls, values):
        """Fit on an array of finite values.

        ``relative_spread = std / max(|mean|, std)`` (1 when constant at 0):
        about 1e-16 means the values differ only by rounding.
        """
        v = np.asarray(values, dtype=np.float64)
        mag = float(np.max(np.abs(v))) if v.size else 0.0
        if not (mag > 0 and np.isfinite(mag)):
            return cls(1.0, 1.0)
        z = v / mag  # no overflow or underflow in the moments below
        rms = float(np.sqrt(np.mean(z * z))) * mag
        mean, std = float(z.mean()), float(z.std())
        spread = std / max(abs(mean), std) if std > 0 else 0.0
        return cls(2.0 ** round(np.log2(rms)), spread)

    def forward(self, x):
        """Rescaled values of ``x`` (exact: a power of two)."""
        return np.asarray(x, dtype=np.float64) / self.scale

    def inverse(self, z):
        """Original units of rescaled values ``z``."""
        return np.asarray(z, dtype=np.float64) * self.scale

    def __repr__(self):
        return f"Standardiser(scale={self.scale!r}, relative_spread={self.relative_spread!r})"
