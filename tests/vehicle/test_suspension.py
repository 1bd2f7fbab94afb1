"""Suspension force elements: friction wedge hysteresis, centre-bowl ring, sliders, and the
energy audit of the whole equations of motion."""

import math

import numpy as np
import pytest

from conftest import harmonic_drive
from railsusp.vehicle import layout as L
from railsusp.vehicle.energy import energy_audit
from railsusp.vehicle.operating_point import linearisation_point
from railsusp.vehicle.suspension import (
    BOWL_POINTS,
    bowl_ring_forces,
    damped_slider,
    damped_slider_2d,
    friction_wedges,
)
from railsusp.vehicle.wagon import load_wagon

TAN40 = math.tan(math.radians(40.0))
COS40 = math.cos(math.radians(40.0))


def _wedge_loop(amplitude, f_ctrl0, k_ctrl, mu, k_stick, c_stick, n=4000, cycles=2):
    """Drive one nest's wedge pair through harmonic compression x = A sin(w t) at 1 Hz with
    explicit Euler on the friction states (small steps); returns x and the vertical friction
    force on the bolster over the last cycle."""
    state = np.zeros(L.WEDGE_STATES)
    d = np.zeros(L.WEDGE_STATES)
    xs, fs = [], []
    for dt, x, v, last in harmonic_drive(amplitude, n, cycles):
        fz, *_ = friction_wedges(
            x, v, 0.0, 0.0, 0.0, f_ctrl0, k_ctrl, TAN40, COS40, mu, 0.2, 1.0, k_stick, c_stick,
            state, d, 0,
        )  # fmt: skip
        state += dt * d
        if last:
            xs.append(x)
            fs.append(fz)
    return np.array(xs), np.array(fs)


def test_wedge_hysteresis_loop_matches_the_massless_wedge_closed_form():
    # Massless wedge (physics notes): column normal force F_s / (tan a - mu) in compression,
    # F_s / (tan a + mu) on rebound; friction mu N. Over a stroke of +-A with a linear control
    # spring F_s = F0 + k x the linear part cancels, so the loop area (energy per cycle) is
    # 2 A mu F0 (1 / (tan a - mu) + 1 / (tan a + mu)), less the stick transitions: at each
    # reversal the force crosses from one limit to the other over (L+ + L-) / k_stick.
    A, f0, kc, mu, ks = 0.010, 59.2e3, 1.538e6, 0.25, 20.0e6
    x, f = _wedge_loop(A, f0, kc, mu, ks, 0.0)
    area = np.trapezoid(f, x)  # f resists the compression x: energy dissipated per cycle
    l_comp = mu * f0 / (TAN40 - mu)
    l_reb = mu * f0 / (TAN40 + mu)
    expected = 2 * A * (l_comp + l_reb) - (l_comp + l_reb) ** 2 / ks
    assert area == pytest.approx(expected, rel=0.03)
    # compression/rebound asymmetry at mid-stroke (x ~ 0): (tan a + mu) / (tan a - mu)
    mid = np.abs(x) < 0.05 * A
    up = f[mid & (np.gradient(x) > 0)].mean()
    down = -f[mid & (np.gradient(x) < 0)].mean()
    assert up / down == pytest.approx((TAN40 + mu) / (TAN40 - mu), rel=0.02)
    # no friction, no loop
    _, f0_ = _wedge_loop(A, f0, kc, 0.0, ks, 0.0)
    assert np.abs(f0_).max() == 0.0


def test_wedge_relative_friction_of_the_k6_data_is_in_the_published_range():
    # Relative friction coefficient of variable-friction wedges, friction force / nest force,
    # about 0.07-0.10 (physics notes, from the K-type bogie literature). With the wagon data:
    # the mean of compression and rebound friction over the static nest force.
    w = load_wagon()
    sec = w.secondary
    k = linearisation_point().K
    f_nest = k[L.K["F0_nest"]]
    f_ctrl = k[L.K["F0_ctrl"]]
    tan_a = math.tan(math.radians(sec.wedge_angle_deg))
    mu = sec.column_friction_coefficient
    comp = mu * f_ctrl / (tan_a - mu) / f_nest
    reb = mu * f_ctrl / (tan_a + mu) / f_nest
    assert 0.07 <= 0.5 * (comp + reb) <= 0.10
    assert comp > reb  # more friction in compression than on rebound


