"""Fixed-step RK4 integration of a DDE with one delayed component (numba).

The generic engine for every system of :mod:`skdelay.systems`.  A system is
``dx/dt = f(x(t), x_l(t - tau))`` with ``x`` in R^d and one fed-back component
``l``; it supplies ``f`` and its Jacobian as numba-compilable functions::

    rhs(x, xd, p, out)      out[i] = f_i(x, xd; p)
    jac(x, xd, p, jx, jd)   jx[i, j] = df_i/dx_j,  jd[i] = df_i/dxd

(``xd`` is the delayed value, ``p`` the float64 parameter vector) and is
identified inside the kernels by a *tag*: an instance of a namedtuple class
made for it by :func:`register`.  :func:`system_rhs` / :func:`system_jac` are
resolved at compile time from the tag's type, so the system's functions are
inlined into the one generic kernel, which numba compiles and caches once per
system (``cache=True`` keys the cache on the tag type, whose name carries a
hash of the system's source -- see :mod:`._tags`).

Scheme
------
Classical 4-stage Runge-Kutta with step ``dt``.  The delayed value at the stage
times ``t_n``, ``t_n + dt/2`` and ``t_n + dt`` is read from a ring buffer of
past values of ``x_l`` (one per step) by cubic Lagrange interpolation on four
neighbouring grid points (exact, without interpolation, when the stage time
falls on the grid), so ``tau`` need not be a multiple of ``dt`` and the scheme
stays fourth-order accurate.  Grid points newer than ``t_n`` are never used,
which requires ``tau >= dt``.
"""

from __future__ import annotations

import hashlib
import inspect

import numpy as np
from numba import njit, types
from numba.extending import intrinsic, overload

from .._jit import plain_kernel, stack_array, stack_array_type
from ._tags import tag_class

#: tag class -> (rhs, jac) of every registered system
REGISTRY = {}



def _source_hash(*funcs):
    h = hashlib.sha1()
    for f in funcs:
        f = getattr(f, "py_func", f)
        try:
            h.update(inspect.getsource(f).encode())
        except (OSError, TypeError):
            h.update(f.__code__.co_code)
            h.update(repr(f.__code__.co_consts).encode())
    return h.hexdigest()[:12]


def register(name, rhs, jac, dim):
    """Register a system's ``rhs``/``jac`` (state dimension ``dim``) and return its tag class.

    ``rhs`` and ``jac`` are plain Python functions (or numba dispatchers, whose
    ``py_func`` is used); they are compiled with ``inline="always"`` so that
    they are inlined into the kernels (a non-inlined call costs ~10x the
    arithmetic of a small system).  The tag class (see :mod:`._tags`) is named
    after the system, its dimension and a hash of the two functions' source, so
    cached kernels are recompiled when the equations change; its ``DIM`` is ``dim``.
    """
    dim = int(dim)
    if dim < 1:
        raise ValueError(f"{name}: the state dimension dim must be a positive integer, "
                         f"got {dim}.")
    tag_cls = tag_class(f"{name}_{dim}d_{_source_hash(rhs, jac)}")
    REGISTRY[tag_cls] = (njit(inline="always")(getattr(rhs, "py_func", rhs)),
                         njit(inline="always")(getattr(jac, "py_func", jac)))
    return tag_cls


def system_rhs(tag, x, xd, p, out):
    """Evaluate the right-hand side of the system ``tag`` (numba only)."""
    raise TypeError("system_rhs is only callable from numba-compiled code.")


def system_jac(tag, x, xd, p, jx, jd):
    """Evaluate the Jacobian of the system ``tag`` (numba only)."""
    raise TypeError("system_jac is only callable from numba-compiled code.")


@overload(system_rhs, inline="always")
def _system_rhs(tag, x, xd, p, out):
    rhs = REGISTRY[tag.instance_class][0]

    def impl(tag, x, xd, p, out):
        rhs(x, xd, p, out)

    return impl


@overload(system_jac, inline="always")
def _system_jac(tag, x, xd, p, jx, jd):
    jac = REGISTRY[tag.instance_class][1]

    def impl(tag, x, xd, p, jx, jd):
        jac(x, xd, p, jx, jd)

    return impl


@intrinsic
def state_array(typingctx, tag, rows):
    """A ``(rows, d)`` float64 work array on the kernel's stack, ``d`` the dimension of the
    system ``tag`` (its class's ``DIM``, known when the kernel is compiled); see
    :func:`skdelay._jit.stack_array`."""
    dim = getattr(getattr(tag, "instance_class", None), "DIM", None)
    if dim is None or not isinstance(rows, types.IntegerLiteral):
        return None
    aryty, codegen = stack_array_type(types.float64, (rows.literal_value, dim))
    return aryty(tag, rows), codegen


