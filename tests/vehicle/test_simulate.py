"""Verification of the wagon simulator against analytic cases and physical invariants."""

import math
from importlib import resources

import numpy as np
import pytest

from railsusp.conditions import CANT_BASE_M, GRAVITY, get_condition
from railsusp.errors import ParameterError, RailsuspInputError
from railsusp.params import MAIN_SUSPENSION, ParameterSet, spec
from railsusp.vehicle import layout as L
from railsusp.vehicle.contact import equivalent_conicity
from railsusp.vehicle.profile_shapes import chn60_rail, lm_worn_wheel
from railsusp.vehicle.rigid_profile_contact import contact_table
from railsusp.vehicle.simulate import (
    SolverSettings,
    contact_arrays,
    simulate,
    simulate_batch,
)
from railsusp.vehicle.wagon import load_wagon
from railsusp.vehicle.wheelset import free_wheelset_sway, sway_wavelength

SHORT = {"duration_s": 6.0, "n_steps": 300}


def wagon_text() -> str:
    """The embedded C80/K6 wagon file, as text to edit into other wagons."""
    return resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")


def total_mass(wagon=None):
    w = load_wagon() if wagon is None else wagon
    return w.car_body.mass + 2 * w.bolster.mass + 4 * w.side_frame.mass + 4 * spec("X1").nominal


def test_static_equilibrium_on_perfect_straight_track():
    """Zero excitation: every wheel carries weight / 8 (0.5 %), no net lateral force, at rest."""
    cond = get_condition("straight", irregularity_class=None, duration_s=3.0, n_steps=150)
    r = simulate(None, cond)
    assert r.ok.all()
    q_static = total_mass() * GRAVITY / 8.0
    np.testing.assert_allclose(r.Q[0], q_static, rtol=0.005)
    assert np.abs(r.H[0]).max() < 50.0  # N: wheelset lateral forces ~0
    # a coned tread pushes each rail outward by N sin(delta) less the spin creep force; the
    # two wheels of a wheelset balance, and nothing moves
    assert np.ptp(r.Y[0], axis=1).max() < 1.0
    assert np.abs(r.Y[0]).max() < 0.06 * q_static
    assert np.abs(r.car_acc_y[0]).max() < 1e-3 and np.abs(r.car_acc_z[0]).max() < 1e-3


def test_free_wheelset_reproduces_klingel_wavelength():
    """Klingel: L = 2 pi sqrt(r0 b0 / lambda_e), with the table's own equivalent conicity."""
    s, y, _ = free_wheelset_sway(speed_kmh=20.0, y_initial=0.003, duration=10.0)
    wavelength = sway_wavelength(s, y)
    table = contact_table(lm_worn_wheel(), chn60_rail(), wheelset_roll=False)
    lam = equivalent_conicity(table, 0.003)
    klingel = 2 * math.pi * math.sqrt(0.42 * 0.7465 / lam)
    assert wavelength == pytest.approx(klingel, rel=0.05)


@pytest.fixture(scope="module")
def steady_curve():
    cond = get_condition("curve", irregularity_class=None, duration_s=8.0, n_steps=400)
    return cond, simulate(None, cond)


def test_steady_curving_lateral_force_balance(steady_curve):
    """Quasi-static balance: sum of wheelset forces = m (V^2/R cos phi - g sin|phi|) (3 %)."""
    cond, r = steady_curve
    phi = math.asin(cond.cant_mm * 1e-3 / CANT_BASE_M)
    expected = total_mass() * (
        cond.speed**2 / cond.curve_radius_m * math.cos(phi) - GRAVITY * math.sin(phi)
    )
    # H is + to the left (towards the centre of this left-hand curve): the wagon pushes the
    # track outwards, so the sum of H is negative
    total = -r.H[0].mean(axis=1).sum()
    assert total == pytest.approx(expected, rel=0.03)


