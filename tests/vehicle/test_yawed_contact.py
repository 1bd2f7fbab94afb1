"""Contact of a yawed wheelset (vehicle/wheel_rail.py): the lead of the contact point, the
touching height, contact angle and gap rate against a brute-force search over the yawed wheel
of revolution on the prismatic rail, the classical lateral creepage -psi / cos(delta) of a
yawed wheelset in flange contact, left/right mirror symmetry, and zero yaw equal to the
zero-yaw contact bit for bit."""

import math
from pathlib import Path

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.profile_shapes import chn60_rail, lm_worn_wheel
from railsusp.vehicle.rigid_profile_contact import rails_in_track_frame
from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays
from railsusp.vehicle.wagon import WagonData, load_wagon
from railsusp.vehicle.wheel_rail import (
    contact_geometry,
    creep_contact_forces,
    wheel_rail_forces,
)

R0 = 0.42
BACK_TO_BACK, BACK_FACE_OFFSET = 1.353, 0.070  # contact_table's defaults


def _zero_yaw_wagon(rigid_bowl: bool = False) -> WagonData:
    """The wagon with the zero-yaw contact; ``rigid_bowl``: and with the centre bowl of the
    model before 2026-11-24's rocking stiffness (a ring of the bowl's vertical stiffness on a
    bolster rigid in bending and pitch) and its wedge pair at the nest centre (no warp
    friction)."""
    if rigid_bowl:
        return load_wagon().with_physics_before_2026_11_24()
    return load_wagon().with_values({"contact.yaw_geometry": False})


@pytest.fixture(scope="module")
def setup():
    wagon = load_wagon()
    ca = contact_arrays(wagon)
    cond = get_condition("curve", irregularity_class=None)
    k = constants(wagon, cond, ParameterSet.nominal().to_array(), ca, SolverSettings())
    return wagon, ca, k


def _geometry(ca, y, yaw, *, vy=0.0, vyaw=0.0, side=1.0, block=1):
    """contact_geometry of one wheel of a wheelset at shift ``y`` (rail at 0, no roll)."""
    return contact_geometry(
        y, 0.0, 0.0, yaw, vy, 0.0, 0.0, vyaw, side, block, 0.0, 0.0, 0.0, 0.0,
        ca.table, ca.y0, 1.0 / ca.dy, 0.0, 0.0, R0, 1.0 / R0, 1.0, True,
    )  # fmt: skip


def _brute_force(y: float, yaw: float, split: float) -> tuple[float, float]:
    """Touching height (m, relative) and lead (m) of the left wheel's flange part, yawed by
    ``yaw``: the lowest vertical gap over the wheel surface of revolution (profile point u,
    angle theta from the bottom) placed in the track frame, against the inclined rail."""
    wheel, rail = lm_worn_wheel(), chn60_rail()
    left, _ = rails_in_track_frame(rail, 1.435, 0.016, 1.0 / 40.0, 1e-5)
    u = np.arange(wheel.y[0], split, 1e-5)
    radius = R0 + wheel.evaluate(u)[0]
    w = 0.5 * BACK_TO_BACK + BACK_FACE_OFFSET + u  # lateral place of the profile point
    theta = np.linspace(-0.12, 0.12, 1201)[:, None]
    sp, cp = math.sin(yaw), math.cos(yaw)
    ty = y + radius * np.sin(theta) * sp + w * cp
    gap = -radius * np.cos(theta) - np.interp(ty, left.y, left.z)
    k = np.unravel_index(np.argmin(gap), gap.shape)
    # parabolic refinement in theta (the surface is smooth in theta)
    g0, g1, g2 = gap[k[0] - 1, k[1]], gap[k], gap[k[0] + 1, k[1]]
    t = 0.5 * (g0 - g2) / (g0 - 2.0 * g1 + g2)
    dth = float(theta[1, 0] - theta[0, 0])
    th = float(theta[k[0], 0]) + t * dth
    g = g1 - 0.25 * (g0 - g2) * t
    return -g, radius[k[1]] * math.sin(th) * cp


