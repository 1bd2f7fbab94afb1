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
from railsusp.vehicle.model import rhs as model_rhs
from railsusp.vehicle.operating_point import LinearisationPoint, point_of
from railsusp.vehicle.setup import SolverSettings, constants
from railsusp.vehicle.suspension import series_stiffness
from railsusp.vehicle.track_grid import track_arrays
from railsusp.vehicle.track_lookup import frame_turn, track_point, track_rate
from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_12_03_1, WagonData, load_wagon
from railsusp.working_condition import CANT_BASE_M, make_condition

NQ = L.N_DOF
RADIUS, CANT, SPIRAL, START = 300.0, 0.110, 200.0, 100.0  # m
DT = 1.0e-3  # s, the simulator's step at 40 km/h
_IDENTITY = np.array([[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]])
_OLD = FORCE_LAWS_BEFORE_2026_12_03_1


def _condition():
    return make_condition(
        {
            "name": "spiral", "speed_kmh": 40.0, "irregularity_class": None, "lead_in_m": 0.0,
            "duration_s": 40.0, "curve_radius_m": RADIUS, "cant_mm": CANT * 1e3,
            "curve_start_m": START, "entry_spiral_m": SPIRAL,
        }
    )  # fmt: skip


def _point(wagon: WagonData, settings: SolverSettings | None = None) -> LinearisationPoint:
    """The model's inputs on a perfect left-hand curve entered from tangent over a long
    spiral (clothoid with a linear cant ramp from START to START + SPIRAL); ``settings``:
    other solver settings (a finer track grid) than the simulator's defaults."""
    point = point_of(ParameterSet.nominal().to_array(), wagon, _condition())
    if settings is None:
        return point
    cond = _condition()
    tracks, s0, ds = track_arrays(cond, [0], wagon, settings)
    K = constants(wagon, cond, point.P, point.contact, settings)
    return dataclasses.replace(point, K=K, track=np.ascontiguousarray(tracks[0]), s0=s0, ds=ds)


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


@pytest.mark.parametrize("laws", ["today", "before 2026-12-03.1", "on a 5 mm grid"])
def test_the_car_body_keeps_its_roll_rate_where_the_cant_ramp_starts(laws):
    """Where the car body passes the ramp's start, its frame begins to roll at V dphi/ds
    (here -4.08 mrad/s) within a few milliseconds. The car body, on soft springs, cannot
    change its own roll rate or its lateral speed in that time, so against its frame its
    roll rate changes by -V dphi/ds and the lateral speed of its centre of gravity, h above
    the rail, by h V dphi/ds (the frame's axis at that height moves under it). Measured
    within 0.02 s across the passage: 3.92 mrad/s of 4.08 and -7.5 mm/s of -8.4 (the
    leading bogie, 0.8 s into the ramp, moves the body meanwhile). Without the frame's
    roll acceleration the body's relative roll rate stays (0.37 mrad/s): its absolute roll
    rate jumped with no moment on it. On a grid of 5 mm the roll impulse passes in 0.45 ms,
    under the 1 ms step: spread over the grid's half cells alone RK4 took it 1.54 times."""
    wagon = load_wagon() if laws != "before 2026-12-03.1" else load_wagon().with_values(_OLD)
    point = _point(wagon, SolverSettings(track_step=0.005) if laws == "on a 5 mm grid" else None)
    k = point.K
    t0 = (START + k[L.K["l_c"]] + k[L.K["a"]]) / point.speed  # the car body's centre passes
    before, after = _states(point, [t0 - 0.01, t0 + 0.01])
    frame_rate = point.speed * _cant_slope()
    roll_jump = after[NQ + L.CB_ROLL] - before[NQ + L.CB_ROLL]
    lateral_jump = after[NQ + L.CB_Y] - before[NQ + L.CB_Y]
    turning = laws != "before 2026-12-03.1"
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
    flat = _states(_point(wagon.with_values({"track.design_twist": False})), times)
    jl, jr = L.SF0, L.SF0 + 5  # the leading bogie's left and right side frames
    point = _point(wagon)
    a, b1 = point.K[L.K["a"]], point.K[L.K["b1"]]
    expected = -b1 * (2.0 * a * _cant_slope()) / a
    for x, y in zip(twisted, flat, strict=True):
        part = (x[jl + 3] - x[jr + 3]) - (y[jl + 3] - y[jr + 3])
        assert part == pytest.approx(expected, rel=0.05)