def test_slider_holds_a_static_load_and_slides_at_its_limit():
    d = np.zeros(1)
    # sticking and at rest: holds its elastic force, no rate
    assert damped_slider(500.0, 1000.0, 1e6, 1e3, 0.0, d, 0) == 500.0
    assert d[0] == 0.0
    # at the limit and moving outwards: slides, force on the limit, state frozen
    assert damped_slider(1000.0, 1000.0, 1e6, 1e3, 0.1, d, 0) == 1000.0
    assert d[0] == 0.0
    # at the limit, reversing: sticks again, force leaves the limit at once with the damper
    f = damped_slider(1000.0, 1000.0, 1e6, 1e3, -0.1, d, 0)
    assert f == pytest.approx(900.0) and d[0] == pytest.approx(-1e5)
    # 2-D: at the limit, slip along the force direction keeps the force on the circle
    d2 = np.zeros(2)
    fx, fy = damped_slider_2d(600.0, 800.0, 1000.0, 1e6, 0.0, 0.3, 0.4, d2, 0, 1)
    assert math.hypot(fx, fy) == pytest.approx(1000.0)
    assert d2 == pytest.approx([0.0, 0.0], abs=1e-9)
    # slip across the force turns it (tangential loading only)
    damped_slider_2d(1000.0, 0.0, 1000.0, 1e6, 0.0, 0.1, 0.2, d2, 0, 1)
    assert d2[0] == pytest.approx(0.0, abs=1e-9) and d2[1] == pytest.approx(2e5)


def _ring(droll, dpitch=0.0, mu=0.0, state=0.0, R=0.1875, k=200e6, f0=400e3):
    """Centre-bowl ring at rest (no rates), no vertical compression."""
    d = np.zeros(1)
    return bowl_ring_forces(
        0.0, droll, dpitch, 0.0, R, k, 1e30, 1e30, f0, mu, 1e6, 0.0, state, d, 0
    )


def test_centre_bowl_ring_roll_stiffness_and_rocking_capacity():
    R, k, f0 = 0.1875, 200e6, 400e3
    # small relative roll: elastic, k R^2 / 2, no net vertical change
    n, m_roll, m_pitch, _ = _ring(1e-4)
    assert n == pytest.approx(f0)
    assert m_roll == pytest.approx(-k * R * R / 2 * 1e-4, rel=1e-9)
    assert m_pitch == pytest.approx(0.0, abs=1e-6)
    # pitch the same way about the other axis (car-body pitch + lifts the front: x > 0)
    _, _, m_pitch, _ = _ring(0.0, 1e-4)
    assert m_pitch == pytest.approx(-k * R * R / 2 * 1e-4, rel=1e-9)
    # lift-off starts at N R / 2; rocked far over, the whole load sits on the rim: N R
    lift = f0 * R / 2 / (k * R * R / 2)
    n, m_roll, _, _ = _ring(0.9 * lift)
    assert n == pytest.approx(f0) and abs(m_roll) == pytest.approx(0.9 * f0 * R / 2, rel=1e-9)
    n, m_roll, _, _ = _ring(0.2)
    assert abs(m_roll) <= n * R * (1 + 1e-12)
    assert n > f0  # the edge point alone, deeply compressed
    # friction moment limit: mu N (2/3) R of a flat disc
    *_, m_fr = _ring(0.0, mu=0.1, state=1e9)
    assert m_fr == pytest.approx(0.1 * f0 * 2 / 3 * R)
    assert BOWL_POINTS >= 8


def _bowl(dz, droll, dpitch, k_rock=194e6, k_v=1e9, k_pitch=2.8e6, R=0.1875, f0=400e3):
    """The bowl of the wagon data: ring k_ring = 2 k_rock / R^2 on the bolster's bending
    (in series: k_v in all) and its pitch restraint k_pitch."""
    k_ring = 2.0 * k_rock / (R * R)
    k_bend = 1.0 / (1.0 / k_v - 1.0 / k_ring)
    d = np.zeros(1)
    return bowl_ring_forces(
        dz, droll, dpitch, 0.0, R, k_ring, k_bend, k_pitch, f0, 0.0, 1e6, 0.0, 0.0, d, 0
    )[:3]


