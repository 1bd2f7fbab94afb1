"""The track-following frames in transitions (force-law revision 2026-12-03.1; docs/model.md,
"Transitions"): each body's coordinates are taken against the frame of the design track at
its own position, which turns in yaw along a spiral and in roll along a cant ramp. Its
relative motion must then carry the frame's angular accelerations, and the primary's
vertical deflection the design twist between an axle's frame and its bogie centre's. Each
test reads the model's own states on perfect track (the nominal loaded wagon, R 300 m with
110 mm of cant reached over a 200 m spiral at 40 km/h) against what the frame's rotation
demands, and each fails with the term left out (the switches of
``FORCE_LAWS_BEFORE_2026_12_03_1``, the model before the revision)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.integrate import _run_one
from railsusp.vehicle.operating_point import LinearisationPoint, point_of
from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_12_03_1, WagonData, load_wagon
from railsusp.working_condition import CANT_BASE_M, make_condition

NQ = L.N_DOF
RADIUS, CANT, SPIRAL, START = 300.0, 0.110, 200.0, 100.0  # m
DT = 1.0e-3  # s, the simulator's step at 40 km/h
_IDENTITY = np.array([[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]])
_OLD = FORCE_LAWS_BEFORE_2026_12_03_1


def _point(wagon: WagonData) -> LinearisationPoint:
    """The model's inputs on a perfect left-hand curve entered from tangent over a long
    spiral (clothoid with a linear cant ramp from START to START + SPIRAL)."""
    cond = make_condition(
        {
            "name": "spiral", "speed_kmh": 40.0, "irregularity_class": None, "lead_in_m": 0.0,
            "duration_s": 40.0, "curve_radius_m": RADIUS, "cant_mm": CANT * 1e3,
            "curve_start_m": START, "entry_spiral_m": SPIRAL,
        }
    )  # fmt: skip
    return point_of(ParameterSet.nominal().to_array(), wagon, cond)


def _states(point: LinearisationPoint, times: list[float]) -> list[np.ndarray]:
    """The full state at each of ``times`` (ascending, s), integrated by the simulator's own
    RK4 loop from rest with the leading wheelset at the section start."""
    ca = point.contact
    x = np.zeros(L.N_STATE)
    series = np.zeros((L.N_OUT, 1))
    done, states = 0, []
    for t in times:
        n = round(t / DT) - done
        code, _ = _run_one(
            x, point.P, point.K, point.track, point.s0, point.ds, ca.table, ca.y0, ca.dy,
            ca.H0L, ca.H0R, DT, point.speed * done * DT, n - 1, 1, 1, _IDENTITY, series, 4,
        )  # fmt: skip
        assert code == 0
        done += n
        states.append(x.copy())
    return states


def _cant_slope() -> float:
    """d(cant angle)/ds along the ramp, rad/m (negative: a left-hand curve lowers the left
    rail)."""
    return -math.asin(CANT / CANT_BASE_M) / SPIRAL


@pytest.mark.parametrize("laws", ["today", "before 2026-12-03.1"])
def test_the_car_body_keeps_its_roll_rate_where_the_cant_ramp_starts(laws):
    """Where the car body passes the ramp's start, its frame begins to roll at V dphi/ds
    (here -4.08 mrad/s) within a few milliseconds. The car body, on soft springs, cannot
    change its own roll rate or its lateral speed in that time, so against its frame its
    roll rate changes by -V dphi/ds and the lateral speed of its centre of gravity, h above
    the rail, by h V dphi/ds (the frame's axis at that height moves under it). Measured
    within 0.02 s across the passage: 3.92 mrad/s of 4.08 and -7.5 mm/s of -8.4 (the
    leading bogie, 0.8 s into the ramp, moves the body meanwhile). Without the frame's
    roll acceleration the body's relative roll rate stays (0.37 mrad/s): its absolute roll
    rate jumped with no moment on it."""
    wagon = load_wagon() if laws == "today" else load_wagon().with_values(_OLD)
    point = _point(wagon)
    k = point.K
    t0 = (START + k[L.K["l_c"]] + k[L.K["a"]]) / point.speed  # the car body's centre passes
    before, after = _states(point, [t0 - 0.01, t0 + 0.01])
    frame_rate = point.speed * _cant_slope()
    roll_jump = after[NQ + L.CB_ROLL] - before[NQ + L.CB_ROLL]
    lateral_jump = after[NQ + L.CB_Y] - before[NQ + L.CB_Y]
    turning = laws == "today"
    assert (roll_jump == pytest.approx(-frame_rate, rel=0.1)) == turning
    assert (lateral_jump == pytest.approx(k[L.K["h_cg_c"]] * frame_rate, rel=0.15)) == turning


@pytest.mark.parametrize("laws", ["today", "before 2026-12-03.1"])
def test_the_forces_on_the_car_body_turn_it_with_the_spiral(laws):
    """In the spiral the frame's yaw accelerates at V^2 dkappa/ds = V^2 / (R L)
    (2.06 mrad/s^2 here); the car body follows its frame, so the forces on it (the centre
    plates', the bowls' and side bearers' friction) must give it that yaw acceleration:
    their yaw moment over I_z, read by evaluating the right-hand side without the frame's
    terms at the model's own states, averages V^2 / (R L) cos phi over 2 s in mid-spiral
    (1.99 measured, 1.40-2.99 as the body's yaw oscillates about it). Without the frame's
    yaw acceleration nothing asks for it: -0.07 mrad/s^2 (-0.66 to 0.93)."""
    wagon = load_wagon() if laws == "today" else load_wagon().with_values(_OLD)
    point = _point(wagon)
    without = point.K.copy()
    without[L.K["frame_rotation"]] = 0.0
    forces_only = dataclasses.replace(point, K=without)
    t_60 = (START + 60.0 + point.K[L.K["l_c"]] + point.K[L.K["a"]]) / point.speed
    times = list(t_60 + np.arange(0.0, 2.0, 0.05))  # the car body 60-82 m into the spiral
    moments = [
        forces_only.rhs(x, s_front=point.speed * t)[NQ + L.CB_YAW]
        for t, x in zip(times, _states(point, times), strict=True)
    ]
    yaw_acc = point.speed**2 / (RADIUS * SPIRAL)
    s_c = point.speed * np.mean(times) - point.K[L.K["l_c"]] - point.K[L.K["a"]] - START
    cos_phi = math.cos(_cant_slope() * s_c)
    assert (float(np.mean(moments)) == pytest.approx(yaw_acc * cos_phi, rel=0.1)) == (
        laws == "today"
    )


def test_the_side_frames_pitch_with_the_twist_between_their_axles():
    """In the ramp a bogie's two axles stand on cants 2a dphi/ds apart: its side frames sit
    on their axle boxes, b1 off the centreline, so the left frame's boxes differ in height
    by b1 (phi_lead - phi_trail) and the right's by as much the other way, and the two
    frames pitch against each other by -b1 (phi_lead - phi_trail) / a (0.72 mrad here). The
    design twist's own part of that pitch, with the term against without, is 0.71 mrad
    10 and 30 m into the ramp (the bolster's pitch restraint takes 2 %). Without it the
    primary saw no twist, and the frames' pitch difference held about 0.03-0.26 mrad of
    other loads."""
    wagon = load_wagon()
    times = [10.0, 12.0]
    twisted = _states(_point(wagon), times)
    flat = _states(_point(wagon.with_values({"primary.design_twist": False})), times)
    jl, jr = L.SF0, L.SF0 + 5  # the leading bogie's left and right side frames
    point = _point(wagon)
    a, b1 = point.K[L.K["a"]], point.K[L.K["b1"]]
    expected = -b1 * (2.0 * a * _cant_slope()) / a
    for x, y in zip(twisted, flat, strict=True):
        part = (x[jl + 3] - x[jr + 3]) - (y[jl + 3] - y[jr + 3])
        assert part == pytest.approx(expected, rel=0.05)


def test_a_wheelsets_gyroscopic_roll_moment_is_of_its_absolute_yaw_rate():
    """The spinning wheelset's roll moment I_y (V / r0) psi' is of its yaw rate in space
    (Euler's equations), which on the arc is its frame's V kappa cos phi plus its own. With
    the creep forces off (they act on a yaw rate too), the frame's turning adds
    I_y V / r0 V kappa cos phi (107 N m here) to a wheelset at rest in its frame, and a
    wheelset yawing against its frame at -V kappa cos phi, still in space, has the roll
    moment the model before the revision gave the one at rest in its frame (which it
    treated as still)."""
    wagon = load_wagon()
    point = _point(wagon)
    k = point.K.copy()
    k[L.K["creep_factor"]] = 0.0
    turning = dataclasses.replace(point, K=k)
    k_old = k.copy()
    k_old[L.K["frame_rotation"]] = 0.0
    old = dataclasses.replace(point, K=k_old)
    s_front = START + SPIRAL + 100.0  # the whole wagon on the arc
    phi = -math.asin(CANT / CANT_BASE_M)
    frame_yaw_rate = point.speed / RADIUS * math.cos(phi)
    h_spin = point.P[2] * point.speed / k[L.K["r0"]]
    iw = L.WS0
    i_x = point.dof_inertia()[iw + 2]
    rest = np.zeros(L.N_STATE)
    still = np.zeros(L.N_STATE)
    still[NQ + iw + 3] = -frame_yaw_rate
    turned = turning.rhs(rest, s_front)[NQ + iw + 2] - old.rhs(rest, s_front)[NQ + iw + 2]
    assert turned * i_x == pytest.approx(h_spin * frame_yaw_rate, rel=1e-6)
    in_space = turning.rhs(still, s_front)[NQ + iw + 2] - old.rhs(rest, s_front)[NQ + iw + 2]
    assert in_space * i_x == pytest.approx(0.0, abs=1e-6 * h_spin * frame_yaw_rate)
