"""Contact force laws: Hertz (closed forms, notes' figures), Kalker coefficients, SHE saturation."""

import math

import numpy as np
import pytest
from scipy.special import ellipe, ellipk

from railsusp.vehicle.contact_forces import (
    E_STEEL,
    POISSON_STEEL,
    hertz_coefficients,
    hertz_contact,
    kalker_coefficients,
    kalker_creep_coefficients,
    kalker_linear_forces,
    shen_hedrick_elkins,
    simplified_hertz_approach,
    simplified_hertz_force,
    simplified_hertz_stiffness,
)

STATIC_LOAD = 122.6e3  # N, C80 static wheel load (physics notes)
E_STAR = E_STEEL / (2.0 * (1.0 - POISSON_STEEL**2))


# ---------------------------------------------------------------------------- Hertz
def test_hertz_sphere_on_plane_closed_form():
    # A = B = 1/(2R): a = (3 N R / (4 E*))^(1/3), approach a^2 / R (Johnson 1985, eq. 4.22-23)
    radius, load = 0.1, np.array([1e3, 1e4, 1e5])
    patch = hertz_contact(load, 1 / radius, 1 / radius, 0.0, 0.0)
    a_ref = np.cbrt(3 * load * radius / (4 * E_STAR))
    np.testing.assert_allclose(patch.a, a_ref, rtol=1e-7)
    np.testing.assert_allclose(patch.b, a_ref, rtol=1e-7)
    np.testing.assert_allclose(patch.approach, a_ref**2 / radius, rtol=1e-7)
    np.testing.assert_allclose(patch.p0, 3 * load / (2 * np.pi * a_ref**2), rtol=1e-7)


@pytest.mark.parametrize("ratio", [1.5, 4.0, 30.0])
def test_hertz_ellipse_satisfies_hertz_equations(ratio):
    # Johnson 1985 eq. 4.39: A = p0 b (K - E) / (E* a^2 e^2), B = p0 b (a^2/b^2 E - K) /
    # (E* a^2 e^2), a the major semi-axis along the direction of the smaller curvature A
    curv_a, load = 1.2, 5e4
    curv_b = ratio * curv_a
    patch = hertz_contact(load, 2 * curv_a, 2 * curv_b, 0.0)
    a, b = float(patch.a), float(patch.b)
    e2 = 1.0 - (b / a) ** 2
    k, e = ellipk(e2), ellipe(e2)
    scale = float(patch.p0) * b / (E_STAR * a * a * e2)
    assert scale * (k - e) == pytest.approx(curv_a, rel=1e-6)
    assert scale * ((a / b) ** 2 * e - k) == pytest.approx(curv_b, rel=1e-6)
    m, n = hertz_coefficients(curv_a, curv_b)
    assert m > 1.0 > n  # elongated ellipse; m = n = 1 only for A = B


def test_hertz_at_static_load_matches_notes():
    # physics notes: 122.6 kN gives about 7.4 x 5.9 mm and p0 about 1.35 GPa. Matching pair:
    # wheel r0 = 0.42 m with a straight (conical) tread, on the R300 rail crown.
    patch = hertz_contact(STATIC_LOAD, 1 / 0.42, 0.0, 1 / 0.300)
    assert float(patch.a) == pytest.approx(7.4e-3, rel=0.15)
    assert float(patch.b) == pytest.approx(5.9e-3, rel=0.15)
    assert float(patch.p0) == pytest.approx(1.35e9, rel=0.15)
    # ... and an approach close to the simplified LM law dz = G P^(2/3)
    assert float(patch.approach) == pytest.approx(simplified_hertz_approach(STATIC_LOAD), rel=0.2)


def test_hertz_zero_load_and_conformal_rejection():
    patch = hertz_contact(np.array([0.0, -5.0]), 2.4, 1.0, 3.3)
    assert np.all(patch.a == 0.0) and np.all(patch.p0 == 0.0) and np.all(patch.approach == 0.0)
    with pytest.raises(ValueError, match="positive relative curvatures"):
        hertz_contact(1e4, 2.4, -4.0, 3.3)  # hollow wheel more curved than the rail crown


