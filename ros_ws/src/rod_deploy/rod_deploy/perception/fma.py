"""Fused multiply-add for the compiled perception kernels: a b + c with a single rounding (LLVM's ``fma``: the
CPU's FMA instruction, or the C library's ``fma`` / ``fmaf`` where there is none).

The kernels that replace numpy / OpenCV calls reproduce those libraries' arithmetic bit for bit; where the
libraries fuse (OpenCV's bilinear remap kernel in float32; OpenBLAS's dot products and ``A.T @ A`` of small
float64 arrays, running fused sums), so must the kernels. Numba itself never fuses (no fast-math here).
"""
from numba.core import types
from numba.extending import intrinsic


@intrinsic
def fma32(typingctx, a, b, c):
    """a b + c in float32, rounded once."""
    sig = types.float32(types.float32, types.float32, types.float32)

    def codegen(context, builder, signature, args):
        return builder.fma(args[0], args[1], args[2])
    return sig, codegen


@intrinsic
def fma64(typingctx, a, b, c):
    """a b + c in float64, rounded once."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(args[0], args[1], args[2])
    return sig, codegen
