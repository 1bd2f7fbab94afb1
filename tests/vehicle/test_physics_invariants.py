"""Physics invariants and analytic cases that close gaps found by the mutation review of stop
74: sign errors in the vehicle model (the moving frame's vertical pseudo-force, the grade's
pitch moment, the wheelset's gyroscopic coupling, the creep force's vertical component, a
nest's longitudinal damping) and in the simulator's RK4 weights passed every physics test.
Each test states a law (statics, Euler's equations, the contact frame, Rayleigh's
dissipation, the integrator's order) with its derivation, not a stored number, so that a
regenerated reference cannot freeze a wrong sign.

Axes (railsusp.vehicle.layout): x forward (the running direction), y left, z up, angles
right-handed (roll about x lifts the left side, pitch about y lowers the front, yaw about z
turns the nose left); the track's cant angle phi_t lifts the left rail when positive, the
curvature kappa is positive in a left-hand curve (whose outer rail, the right one, is
raised: phi_t < 0)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from railsusp.conditions import GRAVITY as G
from railsusp.conditions import get_condition
from railsusp.params import ParameterSet
from railsusp.vehicle import contact_batch as CB
from railsusp.vehicle import layout as L
from railsusp.vehicle.decay import modal_filters
from railsusp.vehicle.decay_runs import decay_run
from railsusp.vehicle.integrate import integrate_batch
from railsusp.vehicle.model import rhs as model_rhs
from railsusp.vehicle.modes import modal_analysis
from railsusp.vehicle.operating_point import LinearisationPoint, linearisation_point
from railsusp.vehicle.setup import SolverSettings
from railsusp.vehicle.simulate import simulate
from railsusp.vehicle.track_geometry import write_track_geometry
from railsusp.vehicle.track_grid import section_irregularities
from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_12_02_1, load_wagon
from railsusp.vehicle.wheel_rail import creep_contact_forces

NQ = L.N_DOF


def _total_mass() -> float:
    """m_tot = m_c + 2 m_b + 4 m_f + 4 m_w (kg) of the nominal loaded wagon; m_w is the
    catalogue's X1 at its nominal value, as the simulator takes it."""
    wagon = load_wagon()
    m_w = ParameterSet.nominal().to_array()[0]
    return wagon.car_body.mass + 2 * wagon.bolster.mass + 4 * wagon.side_frame.mass + 4 * m_w


def _force_change(point: LinearisationPoint, x: np.ndarray) -> np.ndarray:
    """Generalised forces (N, N m) that the state x adds to those of the zero state (the
    static equilibrium): (rhs(x) - rhs(0)) times each degree of freedom's inertia."""
    dv = point.rhs(x)[NQ : 2 * NQ] - point.rhs(np.zeros(L.N_STATE))[NQ : 2 * NQ]
    return dv * point.dof_inertia()


# ------------------------------------------------------------------ 1. moving frame, curve
@pytest.mark.parametrize("cant_mm", [110.0, 150.0])
def test_wheel_loads_of_steady_curving_balance_gravity_and_centripetal_acceleration(cant_mm):
    """Steady curving on perfect track, R = 300 m at 60 km/h, a cant deficiency (110 mm)
    and a cant excess (150 mm; balance 141.6 mm). Every body moves on the same circle at
    constant speed, so the rails' forces on the wheels balance the bodies' weight and
    centripetal force: in the track frame (rotated by the cant angle phi_t about x) the
    acceleration V^2 kappa along the horizontal y_world has components V^2 kappa cos phi_t
    along y and -V^2 kappa sin phi_t along z, gravity -g sin phi_t and -g cos phi_t
    (docs: model.py's module docstring, pseudo-forces -m (V^2 kappa cos phi_t + g sin phi_t)
    and -m (g cos phi_t - V^2 kappa sin phi_t)). All suspension forces are internal and no
    coupler force acts, so (bars: means over the steady record)

        sum_8 Q  = m_tot (g cos phi_t - V^2 kappa sin phi_t)
                 = m_tot (g cos phi + V^2 / R sin phi)            (canted to the outside)
        sum_4 H  = -sum f_y = -m_tot (V^2 kappa cos phi_t + g sin phi_t)

    i.e. for this left-hand curve -sum H = m_tot (V^2 / R cos phi - g sin phi), which changes
    sign between the two cants. Measured to 1e-9 and 1e-5; a flipped V^2 kappa sin phi_t
    gives 966,050 N instead of 979,553 N at 110 mm (cant 0 cannot tell: sin phi = 0)."""
    c = get_condition("curve", irregularity_class=None, duration_s=1.0, n_steps=50)
    c = c.with_changes(cant_mm=cant_mm)
    assert c.curve_radius_m == 300.0 and c.coupler_force == 0.0
    r = simulate(None, c, wagon=load_wagon(), settings=SolverSettings(start="settled"))
    assert r.status[0] == 0 and r.settled_start[0]
    kappa = c.curvature
    phi_t = -math.copysign(c.cant_angle, kappa)  # the outer rail raised
    m_tot, v2 = _total_mass(), c.speed**2
    sum_q = float(r.Q[0].mean(axis=-1).sum())
    sum_h = float(r.H[0].mean(axis=-1).sum())
    expected_q = m_tot * (G * math.cos(phi_t) - v2 * kappa * math.sin(phi_t))
    expected_h = -m_tot * (v2 * kappa * math.cos(phi_t) + G * math.sin(phi_t))
    phi = c.cant_angle
    assert expected_q == pytest.approx(m_tot * (G * math.cos(phi) + v2 / 300.0 * math.sin(phi)))
    assert sum_q == pytest.approx(expected_q, rel=2e-5)
    assert sum_h == pytest.approx(expected_h, rel=1e-3, abs=20.0)
    # a cant deficiency pushes the wagon out of the curve (H against kappa), an excess in
    assert (sum_h * kappa < 0.0) == (cant_mm < c.balance_cant_mm)


