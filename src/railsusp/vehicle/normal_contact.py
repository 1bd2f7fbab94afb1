"""Normal forces of a wheel on its elastically supported rail, for the simulator's kernels:
one Hertz contact in series with the rail support, and the tread and the flange together on
one rail, whose deflection under either load lowers it under the other (the shared-rail
solve; docs/model.md, two-point contact).

Both are Newton solves in u = N^(1/3), where the equations are polynomials: the Hertz
approach G N^(2/3) = G u^2 and the rail's deflection N / k = u^3 / k. They allocate nothing
and return tuples, for :mod:`railsusp.vehicle.wheel_rail` (one wheel) and
:mod:`railsusp.vehicle.contact_batch` (eight wheels, SIMD), which keeps each wheel's shared-
rail solution as the next evaluation's warm start.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)

#: Newton iterations of the Hertz-on-elastic-rail cubic at most, and the relative step in
#: u = N^(1/3) after which the solve stops: Newton converges quadratically, so the error
#: after a step of 1e-8 is of order 1e-16 (tests/vehicle/test_wheel_rail_kernel.py)
HERTZ_ITERATIONS = 8
HERTZ_TOLERANCE = 1.0e-8


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def hertz_rail_solve(dn, G, krn):
    """Normal force N (N) and its cube root u for normal approach dn (m) of Hertz contact in
    series with the rail support: dn = G N^(2/3) + N / krn (Hertz law P = (dz/G)^1.5 plus a
    linear rail). Returns (0, 0) for dn <= 0.

    Newton on the cubic u^3 + c u^2 - d = 0 (c = krn G, d = krn dn), convex and increasing
    for u > 0, so that Newton converges monotonically once above the root. Start: where the
    rail dominates (cbrt(d) > c), u = cbrt(d) - c/3 + c^2 / (9 cbrt(d)), the root's expansion
    in c / cbrt(d) (the depressed cubic in u + c/3) to second order, so that two or three
    steps reach round-off; else the smaller of the Hertz-alone and rail-alone roots, each an
    upper bound.
    """
    if dn <= 0.0:
        return 0.0, 0.0
    c = krn * G
    d = krn * dn
    u2 = np.cbrt(d)  # rail alone
    if u2 > c:
        u = u2 - c / 3.0 + c * c / (9.0 * u2)
    else:
        u1 = math.sqrt(dn / G)  # Hertz alone
        u = u1 if u1 < u2 else u2
    for _ in range(HERTZ_ITERATIONS):
        f = (u + c) * u * u - d
        fp = (3.0 * u + 2.0 * c) * u
        du = f / fp
        u -= du
        if abs(du) <= HERTZ_TOLERANCE * u:
            break
    return u * u * u, u


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def hertz_rail_normal_force(dn, G, krn):
    """Normal force N (N) of :func:`hertz_rail_solve`."""
    return hertz_rail_solve(dn, G, krn)[0]


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME)
def shared_rail_normal_forces(a1, g1, a2, g2, m11, m12, m22):
    """Normal forces (N) of two Hertz contacts pressing one elastically supported rail.

    a1, a2: rigid approaches along each contact's normal (m); g1, g2: Hertz constants
    (approach = g N^(2/3)); m_ij = n_i . C n_j: the rail support's compliance C =
    diag(1/k_lateral, 1/k_vertical) projected on the contact normals (m/N). Each contact's
    elastic approach is a_i = g_i N_i^(2/3) + sum_j m_ij N_j: the rail deflects under both
    forces, so a tread load also lowers the rail under the flange. Solved for u_i = N_i^(1/3)
    by Newton from the single-contact solutions (upper bounds, since m12 > 0); a contact
    that the other one's deflection opens carries nothing.
    """
    n1, u1 = hertz_rail_solve(a1, g1, 1.0 / m11)  # (0, 0) for a1 <= 0
    n2, u2 = hertz_rail_solve(a2, g2, 1.0 / m22)
    return shared_rail_newton(n1, u1, n2, u2, a1, g1, a2, g2, m11, m12, m22, 0.0, 0.0)[:2]


#: Newton steps of the shared-rail 2 x 2 solve at most, from either start
SHARED_RAIL_ITERATIONS = 8
#: a warm start's steps stop once each is below this fraction of its u (the error after a
#: step of relative size s is of order s^2: converged to round-off, as the cold start's)
WARM_TOLERANCE = 1.0e-8
#: the warm result stands where neither single-contact solution lies more than this factor
#: above it (in u = N^(1/3)); beyond, the cold start is used. Its steps then halve the
#: nearly opened contact's u before converging quadratically (7 steps at a factor of 2-2.9,
#: 8 at 3.1-4.5, more beyond 5, measured on 16,800 solves in three conditions), and from
#: about 5 its eight steps end unconverged: the force laws' solve as stored (a flange of 12 N
#: left at 12.13, the tread's load 6e-9 off). The warm start would be nearer the solution
#: there, but that moves the recorded forces (by up to 3e-7 of the largest over 3 s), a force
#: change for a new model revision, not a speed-up. Below the factor both starts converge to
#: round-off (forces within 6e-14 of the cold start's over 3 s).
WARM_RATIO = 2.0


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def shared_rail_step(u1, u2, a1, g1, a2, g2, m11, m12, m22):
    """Newton step (d1, d2) in (u1, u2) of the shared-rail equations g_i u_i^2 + sum_j m_ij
    u_j^3 = a_i (:func:`shared_rail_normal_forces`): the new point is u - d."""
    c1 = u1 * u1 * u1
    c2 = u2 * u2 * u2
    f1 = g1 * u1 * u1 + m11 * c1 + m12 * c2 - a1
    f2 = g2 * u2 * u2 + m12 * c1 + m22 * c2 - a2
    j11 = 2.0 * g1 * u1 + 3.0 * m11 * u1 * u1
    j12 = 3.0 * m12 * u2 * u2
    j21 = 3.0 * m12 * u1 * u1
    j22 = 2.0 * g2 * u2 + 3.0 * m22 * u2 * u2
    inv_det = 1.0 / (j11 * j22 - j12 * j21)
    return (j22 * f1 - j12 * f2) * inv_det, (j11 * f2 - j21 * f1) * inv_det


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def _warm_steps(w1, w2, u1, u2, a1, g1, a2, g2, m11, m12, m22):
    """The shared-rail solve from the warm start (w1, w2) held below the single-contact
    solutions (u1, u2): (u1, u2, whether it stands). It does not where a step leaves a u at
    or below zero (or NaN), where SHARED_RAIL_ITERATIONS steps do not converge, or where the
    result is not within WARM_RATIO of the single-contact solutions (below them by more: a
    nearly opened contact, see WARM_RATIO; above them: an overflowed step, since the shared
    loads lie below the single ones). Written in N, the equations' Jacobian is positive
    definite (a diagonal plus the rail's compliance as a Gram matrix), so they have one
    positive root: a start that converges has found it."""
    v1 = min(w1, u1)
    v2 = min(w2, u2)
    for _ in range(SHARED_RAIL_ITERATIONS):
        d1, d2 = shared_rail_step(v1, v2, a1, g1, a2, g2, m11, m12, m22)
        v1 -= d1
        v2 -= d2
        if not (v1 > 0.0 and v2 > 0.0):
            return v1, v2, False
        if abs(d1) <= WARM_TOLERANCE * v1 and abs(d2) <= WARM_TOLERANCE * v2:
            near1 = u1 <= WARM_RATIO * v1 and v1 <= WARM_RATIO * u1
            return v1, v2, near1 and u2 <= WARM_RATIO * v2 and v2 <= WARM_RATIO * u2
    return v1, v2, False


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, error_model="numpy")
def shared_rail_newton(n1, u1, n2, u2, a1, g1, a2, g2, m11, m12, m22, w1, w2):
    """:func:`shared_rail_normal_forces` from the single-contact solutions (n_i, u_i = n_i^(1/3);
    0 where a contact does not touch), started warm from (w1, w2) where they lie within
    WARM_RATIO below those.

    The cold start is the single-contact solutions (upper bounds, since m12 > 0), from which
    the steps fall monotonically: 1e-1, 1e-2, 1e-4, 1e-8 of u, five steps. The warm start is
    the previous evaluation's solution of the same wheel (issue 24): an integration step
    moves it little, and two or three steps converge. Where it does not stand
    (:func:`_warm_steps`, WARM_RATIO) the cold start is used. Returns (N1, N2, w1, w2): the
    next evaluation's warm start, 0 where both contacts did not carry load together.
    Compiled with ``error_model="numpy"``: a division by zero gives inf or NaN, which the
    warm steps reject, instead of raising inside the parallel integration.
    """
    if n2 == 0.0 or a2 - m12 * n1 <= 0.0:
        return n1, 0.0, 0.0, 0.0
    if n1 == 0.0 or a1 - m12 * n2 <= 0.0:
        return 0.0, n2, 0.0, 0.0
    # a start below half the single-contact solutions is not tried: the result must lie
    # within WARM_RATIO of them to stand, and a start near zero (uninitialised memory) would
    # underflow the Newton step's determinant (NaN and 0 fail the comparison too)
    if u1 <= WARM_RATIO * w1 and u2 <= WARM_RATIO * w2:
        v1, v2, ok = _warm_steps(w1, w2, u1, u2, a1, g1, a2, g2, m11, m12, m22)
        if ok:
            return v1 * v1 * v1, v2 * v2 * v2, v1, v2
    for _ in range(SHARED_RAIL_ITERATIONS):
        d1, d2 = shared_rail_step(u1, u2, a1, g1, a2, g2, m11, m12, m22)
        u1 = max(u1 - d1, 0.0)
        u2 = max(u2 - d2, 0.0)
        if abs(d1) + abs(d2) < 1e-9 * (u1 + u2):  # N to ~3e-9 relative
            break
    return u1 * u1 * u1, u2 * u2 * u2, u1, u2
