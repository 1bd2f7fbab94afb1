"""Wheel-rail contact force laws: Hertz normal contact, Kalker linear creep, SHE saturation.

Pure, vectorised NumPy functions (SI units). The contact geometry that feeds them (contact
points, curvatures) is in :mod:`railsusp.vehicle.contact` (its tables made by
:mod:`railsusp.vehicle.rigid_profile_contact`); the simulator re-writes the force
laws in its Numba kernel (:mod:`railsusp.vehicle.model`) and uses these for its tables.
Creep forces are those of the rail on the wheel, in the contact plane.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.special import ellipe, ellipk

__all__ = [
    "E_STEEL",
    "POISSON_STEEL",
    "SHEAR_MODULUS_STEEL",
    "HertzPatch",
    "hertz_coefficients",
    "hertz_contact",
    "kalker_coefficients",
    "kalker_creep_coefficients",
    "kalker_linear_forces",
    "shen_hedrick_elkins",
    "simplified_hertz_approach",
    "simplified_hertz_constant",
    "simplified_hertz_force",
    "simplified_hertz_stiffness",
]

Array = np.ndarray | float

#: Young's modulus (Pa) and Poisson's ratio of wheel and rail steel used for Hertz contact.
E_STEEL = 2.1e11
POISSON_STEEL = 0.28
#: Shear modulus (Pa) used in Kalker's linear creep coefficients.
SHEAR_MODULUS_STEEL = 8.0e10


# --------------------------------------------------------------------------------------------
# normal contact: Hertz
# --------------------------------------------------------------------------------------------


class HertzPatch(NamedTuple):
    """Hertz contact ellipse: semi-axes ``a`` (rolling direction) and ``b`` (lateral), m;
    peak pressure ``p0`` (Pa); normal approach (penetration) of the two bodies (m)."""

    a: np.ndarray
    b: np.ndarray
    p0: np.ndarray
    approach: np.ndarray


def _k_minus_e(m: np.ndarray) -> np.ndarray:
    """(K(m) - E(m)) / m, with the series pi/4 (1 + 3m/8) where the difference cancels."""
    mm = np.maximum(m, 1e-300)
    direct = (ellipk(mm) - ellipe(mm)) / mm
    return np.where(m < 1e-5, 0.25 * np.pi * (1.0 + 0.375 * m), direct)


def _e_over_k(m: np.ndarray) -> np.ndarray:
    """(E(m) / (1 - m) - K(m)) / m, with the series pi/4 (1 + 9m/8) for small m."""
    mm = np.maximum(m, 1e-300)
    direct = (ellipe(mm) / (1.0 - mm) - ellipk(mm)) / mm
    return np.where(m < 1e-5, 0.25 * np.pi * (1.0 + 1.125 * m), direct)


def _ellipse_ratio(ratio: np.ndarray) -> np.ndarray:
    """Minor/major semi-axis ratio k of the Hertz ellipse for curvature ratio B/A >= 1.

    Solves B/A = (E(e)/(1 - e^2) - K(e)) / (K(e) - E(e)), e^2 = 1 - k^2, K, E complete
    elliptic integrals (Johnson, Contact Mechanics, 1985, eq. 4.39), by bisection in ln k.
    """
    lo = np.full(ratio.shape, math.log(1e-6))
    hi = np.zeros(ratio.shape)
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        m = -np.expm1(2.0 * mid)  # e^2 = 1 - k^2
        too_round = _e_over_k(m) / _k_minus_e(m) < ratio  # the ellipse must be longer
        hi = np.where(too_round, mid, hi)
        lo = np.where(too_round, lo, mid)
    return np.exp(0.5 * (lo + hi))


def hertz_coefficients(
    curvature_a: np.ndarray | float, curvature_b: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """Hertz coefficients (m, n) for relative curvatures A, B (1/m, both > 0).

    Semi-axes (major, minor) = (m, n) * (3 N / (4 E* (A + B)))^(1/3); the major axis lies
    along the direction of the smaller of A and B. m = n = 1 for A = B (sphere).
    """
    a_ = np.asarray(curvature_a, dtype=float)
    b_ = np.asarray(curvature_b, dtype=float)
    small, large = np.minimum(a_, b_), np.maximum(a_, b_)
    k = _ellipse_ratio(large / small)
    # A_small = 3N (K - E) / (2 pi E* a^3 e^2)  =>  a^3 in units of 3N / (4 E* (A + B))
    m_cubed = 2.0 * _k_minus_e(1.0 - k * k) * (a_ + b_) / (np.pi * small)
    m_coef = np.cbrt(m_cubed)
    return m_coef, k * m_coef


def hertz_contact(
    normal_force: np.ndarray | float,
    wheel_curvature_long: np.ndarray | float,
    wheel_curvature_lat: np.ndarray | float,
    rail_curvature_lat: np.ndarray | float,
    rail_curvature_long: np.ndarray | float = 0.0,
    *,
    youngs_modulus: float = E_STEEL,
    poisson_ratio: float = POISSON_STEEL,
) -> HertzPatch:
    """Hertz contact ellipse for a normal force (N) and principal curvatures (1/m, convex +).

    A = (k_wheel,long + k_rail,long)/2, B = (k_wheel,lat + k_rail,lat)/2 must be positive.
    E* = E / (2 (1 - nu^2)) for two bodies of the same steel (E = 210 GPa, nu = 0.28).
    Semi-axes from :func:`hertz_coefficients`, p0 = 3 N / (2 pi a b), approach
    delta = p0 b_minor K(e) / E* (Johnson, Contact Mechanics, 1985, section 4.2). For
    A = B = 1/(2R) this is a = (3 N R / (4 E*))^(1/3). N <= 0 gives a zero patch.
    """
    n = np.maximum(np.asarray(normal_force, dtype=float), 0.0)
    ca = 0.5 * (np.asarray(wheel_curvature_long, float) + np.asarray(rail_curvature_long, float))
    cb = 0.5 * (np.asarray(wheel_curvature_lat, float) + np.asarray(rail_curvature_lat, float))
    if np.any(ca <= 0.0) or np.any(cb <= 0.0):
        raise ValueError(
            "Hertz contact needs positive relative curvatures A (rolling) and B (lateral); "
            f"got A min {np.min(ca):.4g} 1/m, B min {np.min(cb):.4g} 1/m (conformal contact)"
        )
    e_star = youngs_modulus / (2.0 * (1.0 - poisson_ratio**2))
    m_coef, n_coef = hertz_coefficients(ca, cb)
    scale = np.cbrt(3.0 * n / (4.0 * e_star * (ca + cb)))
    major, minor = m_coef * scale, n_coef * scale
    long_is_major = ca <= cb
    a = np.where(long_is_major, major, minor)
    b = np.where(long_is_major, minor, major)
    with np.errstate(invalid="ignore", divide="ignore"):
        p0 = np.where(n > 0.0, 3.0 * n / (2.0 * np.pi * a * b), 0.0)
    approach = p0 * minor * ellipk(1.0 - (n_coef / m_coef) ** 2) / e_star
    return HertzPatch(a, b, p0, approach)


def simplified_hertz_constant(wheel_radius: float | np.ndarray = 0.42) -> float | np.ndarray:
    """G = 3.86 R^-0.115 * 1e-8 (m/N^(2/3)), wheel radius R in m: worn (LM) tread.

    Zhai, Vehicle-Track Coupled Dynamics (Springer, 2020), nonlinear Hertz contact
    P = (dz / G)^(3/2) for a worn-type tread.
    """
    return 3.86e-8 * np.power(wheel_radius, -0.115)


def simplified_hertz_force(
    approach: np.ndarray | float, wheel_radius: float | np.ndarray = 0.42
) -> np.ndarray:
    """Normal force P = (dz / G)^1.5 (N) for an approach dz (m); 0 when dz <= 0 (lift-off)."""
    dz = np.maximum(np.asarray(approach, dtype=float), 0.0)
    return (dz / simplified_hertz_constant(wheel_radius)) ** 1.5


def simplified_hertz_approach(
    normal_force: np.ndarray | float, wheel_radius: float | np.ndarray = 0.42
) -> np.ndarray:
    """Approach dz = G P^(2/3) (m) for a normal force P (N), the inverse of the force law."""
    p = np.maximum(np.asarray(normal_force, dtype=float), 0.0)
    return simplified_hertz_constant(wheel_radius) * np.cbrt(p) ** 2


def simplified_hertz_stiffness(
    normal_force: np.ndarray | float, wheel_radius: float | np.ndarray = 0.42
) -> np.ndarray:
    """Linearised contact stiffness dP/d(dz) = 1.5 P^(1/3) / G (N/m) at a load P (N)."""
    p = np.maximum(np.asarray(normal_force, dtype=float), 0.0)
    return 1.5 * np.cbrt(p) / simplified_hertz_constant(wheel_radius)


# --------------------------------------------------------------------------------------------
# tangential contact: Kalker linear theory and Shen-Hedrick-Elkins saturation
# --------------------------------------------------------------------------------------------

# Kalker's creepage and spin coefficients for Poisson's ratio 0.25 (J. J. Kalker,
# Three-dimensional elastic bodies in rolling contact, Kluwer 1990, table E3; also in
# Kalker 1967 thesis). Columns: g, C11, C22, C23, C33.
_KALKER_A_LT_B = np.array(  # g = a/b <= 1
    [
        [0.1, 3.31, 2.52, 0.473, 8.28],
        [0.2, 3.37, 2.63, 0.603, 4.27],
        [0.3, 3.44, 2.75, 0.715, 2.96],
        [0.4, 3.53, 2.88, 0.823, 2.32],
        [0.5, 3.62, 3.01, 0.929, 1.93],
        [0.6, 3.72, 3.14, 1.03, 1.68],
        [0.7, 3.81, 3.28, 1.14, 1.50],
        [0.8, 3.91, 3.41, 1.25, 1.37],
        [0.9, 4.01, 3.54, 1.36, 1.27],
        [1.0, 4.12, 3.67, 1.47, 1.19],
    ]
)
_KALKER_A_GT_B = np.array(  # g = b/a <= 1
    [
        [0.1, 11.7, 12.8, 14.6, 0.526],
        [0.2, 7.78, 8.14, 6.63, 0.601],
        [0.3, 6.34, 6.40, 4.32, 0.674],
        [0.4, 5.57, 5.48, 3.24, 0.747],
        [0.5, 5.10, 4.90, 2.62, 0.819],
        [0.6, 4.78, 4.50, 2.23, 0.892],
        [0.7, 4.54, 4.21, 1.95, 0.965],
        [0.8, 4.36, 3.99, 1.75, 1.04],
        [0.9, 4.22, 3.81, 1.59, 1.11],
        [1.0, 4.12, 3.67, 1.47, 1.19],
    ]
)


def kalker_coefficients(
    a_over_b: np.ndarray | float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Kalker's C11, C22, C23, C33 (-) for nu = 0.25 at semi-axis ratio a/b (any shape).

    Linear interpolation in g = a/b (a/b <= 1) or g = b/a (a/b > 1) of Kalker's table (1990,
    table E3); a/b is clipped to the tabulated range 0.1..10.
    """
    ratio = np.clip(np.asarray(a_over_b, dtype=float), 0.1, 10.0)
    g_lt = np.minimum(ratio, 1.0)
    g_gt = np.minimum(1.0 / ratio, 1.0)
    out = []
    for col in range(1, 5):
        lt = np.interp(g_lt, _KALKER_A_LT_B[:, 0], _KALKER_A_LT_B[:, col])
        gt = np.interp(g_gt, _KALKER_A_GT_B[:, 0], _KALKER_A_GT_B[:, col])
        out.append(np.where(ratio <= 1.0, lt, gt))
    return out[0], out[1], out[2], out[3]


