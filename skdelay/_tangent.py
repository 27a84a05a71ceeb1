"""Tangent dynamics of a delay map and its QR (Benettin) iteration.

The iterated two-window model ``s_{n+1} = b_n + a_n . v_n`` lives on the state
``x_n = (s_n, s_{n-1}, ..., s_{n-D+1})`` of dimension
``D = required_lags(m, tau) = max(tau + m // 2, m)`` (the second window is
centred on the delay, see :class:`skdelay.TwoWindowEmbedding`).  Its
Jacobian is a *shift* plus one new first row holding ``a_n`` at the lag
columns of ``v_n``:

    delta s_{n+1} = sum_f a_n[f] * delta s_{n - lag_f},   rows 1..D-1: shift.

So a tangent step of ``k`` vectors costs O(2m k), not O(D^2 k): the ``k``
tangent vectors are kept as the rows of a buffer (one row per lag), each step
writes one new row *above* the current block, and every ``interval`` steps the
``D x k`` block is re-orthonormalised by a QR decomposition whose
``log |R_jj|`` accumulate the exponents.  Between two QRs the block keeps
``D - interval`` rows of the previous orthonormal matrix, which keeps it well
conditioned as long as ``interval`` is a fraction of ``tau``; a QR is also
taken early whenever a tangent component grows beyond ``_GROWTH_LIMIT``
(strongly expanding local maps would otherwise wash out the weak directions).
"""

from __future__ import annotations

import numpy as np
from numba import njit

_GROWTH_LIMIT = 1e6


@njit(cache=True)
def _reflect(v, y, j):
    """Apply the Householder reflection ``I - 2 v v^T`` (``v`` zero before ``j``) to ``y``."""
    w = 0.0
    for i in range(j, v.size):
        w += v[i] * y[i]
    w *= 2.0
    for i in range(j, v.size):
        y[i] -= w * v[i]


@njit(cache=True)
def _householder_qr_rows(vec, logs_out):
    """In-place thin QR of the ``D x k`` matrix whose *columns* are the rows of ``vec``.

    ``vec`` (k, D) is overwritten by the orthonormal ``Q`` (again one column
    per row); ``logs_out[j] = log |R_jj|``.  Householder reflections, single
    threaded (a threaded LAPACK on a busy 2-core machine is several times
    slower for these skinny matrices).
    """
    k, dim = vec.shape
    refl = np.zeros((k, dim))
    for j in range(k):
        x = vec[j]
        norm = 0.0
        for i in range(j, dim):
            norm += x[i] * x[i]
        norm = np.sqrt(norm)
        logs_out[j] = np.log(norm) if norm > 1e-300 else -690.8
        v = refl[j]
        alpha = -norm if x[j] >= 0 else norm
        for i in range(j, dim):
            v[i] = x[i]
        v[j] -= alpha
        vn = 0.0
        for i in range(j, dim):
            vn += v[i] * v[i]
        if vn > 0.0:
            vn = np.sqrt(vn)
            for i in range(j, dim):
                v[i] /= vn
        for c in range(j + 1, k):
            _reflect(v, vec[c], j)
    # Q e_c = H_0 ... H_{k-1} e_c
    for c in range(k):
        y = vec[c]
        for i in range(dim):
            y[i] = 0.0
        y[c] = 1.0
        for j in range(min(c, k - 1), -1, -1):
            _reflect(refl[j], y, j)


# Explicit loops rather than slice assignments (``buf[:, a:] = q0``): numba compiles a slice
# assignment with its shape-mismatch error message, whose string formatting took 5.5 of the
# 9.8 s that _qr_iteration took to compile (numba 0.68.1, cold cache, in-process profile;
# benchmarks/cold_compile.py: 7.7-8.5 -> 2.7-2.9 s) -- in every fresh process that computes
# a spectrum.  The copies are the same (bit-identical output).
@njit(cache=True, inline="always")
def _copy_rows(src, src_col, dst, dst_col, width):
    """``dst[:, dst_col:dst_col + width] = src[:, src_col:src_col + width]``."""
    for j in range(src.shape[0]):
        for i in range(width):
            dst[j, dst_col + i] = src[j, src_col + i]