def test_the_car_body_yaws_to_meet_its_centre_plates_in_their_bogies_canted_frames():
    """The design twist's lateral part: each centre plate, h_cp above the rail, lies in its
    bolster's frame, rolled against the car body's by cant_b - cant_c = +-l_c dphi/ds along
    the ramp, so the two plates stand -+h_cp l_c dphi/ds across from where the car body's
    frame puts them, and the car body, free to yaw, turns against its frame by
    -h_cp dphi/ds to meet them (0.257 mrad here; 0.254-0.259 measured 65-90 m into the
    ramp, the term against without). Without it the car body did not turn: the plates were
    taken across as if both bogies stood on its cant."""
    wagon = load_wagon()
    times = [14.0, 16.0, 18.0]
    twisted = _states(_point(wagon), times)
    flat = _states(_point(wagon.with_values({"track.design_twist": False})), times)
    expected = -_point(wagon).K[L.K["h_cp"]] * _cant_slope()
    for x, y in zip(twisted, flat, strict=True):
        assert x[L.CB_YAW] - y[L.CB_YAW] == pytest.approx(expected, rel=0.03)


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


def _rhs(point, K, x, s_front):
    """(d x / d t, output channels) of the model at state x."""
    dxdt = np.zeros(L.N_STATE)
    out = np.zeros(L.N_OUT_WORK)
    ca = point.contact
    code = model_rhs(
        x, dxdt, point.P, K, point.track, point.s0, point.ds, ca.table, ca.y0, ca.dy, ca.H0L,
        ca.H0R, s_front, out,
    )  # fmt: skip
    assert code == 0
    return dxdt, out