def kalker_creep_coefficients(
    a: np.ndarray | float, b: np.ndarray | float, shear_modulus: float = SHEAR_MODULUS_STEEL
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """f11, f22 (N), f23 (N m), f33 (N m^2) from semi-axes a (rolling), b (lateral) in m.

    f11 = G a b C11, f22 = G a b C22, f23 = G (a b)^1.5 C23, f33 = G (a b)^2 C33, G = 80 GPa.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    ab = a * b
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(b > 0.0, a / np.where(b > 0.0, b, 1.0), 1.0)
    c11, c22, c23, c33 = kalker_coefficients(ratio)
    g = shear_modulus
    return g * ab * c11, g * ab * c22, g * ab**1.5 * c23, g * ab**2 * c33


def kalker_linear_forces(
    xi_x: Array, xi_y: Array, phi: Array, f11: Array, f22: Array, f23: Array, f33: Array
) -> tuple[Array, Array, Array]:
    """Kalker's linear creep forces (N) and spin moment (N m) of the rail on the wheel.

    Fx = -f11 xi_x, Fy = -f22 xi_y - f23 phi, Mz = f23 xi_y - f33 phi, with creepages
    xi_x, xi_y (-) and spin phi (1/m). Plain element-wise arithmetic on arrays of any shape.
    """
    fx = -f11 * xi_x
    fy = -f22 * xi_y - f23 * phi
    mz = f23 * xi_y - f33 * phi
    return fx, fy, mz


def shen_hedrick_elkins(
    fx: Array, fy: Array, mz: Array, mu: Array, normal_force: Array
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shen-Hedrick-Elkins (1983) saturation of linear creep forces, element-wise.

    beta = |F| / (mu N) with |F| = sqrt(Fx^2 + Fy^2); the resultant becomes
    mu N (beta - beta^2/3 + beta^3/27) for beta <= 3 and mu N beyond, and all three
    components (Fx, Fy, Mz) are scaled by that over |F|. Zero creep gives zero force (the
    factor tends to 1), and N <= 0 (lift-off) gives zero force.
    """
    fx = np.asarray(fx, dtype=float)
    fy = np.asarray(fy, dtype=float)
    mz = np.asarray(mz, dtype=float)
    limit = np.asarray(mu, dtype=float) * np.maximum(np.asarray(normal_force, dtype=float), 0.0)
    f_lin = np.sqrt(fx * fx + fy * fy)
    has_load = limit > 0.0
    beta = np.where(has_load, f_lin / np.where(has_load, limit, 1.0), 0.0)
    small = beta <= 3.0
    factor = np.where(small, 1.0 - beta / 3.0 + beta * beta / 27.0, 1.0 / np.maximum(beta, 3.0))
    factor = np.where(has_load, factor, 0.0)
    return fx * factor, fy * factor, mz * factor