@njit(cache=True)
def _qr_iteration(jac, lags, q0, interval):
    """Run the tangent QR iteration over the Jacobian rows ``jac``.

    Parameters
    ----------
    jac : (n_steps, n_features) float64
        ``a_n`` for every step.
    lags : (n_features,) int64
        Lag (0 = most recent) that each feature of ``v_n`` reads.
    q0 : (k, D) float64
        Orthonormal initial tangent vectors, one per row (entries = lags 0..D-1).
    interval : int
        Steps between re-orthonormalisations (``1 <= interval``).

    Returns
    -------
    logs : (n_qr, k) float64
        ``log |R_jj|`` of each QR.
    ends : (n_qr,) int64
        Number of steps done when each QR was taken.
    """
    n_steps, n_feat = jac.shape
    k, dim = q0.shape
    n_qr = n_steps // interval + 2
    buf = np.zeros((k, dim + interval))
    _copy_rows(q0, 0, buf, interval, dim)
    top = interval
    logs = np.zeros((n_qr, k))
    ends = np.zeros(n_qr, dtype=np.int64)
    block = np.empty((k, dim))
    iq = 0
    for t in range(n_steps):
        src = top
        top -= 1
        big = 0.0
        for j in range(k):
            acc = 0.0
            for f in range(n_feat):
                acc += jac[t, f] * buf[j, src + lags[f]]
            buf[j, top] = acc
            big = max(big, abs(acc))
        if top == 0 or t == n_steps - 1 or big > _GROWTH_LIMIT:
            if iq == logs.shape[0]:
                grown = np.zeros((2 * iq, k))
                grown_ends = np.zeros(2 * iq, dtype=np.int64)
                for r in range(iq):
                    grown_ends[r] = ends[r]
                    for j in range(k):
                        grown[r, j] = logs[r, j]
                logs = grown
                ends = grown_ends
            _copy_rows(buf, top, block, 0, dim)
            _householder_qr_rows(block, logs[iq])
            ends[iq] = t + 1
            iq += 1
            _copy_rows(block, 0, buf, interval, dim)
            top = interval
    return logs[:iq], ends[:iq]


def tangent_qr(jac, lags, dim, n_exponents, *, interval=None, random_state=None):
    """Log-stretching factors of the ``n_exponents`` leading tangent directions.

    Returns ``(logs, ends)`` as :func:`_qr_iteration`; ``interval`` defaults
    to ``max(1, min(dim // 2, 64))``.
    """
    jac = np.ascontiguousarray(jac, dtype=np.float64)
    lags = np.ascontiguousarray(lags, dtype=np.int64)
    if jac.ndim != 2 or jac.shape[1] != lags.size:
        raise ValueError("jac must be (n_steps, n_features) with one lag per feature.")
    if lags.min() < 0 or lags.max() >= dim:
        raise ValueError(f"lags must lie in [0, {dim - 1}], got {lags.min()}..{lags.max()}.")
    if not 1 <= n_exponents <= dim:
        raise ValueError(f"n_exponents must be in [1, {dim}], got {n_exponents}.")
    if interval is None:
        interval = max(1, min(dim // 2, 64))
    rng = np.random.default_rng(random_state)
    q0, _ = np.linalg.qr(rng.standard_normal((dim, n_exponents)))
    return _qr_iteration(jac, lags, np.ascontiguousarray(q0.T), int(interval))


def exponents_from_logs(logs, ends, *, n_transient=0, n_blocks=10):
    """Exponents per step, their standard error over blocks, and the steps used.

    QR intervals ending at or before ``n_transient`` steps are discarded; the
    rest is split into ``n_blocks`` contiguous blocks of intervals whose
    per-block exponents give the standard error of the mean.
    """
    starts = np.concatenate([[0], ends[:-1]])
    keep = starts >= n_transient
    if keep.sum() < 2:
        keep = np.zeros(ends.size, dtype=bool)
        keep[ends.size // 2:] = True
    logs, starts, ends = logs[keep], starts[keep], ends[keep]
    n_used = int(ends[-1] - starts[0])
    lam = logs.sum(axis=0) / n_used
    n_blocks = int(max(2, min(n_blocks, logs.shape[0])))
    groups = np.array_split(np.arange(logs.shape[0]), n_blocks)
    block = np.array([logs[g].sum(0) / (ends[g[-1]] - starts[g[0]]) for g in groups])
    spread = block.std(axis=0, ddof=1) / np.sqrt(n_blocks)
    return lam, spread, n_used
