"""Cube root, sine and cosine in plain arithmetic (vehicle/vector_math.py) against the C
library's, and the contact tables' angles inside the range of the series."""

import numba as nb
import numpy as np

from railsusp.vehicle import layout as L
from railsusp.vehicle.setup import contact_arrays
from railsusp.vehicle.vector_math import SIN_COS_RANGE, cbrt_positive, cbrt_rough, sin_cos
from railsusp.vehicle.wagon import load_wagon


@nb.njit(error_model="numpy")
def _cbrt_all(a):
    out = np.empty_like(a)
    for i in range(a.size):
        out[i] = cbrt_positive(a[i])
    return out


@nb.njit(error_model="numpy")
def _cbrt_rough_all(a):
    out = np.empty_like(a)
    for i in range(a.size):
        out[i] = cbrt_rough(a[i])
    return out


@nb.njit(error_model="numpy")
def _sin_cos_all(a):
    s = np.empty_like(a)
    c = np.empty_like(a)
    for i in range(a.size):
        s[i], c[i] = sin_cos(a[i])
    return s, c


def test_cbrt_within_a_few_ulp_of_the_c_library():
    rng = np.random.default_rng(0)
    x = np.concatenate([np.geomspace(1e-300, 1e300, 20001), rng.uniform(1e-3, 10.0, 20000)])
    ref = np.cbrt(x)
    assert np.max(np.abs(_cbrt_all(x) - ref) / np.spacing(ref)) <= 4
    assert _cbrt_all(np.array([8.0, 27.0, 1.0]))[0] == 2.0


def test_rough_cbrt_is_a_start_within_1e_4():
    x = np.geomspace(1e-200, 1e200, 40001)
    assert np.max(np.abs(_cbrt_rough_all(x) / np.cbrt(x) - 1.0)) < 1e-4


def test_sin_cos_within_round_off_over_their_range():
    a = np.linspace(-SIN_COS_RANGE, SIN_COS_RANGE, 100001)
    s, c = _sin_cos_all(a)
    assert np.max(np.abs(s - np.sin(a))) < 1e-15
    assert np.max(np.abs(c - np.cos(a))) < 1e-15
    # odd and even
    s2, c2 = _sin_cos_all(-a)
    np.testing.assert_array_equal(s2, -s)
    np.testing.assert_array_equal(c2, c)


def test_contact_angles_of_the_tables_lie_in_the_series_range():
    table = contact_arrays(load_wagon()).table
    for block in range(4):
        delta = table[block * L.CT_PER_WHEEL + L.CT_DELTA]
        assert np.max(np.abs(delta)) < SIN_COS_RANGE