def test_every_bodys_frame_terms_are_the_rigid_kinematics_of_its_centre_of_gravity():
    """At the same state, the frame's terms change each body's relative acceleration by
    minus the frame's own at the body's centre of gravity. The frame turns at
    omega = (phi', psi' sin phi, psi' cos phi) in the canted axes (psi' = V kappa, phi' the
    cant rate), about the rail-level centreline: a body's moments change by
    -I domega/dt - omega x I omega (Euler's equations; the car body's whole, the other
    bodies' -I domega/dt, their omega x I omega under a newton metre), its centre of gravity
    H above the rail by the lateral +H phi'' and a side frame b2 off the centreline by the
    vertical -(+-b2) phi''; each wheelset's gyroscopic moments are those of the frame's
    rates (roll +h psi' cos phi, yaw -h phi'). The forces of the elements and contacts do
    not change, so neither does the car body's specific force (the lateral acceleration
    output). Each body is put at the ramp's start in turn (its phi'' nonzero), the others in
    the spiral or before it."""
    point = _point(load_wagon())
    k = point.K
    old = k.copy()
    old[L.K["frame_rotation"]] = 0.0
    lc, a, b2, V = k[L.K["l_c"]], k[L.K["a"]], k[L.K["b2"]], point.speed
    h = {"c": k[L.K["h_cg_c"]], "b": k[L.K["h_cg_b"]], "f": k[L.K["h_cg_f"]]}
    h_spin = point.P[2] * V / k[L.K["r0"]]
    inertia = point.dof_inertia()
    n, inv_ds = point.track.shape[1], 1.0 / point.ds
    half = max(0.5, k[L.K["turn_half_window"]] * inv_ds)

    def frame(s):
        """The frame's angular velocity and acceleration in the canted axes at s."""
        i, f, inside = track_point(s, point.s0, inv_ds, n)
        yaw_dd, roll_dd = frame_turn(point.track, i, f, inside, n, V, V * inv_ds, half)
        kappa = point.track[L.TR_KAPPA, i] * (1 - f) + point.track[L.TR_KAPPA, i + 1] * f
        phi = point.track[L.TR_CANT, i] * (1 - f) + point.track[L.TR_CANT, i + 1] * f
        phi_d = track_rate(point.track, L.TR_CANT, i, inside, V * inv_ds)
        psi_d = V * kappa
        omega = np.array([phi_d, psi_d * math.sin(phi), psi_d * math.cos(phi)])
        omega_d = np.array(
            [
                roll_dd,
                yaw_dd * math.sin(phi) + psi_d * phi_d * math.cos(phi),
                yaw_dd * math.cos(phi) - psi_d * phi_d * math.sin(phi),
            ]
        )
        return omega, omega_d

    car_i = np.array([k[L.K["Ix_c"]], k[L.K["Iy_c"]], k[L.K["Iz_c"]]])
    x = np.zeros(L.N_STATE)
    for behind in (0.0, a, 2 * a, lc + a, 2 * lc, 2 * lc + a, 2 * lc + 2 * a):
        s_front = START + behind + 0.3 * point.ds
        new, out_new = _rhs(point, k, x, s_front)
        was, out_was = _rhs(point, old, x, s_front)
        want = np.zeros(L.N_STATE)
        s_c = s_front - lc - a
        w, wd = frame(s_c)
        moment = -car_i * wd - np.cross(w, car_i * w)
        want[NQ + L.CB_Y] = h["c"] * wd[0]
        want[NQ + L.CB_ROLL : NQ + L.CB_YAW + 1] = moment / car_i
        for kb in range(2):
            s_b = s_c + (lc if kb == 0 else -lc)
            w, wd = frame(s_b)
            ib = NQ + L.BOL0 + 4 * kb
            want[ib], want[ib + 2], want[ib + 3] = h["b"] * wd[0], -wd[0], -wd[2]
            for sidx, side in enumerate((1.0, -1.0)):
                jf = NQ + L.SF0 + 5 * (2 * kb + sidx)
                want[jf + 1], want[jf + 2] = h["f"] * wd[0], -side * b2 * wd[0]
                want[jf + 3], want[jf + 4] = -wd[1], -wd[2]
            for wi in range(2):
                w, wd = frame(s_b + (a if wi == 0 else -a))
                iw = NQ + L.WS0 + 4 * (2 * kb + wi)
                want[iw] = k[L.K["r0"]] * wd[0]
                want[iw + 2] = -wd[0] + h_spin * w[2] / inertia[iw - NQ + 2]
                want[iw + 3] = -wd[2] - h_spin * w[0] / inertia[iw - NQ + 3]
        scale = np.abs(want).max()
        np.testing.assert_allclose(new - was, want, rtol=0, atol=1e-9 * scale)
        assert out_new[L.OUT_ACC_Y] == pytest.approx(out_was[L.OUT_ACC_Y], abs=1e-9 * scale)
    assert frame(START + 0.3 * point.ds)[1][0] != 0.0  # (each body there in turn)


@pytest.mark.parametrize(
    "layout",
    [
        {"entry_spiral_m": 60.0, "arc_length_m": 40.0, "exit_spiral_m": 30.0},
        {"entry_spiral_m": 0.0, "arc_length_m": 25.0, "exit_spiral_m": 0.0},
        {"entry_spiral_m": 45.0},
    ],
)
def test_the_frame_turns_only_within_the_transitions_the_constants_name(layout):
    """The right-hand side evaluates the frame's angular accelerations only within the
    transitions the constants name (``layout.TURN_SPANS``, widened), since they are zero
    elsewhere: checked at every grid sample and between, on a curve with both spirals, one
    entered and left abruptly (each step an impulse of one cell) and one without end. A span
    too narrow would drop a ramp end's roll impulse."""
    wagon = load_wagon()
    cond = _condition().with_changes(curve_start_m=40.0, **layout)
    point = point_of(ParameterSet.nominal().to_array(), wagon, cond)
    k, n, inv_ds = point.K, point.track.shape[1], 1.0 / point.ds
    spans = [k[L.K[name]] for name in L.TURN_SPANS]
    half = max(0.5, k[L.K["turn_half_window"]] * inv_ds)
    turning = 0
    for s in point.s0 + point.ds * np.arange(0.0, n - 1.0, 0.25):
        i, f, inside = track_point(s, point.s0, inv_ds, n)
        yaw, roll = frame_turn(
            point.track, i, f, inside, n, point.speed, point.speed * inv_ds, half
        )
        if yaw != 0.0 or roll != 0.0:
            turning += 1
            assert spans[0] <= s <= spans[1] or spans[2] <= s <= spans[3], s
    assert turning > 0