@pytest.mark.parametrize("extra", [0.5e-3, 1.5e-3])
@pytest.mark.parametrize("yaw", [0.01, -0.02])
def test_flange_lead_and_height_match_the_yawed_wheel_of_revolution(setup, extra, yaw):
    """Left wheel pressed into its flange: the kernel's lead x_c = r tan(delta) psi (ahead of
    the axle for psi > 0), its touching height raised by r tan^2(delta) psi^2 / 2 and its
    contact angle (the slope of the yawed touching height), with the wheel l psi^2 / 2 nearer
    the track centre (the yawed axle's foreshortening), agree with a brute-force search
    of the lowest point of the yawed wheel of revolution over the prismatic rail."""
    _, ca, _ = setup
    y = ca.flange_shift + extra
    code, gap0, cd0, sd0, *_ = _geometry(ca, y, 0.0)
    code, gap, cd, sd, _, r, *_, x_c, _ = _geometry(ca, y, yaw)
    assert code == 0 and gap0 < 0.0
    tan0 = sd0 / cd0
    assert tan0 > 1.0  # on the flange
    # the analytic small-angle lead, sign and size
    assert x_c == pytest.approx(r * tan0 * yaw, rel=0.03)
    assert math.copysign(1.0, x_c) == math.copysign(1.0, yaw)
    h0, lead0 = _brute_force(y, 0.0, ca.flange_split)
    h1, lead1 = _brute_force(y, yaw, ca.flange_split)
    assert abs(lead0) < 1e-4
    assert x_c == pytest.approx(lead1, rel=0.03)
    dh_kernel = gap0 - gap  # touching height gained by the yaw
    dh_true = h1 - h0
    # the lead's section closes the flange gap, the axle's foreshortening opens it less
    assert 0.0 < dh_true < 0.5 * r * tan0**2 * yaw**2
    assert dh_kernel == pytest.approx(dh_true, rel=0.05)
    # contact angle of the yawed contact: the slope of its touching height
    step = 2e-5
    slope = (_brute_force(y + step, yaw, ca.flange_split)[0]
             - _brute_force(y - step, yaw, ca.flange_split)[0]) / (2 * step)  # fmt: skip
    assert sd / cd == pytest.approx(slope, rel=0.03)


def test_gap_rate_follows_the_yaw_rate(setup):
    """The gap rate the rail damping uses is the time derivative of the yawed gap."""
    _, ca, _ = setup
    y = ca.flange_shift + 1e-3
    yaw, vyaw, h = 0.012, 0.3, 1e-6
    rate = _geometry(ca, y, yaw, vyaw=vyaw)[10]
    fd = (_geometry(ca, y, yaw + vyaw * h)[1] - _geometry(ca, y, yaw - vyaw * h)[1]) / (2 * h)
    # (5e-3: the table's contact angle is a central difference of its heights, not the
    # secant the interpolation follows; each yaw term of the rate is ~100 % of it)
    assert rate == pytest.approx(fd, rel=5e-3)