# ------------------------------------------------------------------ 2. grade pitch moment
def test_an_uphill_grade_unloads_the_leading_bogie_by_the_coupler_moment():
    """Uphill 12 per mille, perfect track, steady (the last 50 of 200 samples of 4 s). The
    wagon climbs at constant speed: the train's net coupler pull equals the whole wagon's
    grade force F = m_tot g sin a (at coupler height h_k), the car body pushes the bogies up
    the grade with their share F_b = (m_tot - m_c) g sin a (reacting at the centre plates,
    height h_cp) and its own grade force acts at its CG (h_cg). About the car body's CG the
    longitudinal forces' moment is, nose up (front lifted),

        M = (h_cg - h_k) F - (h_cg - h_cp) F_b                     (setup.constants)

    positive for the C80 (coupler 1.17 m and centre plates 1.35 m below the CG, F_b 8 % of
    F: 12.4 kN m). The car body's vertical and pitch equilibrium then moves M / (2 l_c) from
    each centre plate: the leading (front, k = 0, wheelsets w1 and w2: it leads in the
    running direction +x) bogie's four wheels carry M / l_c less than the trailing bogie's,
    and the eight together still carry m_tot g cos a. The car body's statics here neglect
    the share of M the centre bowls' pitch moments take (0.35 %; they reach the axles of
    each bogie as a couple, which the whole wagon's moment balance below counts); a flipped
    moment gives +3025 N instead of -3025 N."""
    c = get_condition("uphill", irregularity_class=None, duration_s=4.0, n_steps=200)
    wagon = load_wagon()
    r = simulate(None, c, wagon=wagon)
    assert r.status[0] == 0
    q = r.Q[0][:, -50:].mean(axis=-1)  # w1L, w1R, w2L, w2R (leading bogie), w3L .. w4R
    cb, bg = wagon.car_body, wagon.bogie
    m_tot = _total_mass()
    sin_a = c.grade / math.sqrt(1.0 + c.grade**2)
    f_net = m_tot * G * sin_a
    f_bogies = (m_tot - cb.mass) * G * sin_a
    nose_up = (cb.cg_height - cb.coupler_height) * f_net - (
        cb.cg_height - bg.centre_plate_height
    ) * f_bogies
    assert nose_up > 0.0
    leading_minus_trailing = float(q[:4].sum() - q[4:].sum())
    assert leading_minus_trailing == pytest.approx(-nose_up / cb.bogie_half_spacing, rel=0.01)
    assert float(q.sum()) == pytest.approx(m_tot * G / math.sqrt(1.0 + c.grade**2), rel=1e-6)


