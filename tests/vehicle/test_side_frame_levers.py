"""The side frames' yaw as a lever of the points that lie off their centrelines (revision
2026-12-03.2, docs/model.md "Spring nests and friction wedges"): the cross-bracing pins,
X10 / 2 from the wagon's centreline, i.e. X10 / 2 - b2 (12.5 mm with the K6 data) outboard of
each side frame's centreline, and the axle boxes, b1 - b2 off it (zero for the K6). A side
frame's yaw moves them longitudinally, so that turning the whole wagon rigidly in yaw strains
no suspension element. Before, the bars' direction took the pins at X10 / 2 and their
displacements at b2: a rigid yaw of a bogie stretched one bar and shortened the other by
0.0113 m per radian each (1.7 kN at 5 mrad); a wagon file with b1 != b2 strained its primary
longitudinal springs alike."""

import numpy as np
import pytest

from railsusp.vehicle import layout as L
from railsusp.vehicle.operating_point import linearisation_point
from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_12_03_2, load_wagon


def _rigid_yaw(K: np.ndarray, psi: float) -> np.ndarray:
    """Displacements of the whole wagon turned rigidly by ``psi`` about the vertical through
    its centre on straight track: every body yaws psi, a point (x, y) moves (-y psi, x psi)."""
    lc, a, b2 = K[L.K["l_c"]], K[L.K["a"]], K[L.K["b2"]]
    u = np.zeros(L.N_DOF)
    u[L.CB_YAW] = psi
    for k, x in enumerate((lc, -lc)):
        ib = L.BOL0 + 4 * k
        u[ib], u[ib + 3] = x * psi, psi
        for sidx, side in enumerate((1.0, -1.0)):
            jf = L.SF0 + 5 * (2 * k + sidx)
            u[jf], u[jf + 1], u[jf + 4] = -side * b2 * psi, x * psi, psi
        for wi, e in enumerate((a, -a)):
            iw = L.WS0 + 4 * (2 * k + wi)
            u[iw], u[iw + 3] = (x + e) * psi, psi
    return u


@pytest.mark.parametrize(("x19_factor", "box_half_span"), [(1.0, None), (1.5, None), (1.0, 1.0)])
def test_turning_the_whole_wagon_in_yaw_strains_no_suspension_element(x19_factor, box_half_span):
    """Every generalised force above the wheelsets stays put (central difference at 0.1
    mrad, friction stuck): measured 1e-12 N; with the pins' lever left out of the side
    frames' yaw, 30.5 N on each side frame's longitudinal and 30.2 N m on its yaw; with the
    axle boxes 22 mm off the side frames' centrelines (b1 = 1.0 m) and their lever left out,
    60.7 N."""
    wagon = load_wagon()
    if box_half_span is not None:
        wagon = wagon.with_values({"bogie.axle_box_half_span": box_half_span})
    point = linearisation_point(wagon=wagon)
    assert point.K[L.K["b1"]] == (box_half_span or point.K[L.K["b2"]])
    point.P[L.P_X["X19"]] *= x19_factor
    x = np.zeros(L.N_STATE)
    x[: L.N_DOF] = _rigid_yaw(point.K, 1.0e-4)
    f = 0.5 * (point.rhs(x) - point.rhs(-x))[L.N_DOF : 2 * L.N_DOF] * point.dof_inertia()
    assert np.abs(f[: L.WS0]).max() < 1e-6


def test_the_bars_warp_stiffness_is_the_parallelogram_one():
    """Pure warp (the side frames shift -+ b2 w longitudinally, staying parallel, no wedge
    friction): the bars' moment is 2 k ux^2 (2 b2)^2 w, 46.6 MN m/rad per bogie (docs)."""
    point = linearisation_point(friction="sliding")
    P, K = point.P, point.K
    b2 = K[L.K["b2"]]
    k_bar, x9, x10 = P[L.P_X["X19"]], P[L.P_X["X9"]], P[L.P_X["X10"]]
    ux2 = x9 * x9 / (x9 * x9 + x10 * x10)
    w = 1.0e-4
    x = np.zeros(L.N_STATE)
    jl, jr = L.SF0, L.SF0 + 5
    x[jl], x[jr] = b2 * w, -b2 * w
    d = 0.5 * (point.rhs(x) - point.rhs(-x))[L.N_DOF : 2 * L.N_DOF] * point.dof_inertia()
    # the bars' share of the side frames' longitudinal forces (the nests and axle boxes,
    # which also resist this shift, held out by the bars-off difference)
    P0 = P.copy()
    P0[L.P_X["X19"]] = 0.0
    point.P[:] = P0
    d0 = 0.5 * (point.rhs(x) - point.rhs(-x))[L.N_DOF : 2 * L.N_DOF] * point.dof_inertia()
    point.P[:] = P
    q_w = b2 * (d[jl] - d0[jl]) - b2 * (d[jr] - d0[jr])  # generalised force of the warp w
    assert q_w == pytest.approx(-2.0 * k_bar * ux2 * (2.0 * b2) ** 2 * w, rel=1e-6)
    assert 46e6 < 2.0 * k_bar * ux2 * (2.0 * b2) ** 2 < 47e6


def test_the_switch_of_revision_2026_12_03_1_restores_the_strain_of_a_rigid_yaw():
    """``FORCE_LAWS_BEFORE_2026_12_03_2`` takes the pins' motion at the side frames'
    centrelines again: the rigid yaw then strains the bars (the switch is no dead field)."""
    point = linearisation_point(wagon=load_wagon().with_values(FORCE_LAWS_BEFORE_2026_12_03_2))
    x = np.zeros(L.N_STATE)
    x[: L.N_DOF] = _rigid_yaw(point.K, 1.0e-4)
    f = 0.5 * (point.rhs(x) - point.rhs(-x))[L.N_DOF : 2 * L.N_DOF] * point.dof_inertia()
    assert 25.0 < np.abs(f[L.SF0 : L.WS0]).max() < 40.0