def test_yaw_moment_of_the_normal_force_is_the_gradient_of_the_contact_potential(setup):
    """With creep off, the lateral force at x_pos gives the yaw moment x_pos F_y, which
    must equal -N d(approach)/d(psi) = N cos(delta) d(gap)/d(psi): the yawed contact stores
    no spurious energy."""
    _, ca, k = setup
    k = k.copy()
    k[L.K["creep_factor"]] = 0.0
    y, yaw, h = ca.flange_shift + 1e-3, -0.015, 1e-6
    z = -1.5e-3  # pressed into the rail
    res = wheel_rail_forces(
        y, z, 0.0, yaw, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0,
        ca.table, ca.y0, ca.dy, 0.0, 0.0, k,
    )  # fmt: skip
    assert res[0] == 0
    # the flange contact alone (the tread's lead is tiny): its normal force from Y
    _, _, cd, sd, *_ = _geometry(ca, y, yaw)
    geo = [_geometry(ca, y, yaw + s * h) for s in (1, -1)]
    dgap = (geo[0][1] - geo[1][1]) / (2 * h)
    tread = _geometry(ca, y, yaw, block=0)
    n_flange = (-res[1] - res[6] * tread[3]) / sd  # Y = -N_f sin d_f - N_t sin d_t
    mz_flange = res[5] - tread[12] * (-res[6] * tread[3])  # less the tread's at x_pos
    assert n_flange > 1e4
    # (1e-2: the contact angle is the table's central difference of the heights, the gap's
    # derivative their interpolation's secant; a wrong sign or term is off by 100 % or more)
    assert mz_flange == pytest.approx(n_flange * cd * dgap, rel=1e-2)


def test_lateral_creepage_is_the_classical_yawed_flange_value():
    """Unsaturated creep (mu large), no velocities: the yaw's lateral creepage at a contact
    of angle delta led by x_c = r tan(delta) psi, with r = r0, is -psi / cos(delta) (the
    in-plane slip of a yawed wheelset in flange contact)."""
    K = np.zeros(L.N_K)
    for name, value in (("r0", R0), ("inv_r0", 1 / R0), ("inv_V", 1 / 16.0), ("mu", 1e12),
                        ("creep_factor", 1.0), ("N_ref", 1e5), ("pen_max", 1.0)):  # fmt: skip
        K[L.K[name]] = value
    for side in (1.0, -1.0):
        for delta in (0.05, 0.6, 1.2):
            cd, sd = math.cos(delta), math.sin(delta)
            yaw = 0.004
            x_c = side * R0 * math.tan(delta) * yaw
            args = (1e5, 0.0, cd, sd, 0.75, R0, 1e-8, 1e6, 1e6, 0.0)
            x_pos = x_c - side * 0.75 * yaw
            f0 = creep_contact_forces(*args, 0.0, 0.0, side, 0.0, 0.0, 0.0, 0.0, 0.0, K, False)
            f1 = creep_contact_forces(*args, x_c, x_pos, side, 0.0, 0.0, yaw, 0.0, 0.0, K, True)
            # fy = -c22 xi_y along the contact-plane lateral t = (cos d, side sin d)
            dfy = (f1[1] - f0[1]) / cd
            assert dfy == pytest.approx(1e6 * yaw / cd, rel=1e-9)  # -c22 (-psi / cos d)
            assert f1[5] - f0[5] == pytest.approx(x_pos * f1[1], rel=1e-9)  # force at x_pos


def test_left_and_right_wheels_mirror(setup):
    """A left wheel at shift y, yaw psi and the right wheel of the mirrored state (-y, -psi,
    mirrored rates and curvature) carry mirrored forces: Y, roll and yaw moments change sign,
    Q and Fx do not."""
    _, ca, k = setup
    rng = np.random.default_rng(5)
    for _ in range(40):
        y = rng.uniform(-0.004, ca.flange_shift + 1.5e-3)
        yaw = rng.uniform(-0.02, 0.02)
        z = rng.uniform(-1.5e-3, 0.0)
        vy, vz, vroll, vyaw = rng.normal(0.0, [0.05, 0.02, 0.05, 0.05])
        roll, kappa = rng.uniform(-2e-3, 2e-3), 1.0 / 300.0
        left = wheel_rail_forces(
            y, z, roll, yaw, vy, vz, vroll, vyaw, kappa, 1.0, 0.0, 0.0, 0.0, 0.0,
            ca.table, ca.y0, ca.dy, ca.H0L, 0.0, k,
        )  # fmt: skip
        right = wheel_rail_forces(
            -y, z, -roll, -yaw, -vy, vz, -vroll, -vyaw, -kappa, -1.0, 0.0, 0.0, 0.0, 0.0,
            ca.table, ca.y0, ca.dy, ca.H0R, 0.0, k,
        )  # fmt: skip
        assert left[0] == right[0] == 0
        scale = max(abs(left[2]), 1.0)
        for j, sign in ((1, -1), (2, 1), (3, 1), (6, 1)):
            assert right[j] == pytest.approx(sign * left[j], abs=2e-4 * scale)
        for j in (4, 5):  # moments, N m
            assert right[j] == pytest.approx(-left[j], abs=2e-4 * scale)


