"""The roll moments of revision 2026-11-30.2 (docs/model.md, "Roll moments"): the side frames
roll with their wheelsets, the car body's support loads give a gravity roll moment, and the
coupler line between like cars lies along the track's tangent halfway between them.

Each test is checked against the model before it (the wagon fields of
``FORCE_LAWS_BEFORE_2026_11_30_2``), which fails it."""

import numpy as np
import pytest

from railsusp.conditions import GRAVITY as G
from railsusp.conditions import get_condition
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.operating_point import linearisation_point
from railsusp.vehicle.setup import SolverSettings
from railsusp.vehicle.simulate import simulate
from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_11_30_2, WagonData, load_wagon


def _before() -> WagonData:
    return load_wagon().with_values(FORCE_LAWS_BEFORE_2026_11_30_2)


def _rigid_roll(wagon: WagonData, theta: float) -> np.ndarray:
    """Displacements of the whole wagon turned rigidly by ``theta`` about the track's
    centreline at rail level: each body's CG moves -h theta sideways (h its height), the
    rolling bodies roll theta, the side frames (no roll freedom of their own) move up and
    down by +-b2 theta."""
    cb, bo, sf, bg = wagon.car_body, wagon.bolster, wagon.side_frame, wagon.bogie
    u = np.zeros(L.N_DOF)
    u[L.CB_Y], u[L.CB_ROLL] = -cb.cg_height * theta, theta
    for k in range(2):
        ib = L.BOL0 + 4 * k
        u[ib], u[ib + 2] = -bo.cg_height * theta, theta
        for sidx, side in enumerate((1.0, -1.0)):
            jf = L.SF0 + 5 * (2 * k + sidx)
            u[jf + 1] = -sf.cg_height * theta
            u[jf + 2] = side * bg.spring_nest_half_span * theta
    for w in range(4):
        iw = L.WS0 + 4 * w
        u[iw], u[iw + 2] = -wagon.wheelset.rolling_radius * theta, theta
    return u


def _forces_of_rigid_roll(wagon: WagonData, theta: float = 1e-4) -> np.ndarray:
    """Generalised forces (N, N m) on the degrees of freedom above the wheelsets when the
    whole wagon is turned rigidly by theta (central difference of the right-hand side at the
    static equilibrium, friction stuck)."""
    point = linearisation_point(wagon=wagon)
    x = np.zeros(L.N_STATE)
    x[: L.N_DOF] = _rigid_roll(wagon, theta)
    f = 0.5 * (point.rhs(x) - point.rhs(-x))[L.N_DOF : 2 * L.N_DOF] * point.dof_inertia()
    return f[: L.WS0]


def test_turning_the_whole_wagon_strains_no_suspension_element():
    """A rigid turn of the whole wagon deforms nothing between the bodies: no suspension force
    may change. The one generalised force left above the wheelsets is the car body's gravity
    roll moment W h theta (its support loads now h theta off its centreline). Before, the side
    frames could not follow the turn: their nests and axle boxes were strained (54 N on each
    bolster, 32 N on each side frame at 0.1 mrad)."""
    wagon = load_wagon()
    theta = 1e-4
    f = _forces_of_rigid_roll(wagon, theta)
    w_body = wagon.car_body.mass * G
    h = wagon.car_body.cg_height - wagon.bogie.centre_plate_height
    assert f[L.CB_ROLL] == pytest.approx(w_body * h * theta, rel=1e-6)
    others = np.delete(f, L.CB_ROLL)
    assert np.max(np.abs(others)) < 1e-6
    before = np.delete(_forces_of_rigid_roll(_before(), theta), L.CB_ROLL)
    assert np.max(np.abs(before)) > 10.0


def _transfer(wagon: WagonData, cant_mm: float) -> tuple[float, float]:
    """(sum over the axles of Q_outer - Q_inner, N; the uncompensated lateral acceleration,
    m/s²) of the nominal wagon settled in a 300 m curve at 60 km/h on perfect track."""
    c = get_condition("curve", irregularity_class=None, duration_s=1.0, n_steps=50)
    c = c.with_changes(curve_radius_m=300.0, cant_mm=cant_mm)
    r = simulate(None, c, wagon=wagon, settings=SolverSettings(start="settled"))
    assert r.status[0] == 0 and r.settled_start[0]
    q = r.Q[0].mean(axis=-1)
    outer = 1 if c.curvature > 0 else 0  # a left curve's outer wheels are the right ones
    dq = float(np.sum(q[outer::2] - q[1 - outer :: 2]))
    phi = c.cant_angle
    return dq, c.speed**2 / 300.0 * np.cos(phi) - G * np.sin(phi)


