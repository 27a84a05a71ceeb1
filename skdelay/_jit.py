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

from numba import njit, types
from numba.extending import intrinsic

__all__ = ["plain_kernel", "stack_array", "stack_array_type"]


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


def _alloca_array(context, builder, aryty, shape):
    """An array struct of type ``aryty`` (C order) over stack memory of ``shape`` (ints).

    The memory is reserved in the function's entry block (``alloca``), so it is freed
    on return and costs nothing per call; there is no meminfo, so the array is never
    reference-counted and must not outlive the kernel that made it.
    """
    from numba.core import cgutils
    from numba.np.arrayobj import make_array, populate_array

    el = context.get_value_type(aryty.dtype)
    itemsize = context.get_abi_sizeof(el)
    size = 1
    for s in shape:
        size *= s
    data = cgutils.alloca_once(builder, el, size=max(size, 1))
    intp = context.get_value_type(types.intp)
    strides, step = [], itemsize
    for s in reversed(shape):
        strides.insert(0, intp(step))
        step *= s
    ary = make_array(aryty)(context, builder)
    populate_array(ary, data=data, shape=[intp(s) for s in shape], strides=strides,
                   itemsize=intp(itemsize), meminfo=None)
    return ary._getvalue()


def stack_array_type(dtype, shape):
    """``(signature return type, codegen)`` of an intrinsic returning a stack array of
    ``dtype`` (a numba type) and the compile-time ``shape``; see :func:`stack_array`."""
    aryty = types.Array(dtype, len(shape), "C")

    def codegen(context, builder, signature, args):
        return _alloca_array(context, builder, aryty, shape)

    return aryty, codegen


@intrinsic
def stack_array(typingctx, rows, cols, dtype):
    """A ``(rows, cols)`` C-ordered work array of ``dtype`` on the kernel's stack.

    ``rows`` and ``cols`` must be compile-time integer constants (literals or
    closure constants) and ``dtype`` a numpy scalar type (``np.float64``).  For
    the work arrays of :func:`plain_kernel` loops: a kernel without the runtime
    cannot allocate arrays, and arrays passed in from outside are memory that
    the compiler must assume may alias every other argument, so it stores and
    reloads them around each write.  Stack arrays of constant shape are known not
    to alias anything: small ones (a step's Runge-Kutta stages) are kept in
    registers.  Contents start undefined, as with ``np.empty``.
    """
    if not (isinstance(rows, types.IntegerLiteral) and isinstance(cols, types.IntegerLiteral)
            and isinstance(dtype, types.NumberClass)):
        return None
    aryty, codegen = stack_array_type(dtype.dtype, (rows.literal_value, cols.literal_value))
    return aryty(rows, cols, dtype), codegen