def test_the_wheel_loads_on_a_grade_balance_the_whole_wagons_pitch_moment():
    """Newton for the whole wagon climbing steadily (uphill 12 per mille, perfect track): the
    rails' vertical reactions Q_i at the axles' positions x_i (+x forward, about the wagon's
    centre) balance the moment of the longitudinal forces, the train's net pull F = m_tot g
    sin a at coupler height h_k against each body's grade force m_j g sin a at its centre of
    gravity h_j (the normal components act symmetrically and cancel):

        sum_i x_i Q_i = g sin a sum_j m_j (h_k - h_j)

    over the car body, two bolsters, four side frames and four wheelsets (at r0). Every
    internal force must pass on its reaction for this to hold: measured to 4e-12 relative.
    Before revision 2026-12-02.1 it missed by 1.5 % (the centre bowls' pitch moment acted
    on the car body against the track, with no reaction on the bogies, and each bogie's own
    moment on the grade did not reach its axles), which this test fails. Each bogie's leading
    axle carries more than its trailing one (the pull at the centre plate acts above the
    bogie's parts' centres of gravity: a forward tip)."""
    c = get_condition("uphill", irregularity_class=None, duration_s=4.0, n_steps=200)
    wagon = load_wagon()
    r = simulate(None, c, wagon=wagon)
    assert r.status[0] == 0
    q = r.Q[0][:, -50:].mean(axis=-1)  # w1L, w1R (front axle of the leading bogie), ... w4R
    cb, bg, bo, sf = wagon.car_body, wagon.bogie, wagon.bolster, wagon.side_frame
    m_w = ParameterSet.nominal().to_array()[0]
    l_c, a, h_k = cb.bogie_half_spacing, bg.half_wheelbase, cb.coupler_height
    x = np.repeat([l_c + a, l_c - a, -l_c + a, -l_c - a], 2)
    sin_a = c.grade / math.sqrt(1.0 + c.grade**2)
    moment = (
        G
        * sin_a
        * (
            cb.mass * (h_k - cb.cg_height)
            + 2 * bo.mass * (h_k - bo.cg_height)
            + 4 * sf.mass * (h_k - sf.cg_height)
            + 4 * m_w * (h_k - wagon.wheelset.rolling_radius)
        )
    )
    assert float((x * q).sum()) == pytest.approx(moment, rel=1e-8)
    assert q[0:2].sum() > q[2:4].sum()
    assert q[4:6].sum() > q[6:8].sum()


def test_the_old_force_laws_load_a_bogies_axles_alike_on_a_grade():
    """The switches of revision 2026-12-02.1 off (FORCE_LAWS_BEFORE_2026_12_02_1) give the
    model before it on a grade too, where its grade moment acts: each bogie's leading and
    trailing axles carry the same load and the whole wagon's moment balance misses (by the
    centre bowls' moment, which had no reaction, and the bogies' own moment)."""
    c = get_condition("uphill", irregularity_class=None, duration_s=4.0, n_steps=200)
    wagon = load_wagon().with_values(FORCE_LAWS_BEFORE_2026_12_02_1)
    r = simulate(None, c, wagon=wagon)
    assert r.status[0] == 0
    q = r.Q[0][:, -50:].mean(axis=-1)
    assert q[0:2].sum() == pytest.approx(q[2:4].sum(), rel=1e-12)
    assert q[4:6].sum() == pytest.approx(q[6:8].sum(), rel=1e-12)


def test_the_centre_bowl_couples_the_car_bodys_pitch_and_its_side_frames_both_ways():
    """The bowl's ring (pitch stiffness k_r = k_ring R^2 / 2) in series with the bolster's
    pitch restraint (k_p, k_p / 2 in each side-frame window) stores, for the car body's
    pitch t_c and its bogie's side frames' t_l, t_r (the bolster pitches with their mean),

        U = k_e / 2 (t_c - (t_l + t_r) / 2)^2 + k_p / 8 (t_l - t_r)^2,  k_e = k_r k_p / (k_r + k_p)

    so a car-body pitch d pushes each of the four side frames' pitch by k_e d / 2, a side
    frame's pitch d pushes the car body's by k_e d / 2 (the reaction), and the other frame
    of its bogie by (k_p - k_e) d / 4 (the shared bowl pulls it along, its own window holds
    it back), the frames of the other bogie not at all. Revision 2026-11-30.2 gave the
    car body k_e per bowl against the track and the frames nothing; a flipped sign of the
    frames' mean in the ring or of the windows' term, or the windows' term left out, fail
    here (the stiffness symmetric: the bowl stays conservative)."""
    point = linearisation_point()
    k = L.K
    kr = 0.5 * point.K[k["k_cpz"]] * point.K[k["R_cp"]] ** 2
    kp = point.K[k["k_cpp"]]
    k_e = kr * kp / (kr + kp)
    frames = [L.SF0 + 5 * j + 3 for j in range(4)]  # pitch of w1-w2 left, right, w3-w4 ...
    d = 1e-6
    x = np.zeros(L.N_STATE)
    x[L.CB_PITCH] = d
    f = _force_change(point, x)
    for j in frames:
        assert f[j] == pytest.approx(k_e * d / 2, rel=1e-6)
    x = np.zeros(L.N_STATE)
    x[frames[0]] = d
    f = _force_change(point, x)
    assert f[L.CB_PITCH] == pytest.approx(k_e * d / 2, rel=1e-6)
    assert f[frames[1]] == pytest.approx((kp - k_e) * d / 4, rel=1e-4)
    assert f[frames[2]] == 0.0 and f[frames[3]] == 0.0


