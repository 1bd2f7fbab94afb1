"""The cant angle's cosine and sine in the right-hand side (model.cant_cos_sin): the C
library's numbers bit for bit, with the calls saved on tangent and in a curve's body."""

from __future__ import annotations

import math

import numpy as np
import pytest

from railsusp.vehicle.model import cant_cos_sin


def _bits(x: float) -> int:
    return int(np.float64(x).view(np.int64))


@pytest.mark.parametrize("cant", [0.0, -0.0, 1e-300, -2.5e-3, 0.0123, 0.09, -0.09])
def test_equals_the_c_library_bit_for_bit(cant):
    """Whatever the nearby body's cant, the numbers are math.cos's and math.sin's, the sign
    of a zero angle included (sin(-0) = -0)."""
    for near in (0.0, -0.0, cant, 0.05):
        c, s = cant_cos_sin(cant, near, math.cos(near), math.sin(near))
        assert _bits(c) == _bits(math.cos(cant))
        assert _bits(s) == _bits(math.sin(cant))


def test_reuses_the_nearby_bodys_numbers_for_the_same_cant():
    """The same nonzero cant takes the nearby body's numbers (here marked, to see that they
    are used); another cant does not."""
    assert cant_cos_sin(0.0123, 0.0123, 7.0, 8.0) == (7.0, 8.0)
    c, s = cant_cos_sin(0.0123, 0.0124, 7.0, 8.0)
    assert (c, s) == (math.cos(0.0123), math.sin(0.0123))


def test_nan_stays_nan():
    """A NaN cant (a diverged state) gives NaN, as the C library does, for the integrator's
    finiteness check."""
    c, s = cant_cos_sin(math.nan, math.nan, 1.0, 0.0)
    assert math.isnan(c) and math.isnan(s)
