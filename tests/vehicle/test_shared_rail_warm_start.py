"""The shared-rail solve of tread and flange started warm from the previous evaluation's
solution (vehicle/normal_contact.py, issue 24): the cold start's forces to round-off where it
stands, the cold start's own result, bit for bit, where a contact is nearly opened."""

import numpy as np
import pytest

from railsusp.vehicle.normal_contact import (
    WARM_RATIO,
    _warm_steps,
    hertz_rail_solve,
    shared_rail_newton,
)

G_TREAD, G_FLANGE = 4.2e-8, 5.8e-8  # Hertz constants of the C80 tread and flank, m/N^(2/3)
K_RY, K_RZ = 40e6, 150e6  # rail support per wheel, N/m
A_TREAD = 0.9e-3  # the tread's rigid approach, m


def _compliance(d1: float = 0.06, d2: float = 1.22) -> tuple[float, float, float]:
    """m_ij = n_i . diag(1/k_ry, 1/k_rz) n_j for contact angles d1, d2 (rad)."""
    s1, c1, s2, c2 = np.sin(d1), np.cos(d1), np.sin(d2), np.cos(d2)
    return (
        s1 * s1 / K_RY + c1 * c1 / K_RZ,
        s1 * s2 / K_RY + c1 * c2 / K_RZ,
        s2 * s2 / K_RY + c2 * c2 / K_RZ,
    )


def _solve(a2: float, w1: float = 0.0, w2: float = 0.0):
    """(N1, N2, warm u1, warm u2, single-contact u1, u2) of tread and flange."""
    m11, m12, m22 = _compliance()
    n1, u1 = hertz_rail_solve(A_TREAD, G_TREAD, 1.0 / m11)
    n2, u2 = hertz_rail_solve(a2, G_FLANGE, 1.0 / m22)
    got = shared_rail_newton(n1, u1, n2, u2, A_TREAD, G_TREAD, a2, G_FLANGE, m11, m12, m22, w1, w2)
    return (*got, u1, u2)


def _opening_approach() -> float:
    """The flange's approach at which the tread's load alone opens it (a2 = m12 N1)."""
    m11, m12, _ = _compliance()
    return m12 * hertz_rail_solve(A_TREAD, G_TREAD, 1.0 / m11)[0]


@pytest.mark.parametrize("a2_mm", [0.6, 1.0, 2.0])
@pytest.mark.parametrize("moved", [0.0, 1e-3, -1e-3, 2e-2])
def test_a_warm_start_gives_the_cold_start_forces_to_round_off(a2_mm, moved):
    """From the solution moved by ``moved`` of itself (the previous evaluation's, one step
    of the integrator away), the loads equal the cold start's to 1e-14."""
    cold = _solve(a2_mm * 1e-3)
    assert cold[0] > 0.0 and cold[1] > 0.0
    start = (cold[2] * (1.0 + moved), cold[3] * (1.0 - moved))
    warm = _solve(a2_mm * 1e-3, *start)
    np.testing.assert_allclose(warm[:2], cold[:2], rtol=1e-14)
    # the result is the warm steps' (which differ from the cold steps' in the last bits in
    # most of these cases): the warm start is taken
    assert warm[2:4] == _warm_steps(*start, *_problem(a2_mm * 1e-3))[:2]
    # the warm start's result is kept for the next evaluation: u = N^(1/3)
    np.testing.assert_allclose(np.array(warm[2:4]) ** 3, warm[:2], rtol=1e-15)


def test_a_nearly_opened_flange_keeps_the_cold_start_result_bit_for_bit():
    """Where the flange is nearly opened by the tread's deflection of the rail, its single-
    contact load lies far above the shared one, the cold start's steps only halve its u at
    first and its eight steps end before converging: that result stands as the force laws'
    (a warm start nearer the solution would change the recorded forces), so the warm start is
    not used, even the exact solution."""
    a2 = 1.0000005 * _opening_approach()
    cold = _solve(a2)
    assert cold[1] > 0.0  # the flange still carries a little
    exact = _solve(a2, cold[2], cold[3])  # converged from near it: not taken
    assert exact[:2] == cold[:2]
    assert cold[5] > WARM_RATIO * cold[3]  # the case the ratio guards
    # the cold start's result is off (what the guard keeps), the converged one satisfies the
    # compatibility equation of the flange
    _, m12, m22 = _compliance()
    u1, u2 = _tight(a2)
    assert abs(u2**3 - cold[1]) > 1e-6 * u2**3
    residual = G_FLANGE * u2**2 + m12 * u1**3 + m22 * u2**3 - a2
    assert abs(residual) < 1e-12 * a2


def _tight(a2: float) -> tuple[float, float]:
    """u of tread and flange converged far beyond the solve's own stop (40 Newton steps)."""
    from railsusp.vehicle.normal_contact import shared_rail_step

    m11, m12, m22 = _compliance()
    u1 = hertz_rail_solve(A_TREAD, G_TREAD, 1.0 / m11)[1]
    u2 = hertz_rail_solve(a2, G_FLANGE, 1.0 / m22)[1]
    for _ in range(40):
        d1, d2 = shared_rail_step.py_func(u1, u2, A_TREAD, G_TREAD, a2, G_FLANGE, m11, m12, m22)
        u1, u2 = u1 - d1, u2 - d2
    return u1, u2


@pytest.mark.parametrize(
    "w",
    [
        (0.0, 1.0), (1.0, 0.0), (np.nan, np.nan), (-1.0, -1.0),
        (1e-300, 1e-300), (1e-300, 30.0), (6.9e-310, 6.9e-310),  # uninitialised memory
    ],
)  # fmt: skip
def test_no_warm_start_or_a_bad_one_gives_the_cold_start(w):
    """A wheel with no previous solution (0), or a work vector holding garbage (NaN,
    negative, denormal: a start near zero would underflow the step's determinant and give
    an infinite force or a division error), is solved from the single-contact start: the
    cold result bit for bit."""
    cold = _solve(1.0e-3)
    assert _solve(1.0e-3, *w)[:2] == cold[:2]


def _problem(a2: float) -> tuple:
    """(single-contact u1, u2, and the shared-rail equations' a1, g1, a2, g2, m11, m12, m22)."""
    m11, m12, m22 = _compliance()
    u1 = hertz_rail_solve(A_TREAD, G_TREAD, 1.0 / m11)[1]
    u2 = hertz_rail_solve(a2, G_FLANGE, 1.0 / m22)[1]
    return u1, u2, A_TREAD, G_TREAD, a2, G_FLANGE, m11, m12, m22


@pytest.mark.parametrize("scale", [1.001, 0.999, 1e3, np.inf])
def test_the_warm_start_stands_from_near_the_solution_and_from_above_the_bounds(scale):
    """From the solution moved a little, the warm steps converge and their result is used;
    from far above (or infinity) they start at the single-contact solutions, from which they
    converge (without that clamp, eight steps from 1000 times the solution would not)."""
    cold = _solve(1.0e-3)
    u1, u2, *equations = _problem(1.0e-3)
    v1, v2, stands = _warm_steps(cold[2] * scale, cold[3] * scale, u1, u2, *equations)
    assert stands
    np.testing.assert_allclose([v1**3, v2**3], cold[:2], rtol=1e-14)
    # and a wrong force never stands: a start that ends outside (0, inf) does not
    assert not _warm_steps(1e-300, 1e-300, u1, u2, *equations)[2]
    assert not _warm_steps(1e-300, cold[3], u1, u2, *equations)[2]