# ------------------------------------------------------------------ 3. gyroscopic coupling
def test_the_spinning_wheelset_couples_roll_and_yaw_as_eulers_equations_say():
    """The wheelset spins at Omega = V / r0 about +y (rolling forward, its lowest point at
    rest: omega x (0, 0, -r0) = (-Omega r0, 0, 0) = -V x), angular momentum I_y Omega y.
    Turned by roll rate phi' (about x) and yaw rate psi' (about z), y turns at
    (phi' x + psi' z) x y = phi' z - psi' x, so Euler's equations dL/dt = M read

        I_x phi'' = M_x + I_y Omega psi',    I_z psi'' = M_z - I_y Omega phi'

    (Iwnicki, Handbook of Railway Vehicle Dynamics, the wheelset's equations: the spin
    couples roll and yaw through I_y V / r0; signs here from the model's right-handed axes).
    With the creep forces off (creep_factor 0: the yaw rate acts through spin creepage
    otherwise) the roll moment of a yaw rate is the gyroscopic term alone, and so is the yaw
    moment of a roll rate; the two do no work together (psi' M_x + phi' M_z = 0). A flipped
    coupling gives -43.65 N m for +43.65 at 0.01 rad/s."""
    point = linearisation_point()
    k = point.K.copy()
    k[L.K["creep_factor"]] = 0.0
    point = dataclasses.replace(point, K=k)
    h_spin = point.P[2] * point.speed / k[L.K["r0"]]  # I_y V / r0 (X3)
    iw = L.WS0  # leading wheelset: y, z, roll, yaw
    rate = 0.01
    x = np.zeros(L.N_STATE)
    x[NQ + iw + 3] = rate
    from_yaw = _force_change(point, x)
    assert from_yaw[iw + 2] == pytest.approx(h_spin * rate, rel=1e-6)
    x = np.zeros(L.N_STATE)
    x[NQ + iw + 2] = rate
    from_roll = _force_change(point, x)
    assert from_roll[iw + 3] == pytest.approx(-h_spin * rate, rel=1e-6)
    assert from_yaw[iw + 2] * rate + from_roll[iw + 3] * rate == pytest.approx(0.0, abs=1e-9)


# ------------------------------------------------------------------ 4. RK4 of the simulator
def _simulator_outputs(point, x0, dt, every, n_out):
    """The 18 output channels of the simulator's integrator (integrate.integrate_batch) from
    state x0 on the point's ideal track, every ``every`` steps of dt, unfiltered (an
    identity second-order section)."""
    ca = point.contact
    sos = np.array([[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]])
    out = np.zeros((1, L.N_OUT, n_out))
    status = np.zeros(1, dtype=np.int64)
    fail = np.zeros(1)
    integrate_batch(
        point.P[None], point.K[None], x0[None], point.track[None], np.zeros(1, dtype=np.int64),
        point.s0, point.ds, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R, dt, 0.0, 0, every, n_out,
        sos, 1, out, status, fail,
    )  # fmt: skip
    assert status[0] == 0
    return out[0]


