"""How the hot loops are compiled: numba kernels that skip the runtime's reference counts.

A step loop that hands its work arrays to small helpers (inlined with
``inline="always"``) makes numba's runtime (NRT) count a reference for every
such pass.  Those counts are atomic operations, and in the tightest loops they
cost more than the arithmetic: in the delay-system integrator they took more
than half of a Mackey-Glass RK4 step (benchmarks/out/simulate_stop36.txt).
Skipping them leaves the output bit-identical: the same floating-point
operations in the same order.

:func:`plain_kernel` compiles a function without the runtime.  Such a kernel
must not allocate, return or store arrays: a thin ordinary ``njit`` wrapper
allocates every work array and passes it in.  ``_nrt`` is numba's own switch,
not a documented option, and numba checks options only when it compiles: where
a numba version lacks it, the kernel is compiled as usual and is only slower.
"""

from __future__ import annotations

from numba import njit

__all__ = ["plain_kernel"]


def _has_nrt_switch():
    try:
        from numba.core.cpu import CPUTargetOptions
    except ImportError:  # pragma: no cover - depends on numba
        return False
    return hasattr(CPUTargetOptions, "_nrt")


_PLAIN = _has_nrt_switch()


def plain_kernel(func=None, **options):
    """``njit(cache=True, **options)`` without reference counting where numba allows it."""
    if func is None:
        return lambda f: plain_kernel(f, **options)
    if _PLAIN:
        return njit(cache=True, _nrt=False, **options)(func)
    return njit(cache=True, **options)(func)  # pragma: no cover - depends on numba