@njit(cache=True)
def ipow(x, n):
    """``x ** n``, by repeated squaring when ``n`` is a small non-negative integer.

    (libm ``pow`` costs about ten times more and would dominate e.g. Mackey-Glass.)
    """
    if n == np.floor(n) and 0.0 <= n <= 64.0:
        k = int(n)
        r = 1.0
        b = x
        while k:
            if k & 1:
                r *= b
            b *= b
            k >>= 1
        return r
    return x**n


@njit(cache=True)
def stencil(shift, starts, weights, c):
    """Cubic Lagrange stencil for the value at (relative) grid position ``shift <= 0``.

    Fills row ``c`` of ``starts`` / ``weights``: the value is
    ``sum_i weights[c, i] * h[n + starts[c] + i]`` with ``h[n]`` the current
    value.  Positions on the grid get the exact weights ``(0, 1, 0, 0)``
    (tolerance 1e-9 steps, against round-off in ``tau / dt``).
    """
    j = np.floor(shift)
    r = shift - j
    if r > 1.0 - 1e-9:
        j += 1.0
        r = 0.0
    if r < 1e-9:
        starts[c] = int(j) - 1
        weights[c, 0] = 0.0
        weights[c, 1] = 1.0
        weights[c, 2] = 0.0
        weights[c, 3] = 0.0
        return
    s = j - 1.0
    if s + 3.0 > 0.0:  # never read the future: shift the stencil back
        s = -3.0
    t = shift - s
    starts[c] = int(s)
    weights[c, 0] = -(t - 1.0) * (t - 2.0) * (t - 3.0) / 6.0
    weights[c, 1] = t * (t - 2.0) * (t - 3.0) / 2.0
    weights[c, 2] = -t * (t - 1.0) * (t - 3.0) / 2.0
    weights[c, 3] = t * (t - 1.0) * (t - 2.0) / 6.0


@njit(cache=True)
def stencils(tau_steps, starts, weights):
    """The three RK4 stencils (stage offsets 0, 1/2, 1) for a delay of ``tau_steps`` steps."""
    for c in range(3):
        stencil(0.5 * c - tau_steps, starts, weights, c)


# The per-step helpers below are inlined into the kernels at numba's IR level
# (``inline="always"``): a call with array arguments costs more than a small system's
# arithmetic.  The integrator's step loop (:func:`_advance`) also runs without the
# runtime's reference counts (:mod:`skdelay._jit`).  Together: a Mackey-Glass RK4 step
# 155 -> 41 ns, Ikeda runs 2.3x and electro-optic runs 2.7x faster
# (benchmarks/out/simulate_stop36.txt), with bit-identical output (the same
# floating-point operations in the same order; tests/test_systems.py pins seeded runs).
@njit(cache=True, inline="always")
def delayed(current, ring, slot, starts, weights, c):
    """Interpolated history value (stencil ``c``); ``slot`` = ring position of the current step."""
    m_ring = ring.shape[0]
    acc = 0.0
    for i in range(4):
        w = weights[c, i]
        if w != 0.0:
            off = starts[c] + i
            if off == 0:
                acc += w * current
            else:
                idx = slot + off
                if idx < 0:
                    idx += m_ring
                acc += w * ring[idx]
    return acc


@njit(cache=True, inline="always")
def rk4_stages(tag, x, xd0, xdh, xd1, p, dt, k, xs):
    """Evaluate the four RK4 stages: ``xs[s]`` stage states, ``k[s]`` slopes."""
    d = x.shape[0]
    for i in range(d):
        xs[0, i] = x[i]
    system_rhs(tag, xs[0], xd0, p, k[0])
    for i in range(d):
        xs[1, i] = x[i] + 0.5 * dt * k[0, i]
    system_rhs(tag, xs[1], xdh, p, k[1])
    for i in range(d):
        xs[2, i] = x[i] + 0.5 * dt * k[1, i]
    system_rhs(tag, xs[2], xdh, p, k[2])
    for i in range(d):
        xs[3, i] = x[i] + dt * k[2, i]
    system_rhs(tag, xs[3], xd1, p, k[3])


@njit(cache=True, inline="always")
def rk4_update(x, dt, k):
    """``x += dt/6 (k1 + 2 k2 + 2 k3 + k4)``."""
    for i in range(x.shape[0]):
        x[i] += dt / 6.0 * (k[0, i] + 2.0 * k[1, i] + 2.0 * k[2, i] + k[3, i])