def test_the_simulators_integrator_is_fourth_order_runge_kutta():
    """The eigenvalue-decay tests run decay_runs.py's own RK4 loop; every simulation runs
    integrate.py's. From the bounce eigenvector (0.5 mm of car body) on ideal straight track
    both must give the same trajectory: the outputs (wheel forces, car-body accelerations) of
    integrate_batch are model.rhs's outputs at decay_run's states, to round-off. And the
    classical RK4 (weights 1, 2, 2, 1 / 6; Butcher 1963) has global error O(h^4): halving the
    step divides the change of the solution by 2^4 = 16 (measured 18.7 for Q, 1 ms to 0.5 ms
    against 0.5 ms to 0.25 ms); other weights that sum to 1 are first order (a ratio of
    about 2)."""
    stuck = modal_analysis()
    i = stuck.car_body_kinds()["bounce"]
    _, v = modal_filters(stuck, [i])
    x0 = v[:, 0].real / np.abs(v[: L.CB_YAW + 1, 0].real).max() * 5e-4
    point = linearisation_point()
    dt, every, n_out = 1.0e-3, 10, 31
    run = decay_run(point, "none", x0=x0, duration_s=0.3, dt=dt, sample_dt=every * dt)
    assert run.state.shape[0] == n_out
    ca = point.contact
    expected = np.zeros((L.N_OUT, n_out))
    dxdt, work = np.zeros(L.N_STATE), np.zeros(L.N_OUT_WORK)
    for j, state in enumerate(run.state):
        code = model_rhs(
            np.ascontiguousarray(state), dxdt, point.P, point.K, point.track, point.s0, point.ds,
            ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R, point.speed * j * every * dt, work,
        )  # fmt: skip
        assert code == 0
        expected[:, j] = work[: L.N_OUT]
    got = _simulator_outputs(point, x0, dt, every, n_out)
    for rows in (slice(L.OUT_Q, L.OUT_Q + 8), slice(L.OUT_ACC_Z, L.OUT_ACC_Z + 1)):
        swing = np.ptp(expected[rows], axis=-1, keepdims=True)
        assert np.all(swing > 0.0)
        np.testing.assert_allclose(got[rows], expected[rows], rtol=0.0, atol=1e-9 * swing.max())
    # step halving: changes of Q (N) at the 21 common times of 0.2 s
    runs = [_simulator_outputs(point, x0, dt / 2**k, 10 * 2**k, 21) for k in range(3)]
    q = [r[L.OUT_Q : L.OUT_Q + 8] for r in runs]
    first, second = np.abs(q[0] - q[1]).max(), np.abs(q[1] - q[2]).max()
    assert second > 0.0
    assert 10.0 < first / second < 25.0


# ------------------------------------------------------------------ 5. contact frame
@pytest.mark.parametrize("side", [1.0, -1.0])
@pytest.mark.parametrize("kernel", ["scalar", "batch"])
def test_contact_forces_are_the_contact_frames_normal_and_creep_forces(side, kernel):
    """A loaded contact at contact angle delta = 0.3 rad with a pure lateral creepage
    xi_y = 3e-3 (no longitudinal creepage; spin coefficient f23 = 0). The rail pushes the
    wheel along the contact normal n = (-side sin delta, cos delta) (y, z; the coned tread
    of the left wheel, side = +1, descends towards its flange, so its normal leans inwards)
    with the Hertz force N, and the creep force F_t acts along the contact plane's lateral
    t = (cos delta, side sin delta) (n . t = 0). So the force on the wheel, f = N n + F_t t,
    gives back N = n . f and F_t = t . f:

        -side sin delta f_y + cos delta f_z = N,     cos delta f_y + side sin delta f_z = F_t

    with F_t Kalker's linear -c22 xi_y (c22 = f22 (N / N_ref)^(2/3), Kalker 1967) reduced by
    Shen-Hedrick-Elkins' (1983) factor 1 - b/3 + b^2/27, b = |c22 xi_y| / (mu N). For both
    wheels and both kernels (wheel_rail.creep_contact_forces, contact_batch._creep). A
    flipped vertical component (f_z = N cos delta - side F_t sin delta) returns the normal
    force N - 2 side sin delta cos delta F_t."""
    k = linearisation_point().K.copy()
    n_ref, mu, creep, r0 = (k[L.K[n]] for n in ("N_ref", "mu", "creep_factor", "r0"))
    n_load = 0.8 * n_ref
    delta = 0.3
    cd, sd = math.cos(delta), math.sin(delta)
    f22 = 8.0e6
    xi_y = 3e-3
    vy = xi_y * linearisation_point().speed  # xi_y = vy / V (no roll rate, no yaw)
    if kernel == "scalar":
        res = creep_contact_forces(
            n_load, 0.0, cd, sd, 0.0, r0, 1e-8, 8.0e6, f22, 0.0, 0.0, 0.0, side, vy, 0.0, 0.0,
            0.0, 0.0, k, False,
        )  # fmt: skip
        assert res[0] == 0 and res[6] == n_load
        f_y, f_z = res[1], res[2]
    else:
        f_y, f_z, _, _ = CB._creep(
            n_load, np.cbrt(n_load / n_ref), True, cd, sd, 0.0, r0, 8.0e6, f22, 0.0, 0.0, 0.0,
            side, vy, 0.0, 0.0, 0.0, 0.0, k, False,
        )  # fmt: skip
    linear = -f22 * (n_load / n_ref) ** (2.0 / 3.0) * creep * xi_y
    b = abs(linear) / (mu * n_load)
    assert 0.05 < b < 3.0  # Kalker's force is a fair share of the friction limit
    f_t = linear * (1.0 - b / 3.0 + b * b / 27.0)
    assert -side * sd * f_y + cd * f_z == pytest.approx(n_load, rel=1e-12)
    assert cd * f_y + side * sd * f_z == pytest.approx(f_t, rel=1e-9)