def test_leading_outer_wheel_carries_the_largest_lateral_force(steady_curve):
    _, r = steady_curve
    mean_y = r.Y[0].mean(axis=1)
    assert int(np.argmax(mean_y)) == 1  # w1R: leading wheelset, outer (right) wheel
    assert r.measured_wheel() == 1
    # outer wheels loaded, inner unloaded by the cant deficiency
    assert r.Q[0, 1].mean() > r.Q[0, 0].mean()


def test_left_and_right_curves_mirror():
    """Mirror symmetry: a right-hand curve gives the left-hand curve's forces, sides swapped."""
    base = {"irregularity_class": None, "duration_s": 3.0, "n_steps": 150}
    left = simulate(None, get_condition("curve", **base))
    right = simulate(None, get_condition("curve", curve_direction="right", **base))
    np.testing.assert_allclose(left.Y[0, 1], right.Y[0, 0], rtol=1e-6, atol=1.0)
    np.testing.assert_allclose(left.Q[0, 0], right.Q[0, 1], rtol=1e-6, atol=1.0)


def test_single_point_model_with_the_plain_step_is_warned_about():
    # Before the friction wedges and the centre bowl (2026-11-24), a 200 s tangent run of an
    # LHS sample was thrown off the rail by the single-point contact model with the plain
    # 1 ms step (its contact jumps from the tread to the 70 deg flank), and not with split
    # steps or two-point contact. With the friction wedges, 96 LHS samples of 200 s
    # (X11, X12, X13, X14, X17, X18; independent seeds; bowl yaw stick stiffness 5 MN m/rad) did
    # not derail that way, so the
    # event is not reproduced here; the warning stays, the step split is still offered.
    cond = get_condition("straight", duration_s=2.0, n_steps=100)
    one = load_wagon().with_contact_model("single-point")
    with pytest.warns(UserWarning, match="needs SolverSettings.flange_substeps=2."):
        plain = simulate(None, cond, settings=SolverSettings(), wagon=one)
    split = simulate(None, cond, settings=SolverSettings(flange_substeps=2), wagon=one)
    assert plain.ok[0] and split.ok[0]
    ca = contact_arrays(load_wagon())
    assert ca.flange_shift == pytest.approx(0.0106, abs=2e-4)  # the flangeway clearance
    with pytest.raises(RailsuspInputError, match="flange_substeps = 0: accepted an integer 1"):
        SolverSettings(flange_substeps=0)
    with pytest.raises(RailsuspInputError, match="flange_margin = 0.5 m: accepted 0 to 0.02"):
        SolverSettings(flange_margin=0.5)
    with pytest.raises(RailsuspInputError, match="flange_split_speed = 2 m/s: accepted -1 to 1"):
        SolverSettings(flange_split_speed=2.0)


def test_steady_flanging_steps_are_not_split_and_forces_do_not_change():
    """Single-point contact with the step split it needs: in the curve the leading outer
    wheel runs against its flange, and splitting only the steps of a wheel closing on its
    flange gives the same force statistics as splitting every step near the flange, within
    0.2 %."""
    cond = get_condition("curve", **SHORT)
    one = load_wagon().with_contact_model("single-point")
    every = SolverSettings(flange_substeps=2, flange_split_speed=-1.0)
    closing = SolverSettings(flange_substeps=2)
    a = simulate(None, cond, settings=every, wagon=one).statistics()
    b = simulate(None, cond, settings=closing, wagon=one).statistics()
    for key in ("Y_mean", "Y_rms", "Y_max", "Q_rms", "Q_max"):
        assert b[key] == pytest.approx(a[key], rel=0.002), key


