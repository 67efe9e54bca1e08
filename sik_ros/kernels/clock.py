"""A monotonic clock that compiled kernels can read: ``time.perf_counter()``'s own.

On Linux ``time.perf_counter()`` is ``clock_gettime(CLOCK_MONOTONIC)``; kernels call the same C
function, so a deadline taken in Python is compared in the kernel without a conversion. The call
is declared by name in the compiled code (no address baked in), so the kernels that use it stay
in numba's disk cache.
"""

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

#: ``CLOCK_MONOTONIC`` (Linux).
CLOCK_MONOTONIC = 1


@intrinsic
def monotonic(typingctx):
    """Seconds of ``CLOCK_MONOTONIC`` (the value ``time.perf_counter()`` gives) [s]."""
    def codegen(context, builder, signature, args):
        i32, i64, f64 = ir.IntType(32), ir.IntType(64), ir.DoubleType()
        timespec = ir.LiteralStructType([i64, i64])
        fnty = ir.FunctionType(i32, [i32, timespec.as_pointer()])
        fn = cgutils.get_or_insert_function(builder.module, fnty, 'clock_gettime')
        ts = cgutils.alloca_once(builder, timespec)
        builder.call(fn, [ir.Constant(i32, CLOCK_MONOTONIC), ts])
        zero = ir.Constant(i32, 0)
        sec = builder.load(builder.gep(ts, [zero, zero]))
        nsec = builder.load(builder.gep(ts, [zero, ir.Constant(i32, 1)]))
        return builder.fadd(builder.sitofp(sec, f64),
                            builder.fmul(builder.sitofp(nsec, f64), ir.Constant(f64, 1e-9)))
    return types.float64(), codegen