def test_zero_yaw_is_the_zero_yaw_contact_bit_for_bit(setup):
    """At a yaw of exactly 0 the yaw-aware kernel gives the forces of the zero-yaw contact
    (``yaw_geometry = false``, whose lead column is 0, i.e. the kernel before 2026-11-24)
    bit for bit, over tread and flange, both wheels, any rates; with yaw it does not."""
    _, ca, k = setup
    old = contact_arrays(_zero_yaw_wagon())
    assert old.yaw_geometry is False and ca.yaw_geometry is True
    cond = get_condition("curve", irregularity_class=None)
    k_old = constants(_zero_yaw_wagon(), cond, ParameterSet.nominal().to_array(), old,
                      SolverSettings())  # fmt: skip
    assert k[L.K["yaw_geometry"]] == 1.0 and k_old[L.K["yaw_geometry"]] == 0.0
    lead_rows = [b + w + L.CT_LEAD for b in (0, L.CT_FLANGE) for w in (0, L.CT_RIGHT)]
    other = np.setdiff1d(np.arange(L.N_CT), lead_rows)
    np.testing.assert_array_equal(old.table[other], ca.table[other])
    assert np.all(old.table[lead_rows] == 0.0)
    assert np.all(np.any(ca.table[lead_rows] != 0.0, axis=1))
    rng = np.random.default_rng(11)
    changed = 0
    for _ in range(200):
        side = rng.choice([1.0, -1.0])
        y = side * rng.uniform(-0.004, ca.flange_shift + 1.5e-3)
        state = (y, rng.uniform(-1.5e-3, 0.0), rng.uniform(-2e-3, 2e-3))
        rates = tuple(rng.normal(0.0, [0.05, 0.02, 0.05, 0.05]))
        for yaw, expect_equal in ((0.0, True), (rng.uniform(-0.02, 0.02), False)):
            args = (*state, yaw, *rates, 1.0 / 300.0, side, 0.0, 0.0, 0.0, 0.0)
            h0 = ca.H0L if side > 0 else ca.H0R
            new = wheel_rail_forces(*args, ca.table, ca.y0, ca.dy, h0, 0.0, k)
            ref = wheel_rail_forces(*args, old.table, old.y0, old.dy, h0, 0.0, k_old)
            if expect_equal:
                assert new == ref
            else:
                changed += new != ref
    assert changed > 150


ZERO_YAW_REFERENCE = Path(__file__).resolve().parents[1] / "data" / "force_reference_zero_yaw.npz"


def test_zero_yaw_switch_reproduces_the_forces_before_the_yawed_contact():
    """``[contact] yaw_geometry = false`` is the model before 2026-11-24: the curve's forces of
    bench/force_reference.py's three parameter sets equal those stored with that model
    (tests/data/force_reference_zero_yaw.npz, the reference file of commit 9c5e975) to 1e-9
    of the largest force, with that model's centre bowl (a rigid bolster under the ring)."""
    from railsusp.params import MAIN_SUSPENSION, bounds
    from railsusp.vehicle.simulate import simulate_batch

    lo, hi = bounds(MAIN_SUSPENSION)
    sets = lo + (hi - lo) * np.array([[0.5] * len(lo), [0.2] * len(lo), [0.8] * len(lo)])
    cond = get_condition("curve", duration_s=4.0, n_steps=200, lead_in_m=100.0)
    r = simulate_batch(sets, cond, symbols=MAIN_SUSPENSION, wagon=_zero_yaw_wagon(rigid_bowl=True))
    ref = np.load(ZERO_YAW_REFERENCE)
    for name, force in (("curve_Y", r.Y), ("curve_Q", r.Q)):
        assert np.max(np.abs(force - ref[name])) / np.max(np.abs(ref[name])) < 1e-9


