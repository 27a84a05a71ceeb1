"""Exact Lyapunov spectrum of the discretised DDE (tangent dynamics + QR, numba).

The RK4 scheme of :mod:`._integrate` is a map on the state
``(x_n, x_l(t_{n-1}), ..., x_l(t_{n-M}))`` of dimension ``N = d + M``
(``M ~ tau / dt``).  Its Jacobian is a shift plus one new block, so the ``k``
tangent vectors are stored exactly like the trajectory: a current part
``V`` (k, d) and a ring buffer ``W`` (k, M) of past ``delta x_l``.  A step
costs O(k d^2) (the linearised RK4 stages), not O(N^2); every ``qr_every``
steps the ``N x k`` block is re-orthonormalised by modified Gram-Schmidt in
place (inner products do not care about the ring's rotation), and the logs of
the norms accumulate the exponents (Benettin et al. 1980; Farmer 1982).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._jit import stack_array
from ._integrate import (
    delayed,
    next_slot,
    ring_stages,
    rk4_update,
    state_array,
    system_jac,
)


@njit(cache=True)
def _gram_schmidt(V, W, logsum, accumulate):
    k = V.shape[0]
    for i in range(k):
        for j in range(i):
            dot = 0.0
            for q in range(V.shape[1]):
                dot += V[i, q] * V[j, q]
            for q in range(W.shape[1]):
                dot += W[i, q] * W[j, q]
            for q in range(V.shape[1]):
                V[i, q] -= dot * V[j, q]
            for q in range(W.shape[1]):
                W[i, q] -= dot * W[j, q]
        nrm = 0.0
        for q in range(V.shape[1]):
            nrm += V[i, q] * V[i, q]
        for q in range(W.shape[1]):
            nrm += W[i, q] * W[i, q]
        nrm = np.sqrt(nrm)
        if not (nrm > 0.0 and np.isfinite(nrm)):
            return False
        if accumulate:
            logsum[i] += np.log(nrm)
        inv = 1.0 / nrm
        for q in range(V.shape[1]):
            V[i, q] *= inv
        for q in range(W.shape[1]):
            W[i, q] *= inv
    return True


@njit(cache=True)
def orthonormalise(V, W):
    """Orthonormalise the rows of ``[V | W]`` in place (no accumulation)."""
    return _gram_schmidt(V, W, np.zeros(V.shape[0]), False)


@njit(cache=True)
def tangent_run(tag, x, ring, counter, l, p, dt, starts, weights, V, W, n_qr, qr_every,
                logsum, accumulate):
    """Advance trajectory and ``k`` tangent vectors by ``n_qr * qr_every`` RK4 steps.

    ``starts`` (3,) / ``weights`` (3, 4) are the interpolation stencils of the
    delayed value at the stage offsets 0, 1/2, 1 (see
    :func:`._integrate.stencil`); ``ring`` (M,) and ``W`` (k, M) hold the
    history of ``x_l`` and of its tangent components, slot ``m % M`` for step
    ``m``.  ``logsum`` (k,) accumulates the log growth (when ``accumulate``).
    Returns False if the run became non-finite.
    """
    d = x.shape[0]
    k_vec = V.shape[0]
    m_ring = ring.shape[0]
    # the stages on the stack, where the compiler keeps them in registers (see
    # skdelay.systems._integrate._advance); the Jacobians stay on the heap
    ks = state_array(tag, 4)
    xs = state_array(tag, 4)
    jx = np.empty((4, d, d))
    jd = state_array(tag, 4)
    dks = state_array(tag, 4)
    dx = state_array(tag, 1)[0]
    xd = stack_array(1, 4, np.float64)[0]
    ddel = stack_array(1, 4, np.float64)[0]
    n = counter[0]
    slot = n % m_ring
    for _ in range(n_qr):
        for _ in range(qr_every):
            ring_stages(tag, x, ring, slot, l, starts, weights, p, dt, ks, xs, xd)
            if k_vec > 0:
                for s in range(4):
                    system_jac(tag, xs[s], xd[s], p, jx[s], jd[s])
            for v in range(k_vec):
                cv = V[v, l]
                Wv = W[v]
                ddel[0] = delayed(cv, Wv, slot, starts, weights, 0)
                ddel[1] = delayed(cv, Wv, slot, starts, weights, 1)
                ddel[2] = ddel[1]
                ddel[3] = delayed(cv, Wv, slot, starts, weights, 2)
                for s in range(4):
                    c = dt if s == 3 else 0.5 * dt
                    for i in range(d):
                        if s == 0:
                            dx[i] = V[v, i]
                        else:
                            dx[i] = V[v, i] + c * dks[s - 1, i]
                    for i in range(d):
                        acc = jd[s, i] * ddel[s]
                        for j in range(d):
                            acc += jx[s, i, j] * dx[j]
                        dks[s, i] = acc
                Wv[slot] = cv
                rk4_update(V[v], dt, dks)
            rk4_update(x, dt, ks)
            n += 1
            slot = next_slot(slot, m_ring)
        counter[0] = n
        for i in range(d):
            if not np.isfinite(x[i]):
                return False
        if k_vec > 0 and not _gram_schmidt(V, W, logsum, accumulate):
            return False
    return True
