"""The eight wheels' contacts evaluated together (vehicle/contact_batch.py) against the scalar
kernel of one wheel (vehicle/wheel_rail.py): the same forces to round-off and the same
failure codes, over random wheelset states that cover tread and flange contact, lift-off, yaw,
flange climb, lift beyond the bound and over-penetration; with the yaw-aware and the zero-yaw
contact and with single-point contact."""

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.params import ParameterSet
from railsusp.vehicle import contact_batch as CB
from railsusp.vehicle import layout as L
from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays
from railsusp.vehicle.wagon import load_wagon
from railsusp.vehicle.wheel_rail import wheel_rail_forces

#: half-widths of the random draws: wheelset y, z, roll, yaw; their rates; rail y, z, rates
SPREAD = {
    "y": 0.012, "z": 0.0008, "roll": 0.002, "yaw": 0.012, "vy": 0.2, "vz": 0.05,
    "vroll": 0.05, "vyaw": 0.05, "rail": 0.003, "rail_rate": 0.1, "kappa": 1.0 / 250.0,
}  # fmt: skip


@pytest.fixture(scope="module")
def setup():
    ca = contact_arrays(load_wagon())
    cond = get_condition("curve", irregularity_class=None)
    k = constants(load_wagon(), cond, ParameterSet.nominal().to_array(), ca, SolverSettings())
    return ca, k


def _draw(rng, scale=1.0):
    """A state vector with random wheelset states and the rail rows of a work vector."""
    x = np.zeros(L.N_STATE)
    for w in range(4):
        iw = L.WS0 + 4 * w
        x[iw : iw + 4] = (
            rng.uniform(-1, 1, 4)
            * scale
            * np.array([SPREAD["y"], SPREAD["z"], SPREAD["roll"], SPREAD["yaw"]])
        )
        x[iw + 1] -= 0.5 * SPREAD["z"]  # mostly loaded
        x[L.N_DOF + iw : L.N_DOF + iw + 4] = rng.uniform(-1, 1, 4) * np.array(
            [SPREAD["vy"], SPREAD["vz"], SPREAD["vroll"], SPREAD["vyaw"]]
        )
    wk = np.zeros(CB.N_WORK)
    kappa = np.repeat(rng.uniform(-1, 1, 4) * SPREAD["kappa"], 2)
    wk[CB.W_KAPPA * 8 : CB.W_KAPPA * 8 + 8] = kappa
    for row in (CB.W_RY, CB.W_RZ):
        wk[row * 8 : row * 8 + 8] = rng.uniform(-1, 1, 8) * SPREAD["rail"]
    for row in (CB.W_RVY, CB.W_RVZ):
        wk[row * 8 : row * 8 + 8] = rng.uniform(-1, 1, 8) * SPREAD["rail_rate"]
    return x, wk