def test_every_main_suspension_parameter_changes_a_force_statistic():
    """No dead parameter: X11..X20 at -20 % / +20 % change some statistic in some condition.

    The primary lateral pad (X14) in the curve: with the friction wedges (2026-11-24) the
    leading outer wheel's mean lateral force hardly depends on it (-0.4 % over X14's whole
    range on 20 s; before, when the bolster moved freely on its nests, a stiffer pad
    concentrated the bogie's lateral load on the leading wheelset). The wedges hold bolster
    and side frames together, so the bogie shares its lateral load through the warp and
    the pads alike. Checked: the effect stays below 1 % for +-20 %.
    """
    sets = [ParameterSet.nominal()]
    for sym in MAIN_SUSPENSION:
        for f in (0.8, 1.2):
            sets.append(ParameterSet.nominal().replace({sym: spec(sym).nominal * f}))
    keys = ("Y_mean", "Y_rms", "Y_p99", "Y_max", "Q_rms", "Q_p99", "Q_max")
    change = np.zeros(len(MAIN_SUSPENSION))
    x14_curve = None
    for name in ("straight", "curve"):
        r = simulate_batch(sets, get_condition(name, **SHORT))
        assert r.ok.all(), r.failures()
        stats = r.statistics(set_index=None)
        for i in range(len(MAIN_SUSPENSION)):
            for k in keys:
                for j in (1 + 2 * i, 2 + 2 * i):
                    change[i] = max(change[i], abs(stats[k][j] / stats[k][0] - 1))
        if name == "curve":
            i14 = MAIN_SUSPENSION.index("X14")
            x14_curve = stats["Y_mean"][[1 + 2 * i14, 0, 2 + 2 * i14]]
    # the simulator is deterministic (identical inputs give bitwise identical output), so any
    # change is the parameter's. X20 is weak by physics: at 1 GN/m in series with a 14 MN/m pad a
    # 20 % change moves the combined stiffness by 0.3 %. X12, the gib clearance, is dead here
    # by physics too: the wedges' column friction holds the bolster to the side frames
    # laterally, far inside a 9.6 mm clearance, on these runs (it acts only once the stop
    # closes; the estimate's validator reports it as not identified then).
    dead = [s for s, c in zip(MAIN_SUSPENSION, change, strict=True) if c < 1e-4]
    assert dead in ([], ["X12"]), dict(zip(MAIN_SUSPENSION, change, strict=True))
    assert np.abs(x14_curve / x14_curve[1] - 1).max() < 0.01, x14_curve


def test_same_inputs_give_identical_output():
    cond = get_condition("straight", **SHORT)
    a = simulate(None, cond)
    b = simulate(None, cond)
    np.testing.assert_array_equal(a.Y, b.Y)
    np.testing.assert_array_equal(a.Q, b.Q)


def test_failed_set_is_flagged_and_does_not_poison_the_batch():
    cond = get_condition("straight", **SHORT)
    good = ParameterSet.nominal()
    broken = ParameterSet.nominal()  # a 1 g wheelset: stiff beyond the step, diverges; set
    broken._values = {**broken._values, "X1": 1e-3}  # past the check, which refuses it
    r = simulate_batch([good, broken, good], cond)
    assert list(r.status == L.OK) == [True, False, True]
    ((idx, reason, t_fail),) = r.failures()
    assert 0.0 <= t_fail <= cond.lead_in_m / cond.speed + cond.duration_s
    assert idx == 1 and reason in L.FAILURE_REASONS.values() and reason != "ok"
    assert np.isnan(r.Y[1]).all()
    alone = simulate(good, cond)
    np.testing.assert_array_equal(r.Y[0], alone.Y[0])
    np.testing.assert_array_equal(r.Y[2], alone.Y[0])


def test_independent_seeds_and_common_random_numbers():
    cond = get_condition("straight", **SHORT)
    crn = simulate_batch([ParameterSet.nominal()] * 2, cond)
    np.testing.assert_array_equal(crn.Y[0], crn.Y[1])
    indep = simulate_batch([ParameterSet.nominal()] * 2, cond, seeds=[1, 2])
    assert not np.allclose(indep.Y[0], indep.Y[1])
    with pytest.raises(RailsuspInputError, match="seeds: 1 given for 2"):
        simulate_batch([ParameterSet.nominal()] * 2, cond, seeds=[1])


def test_matrix_input_over_symbols_is_range_checked():
    cond = get_condition("straight", duration_s=2.0, n_steps=100)
    ok = simulate_batch(np.array([[14e6, 10e6], [16e6, 8e6]]), cond, symbols=["X13", "X14"])
    np.testing.assert_allclose(ok.params[1, [12, 13]], [16e6, 8e6])
    with pytest.raises(ParameterError, match="row 0: X13"):
        simulate_batch(np.array([[40e6, 10e6]]), cond, symbols=["X13", "X14"])


