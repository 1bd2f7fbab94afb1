"""Cube root, sine and cosine in plain arithmetic, so that a compiled loop over the eight
wheels' contacts can be vectorised by LLVM.

Numba compiles ``np.cbrt``, ``math.sin`` and ``math.cos`` to calls into the C library, one
lane at a time: a loop that calls them is not vectorised (Numba's vector versions came from
Intel's SVML, which Numba no longer supports since 0.62). These versions are branch-free
arithmetic on one double, which LLVM turns into SIMD code inside such a loop; they agree
with the C library to a few units in the last place (tests/vehicle/test_vector_math.py).
"""

from __future__ import annotations

import numba as nb
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

import railsusp.vehicle.kernel_cache  # noqa: F401  (before any kernel is compiled)

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


@nb.njit(cache=True, inline="always", error_model="numpy")
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


@nb.njit(cache=True, inline="always", error_model="numpy")
def sin_cos(x):
    """(sin x, cos x) for |x| <= SIN_COS_RANGE (rad) from their Taylor series (Horner in
    x^2; the first neglected terms are below 1e-17 there). The contact angles of the tables
    lie within +-pi/2."""
    z = x * x
    s = 1.0 / 25.0 / 24.0
    s = 1.0 / 23.0 / 22.0 * (1.0 - z * s)
    s = 1.0 / 21.0 / 20.0 * (1.0 - z * s)
    s = 1.0 / 19.0 / 18.0 * (1.0 - z * s)
    s = 1.0 / 17.0 / 16.0 * (1.0 - z * s)
    s = 1.0 / 15.0 / 14.0 * (1.0 - z * s)
    s = 1.0 / 13.0 / 12.0 * (1.0 - z * s)
    s = 1.0 / 11.0 / 10.0 * (1.0 - z * s)
    s = 1.0 / 9.0 / 8.0 * (1.0 - z * s)
    s = 1.0 / 7.0 / 6.0 * (1.0 - z * s)
    s = 1.0 / 5.0 / 4.0 * (1.0 - z * s)
    s = 1.0 / 3.0 / 2.0 * (1.0 - z * s)
    s = x * (1.0 - z * s)
    c = 1.0 / 24.0 / 23.0
    c = 1.0 / 22.0 / 21.0 * (1.0 - z * c)
    c = 1.0 / 20.0 / 19.0 * (1.0 - z * c)
    c = 1.0 / 18.0 / 17.0 * (1.0 - z * c)
    c = 1.0 / 16.0 / 15.0 * (1.0 - z * c)
    c = 1.0 / 14.0 / 13.0 * (1.0 - z * c)
    c = 1.0 / 12.0 / 11.0 * (1.0 - z * c)
    c = 1.0 / 10.0 / 9.0 * (1.0 - z * c)
    c = 1.0 / 8.0 / 7.0 * (1.0 - z * c)
    c = 1.0 / 6.0 / 5.0 * (1.0 - z * c)
    c = 1.0 / 4.0 / 3.0 * (1.0 - z * c)
    c = 1.0 / 2.0 / 1.0 * (1.0 - z * c)
    c = 1.0 - z * c
    return s, c