def _scalar(x, wk, ca, k):
    """(codes, Y, Q, roll moments, yaw moments) of the eight wheels from wheel_rail_forces."""
    res = np.zeros((5, 8))
    for c in range(8):
        iw = L.WS0 + 4 * (c // 2)
        left = c % 2 == 0
        q, v = x[iw : iw + 4], x[L.N_DOF + iw : L.N_DOF + iw + 4]
        r = wk.reshape(-1, 8)[:, c]
        code, fy, fz, _, mx, mz, _, _, _ = wheel_rail_forces(
            q[0], q[1], q[2], q[3], v[0], v[1], v[2], v[3], r[CB.W_KAPPA], 1.0 if left else -1.0,
            r[CB.W_RY], r[CB.W_RZ], r[CB.W_RVY], r[CB.W_RVZ], ca.table, ca.y0, ca.dy,
            ca.H0L if left else ca.H0R, k[L.K["Z0_L"] if left else L.K["Z0_R"]], k,
        )  # fmt: skip
        res[:, c] = code, fy, fz, mx, mz
    return res


def _batch(x, wk, ca, k):
    CB.contact_forces_8(x, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R, k, wk)
    rows = wk.reshape(-1, 8)
    return np.array([rows[r] for r in (CB.W_CODE, CB.W_FY, CB.W_FZ, CB.W_MX, CB.W_MZ)])


@pytest.mark.parametrize("yaw_geometry", [1.0, 0.0])
@pytest.mark.parametrize("points", [2.0, 1.0])
def test_batch_matches_the_scalar_kernel(setup, yaw_geometry, points):
    ca, k0 = setup
    k = k0.copy()
    k[L.K["yaw_geometry"]] = yaw_geometry
    k[L.K["contact_points"]] = points
    rng = np.random.default_rng(7)
    codes = set()
    flange_loaded = 0
    for _ in range(300):
        x, wk = _draw(rng)
        ref = _scalar(x, wk, ca, k)
        got = _batch(x, wk.copy(), ca, k)
        np.testing.assert_array_equal(got[0], ref[0])
        ok = ref[0] == 0
        codes.update(ref[0].astype(int).tolist())
        scale = max(np.abs(ref[1:3, ok]).max(initial=0.0), 1.0)
        np.testing.assert_allclose(got[1:3, ok], ref[1:3, ok], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(got[3:, ok], ref[3:, ok], rtol=0, atol=1e-12 * scale)
        flange_loaded += int(np.sum(np.abs(ref[1, ok]) > 0.3 * np.abs(ref[2, ok])))
    # the draws reach the flange
    assert flange_loaded > 20
    assert codes == {L.OK}
    # flange climb (beyond the table's shift), lift beyond the bound and over-penetration
    x, wk = _draw(rng)
    x[L.WS0 + 4 : L.WS0 + 16] = 0.0
    wk[CB.W_RY * 8 : CB.W_RVZ * 8 + 8] = 0.0
    x[L.WS0 + 4] = 0.04  # wheelset 2 beyond the table
    x[L.WS0 + 9] = 0.04  # wheelset 3 lifted 40 mm
    x[L.WS0 + 13] = -0.05  # wheelset 4 50 mm into its rails (Hertz approach > 1 mm)
    ref = _scalar(x, wk, ca, k)
    assert ref[0, 2] == ref[0, 3] == L.FAIL_FLANGE_CLIMB
    assert ref[0, 4] == ref[0, 5] == L.FAIL_LIFT
    assert ref[0, 6] == ref[0, 7] == L.FAIL_PENETRATION
    np.testing.assert_array_equal(_batch(x, wk, ca, k)[0], ref[0])


def test_work_vector_fits_the_output_work_array():
    assert CB.N_WORK == L.N_OUT_WORK - L.OUT_CONTACT


def test_each_wheel_keeps_its_shared_rail_solution_as_the_next_warm_start(setup):
    """After an evaluation a wheel whose tread and flange both carry load keeps their u =
    N^(1/3) in W_U1, W_U2 (the next evaluation's start of the shared-rail solve), the others
    0. Evaluated from the rows the previous evaluation left, whether one integration step
    away or of another state altogether, the forces equal those from no warm start to
    round-off."""
    ca, k = setup
    rng = np.random.default_rng(11)
    both = left = 0
    carried = None
    for _ in range(150):
        x, wk = _draw(rng)
        if carried is not None:  # another state's rows: stale warm starts
            wk.reshape(-1, 8)[[CB.W_U1, CB.W_U2]] = carried
        cold_wk = wk.copy()
        cold_wk.reshape(-1, 8)[[CB.W_U1, CB.W_U2]] = 0.0
        for moved in (x, _moved(x, rng)):
            warm, cold = _batch(moved, wk, ca, k), _batch(moved, cold_wk, ca, k)
            np.testing.assert_array_equal(warm[0], cold[0])
            scale = max(np.abs(cold[1:3]).max(initial=0.0), 1.0)
            np.testing.assert_allclose(warm[1:], cold[1:], rtol=0, atol=1e-13 * scale)
            rows = wk.reshape(-1, 8)
            ok = rows[CB.W_CODE] == 0
            tread, flange = rows[CB._P + CB.P_N], rows[CB._P + CB._NP + CB.P_N]
            shared = ok & (tread > 0) & (flange > 0)
            both += int(shared.sum())
            np.testing.assert_array_equal(rows[CB.W_U1][ok] > 0, shared[ok])
            np.testing.assert_array_equal(rows[CB.W_U2][ok] > 0, shared[ok])
            np.testing.assert_allclose(rows[CB.W_U1][shared] ** 3, tread[shared], rtol=1e-15)
            np.testing.assert_allclose(rows[CB.W_U2][shared] ** 3, flange[shared], rtol=1e-15)
            if carried is not None:  # a wheel the previous state coupled and this one not
                left += int(np.sum((carried[0] > 0) & ok & ~shared))
        carried = wk.reshape(-1, 8)[[CB.W_U1, CB.W_U2]].copy()
    assert both > 40  # the draws reach two-point contact (78 evaluations of a wheel)
    assert left > 30  # and leave it, the rows then cleared (72)


def _moved(x: np.ndarray, rng) -> np.ndarray:
    """x with the wheelsets moved by up to 0.2 um and 0.2 urad: about one integration step."""
    moved = x.copy()
    moved[L.WS0 : L.WS0 + 16] += 2e-7 * rng.uniform(-1, 1, 16)
    return moved