def test_result_export_and_derived_quantities(tmp_path):
    cond = get_condition("curve", duration_s=2.0, n_steps=100)
    r = simulate(None, cond)
    df = r.to_dataframe()
    assert len(df) == 100 and df.index.name == "time_s"
    assert {"Y_w1R_kN", "Q_w4L_kN", "H_w1_kN", "car_acc_y_m_s2"} <= set(df.columns)
    np.testing.assert_allclose(df["Y_w1R_kN"].to_numpy() * 1e3, r.Y[0, 1])
    path = r.to_parquet(tmp_path / "run.parquet")
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata
    assert b"railsusp.condition" in meta and b"curve" in meta[b"railsusp.condition"]
    yq = r.derailment_quotient
    np.testing.assert_allclose(yq[0, 1], r.Y[0, 1] / r.Q[0, 1])
    np.testing.assert_allclose(
        r.unloading_ratio[0, 0], (r.static_wheel_load - r.Q[0, 0]) / r.static_wheel_load
    )
    assert r.measured_wheel("w3L") == 4
    with pytest.raises(RailsuspInputError, match="measured wheel 'w9'"):
        r.measured_wheel("w9")


def test_wagon_is_data(tmp_path):
    """Another wagon is another file: a lighter car body lowers the static wheel load."""
    w = load_wagon()
    text = wagon_text()
    light = tmp_path / "light.toml"
    light.write_text(text.replace("mass = 91600.0", "mass = 71600.0"))
    lw = load_wagon(light)
    cond = get_condition("straight", irregularity_class=None, duration_s=2.0, n_steps=100)
    q_light = simulate(None, cond, wagon=lw).Q[0].mean()
    assert q_light == pytest.approx(total_mass(lw) * GRAVITY / 8.0, rel=0.005)
    assert q_light < simulate(None, cond, wagon=w).Q[0].mean()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("mass = 596.0", "mass = -596.0"))
    with pytest.raises(RailsuspInputError, match=r"bad\.toml: bolster\.mass = -596"):
        load_wagon(bad)


def test_contact_arrays_are_consistent():
    ca = contact_arrays(load_wagon())
    y = ca.y0 + ca.dy * np.arange(ca.table.shape[1])
    h = ca.table[L.CT_H]
    # the contact angle is the slope of the touching height (conservative contact forces)
    slope = np.gradient(h, y)
    np.testing.assert_allclose(np.tan(ca.table[L.CT_DELTA]), slope, atol=1e-9)
    # left at +y mirrors right at -y
    np.testing.assert_allclose(ca.table[L.CT_R], ca.table[L.CT_RIGHT + L.CT_R][::-1], atol=1e-6)


def test_user_profile_files_in_the_wagon_file(tmp_path):
    """A wagon file may name profile files; the LM-like tread written out and read back gives
    the same contact functions as the built-in one."""
    from railsusp.vehicle.profiles import write_profile

    write_profile(lm_worn_wheel(), tmp_path / "wheel.txt")
    text = wagon_text()
    f = tmp_path / "w.toml"
    f.write_text(text + '\n[profiles]\nwheel = "wheel.txt"\nrail = "chn60"\n')
    wagon = load_wagon(f)
    assert wagon.profiles.wheel == str((tmp_path / "wheel.txt").resolve())
    a = contact_arrays(wagon)
    b = contact_arrays(load_wagon())
    np.testing.assert_allclose(a.table[L.CT_R], b.table[L.CT_R], atol=2e-5)
    f.write_text(text + '\n[profiles]\nwheel = "missing.txt"\n')
    with pytest.raises(RailsuspInputError, match="profiles.wheel = 'missing.txt'"):
        load_wagon(f)