# ------------------------------------------------------------------ 6. dissipation
def _dampers():
    """(name, velocity pattern {state index: rate}, expected power / rate^2) of viscous
    elements that one velocity strains alone, the suspension's friction limits at zero
    (the sliding linearisation: every friction slider carries no force, stuck or sliding)."""
    wagon = load_wagon()
    c_px, c_py, c_pz = (
        wagon.primary.longitudinal_damping,
        wagon.primary.lateral_damping,
        wagon.primary.vertical_damping,
    )
    c_sx, c_sb = wagon.secondary.longitudinal_damping, wagon.side_bearer.damping
    b2 = wagon.bogie.spring_nest_half_span
    sb_half = 0.5 * ParameterSet.nominal().to_array()[L.P_X["X11"]]
    bol, sf = NQ + L.BOL0, NQ + L.SF0  # leading bolster, its left side frame: velocities
    return [
        # bolster yaw: both nests' bolster ends slide +-b2 w along x (c_sx alone)
        ("nest longitudinal (bolster yaw)", {bol + 3: 1.0}, -2.0 * c_sx * b2**2),
        # side frame x: its nest (c_sx) and its two axle boxes (c_px each)
        ("nest + primary longitudinal (side frame x)", {sf: 1.0}, -(c_sx + 2.0 * c_px)),
        ("primary lateral (side frame y)", {sf + 1: 1.0}, -2.0 * c_py),
        ("primary vertical (side frame z)", {sf + 2: 1.0}, -2.0 * c_pz),
        # car body bounce and roll: the four side bearers' elastomer (c_sb each)
        ("side bearers (car body z)", {NQ + L.CB_Z: 1.0}, -4.0 * c_sb),
        ("side bearers (car body roll)", {NQ + L.CB_ROLL: 1.0}, -4.0 * c_sb * sb_half**2),
    ]


def test_every_viscous_element_dissipates_its_rayleigh_power():
    """Rayleigh's dissipation function R = 1/2 sum c_i (dv_i)^2 of linear dampers: at the
    static equilibrium, with velocities v alone (positions at rest), the damping forces'
    power on the moving bodies is sum F_j v_j = -2 R < 0: never positive, and exactly
    -sum c_i (dv_i)^2 over the elements that v strains. Each case moves one degree of freedom
    at 0.01 (m/s or rad/s) so that only named dampers are strained (wheel-rail creep and the
    rail's damping are left out: the wheelsets stay at rest), and the power is
    (rhs(x) - rhs(0)) . v times the inertias. A damper with a flipped sign adds energy: a
    nest's c_sx flipped, the bolster's yaw gains +2 c_sx b2^2 = 38 kW per (rad/s)^2, and the
    side frame's longitudinal power drops from -(c_sx + 2 c_px) to -(2 c_px - c_sx), still
    negative (the review's weak kill), but no longer the elements' sum."""
    point = linearisation_point(friction="sliding")
    rate = 0.01
    for name, pattern, per_rate2 in _dampers():
        x = np.zeros(L.N_STATE)
        for i, value in pattern.items():
            x[i] = value * rate
        forces = _force_change(point, x)
        power = float(forces @ x[NQ : 2 * NQ])
        assert power < 0.0, name
        assert power == pytest.approx(per_rate2 * rate**2, rel=1e-9), name