def test_yaw_geometry_is_checked_in_the_wagon_file(tmp_path):
    from importlib import resources

    from railsusp.errors import RailsuspInputError

    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    assert load_wagon().contact.yaw_geometry is True  # the default
    for value, ok in (("false", True), ('"sometimes"', False)):
        path = tmp_path / "wagon.toml"
        path.write_text(text.replace("[contact]\n", f"[contact]\nyaw_geometry = {value}\n"))
        if ok:
            assert contact_arrays(load_wagon(path)).yaw_geometry is False
        else:
            with pytest.raises(RailsuspInputError, match=r"contact\.yaw_geometry = 'sometimes'"):
                load_wagon(path)


def test_a_row_of_zero_lead_keeps_the_yawed_axle_arm(setup):
    """A tread stretch with a flat touching height (contact angle 0, so lead r tan(delta) = 0,
    as on a cylindrical wheel) under a yawed wheelset: the lateral force still acts at the
    wheel's place x_pos = -side l psi of the yawed axle, so the yaw moment is continuous in
    the lateral shift across the edge of the flat stretch. A kernel that took a zero lead for
    the zero-yaw contact dropped the arm there: a jump of about l psi F_y."""
    _, ca, k = setup
    table = ca.table.copy()
    i = round(-ca.y0 / ca.dy)  # the centred tread row
    # left wheel: rows i - 2 .. i flat, the right wheel the mirror image, rows i .. i + 2
    for side0, rows in ((0, slice(i - 2, i + 1)), (L.CT_RIGHT, slice(i, i + 3))):
        table[side0 + L.CT_DELTA, rows] = 0.0
        table[side0 + L.CT_LEAD, rows] = 0.0
        table[side0 + L.CT_H, rows] = table[side0 + L.CT_H, i]
    yaw, z = 0.01, -0.4e-3  # 10 mrad, pressed into the rail
    edge = ca.y0 + i * ca.dy

    def forces(y, side, psi=yaw):
        res = wheel_rail_forces(
            side * y, z, 0.0, side * psi, 0.0, 0.0, 0.0, 0.0, 0.0, side, 0.0, 0.0, 0.0, 0.0,
            table, ca.y0, ca.dy, 0.0, 0.0, k,
        )  # fmt: skip
        assert res[0] == 0
        return res

    for side in (1.0, -1.0):
        inside, outside = forces(edge - 1e-9, side), forces(edge + 1e-9, side)
        f_y = inside[1]
        arm = ca.table[L.CT_L, i] * yaw
        assert abs(arm * f_y) > 10.0  # the moment the old kernel lost, N m
        assert outside[5] == pytest.approx(inside[5], abs=1e-3 * abs(arm * f_y))
        assert outside[1] == pytest.approx(f_y, rel=1e-6)
        # inside the flat stretch: the lateral force acts at x_pos = -l psi (3e-3: the
        # arm is read at the yawed contact's moved rail point, the old kernel is off by 50 %)
        lat = ca.table[L.CT_L, i]
        assert inside[5] == pytest.approx(-lat * yaw * f_y - side * lat * inside[3],
                                          rel=3e-3)  # fmt: skip
        # and the forces are continuous in the yaw there too: psi -> 0 meets the zero-yaw ones
        small = forces(edge - 1e-4, side, 1e-7)
        zero = forces(edge - 1e-4, side, 0.0)
        assert small[5] == pytest.approx(zero[5], abs=1e-3 * abs(arm * f_y))