def test_simplified_hertz_law():
    # Zhai: P = (dz / G)^1.5, G = 3.86 R^-0.115 1e-8; notes: about 1.7 GN/m at 122.6 kN
    dz = simplified_hertz_approach(STATIC_LOAD)
    assert simplified_hertz_force(dz) == pytest.approx(STATIC_LOAD, rel=1e-12)
    k = simplified_hertz_stiffness(STATIC_LOAD)
    assert k == pytest.approx(1.7e9, rel=0.05)
    h = 1e-9
    numeric = (simplified_hertz_force(dz + h) - simplified_hertz_force(dz - h)) / (2 * h)
    assert k == pytest.approx(numeric, rel=1e-5)
    assert simplified_hertz_force(np.array([-1e-4, 0.0])).tolist() == [0.0, 0.0]  # lift-off


# ---------------------------------------------------------------------------- Kalker
def test_kalker_coefficients_at_circular_patch():
    # Kalker (1990) table, nu = 0.25, a/b = 1: C11 4.12, C22 3.67, C23 1.47, C33 1.19
    got = [float(c) for c in kalker_coefficients(1.0)]
    np.testing.assert_allclose(got, [4.12, 3.67, 1.47, 1.19], rtol=0.02)
    c11, _, _, c33 = kalker_coefficients(np.array([0.5, 2.0]))
    assert c11[1] > c11[0] and c33[1] < c33[0]  # C11 grows, C33 falls with a/b


def test_kalker_creep_coefficients_at_static_load():
    # physics notes: f11 about 15 MN, f22 about 14 MN at the static load
    patch = hertz_contact(STATIC_LOAD, 1 / 0.42, 0.0, 1 / 0.300)
    f11, f22, f23, f33 = kalker_creep_coefficients(patch.a, patch.b)
    assert float(f11) == pytest.approx(15e6, rel=0.1)
    assert float(f22) == pytest.approx(14e6, rel=0.1)
    ab = float(patch.a * patch.b)
    assert float(f23) / float(f22) == pytest.approx(
        math.sqrt(ab) * float(kalker_coefficients(patch.a / patch.b)[2]) / 3.99, rel=0.02
    )
    assert float(f33) > 0.0


def test_kalker_linear_forces_signs():
    fx, fy, mz = kalker_linear_forces(1e-3, 2e-3, 0.1, 15e6, 14e6, 4e4, 150.0)
    assert fx == pytest.approx(-15e3)
    assert fy == pytest.approx(-28e3 - 4e3)
    assert mz == pytest.approx(80.0 - 15.0)


# ---------------------------------------------------------------------------- SHE
def test_she_linear_for_small_creep():
    # beta << 1: factor 1 - beta/3 + beta^2/27 -> 1 (within 1 % for beta < 0.03)
    fx, fy, mz = kalker_linear_forces(1e-6, -2e-6, 0.0, 15e6, 14e6, 4e4, 150.0)
    sx, sy, sm = shen_hedrick_elkins(fx, fy, mz, 0.3, STATIC_LOAD)
    np.testing.assert_allclose([sx, sy, sm], [fx, fy, mz], rtol=0.01)


def test_she_saturates_at_mu_n_and_never_exceeds_it():
    mu, n = 0.3, STATIC_LOAD
    xi = np.logspace(-6, 0, 400)
    fx, fy, mz = kalker_linear_forces(xi, 0.5 * xi, 0.0, 15e6, 14e6, 4e4, 150.0)
    sx, sy, _ = shen_hedrick_elkins(fx, fy, mz, mu, n)
    total = np.hypot(sx, sy)
    assert np.all(total <= mu * n * (1 + 1e-12))
    assert np.all(np.diff(total) >= -1e-12 * mu * n)  # monotonic in creep
    assert total[-1] == pytest.approx(mu * n, rel=1e-12)  # beta >= 3: exactly mu N
    # direction preserved: the saturated force is parallel to the linear one
    np.testing.assert_allclose(sx * fy - sy * fx, 0.0, atol=1e-6 * mu * n)
    assert np.all(np.sign(sx) == np.sign(fx))


def test_she_zero_creep_and_lift_off():
    out = shen_hedrick_elkins(np.zeros(3), np.zeros(3), np.zeros(3), 0.3, STATIC_LOAD)
    assert all(np.all(np.isfinite(o)) and np.all(o == 0.0) for o in out)
    fx = np.full((2, 3), -5e3)
    sx, _, sm = shen_hedrick_elkins(fx, fx, fx, 0.3, np.array([0.0, -1e3, 5e4])[None, :])
    assert sx.shape == (2, 3)
    assert np.all(sx[:, :2] == 0.0) and np.all(sm[:, :2] == 0.0)  # N <= 0: no force
    assert np.all(sx[:, 2] < 0.0)
