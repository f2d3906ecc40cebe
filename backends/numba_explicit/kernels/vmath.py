"""exp, log and pow that LLVM can vectorise across elements (numba, scalars, branch-free).

numba lowers ``math.exp`` / ``math.log`` / ``x ** y`` to calls into the C library, and a loop
containing such a call is never vectorised (this llvmlite has no vector maths library). The
element pass evaluates the material for a block of elements in one loop (``element.py``), so
the block variant of the material's generated code (``codegen.vector_source``) calls these
instead. Each is straight-line arithmetic with selects and integer bit operations, so the loop
vectorises (8 doubles per AVX-512 instruction); accuracy about 1 ulp (exp) and 2 ulp (log),
checked against the C library and mpmath in ``tests/backends/test_numba_vmath.py``.

- ``vexp``: x = k ln 2 + r with |r| <= ln 2 / 2 (Cody-Waite, two-part ln 2), exp(r) by its
  Taylor polynomial to degree 13 (truncation < 2e-18), times 2^k built from the exponent bits.
  exp(0) = 1 exactly; overflow gives inf, underflow below 2^-1022 gives 0 (no subnormals).
- ``vlog``: x = 2^e m with m in [sqrt(2)/2, sqrt(2)) from the bits, log m = 2 atanh(s),
  s = (m - 1) / (m + 1), by its series to s^23 (|s| <= 0.172, truncation < 1e-19);
  log(1) = 0 exactly; log(0) = -inf, log(x < 0) = NaN, subnormals scaled first.
- ``vsqrt``: the LLVM intrinsic (the C library's ``sqrt`` is a call that sets errno).
- ``vpow(x, y) = vexp(y vlog(x))`` for x >= 0 (what the materials use it for: J^(-2/3), stretch
  powers of Ogden terms); its relative error is about (1 + |y log x|) ulp.

References: W. J. Cody, W. Waite, Software Manual for the Elementary Functions (1980), ch. 5-6;
J.-M. Muller, Elementary Functions, 3rd ed. (2016), sec. 11.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core.extending import intrinsic
from cfm_backends.numba_cache import key_on_folder

key_on_folder(__file__)  # numba's cache of these kernels is keyed on every file of the folder
# <<< standalone


@intrinsic
def _bits_to_float(typingctx, x):
    """The float64 whose IEEE bits are the int64 x (a bit cast, no conversion)."""
    def emit(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), emit


@intrinsic
def _float_to_bits(typingctx, x):
    """The IEEE bits of the float64 x as an int64 (a bit cast, no conversion)."""
    def emit(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), emit


@intrinsic
def vsqrt(typingctx, x):
    """Square root (float64) as LLVM's llvm.sqrt intrinsic, correctly rounded like the C
    library's but without errno, so that loops calling it vectorise; sqrt(x < 0) = NaN."""
    def emit(context, builder, signature, args):
        fn = builder.module.declare_intrinsic("llvm.sqrt", [ir.DoubleType()])
        return builder.call(fn, args)
    return types.float64(types.float64), emit


_LN2_HI = 6.93147180369123816490e-01     # ln 2 to 32 bits: k * _LN2_HI is exact for |k| < 2^20
_LN2_LO = 1.90821492927058770002e-10     # ln 2 - _LN2_HI
_LOG2E = 1.4426950408889634
_SQRT2 = 1.4142135623730951
_TINY = 2.2250738585072014e-308          # smallest normal float64
_EXP_HI = 709.782712893384               # log of the largest float64
_EXP_LO = -708.3964185322641             # log of the smallest normal float64


@njit(inline="always", error_model="numpy")
def vexp(x):
    """e^x (float64), about 1 ulp; branch-free so that loops calling it vectorise."""
    xc = min(max(x, -708.0), 709.0)
    k = math.floor(xc * _LOG2E + 0.5)
    r = (xc - k * _LN2_HI) - k * _LN2_LO
    q = 1.0 / 6227020800.0
    q = q * r + 1.0 / 479001600.0
    q = q * r + 1.0 / 39916800.0
    q = q * r + 1.0 / 3628800.0
    q = q * r + 1.0 / 362880.0
    q = q * r + 1.0 / 40320.0
    q = q * r + 1.0 / 5040.0
    q = q * r + 1.0 / 720.0
    q = q * r + 1.0 / 120.0
    q = q * r + 1.0 / 24.0
    q = q * r + 1.0 / 6.0
    q = q * r + 0.5
    q = q * r + 1.0
    q = q * r + 1.0
    y = q * _bits_to_float((np.int64(k) + 1023) << 52)
    y = math.inf if x > _EXP_HI else y
    y = 0.0 if x < _EXP_LO else y
    return y if x == x else x


@njit(inline="always", error_model="numpy")
def vlog(x):
    """Natural logarithm (float64), about 2 ulp; branch-free so that loops calling it vectorise."""
    sub = x < _TINY
    xs = x * 18014398509481984.0 if sub else x        # 2^54: subnormals become normal
    bits = _float_to_bits(xs)
    e = (bits >> 52) - 1023
    m = _bits_to_float((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)   # [1, 2)
    big = m > _SQRT2
    m = m * 0.5 if big else m
    e = e + 1 if big else e
    e = e - 54 if sub else e
    s = (m - 1.0) / (m + 1.0)
    z = s * s
    q = 1.0 / 23.0
    q = q * z + 1.0 / 21.0
    q = q * z + 1.0 / 19.0
    q = q * z + 1.0 / 17.0
    q = q * z + 1.0 / 15.0
    q = q * z + 1.0 / 13.0
    q = q * z + 1.0 / 11.0
    q = q * z + 1.0 / 9.0
    q = q * z + 1.0 / 7.0
    q = q * z + 1.0 / 5.0
    q = q * z + 1.0 / 3.0
    fe = float(e)
    y = fe * _LN2_HI + (2.0 * s + (2.0 * s * z * q + fe * _LN2_LO))
    y = -math.inf if x == 0.0 else y
    y = math.inf if x == math.inf else y
    return y if x >= 0.0 else math.nan


@njit(inline="always", error_model="numpy")
def vpow(x, y):
    """x^y for x >= 0 (float64) as vexp(y vlog(x)); x < 0 gives NaN (real powers of the
    materials are of stretches and J, never negative)."""
    return vexp(y * vlog(x))