def test_a_bolster_rigid_in_pitch_is_refused_where_its_restraint_acts_on_the_side_frames():
    """The 1e30 that stood for a rigid bolster before revision 2026-12-02.1 made, with the
    restraint acting between the side frames, a mode of stable step 4e-14 s (the review of
    stop 75): refused in one line naming the field, the switch and the accepted range; taken
    with the switch off (the model before, as with_physics_before_2026_11_24 gives it), and
    the stiffest accepted value still simulates."""
    from railsusp.errors import RailsuspInputError

    rigid = {"centre_plate.bolster_pitch_stiffness": 1e30}
    with pytest.raises(RailsuspInputError) as err:
        load_wagon().with_values(rigid)
    msg = str(err.value)
    assert "centre_plate.bolster_pitch_stiffness = 1e+30" in msg and "up to 1e+10" in msg
    assert "pitch_reaction_on_side_frames" in msg and "\n" not in msg
    load_wagon().with_values({**rigid, "centre_plate.pitch_reaction_on_side_frames": False})
    load_wagon().with_physics_before_2026_11_24()
    stiff = load_wagon().with_values({"centre_plate.bolster_pitch_stiffness": 1e10})
    c = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=5.0)
    assert simulate(None, c, wagon=stiff).status[0] == 0


# ------------------------------------------------------------------ 9. mirror image, rough track
#: wheel order w1L, w1R, ... w4R: each wheel's mirror image is the other wheel of its axle
_MIRROR_WHEELS = [1, 0, 3, 2, 5, 4, 7, 6]


@pytest.mark.parametrize(
    ("name", "wagon_name", "start"),
    [("curve", "loaded", "settled"), ("uphill", "tare", "lead-in")],
)
def test_the_mirror_image_of_a_rough_track_gives_the_mirror_image_of_the_forces(
    tmp_path, name, wagon_name, start
):
    """The wagon, its profiles and its force laws are symmetric about the track's centre
    plane, so a track and its mirror image (left and right rails swapped: alignment and
    cross-level change sign, vertical profile and gauge do not; a left-hand curve becomes a
    right-hand one, its cant on the other rail) give the same forces with each wheel and its
    partner on the axle swapped: Y and Q wheel for wheel, H and the car body's lateral
    acceleration with their sign changed. The track is the condition's Class 5 realisation
    written as measured geometry, read back as it is and mirrored, so that the whole path
    from the irregularities to the rails under each wheel is checked; the curve from its
    settled start, the grade (650 kN of tension) from rest with the tare wagon. Measured to
    1.5e-12 of the largest force (the fast-math kernels' round-off); the test on perfect track
    (test_simulate.py) cannot see the rails' irregularities: taking the right rail's lateral
    velocity from the left rail leaves it passing and moves this one by kilonewtons."""
    wagon = load_wagon(wagon_name)
    base = get_condition(name, duration_s=3.0, n_steps=150)
    irr = section_irregularities(base, [base.seed], wagon)
    mirrored = dataclasses.replace(irr, alignment=-irr.alignment, crosslevel=-irr.crosslevel)
    origin = base.lead_in_m  # the files' distances count from the record's first sample
    files = [tmp_path / "track.csv", tmp_path / "mirrored.csv"]
    write_track_geometry(files[0], irr, origin_m=origin)
    write_track_geometry(files[1], mirrored, origin_m=origin)
    this = base.with_changes(track_geometry=str(files[0]))
    other = base.with_changes(track_geometry=str(files[1]))
    if base.curve_radius_m is not None:
        assert base.curve_direction == "left"
        other = other.with_changes(curve_direction="right")
    settings = SolverSettings(start=start)
    a = simulate(None, this, wagon=wagon, settings=settings)
    b = simulate(None, other, wagon=wagon, settings=settings)
    assert a.status[0] == 0 and b.status[0] == 0
    assert a.settled_start[0] == b.settled_start[0] == (start == "settled")
    scale = float(np.abs(a.Q[0]).max())
    assert float(np.abs(a.Y[0]).max()) > 10e3  # the rough track does push the wheels
    np.testing.assert_allclose(b.Y[0][_MIRROR_WHEELS], a.Y[0], rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(b.Q[0][_MIRROR_WHEELS], a.Q[0], rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(b.H[0], -a.H[0], rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(b.car_acc_y[0], -a.car_acc_y[0], rtol=0, atol=1e-9)