def test_centre_bowl_rocks_on_its_ring_and_bounces_on_the_bending_bolster():
    """Before lift-off: roll stiffness k_rock (the ring), vertical k_v (the ring in series
    with the bolster's bending), pitch k_rock in series with the bolster's pitch restraint;
    lift-off still starts at the moment N R / 2."""
    R, f0, k_rock, k_v, k_pitch = 0.1875, 400e3, 194e6, 1e9, 2.8e6
    n, m_roll, m_pitch = _bowl(0.0, 1e-5, 0.0)
    assert n == pytest.approx(f0, rel=1e-12) and m_pitch == pytest.approx(0.0, abs=1e-6)
    assert m_roll == pytest.approx(-k_rock * 1e-5, rel=1e-9)
    n, m_roll, m_pitch = _bowl(0.0, 0.0, 1e-4)
    series = 1.0 / (1.0 / k_rock + 1.0 / k_pitch)
    assert m_pitch == pytest.approx(-series * 1e-4, rel=1e-9)
    assert m_roll == pytest.approx(0.0, abs=1e-6)
    n, *_ = _bowl(1e-5, 0.0, 0.0)
    assert n == pytest.approx(f0 + k_v * 1e-5, rel=1e-9)
    lift = f0 * R / 2 / k_rock  # the angle at which the moment reaches N R / 2
    _, m_roll, _ = _bowl(0.0, 0.99 * lift, 0.0)
    assert abs(m_roll) == pytest.approx(0.99 * f0 * R / 2, rel=1e-9)
    _, m_roll, _ = _bowl(0.0, 1.5 * lift, 0.0)  # lifted at one edge: softer
    assert abs(m_roll) < 0.999 * k_rock * 1.5 * lift


@pytest.mark.parametrize("state", [(2e-5, 8e-4, 3e-3), (-3e-4, 5e-4, -1e-2), (1e-4, 0.0, 2e-2)])
def test_centre_bowl_with_lift_off_is_conservative(state):
    """With points lifted, the bowl's forces stay the gradient of one potential U(dz, droll,
    dpitch) (the quasi-static bending and pitch minimise it): normal force dU/d(dz), roll
    moment -dU/d(droll), pitch moment -dU/d(dpitch), so the mixed derivatives agree. A ring
    whose roll and pitch stiffnesses were set apart point by point fails this."""
    h = (1e-9, 1e-7, 1e-7)
    grad = []
    for i in range(3):
        up = list(state)
        dn = list(state)
        up[i] += h[i]
        dn[i] -= h[i]
        f_up, f_dn = _bowl(*up), _bowl(*dn)
        grad.append([(a - b) / (2 * h[i]) for a, b in zip(f_up, f_dn, strict=True)])
    n0 = _bowl(*state)[0]
    assert 0.0 < n0 and n0 != pytest.approx(400e3, rel=1e-3)  # a lifted, loaded state
    g = np.array(grad)  # g[i][j]: d(force j)/d(coordinate i)
    tol = {"rel": 1e-4, "abs": 1e-6 * np.abs(g).max()}
    assert g[1][0] == pytest.approx(-g[0][1], **tol)  # dn/droll = -dm_roll/ddz
    assert g[2][0] == pytest.approx(-g[0][2], **tol)
    assert g[2][1] == pytest.approx(g[1][2], **tol)


def test_a_bowl_that_rocks_more_easily_than_its_ring_compresses_is_refused():
    from railsusp.errors import RailsuspInputError
    from railsusp.vehicle.operating_point import linearisation_point
    from railsusp.vehicle.wagon import load_wagon

    needle = (
        r"^centre_plate\.rocking_stiffness = 1e\+07 N m/rad: accepted from "
        r"vertical_stiffness x R\^2 / 2 = 1\.758e\+07 up"
    )
    with pytest.raises(RailsuspInputError, match=needle):
        # below 1 GN/m x R^2 / 2 = 17.6
        wagon = load_wagon().with_values({"centre_plate.rocking_stiffness": 10.0e6})
        linearisation_point(wagon=wagon)