def test_xarray_export():
    cond = get_condition("straight", duration_s=2.0, n_steps=100)
    r = simulate_batch([ParameterSet.nominal()] * 2, cond, seeds=[1, 2])
    ds = r.to_xarray()
    assert ds["Y"].dims == ("set", "wheel", "time") and ds["Y"].shape == (2, 8, 100)
    np.testing.assert_array_equal(ds["Q"].sel(wheel="w2R").values, r.Q[:, 3])
    assert ds["params"].sel(parameter="X13").values[0] == pytest.approx(14e6)


def test_a_set_the_parallel_integration_did_not_finish_reads_as_failed():
    """An error inside the compiled parallel loop (here a division by zero: the primary
    pad's lateral stiffness X14 in series with the adapter's X20, their sum made zero) is
    not passed on by Numba on several threads: the set, and any after it on the same
    thread, kept the status and outputs they had before the call, zeros, and read as
    successes with flat series (the review of stop 76). They start as FAIL_UNFINISHED and
    NaN now, whether or not the call raised."""
    from scipy.signal import butter

    from railsusp.vehicle.batch_runs import unfinished
    from railsusp.vehicle.integrate import integrate_batch
    from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays
    from railsusp.vehicle.track_grid import track_arrays

    wagon, settings, cond = load_wagon(), SolverSettings(), get_condition("straight", **SHORT)
    P = ParameterSet.nominal().to_array()
    ca = contact_arrays(wagon)
    K = constants(wagon, cond, P, ca, settings)
    tracks, s0, ds = track_arrays(cond, [cond.seed], wagon, settings)
    sos = np.ascontiguousarray(butter(2, 0.4, output="sos"))
    n, n_out = 4, 10
    PP, KK = np.tile(P, (n, 1)), np.tile(K, (n, 1))
    PP[2, 13] = -PP[2, 19]
    out, status = unfinished(n, n_out)
    fail_time = np.zeros(n)
    try:  # on several threads Numba drops the error; on one it passes it on, as a
        integrate_batch(  # SystemError over the ZeroDivisionError: neither says which set
            PP, KK, np.zeros((n, L.N_STATE)), tracks, np.zeros(n, np.int64), s0, ds, ca.table,
            ca.y0, ca.dy, ca.H0L, ca.H0R, 1e-3, 0.0, 0, 10, n_out, sos, 4, out, status,
            fail_time,
        )  # fmt: skip
    except (SystemError, ZeroDivisionError):
        pass
    assert list(status[:3]) == [L.OK, L.OK, L.FAIL_UNFINISHED]
    assert status[3] in (L.OK, L.FAIL_UNFINISHED)  # (after it on its thread, or on another)
    assert np.isfinite(out[:2]).all() and np.isnan(out[2]).all()
    assert "stopped without a result" in L.FAILURE_REASONS[int(status[2])]


def test_the_reciprocal_inertias_are_those_of_the_inertias_the_wagon_gives():
    """The right-hand side multiplies the generalised forces by reciprocal masses and
    inertias kept in K (issue 24); each must be 1 / its inertia, for the tare wagon and for
    a wheelset mass and inertias (X1, X2, X4) off nominal, which come from the parameters."""
    from railsusp.vehicle.operating_point import dof_inertia
    from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays

    for wagon in (load_wagon(), load_wagon("tare")):
        P = ParameterSet.nominal().replace({"X1": 1300.0, "X2": 700.0, "X4": 690.0}).to_array()
        K = constants(wagon, get_condition("straight", **SHORT), P, contact_arrays(wagon),
                      SolverSettings())  # fmt: skip
        names = [f"inv_{n}" for n in L.INERTIAS]
        assert len(names) == 13
        for name in names:
            assert K[L.K[name]] == 1.0 / K[L.K[name[4:]]], name
        # and they are the inertias the modal analysis divides by, DOF for DOF
        inverse = {L.K[n[4:]]: K[L.K[n]] for n in names}
        m = dof_inertia(K, P)
        assert {float(v) for v in m} <= {float(K[i]) for i in inverse}
        assert K[L.K["inv_m_w"]] == 1.0 / 1300.0 and K[L.K["inv_Iz_w"]] == 1.0 / 690.0
