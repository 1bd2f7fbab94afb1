"""Side bearers of the car body on the bolsters (vehicle/body_bolster.py): a
constant-contact elastomer with preload and loss, a solid stop after its travel, lift-off
(no tension).

The side-bearer force is read off the equations of motion themselves: two evaluations of
``model.rhs`` at the same state, one with the wagon's side-bearer constants and one with
them all zero (preload, stiffness, loss, stop), differ by the side bearers' forces alone.
Their difference on the front bolster's vertical row is the sum of the two bearers' forces
over their preloads, on its roll row the moment of their difference at +-X11/2, so each
bearer's force follows. The state lifts and rolls the front bolster against the car body
so that the left bearer is compressed by c from static and the right one not at all.
"""

import numpy as np
import pytest

from railsusp.vehicle import layout as L
from railsusp.vehicle.operating_point import linearisation_point
from railsusp.vehicle.wagon import load_wagon

N = L.N_DOF
BOL = L.BOL0  # front bolster: y, z, roll, yaw
SB_KEYS = ("P_sb", "k_sb", "c_sb", "k_sb_stop")


@pytest.fixture(scope="module")
def point():
    return linearisation_point()


def side_bearer_forces(point, compression: float, rate: float = 0.0) -> tuple[float, float]:
    """(left, right) force of the front bolster's side bearers (N, + compressive) with the
    left one compressed by ``compression`` (m) from static at ``rate`` (m/s), the right one
    at its static height and at rest."""
    half = 0.5 * point.P[10]  # X11
    x = np.zeros(L.N_STATE)
    x[BOL + 1] = 0.5 * compression  # bolster up
    x[BOL + 2] = 0.5 * compression / half  # and rolled: the left side up by c, the right 0
    x[N + BOL + 1] = 0.5 * rate
    x[N + BOL + 2] = 0.5 * rate / half
    with_sb = point.rhs(x)
    K = point.K.copy()
    for key in SB_KEYS:
        K[L.K[key]] = 0.0
    bare = type(point)(**{**point.__dict__, "K": K}).rhs(x)
    inertia = point.dof_inertia()
    # on the bolster: -(sum of df) vertically, -(half (f_L - f_R)) in roll
    total = -(with_sb[N + BOL + 1] - bare[N + BOL + 1]) * inertia[BOL + 1]
    moment = -(with_sb[N + BOL + 2] - bare[N + BOL + 2]) * inertia[BOL + 2]
    preload = point.K[L.K["P_sb"]]
    left = 0.5 * (total + 2.0 * preload + moment / half)
    right = 0.5 * (total + 2.0 * preload - moment / half)
    return left, right


def test_side_bearer_at_static_height_carries_its_preload(point):
    left, right = side_bearer_forces(point, 0.0)
    preload = load_wagon().side_bearer.preload
    assert left == pytest.approx(preload, rel=1e-6)
    assert right == pytest.approx(preload, rel=1e-6)


def test_side_bearer_goes_solid_after_its_travel(point):
    """Force against compression: the elastomer's 2.5 MN/m up to the 5 mm travel, the
    stop's 50 MN/m more beyond it (wagon data), and the right bearer untouched."""
    sb = load_wagon().side_bearer
    travel, k, k_stop = sb.travel, sb.vertical_stiffness, sb.stop_stiffness
    c = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 0.95, 1.05, 1.2, 1.4]) * travel
    f = np.array([side_bearer_forces(point, ci) for ci in c])
    expected = sb.preload + k * c + k_stop * np.clip(c - travel, 0.0, None)
    np.testing.assert_allclose(f[:, 0], expected, rtol=1e-6)
    np.testing.assert_allclose(f[:, 1], sb.preload, rtol=1e-6)
    below = np.diff(f[:5, 0]) / np.diff(c[:5])
    above = np.diff(f[-3:, 0]) / np.diff(c[-3:])
    np.testing.assert_allclose(below, k, rtol=1e-6)
    np.testing.assert_allclose(above, k + k_stop, rtol=1e-6)


def test_side_bearer_lifts_off_without_tension(point):
    """Extended by more than preload / stiffness (10 mm) the bearer leaves its wear plate:
    zero force, never a pull; and on a fast rebound its loss cannot pull either."""
    sb = load_wagon().side_bearer
    lift_off = -sb.preload / sb.vertical_stiffness
    for c in (0.5 * lift_off, 0.99 * lift_off):
        left, _ = side_bearer_forces(point, c)
        assert left == pytest.approx(sb.preload + sb.vertical_stiffness * c, rel=1e-6)
    for c in (1.01 * lift_off, 2.0 * lift_off, 5.0 * lift_off):
        left, right = side_bearer_forces(point, c)
        assert left == pytest.approx(0.0, abs=1e-6)
        assert right == pytest.approx(sb.preload, rel=1e-6)
    # half the lift-off extension, rebounding at 1 m/s: the elastic force minus the loss
    # c v is negative, so the bearer carries nothing
    rate = -1.0
    assert sb.preload + 0.5 * sb.vertical_stiffness * lift_off + sb.damping * rate < 0.0
    left, _ = side_bearer_forces(point, 0.5 * lift_off, rate)
    assert left == pytest.approx(0.0, abs=1e-6)
    # compressing at the same speed adds the loss
    left, _ = side_bearer_forces(point, 0.5 * lift_off, -rate)
    expected = sb.preload + 0.5 * sb.vertical_stiffness * lift_off + sb.damping * -rate
    assert left == pytest.approx(expected, rel=1e-6)