def _perturbed_state():
    x0 = np.zeros(L.N_STATE)
    x0[L.CB_Y] = 0.004
    x0[L.CB_Z] = 0.005
    x0[L.CB_ROLL] = 0.003
    x0[L.N_DOF + L.CB_PITCH] = 0.01  # pitch rate
    x0[L.WS0] = 0.002  # leading wheelset lateral
    # bolster roll and yaw and a side frame's bounce against the car body: relative motion
    # of connected bodies out of phase, which a force without its full reaction turns into
    # energy from nowhere
    x0[L.N_DOF + L.BOL0 + 2] = x0[L.N_DOF + L.BOL0 + 3] = 0.2
    x0[L.N_DOF + L.SF0 + 2] = 0.05
    return x0


@pytest.mark.parametrize(("creep", "tolerance"), [(False, 2e-3), (True, 0.01)])
def test_energy_audit_nonconservative_work_equals_change_of_mechanical_energy(creep, tolerance):
    # d/dt (T + V) = (F - F_c) . v: the work of dampers, friction and creep forces must
    # equal the change of kinetic plus potential energy (issue 18: within 1 %) from a
    # perturbed state on ideal track; and the perturbation must really be damped out.
    # Without creep the audit is held to 0.2 % (measured 0.096 %, 0.073 % with creep). What
    # remains is the wheel-rail normal force, not quite the gradient of the contact gap (the
    # table's contact angle is a central difference of its heights, the gap the secant of
    # their interpolation: d(Y)/d(roll) and d(M_roll)/d(y) of a wheelset differ by 10 %);
    # since the bowl's rocking stiffness (2026-11-24) the wheelsets take more of the
    # perturbation (0.01 % before). The centre bowl's roll moment applied to the bolster
    # 20 % short (a missing reaction) gives 1.27 % (checked on a mutated copy).
    audit = energy_audit(_perturbed_state(), duration_s=1.5, creep=creep)
    assert audit.relative_error < tolerance, audit
    assert audit.work_nonconservative < 0.0
    assert audit.dissipated_fraction > 0.5, audit


def test_energy_of_a_small_bounce_is_dissipated_by_the_stuck_wedges():
    # Car body and bolsters lifted 0.5 mm together: the nests' 0.5 mm is too little to make
    # the wedges slide (their stick force stays under the friction limit), so only the
    # wedges' pre-sliding loss can take the bounce's energy. Within 2 s 41 % goes (the rest
    # stays as the springs' energy of the offset at which friction holds the body); the
    # model before 2026-11-24, whose stuck wedges were lossless springs, lost 10 %.
    x0 = np.zeros(L.N_STATE)
    x0[L.CB_Z] = x0[L.BOL0 + 1] = x0[L.BOL0 + 5] = 5e-4
    audit = energy_audit(x0, duration_s=2.0, creep=False)
    assert audit.relative_error < 0.01, audit
    assert audit.dissipated_fraction > 0.3, audit


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        (
            "column_friction_coefficient = 0.25",
            "column_friction_coefficient = 0.9",
            "secondary: column_friction_coefficient = 0.9: accepted below tan(wedge_angle_deg)",
        ),
        (
            "control_spring_stiffness = 0.769e6",
            "control_spring_stiffness = 3.0e6",
            "secondary: the wedges' control springs (6e+06 N/m) must be part of the nest's",
        ),
    ],
)
def test_a_wedge_that_cannot_work_is_refused_when_the_wagon_file_is_read(
    tmp_path, old, new, needle
):
    from importlib import resources

    from railsusp.errors import RailsuspInputError

    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    assert old in text
    path = tmp_path / "wagon.toml"
    path.write_text(text.replace(old, new))
    with pytest.raises(RailsuspInputError) as err:
        load_wagon(path)
    assert needle in str(err.value) and "\n" not in str(err.value)
