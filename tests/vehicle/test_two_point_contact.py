"""Two-point wheel-rail contact: tread and flange on one elastic rail (kernel level)."""

import numpy as np
import pytest
from scipy.optimize import fsolve

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.normal_contact import hertz_rail_normal_force, shared_rail_normal_forces
from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays
from railsusp.vehicle.wagon import load_wagon
from railsusp.vehicle.wheel_rail import wheel_rail_forces

G_TREAD, G_FLANGE = 4.2e-8, 5.8e-8  # Hertz constants of the C80 tread and flank, m/N^(2/3)
K_RY, K_RZ = 40e6, 150e6  # rail support per wheel, N/m


def compliance(d1: float, d2: float) -> tuple[float, float, float]:
    """m_ij = n_i . diag(1/k_ry, 1/k_rz) n_j for contact angles d1, d2 (rad)."""
    s1, c1, s2, c2 = np.sin(d1), np.cos(d1), np.sin(d2), np.cos(d2)
    return (
        s1 * s1 / K_RY + c1 * c1 / K_RZ,
        s1 * s2 / K_RY + c1 * c2 / K_RZ,
        s2 * s2 / K_RY + c2 * c2 / K_RZ,
    )


@pytest.mark.parametrize("a2_mm", [0.6, 1.0, 2.0])
def test_shared_rail_normal_forces_solve_the_compatibility_equations(a2_mm):
    """a_i = G_i N_i^(2/3) + sum_j m_ij N_j for both contacts (the rail deflects under both)."""
    m11, m12, m22 = compliance(0.06, 1.22)
    a1, a2 = 0.9e-3, a2_mm * 1e-3
    n1, n2 = shared_rail_normal_forces(a1, G_TREAD, a2, G_FLANGE, m11, m12, m22)
    assert n1 > 0.0 and n2 > 0.0

    def residual(n):
        n = np.maximum(n, 0.0)
        return [
            G_TREAD * n[0] ** (2 / 3) + m11 * n[0] + m12 * n[1] - a1,
            G_FLANGE * n[1] ** (2 / 3) + m12 * n[0] + m22 * n[1] - a2,
        ]

    ref = fsolve(residual, [n1 * 0.9, n2 * 0.9], xtol=1e-12)
    np.testing.assert_allclose([n1, n2], ref, rtol=1e-6)
    # each force is below its single-contact value: the other contact's load lowers the rail
    assert n1 < hertz_rail_normal_force(a1, G_TREAD, 1 / m11)
    assert n2 < hertz_rail_normal_force(a2, G_FLANGE, 1 / m22)


def test_a_contact_opened_by_the_others_rail_deflection_carries_nothing():
    m11, m12, m22 = compliance(0.06, 1.22)
    a1 = 0.9e-3
    single = hertz_rail_normal_force(a1, G_TREAD, 1 / m11)
    # the tread load lowers the rail under the flange by m12 * N1 along its normal
    a2 = 0.5 * m12 * single
    assert shared_rail_normal_forces(a1, G_TREAD, a2, G_FLANGE, m11, m12, m22) == (single, 0.0)
    assert shared_rail_normal_forces(a1, G_TREAD, -1e-3, G_FLANGE, m11, m12, m22) == (single, 0.0)


def _wagon(model: str):
    return load_wagon().with_contact_model(model)


def _pushed_wheel(model: str, shift: float) -> tuple[float, float, float]:
    """Left wheel held at lateral ``shift`` (m) and lowered until it carries its static load:
    (Y on the wheel, Q, tread normal force), N."""
    wagon = _wagon(model)
    ca = contact_arrays(wagon)
    cond = get_condition("straight", irregularity_class=None)
    k = constants(wagon, cond, ParameterSet.nominal().to_array(), ca, SolverSettings())
    z0 = k[L.K["Z0_L"]]

    def forces(z: float) -> np.ndarray:
        code, *res = wheel_rail_forces(
            shift, z, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0,
            ca.table, ca.y0, ca.dy, ca.H0L, z0, k,
        )  # fmt: skip
        assert code == 0
        return np.array(res)  # Y, Q, Fx, roll and yaw moments, tread normal force, ...

    lo, hi = -0.012, 0.02  # bisection on the wheel height for Q = static load
    for _ in range(70):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if forces(mid)[1] > k[L.K["Q0"]] else (lo, mid)
    t = forces(lo)
    return t[0], t[1], t[5]


def test_pushed_into_the_flange_the_tread_keeps_the_load():
    """Two-point contact: a wheel pushed 1 mm past the flangeway clearance keeps most of its
    load on the tread while the flange contact takes the lateral force through the rail's
    lateral flexibility. The single-point table moves the whole load onto the flange root and
    flank at once, so Y/Q leaps beyond 1 within 0.1 mm (the flange climb quotient of Nadal's
    formula for 70 deg and mu = 0.3 is 1.34)."""
    clearance = contact_arrays(load_wagon()).flange_shift
    shifts = clearance + np.array([-0.5, 0.0, 0.5, 1.0, 1.5]) * 1e-3
    two = np.array([_pushed_wheel("two-point", s) for s in shifts])
    y_rail = -two[:, 0]  # force on the rail, + towards the field side
    assert np.all(np.diff(y_rail) > 0.0)  # grows steadily with the shift
    assert y_rail[3] / two[3, 1] < 0.5
    assert two[3, 2] > 0.85 * two[3, 1]  # tread normal force: most of the wheel load
    # the flange takes about the rail's lateral stiffness times the extra shift
    stiffness = (y_rail[4] - y_rail[3]) / 0.5e-3
    assert 0.5 * K_RY < stiffness < 1.2 * K_RY
    y_one, q_one, _ = _pushed_wheel("single-point", clearance + 1e-4)
    assert q_one == pytest.approx(two[0, 1], rel=1e-6)  # the same wheel load
    assert -y_one / q_one > 1.0


def test_contact_model_is_checked_in_the_wagon_file(tmp_path):
    from importlib import resources

    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('model = "two-point"', 'model = "three-point"'))
    with pytest.raises(RailsuspInputError, match=r"contact\.model = 'three-point'"):
        load_wagon(bad)
    assert contact_arrays(load_wagon()).contact_points == 2
    assert contact_arrays(_wagon("single-point")).contact_points == 1
    with pytest.raises(RailsuspInputError, match="contact.model = 'one': accepted two-point"):
        load_wagon().with_contact_model("one")
