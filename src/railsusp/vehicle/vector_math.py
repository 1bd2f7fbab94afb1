"""Cube root, sine and cosine in plain arithmetic, so that a compiled loop over the eight
wheels' contacts can be vectorised by LLVM.

Numba compiles ``np.cbrt``, ``math.sin`` and ``math.cos`` to calls into the C library, one
lane at a time: a loop that calls them is not vectorised (Numba's vector versions came from
Intel's SVML, which Numba no longer supports since 0.62). These versions are branch-free
arithmetic on one double, which LLVM turns into SIMD code inside such a loop; they agree
with the C library to a few units in the last place (tests/vehicle/test_vector_math.py).
"""

from __future__ import annotations

import math

import numba as nb
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)

#: the bits of 2^(2/3 * 1023) less a bias that balances the error of the first guess
#: (the classic integer division of a float's bits by 3: x = 2^e m gives about 2^(e/3))
_CBRT_BIAS = float(0x2A9F7893782DA1CE)
#: |x| up to which :func:`sin_cos` holds to a few ulp (its Taylor series to x^25 and x^24)
SIN_COS_RANGE = 2.0


@intrinsic
def _bits(typingctx, x):
    """The IEEE 754 bits of a double as an int64 (a bit cast, no conversion)."""
    if not isinstance(x, types.Float):
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, i):
    """The double whose IEEE 754 bits are the int64 ``i`` (a bit cast)."""
    if not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def cbrt_positive(x):
    """x^(1/3) for a normal x > 0 (other x: a meaningless finite value or NaN; the caller
    selects). First guess from the bits (within 3 %), then three Halley steps
    y (y^3 + 2x) / (2y^3 + x), each cubing the relative error: round-off after the third."""
    y = _from_bits(int(float(_bits(x)) * (1.0 / 3.0) + _CBRT_BIAS))
    # written out: LLVM vectorises no loop that holds a loop
    y3 = y * y * y
    y *= (y3 + 2.0 * x) / (2.0 * y3 + x)
    y3 = y * y * y
    y *= (y3 + 2.0 * x) / (2.0 * y3 + x)
    y3 = y * y * y
    y *= (y3 + 2.0 * x) / (2.0 * y3 + x)
    return y


#: Taylor coefficients in z = x^2 of sin(x) / x and of cos(x), to z^12 (x^25 and x^24)
_S = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(13))
_C = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(13))


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def sin_cos(x):
    """(sin x, cos x) for |x| <= SIN_COS_RANGE (rad) from their Taylor series in z = x^2 to
    z^12 (the first neglected terms are below 1e-17 there), within a few ulp of the C
    library's; the contact angles of the tables lie within +-pi/2. Estrin's scheme (pairs,
    then pairs of pairs in z^2, z^4, z^8): four multiply-add levels deep instead of twelve.
    (Written out: a function inlined into an inlined function is not, and its call stops
    the vectoriser.)"""
    z = x * x
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    s01 = (_S[0] + _S[1] * z) + (_S[2] + _S[3] * z) * z2
    s23 = (_S[4] + _S[5] * z) + (_S[6] + _S[7] * z) * z2
    s45 = (_S[8] + _S[9] * z) + (_S[10] + _S[11] * z) * z2
    c01 = (_C[0] + _C[1] * z) + (_C[2] + _C[3] * z) * z2
    c23 = (_C[4] + _C[5] * z) + (_C[6] + _C[7] * z) * z2
    c45 = (_C[8] + _C[9] * z) + (_C[10] + _C[11] * z) * z2
    s = (s01 + s23 * z4) + (s45 + _S[12] * z4) * z8
    c = (c01 + c23 * z4) + (c45 + _C[12] * z4) * z8
    return x * s, c


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def cbrt_rough(x):
    """x^(1/3) within 3e-5 relative for a normal x > 0 (a start for Newton's method): the
    first guess from the bits and one Halley step."""
    y = _from_bits(int(float(_bits(x)) * (1.0 / 3.0) + _CBRT_BIAS))
    y3 = y * y * y
    return y * ((y3 + 2.0 * x) / (2.0 * y3 + x))