@pytest.mark.parametrize("phase", [0.0, 0.2, 0.5, 0.7, 0.9])
def test_rk4_takes_a_curvature_steps_yaw_impulse_once_on_a_fine_grid(phase):
    """A curve entered without spiral steps the curvature within one grid cell: the frame's
    yaw rate jumps by V kappa, an impulse that on a 5 mm grid passes in 0.45 ms, under the
    1 ms step. RK4's stages (at the step's start, middle and end) must take it once,
    wherever they fall: spread over the roll's window (at least a step's run) they do to
    1e-9; left within its cell they took 0, 0.74 or 1.48 times of it."""
    wagon = load_wagon()
    cond = _condition().with_changes(cant_mm=0.0, entry_spiral_m=0.0)
    settings = SolverSettings(track_step=0.005)
    tracks, s0, ds = track_arrays(cond, [0], wagon, settings)
    trk = np.ascontiguousarray(tracks[0])
    point = point_of(ParameterSet.nominal().to_array(), wagon, cond)
    k = constants(wagon, cond, point.P, point.contact, settings)
    n, V = trk.shape[1], cond.speed
    half = max(0.5, k[L.K["turn_half_window"]] / ds)

    def yaw_acc(s):
        i, f, inside = track_point(s, s0, 1.0 / ds, n)
        return frame_turn(trk, i, f, inside, n, V, V / ds, half)[0]

    rate, s = 0.0, START - 0.2 + phase * V * DT
    for _ in range(40):
        rate += DT / 6.0 * (yaw_acc(s) + 4.0 * yaw_acc(s + 0.5 * V * DT) + yaw_acc(s + V * DT))
        s += V * DT
    assert rate == pytest.approx(V / RADIUS, rel=1e-9)


def test_the_primarys_lateral_twist_moves_the_axle_box_and_its_rate_with_it():
    """The design twist's lateral part in the primary, at the rhs: a leading wheelset just
    past the ramp's start, its bogie centre still before it, stands on cant
    phi_w = (s_w - START) dphi/ds rolled against the bogie's 0, which moves its axle box,
    r0 above the rail, across by -r0 phi_w in the bogie's frame, at the rate -r0 V dphi/ds
    (the two frames' roll rates differ here by the whole ramp's). With the wagon at rest in
    its frames, switching the twist on changes the lateral force on the wheelset by
    2 r0 (k_py phi_w + c_py V dphi/ds) (both sides), the side frames' by as much the other
    way: the displacement's and the damper's parts, each with its sign (the damper's,
    a quarter of the spring's here, went untested: its sign flipped, every other test passed)."""
    point = _point(load_wagon())
    k = point.K
    flat = k.copy()
    flat[L.K["design_twist"]] = 0.0
    a, r0, V = k[L.K["a"]], k[L.K["r0"]], point.speed
    s_front = START + 0.4 * a  # the bogie centre, a behind, before the ramp
    x = np.zeros(L.N_STATE)
    new, _ = _rhs(point, k, x, s_front)
    was, _ = _rhs(point, flat, x, s_front)
    inertia = point.dof_inertia()
    iw, jf = L.WS0, L.SF0
    k_py = series_stiffness(point.P[13], point.P[19])
    phi_w = float(
        np.interp(
            s_front, point.s0 + point.ds * np.arange(point.track.shape[1]), point.track[L.TR_CANT]
        )
    )
    i = int((s_front - point.s0) / point.ds)
    rate = V / point.ds * (point.track[L.TR_CANT, i + 1] - point.track[L.TR_CANT, i])
    assert rate == pytest.approx(V * _cant_slope(), rel=1e-3)
    want = 2.0 * r0 * (k_py * phi_w + k[L.K["c_py"]] * rate)
    assert (new - was)[NQ + iw] * inertia[iw] == pytest.approx(want, rel=1e-9)
    for side_frame in (jf, jf + 5):
        got = (new - was)[NQ + side_frame + 1] * inertia[side_frame + 1]
        assert got == pytest.approx(-want / 2.0, rel=1e-9)
