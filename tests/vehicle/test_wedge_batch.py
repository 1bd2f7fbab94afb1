"""The eight friction wedges evaluated together (vehicle/wedge_batch.py) against the scalar
element of one spring nest (suspension.friction_wedges): the same forces and friction-state
rates to round-off, over random nest motions and friction states that cover sticking and
sliding on the column faces and on the slope faces, warp, an unloaded nest and a wedge
without column friction. (Bit for bit before the kernels compiled with floating-point
contraction, kernel_cache.FASTMATH, which fuses multiply-adds in other places in the SIMD
loop than in the scalar code: they now agree to 1e-12 relative.)"""

import numba as nb
import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.params import ParameterSet
from railsusp.vehicle import contact_batch as CB
from railsusp.vehicle import layout as L
from railsusp.vehicle import wedge_batch as WB
from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays
from railsusp.vehicle.suspension import friction_wedges
from railsusp.vehicle.wagon import load_wagon

NAMES = ("F0_ctrl", "k_ctrl", "tan_wedge", "cos_wedge", "mu_column", "mu_slope")
#: relative agreement of the two kernels (a few ulp of each multiply-add fused or not)
ROUND_OFF = 1e-12


@nb.njit
def _scalar_nest(comp, vv, vlat, vwarp, vlong, f0, kc, tan_a, cos_a, mu_c, mu_s, scale, ks, cs,
                 x, dxdt):  # fmt: skip
    return friction_wedges(
        comp, vv, vlat, vwarp, vlong, f0, kc, tan_a, cos_a, mu_c, mu_s, scale, ks, cs, x, dxdt, 0
    )


@pytest.fixture(scope="module")
def wedge_constants():
    """(F0_ctrl, k_ctrl, tan a, cos a, mu_column, mu_slope, X18 scale, k_stick, c_stick) of
    the nominal wagon."""
    wagon = load_wagon()
    p = ParameterSet.nominal().to_array()
    k = constants(wagon, get_condition("straight"), p, contact_arrays(wagon), SolverSettings())
    scale = p[17] / k[L.K["x18_ref"]]
    return (*(k[L.K[n]] for n in NAMES), scale, k[L.K["k_wedge"]], k[L.K["c_wedge"]])


def _nests(rng, limit_scale):
    """Four random nests: compression, vertical, lateral, warp and longitudinal slip rates,
    and the five friction states of each (wedge forces around their limits)."""
    motion = rng.normal(0.0, 1.0, (4, 5)) * np.array([0.004, 0.05, 0.05, 0.02, 0.05])
    motion[rng.random((4, 5)) < 0.15] = 0.0  # resting slips
    states = rng.normal(0.0, limit_scale, (4, L.WEDGE_STATES))
    return motion, states


def _compare(consts, motion, states):
    """Comparison of wedge_forces with friction_wedges for four nests, to round-off; returns
    whether each column wedge and slope slider was sliding (force on its limit)."""
    f0, kc, tan_a, cos_a, mu_c, mu_s, scale, ks, cs = consts
    wk = np.full(CB.N_WORK, np.nan)
    for n in range(4):
        comp, vv, vlat, vwarp, vlong = motion[n]
        for r in range(2):
            c = WB.BASE + n + WB.NN * r
            wk[c + WB.R_COMP * WB.NL] = comp
            wk[c + WB.R_VV * WB.NL] = vv
            wk[c + WB.R_VY * WB.NL] = vlat + vwarp if r == 0 else vlat - vwarp
            iz = L.W_FRONT_Z if r == 0 else L.W_REAR_Z
            wk[c + WB.R_SZ * WB.NL] = states[n, iz]
            wk[c + WB.R_SY * WB.NL] = states[n, iz + 1]
        wk[WB.BASE + n + WB.R_SX * WB.NL] = states[n, L.W_LONG]
        wk[WB.BASE + n + WB.R_VX * WB.NL] = vlong
    WB.wedge_forces(wk, f0, kc, tan_a, cos_a, mu_c, mu_s, scale, ks, cs)
    sliding = []
    for n in range(4):
        dxdt = np.zeros(L.WEDGE_STATES)
        ref = _scalar_nest(*motion[n], f0, kc, tan_a, cos_a, mu_c, mu_s, scale, ks, cs,
                           states[n].copy(), dxdt)  # fmt: skip
        c = WB.BASE + n
        fy_f, fy_r = wk[c + WB.R_FY * WB.NL], wk[c + WB.R_FY * WB.NL + WB.NN]
        got = (
            wk[c + WB.R_FZ * WB.NL] + wk[c + WB.R_FZ * WB.NL + WB.NN],
            fy_f + fy_r,
            fy_f - fy_r,
            wk[c + WB.R_FX * WB.NL],
        )
        np.testing.assert_allclose(np.array(got), np.array(ref), rtol=ROUND_OFF, atol=1e-9)
        rates = np.zeros(L.WEDGE_STATES)
        for r, iz in ((0, L.W_FRONT_Z), (1, L.W_REAR_Z)):
            rates[iz] = wk[c + WB.NN * r + WB.R_DZ * WB.NL]
            rates[iz + 1] = wk[c + WB.NN * r + WB.R_DY * WB.NL]
            limit = mu_c * wk[c + WB.NN * r + WB.R_N * WB.NL]
            force = np.hypot(
                wk[c + WB.NN * r + WB.R_FZ * WB.NL], wk[c + WB.NN * r + WB.R_FY * WB.NL]
            )
            sliding.append(limit > 0.0 and force >= limit * (1.0 - 1e-12))
        rates[L.W_LONG] = wk[c + WB.R_DX * WB.NL]
        np.testing.assert_allclose(rates, dxdt, rtol=ROUND_OFF, atol=1e-12)
    return sliding


def test_same_numbers_as_the_scalar_element_sticking_and_sliding(wedge_constants):
    rng = np.random.default_rng(24)
    sliding = []
    for trial in range(400):
        limit_scale = (200.0, 2e3, 2e4)[trial % 3]  # mostly sticking .. mostly sliding
        sliding += _compare(wedge_constants, *_nests(rng, limit_scale))
    # both regimes were exercised (else the comparison proves little)
    assert 0.1 < np.mean(sliding) < 0.9


@pytest.mark.parametrize(
    "change",
    ["unloaded", "no_column_friction", "no_slope_friction", "no_stick_damping"],
)
def test_same_numbers_at_the_edges(wedge_constants, change):
    """An unloaded nest (control springs slack: no normal force, no friction), a wedge
    without column or slope friction, no stick damping."""
    consts = list(wedge_constants)
    rng = np.random.default_rng(7)
    motion, states = _nests(rng, 2e3)
    if change == "unloaded":
        motion[:, 0] = -1.0  # a metre of extension: the control springs' force is negative
    elif change == "no_column_friction":
        consts[4] = 0.0
    elif change == "no_slope_friction":
        consts[5] = 0.0
    else:
        consts[8] = 0.0
    _compare(tuple(consts), motion, states)


def test_a_nan_state_stays_nan(wedge_constants):
    """A diverged friction state gives NaN forces, as the scalar element does, for the
    integrator's finiteness check."""
    motion, states = _nests(np.random.default_rng(3), 2e3)
    states[1, L.W_FRONT_Z] = np.nan
    states[2, L.W_LONG] = np.nan
    _compare(wedge_constants, motion, states)  # assert_allclose treats NaN as equal