@njit(cache=True, inline="always")
def ring_stages(tag, x, ring, slot, l, starts, weights, p, dt, k, xs, xd):
    """The RK4 stages of one ring-buffer step (shared by the integrator and the tangent run).

    Reads the delayed value at the stage times (``xd[0..3]``; the two half-step
    stages share one), stores the current ``x_l`` in ``ring[slot]`` (after the
    reads: that slot held the oldest value, which a stencil may still need)
    and evaluates the stages ``xs`` / slopes ``k``; the caller applies
    :func:`rk4_update` and moves to :func:`next_slot`.
    """
    cur = x[l]
    xd[0] = delayed(cur, ring, slot, starts, weights, 0)
    xd[1] = delayed(cur, ring, slot, starts, weights, 1)
    xd[2] = xd[1]
    xd[3] = delayed(cur, ring, slot, starts, weights, 2)
    ring[slot] = cur
    rk4_stages(tag, x, xd[0], xd[1], xd[3], p, dt, k, xs)


@njit(cache=True, inline="always")
def next_slot(slot, m_ring):
    """Ring position of the next step."""
    return 0 if slot + 1 == m_ring else slot + 1


@njit(cache=True)
def integrate_chunk(tag, x, ring, counter, l, p, p0, dp, tau0, dtau, drift, rec_start, rec_len,
                    dt, every, noise, noise_idx, out):
    """Advance ``len(out) * every`` steps, recording ``x_l`` before every ``every`` steps.

    State: ``x`` (d,), ``ring`` (M,) with ``ring[m % M] = x_l(t_m)`` for past
    steps ``m``, ``counter[0]`` = current step ``n``.  With ``drift`` the
    parameters ``p`` and the delay move linearly from ``p0``/``tau0`` to
    ``p0 + dp``/``tau0 + dtau`` over steps ``rec_start .. rec_start + rec_len``.
    ``noise`` is empty or holds the pre-scaled increments (steps,
    len(noise_idx)) added to the components ``noise_idx`` after each step
    (Euler-Maruyama).  Returns the number of samples written before the state
    became non-finite (``len(out)`` when all is well).
    """
    return _advance(tag, x, ring, counter, l, p, p0, dp, tau0, dtau, drift, rec_start, rec_len,
                    dt, every, noise, noise_idx, out)


@plain_kernel
def _advance(tag, x, ring, counter, l, p, p0, dp, tau0, dtau, drift, rec_start, rec_len, dt,
             every, noise, noise_idx, out):
    """:func:`integrate_chunk`'s step loop (without the runtime: :mod:`skdelay._jit`).

    The state is advanced in a copy on the stack, as are the stages and the stencils
    (:func:`state_array`, :func:`~skdelay._jit.stack_array`), and copied back to ``x``
    at the end: arrays passed in may alias each other as far as the compiler knows, so
    every write to one made it reload the others, while stack arrays of a known size are
    kept in registers.  The same floating-point operations in the same order, so the
    output is bit-identical (tests/test_systems.py pins seeded runs); an RK4 step
    1.3-1.45x faster on the four built-in systems (benchmarks/simulate.py).
    """
    k = state_array(tag, 4)
    xs = state_array(tag, 4)
    xl = state_array(tag, 1)[0]
    xd = stack_array(1, 4, np.float64)[0]
    starts = stack_array(1, 3, np.int64)[0]
    weights = stack_array(3, 4, np.float64)
    d = xl.shape[0]
    for q in range(d):
        xl[q] = x[q]
    m_ring = ring.shape[0]
    n = counter[0]
    slot = n % m_ring
    use_noise = noise.shape[0] > 0
    stencils(tau0 / dt, starts, weights)
    step = 0
    written = out.shape[0]
    for i in range(out.shape[0]):
        out[i] = xl[l]
        if not np.isfinite(xl[l]):
            written = i
            break
        for _ in range(every):
            if drift:
                frac = (n - rec_start) / rec_len
                frac = min(max(frac, 0.0), 1.0)
                for q in range(p.shape[0]):
                    p[q] = p0[q] + dp[q] * frac
                stencils((tau0 + dtau * frac) / dt, starts, weights)
            ring_stages(tag, xl, ring, slot, l, starts, weights, p, dt, k, xs, xd)
            rk4_update(xl, dt, k)
            if use_noise:
                for q in range(noise_idx.shape[0]):
                    xl[noise_idx[q]] += noise[step, q]
            step += 1
            n += 1
            slot = next_slot(slot, m_ring)
    counter[0] = n
    for q in range(d):
        x[q] = xl[q]
    if written < out.shape[0]:
        return written
    for q in range(d):
        if not np.isfinite(x[q]):
            return out.shape[0] - 1
    return out.shape[0]