def _rigid_transfer_per_acceleration(wagon: WagonData) -> float:
    """Sum of m h / b0 over the bodies, N per m/s²: the outer-inner load transfer of the wagon
    as one rigid body per unit lateral acceleration (CG heights above rail)."""
    cb, bo, sf = wagon.car_body, wagon.bolster, wagon.side_frame
    m_w = ParameterSet.nominal().to_array()[0]
    mh = (
        cb.mass * cb.cg_height
        + 2 * bo.mass * bo.cg_height
        + 4 * sf.mass * sf.cg_height
        + 4 * m_w * wagon.wheelset.rolling_radius
    )
    return mh / wagon.wheelset.contact_half_distance


def test_the_load_transfer_of_a_curve_is_at_least_the_rigid_wagons():
    """Per m/s² of uncompensated acceleration (the difference between no cant and the balance
    cant at R 300 m, which takes out the curving forces' own share), the wheels' outer-inner
    transfer is at least the rigid wagon's sum m h / b0 (256 kN), and above it by the body's
    sway (its CG moves out as it rolls) by a few per cent. Measured: 265 kN; before the side
    frames' couple and the gravity roll moment 236 kN, 8 % short of the rigid wagon."""
    rigid = _rigid_transfer_per_acceleration(load_wagon())

    def slope(wagon):
        dq0, a0 = _transfer(wagon, 0.0)
        dq1, a1 = _transfer(wagon, 141.6)  # the balance cant at 60 km/h
        return (dq0 - dq1) / (a0 - a1)

    now = slope(load_wagon())
    assert rigid < now < 1.06 * rigid
    assert slope(_before()) < 0.95 * rigid


def test_the_coupler_line_lies_along_the_tangent_halfway_between_the_cars():
    """With a coupler force F in a curve, the couplers pull the wagon inwards by 2 F kappa L/2
    (L the length over couplers: the coupler line between like cars is parallel to the track
    halfway between their centres), the track's lateral forces change by that much: 26.0 kN
    at 650 kN on R 300 m, where the pivot's own distance (5.5 m) gave 23.8 kN."""
    wagon = load_wagon()
    assert wagon.car_body.length_over_couplers == 12.0

    def sum_h(wagon, force_kn):
        c = get_condition("curve", irregularity_class=None, duration_s=1.0, n_steps=50)
        c = c.with_changes(cant_mm=0.0, coupler_force_kN=force_kn)
        r = simulate(None, c, wagon=wagon, settings=SolverSettings(start="settled"))
        assert r.status[0] == 0
        return float(r.H[0].sum(axis=0).mean()), abs(c.curvature)

    h0, kappa = sum_h(wagon, 0.0)
    h1, _ = sum_h(wagon, 650.0)
    expected = 2.0 * 650e3 * kappa * 6.0
    assert abs(h1 - h0) == pytest.approx(expected, rel=1e-3)
    h0b, _ = sum_h(_before(), 0.0)
    h1b, _ = sum_h(_before(), 650.0)
    assert abs(h1b - h0b) == pytest.approx(2.0 * 650e3 * kappa * 5.5, rel=1e-3)


def test_length_over_couplers_is_checked_in_the_wagon_file():
    from railsusp.errors import RailsuspInputError

    with pytest.raises(RailsuspInputError, match=r"car_body.length_over_couplers = 10 m"):
        load_wagon().with_values({"car_body.length_over_couplers": 10.0})
    with pytest.raises(RailsuspInputError, match="length_over_couplers"):
        load_wagon().with_values({"car_body.length_over_couplers": 1000.0})


def test_the_switches_reach_the_kernel_constants():
    """Off, each switch zeroes its constants (the kernel then computes the old model); on,
    they are the wagon's heights and loads."""
    from railsusp.vehicle.setup import constants, contact_arrays

    def consts(wagon):
        c = get_condition("straight")
        return constants(
            wagon, c, ParameterSet.nominal().to_array(), contact_arrays(wagon), SolverSettings()
        )

    wagon = load_wagon()
    k_now, k_before = consts(wagon), consts(_before())
    bo, sf = wagon.bolster, wagon.side_frame
    assert k_now[L.K["sf_arm_nest"]] == pytest.approx(bo.cg_height - sf.cg_height)
    assert k_now[L.K["sf_arm_axle"]] == pytest.approx(wagon.wheelset.rolling_radius - sf.cg_height)
    assert k_now[L.K["x_coupler_line"]] == 6.0
    assert k_now[L.K["rail_damping_cap"]] == 1.0
    for name in ("sf_arm_nest", "sf_arm_axle", "k_roll_gravity", "rail_damping_cap"):
        assert k_before[L.K[name]] == 0.0
    assert k_before[L.K["x_coupler_line"]] == wagon.car_body.coupler_half_spacing
