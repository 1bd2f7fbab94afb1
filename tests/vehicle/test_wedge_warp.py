"""Warp (lozenging) friction of the friction wedges: each spring nest's two wedges, ahead of
and behind the bolster end at +-l_w (``[secondary] wedge_half_spacing``), slide on their
column faces in opposite directions when the bolster yaws relative to the side frame, and
their column friction makes a yaw moment mu_column N_col l_w against it (docs/model.md,
friction wedges). The wedge pair of the model before the warp friction (2026-11-24) acted at
the nest centre and resisted no warp: ``wedge_half_spacing = 0`` is that model, bit for bit
(its stored forces: tests/vehicle/test_force_reference.py)."""

import dataclasses
import math

import numpy as np
import pytest

from conftest import harmonic_drive
from railsusp.vehicle import layout as L
from railsusp.vehicle.operating_point import linearisation_point
from railsusp.vehicle.suspension import friction_wedges
from railsusp.vehicle.wagon import WagonData, load_wagon

NQ = L.N_DOF
L_W = 0.25  # m, the K6 estimate of the wagon data


def _wagon(half_spacing: float) -> WagonData:
    return load_wagon().with_values({"secondary.wedge_half_spacing": half_spacing})


def _point(half_spacing: float):
    """The loaded wagon's operating point with the cross-bracing (X19) off and no stick
    damping: the side frames' yaw moment is then the wedges' column friction alone."""
    point = linearisation_point(wagon=_wagon(half_spacing))
    P = point.P.copy()
    P[L.P_X["X19"]] = 0.0
    K = point.K.copy()
    K[L.K["c_wedge"]] = 0.0
    return dataclasses.replace(point, P=P, K=K)


def _lozenge_loop(point, amplitude, n=4000, cycles=2):
    """Pure lozenge of the front bogie at 1 Hz: the bolster yaws -w(t), w = A sin(2 pi t),
    and its side frames move longitudinally with its ends (x = -side b2 psi_b: no
    longitudinal slip at the nests), staying parallel to the track (no side-frame yaw),
    with no lateral or vertical slip; warp angle w = side-frame yaw - bolster yaw. The
    friction states follow by explicit Euler (small steps). Returns w and the yaw moment
    on the left side frame over the last cycle, and the largest |vertical, lateral| column
    friction state seen (they must stay at 0 and +-limit)."""
    b2 = point.K[L.K["b2"]]
    iz_f = point.K[L.K["Iz_f"]]
    ib = L.BOL0
    jl, jr = L.SF0, L.SF0 + 5
    x = np.zeros(L.N_STATE)
    ws, ms = [], []
    for dt, w, dw, last in harmonic_drive(amplitude, n, cycles):
        x[:NQ] = 0.0
        x[NQ : 2 * NQ] = 0.0
        x[ib + 3], x[NQ + ib + 3] = -w, -dw
        for j, side in ((jl, 1.0), (jr, -1.0)):
            x[j], x[NQ + j] = side * b2 * w, side * b2 * dw
        d = point.rhs(x)
        if last:
            ws.append(w)
            ms.append(iz_f * d[NQ + jl + 4])
        x[2 * NQ :] += dt * d[2 * NQ :]
    return np.array(ws), np.array(ms)


def _slide_moment(point) -> float:
    """mu_column N_col l_w: the nest's column normal force (static control springs' force
    over tan a, X18 scale; no vertical slip, so neither compression nor rebound)."""
    k = point.K
    scale = point.P[L.P_X["X18"]] / k[L.K["x18_ref"]]
    n_col = scale * k[L.K["F0_ctrl"]] / k[L.K["tan_wedge"]]
    return k[L.K["mu_column"]] * n_col * k[L.K["l_wedge"]]


def test_warp_lozenge_is_resisted_by_the_wedges_friction_moment_hysteresis():
    """Moment on the side frame against the warp angle: a friction loop whose sliding value
    is mu_column N_col l_w (4.4 kN m per nest with the K6 data) and whose area is that of
    an elasto-plastic slider, 4 M (A - M / k_w) with the warp stick stiffness
    k_w = 2 (k_stick / 2) l_w^2; the wedge pair at the nest centre (the model before the
    warp friction) gives no moment at all."""
    point = _point(L_W)
    A = 0.01  # rad
    w, m = _lozenge_loop(point, A)
    m_slide = _slide_moment(point)
    assert 4.0e3 < m_slide < 5.0e3  # N m per nest, loaded wagon
    dw = np.gradient(w)
    sliding = np.abs(w) < 0.2 * A  # mid-stroke, long after the reversals
    assert np.all(m[sliding & (dw > 0)] == pytest.approx(-m_slide, rel=1e-6))
    assert np.all(m[sliding & (dw < 0)] == pytest.approx(m_slide, rel=1e-6))
    k_w = point.K[L.K["k_wedge"]] * L_W**2
    area = -np.trapezoid(m, w)  # work of the side frame's moment against the warp: dissipated
    assert area == pytest.approx(4.0 * m_slide * (A - m_slide / k_w), rel=0.02)
    # the wedge pair at the nest centre
    _, m0 = _lozenge_loop(_point(0.0), A, n=400)
    assert np.all(m0 == 0.0)


def test_warp_moment_acts_on_bolster_and_side_frame_equal_and_opposite():
    """The warp moment l_w (F_front - F_rear) is applied to the bolster's yaw and, reversed,
    to the side frame's: the bolster's yaw moment changes by minus the side frame's when the
    wedges' lateral states are set apart."""
    point = _point(L_W)
    iz_b = point.K[L.K["Iz_b"]]
    iz_f = point.K[L.K["Iz_f"]]
    x = np.zeros(L.N_STATE)
    base = point.rhs(x)
    ia = L.AUX_WEDGE  # nest 0: front bogie, left
    x[ia + L.W_FRONT_Y] = 1000.0
    x[ia + L.W_REAR_Y] = -1000.0
    d = point.rhs(x)
    m_bol = iz_b * (d[NQ + L.BOL0 + 3] - base[NQ + L.BOL0 + 3])
    m_sf = iz_f * (d[NQ + L.SF0 + 4] - base[NQ + L.SF0 + 4])
    assert m_bol == pytest.approx(L_W * 2000.0, rel=1e-9)
    assert m_sf == pytest.approx(-m_bol, rel=1e-9)
    m = point.K[L.K["m_b"]]
    assert d[NQ + L.BOL0] == pytest.approx(base[NQ + L.BOL0], abs=1e-9 / m)  # no net lateral


def test_without_relative_yaw_the_split_wedges_are_the_wedge_pair_bit_for_bit():
    """Random states whose side frames yaw with their bolsters (no warp) and whose front and
    rear wedges carry the same friction: the equations with the wedges at +-0.25 m give the
    same derivatives, bit for bit, as with the pair at the nest centre."""
    near, apart = linearisation_point(wagon=_wagon(0.0)), linearisation_point(wagon=_wagon(L_W))
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = np.zeros(L.N_STATE)
        x[:NQ] = rng.normal(0.0, 1e-4, NQ)
        x[NQ : 2 * NQ] = rng.normal(0.0, 1e-2, NQ)
        for k in range(2):
            for sidx in range(2):
                jf = L.SF0 + 5 * (2 * k + sidx)
                ib = L.BOL0 + 4 * k
                x[jf + 4], x[NQ + jf + 4] = x[ib + 3], x[NQ + ib + 3]
                ia = L.AUX_WEDGE + L.WEDGE_STATES * (2 * k + sidx)
                z, y = rng.normal(0.0, 2e3, 2)
                x[ia + L.W_FRONT_Z] = x[ia + L.W_REAR_Z] = z
                x[ia + L.W_FRONT_Y] = x[ia + L.W_REAR_Y] = y
                x[ia + L.W_LONG] = rng.normal(0.0, 2e3)
        x[L.AUX_YAWFR :] = rng.normal(0.0, 1e3, L.N_AUX - L.N_WEDGE_AUX)
        np.testing.assert_array_equal(apart.rhs(x), near.rhs(x))


def test_warp_splits_the_wedges_column_friction_between_front_and_rear():
    """The element alone: with warp slip only, the two wedges slide at half the nest's
    column friction each, in opposite directions (lateral sum zero, difference mu N), and
    their vertical friction stays zero; with lateral slip only they share it equally."""
    tan_a, cos_a, mu = math.tan(math.radians(40.0)), math.cos(math.radians(40.0)), 0.25
    f0 = 59.2e3
    state = np.zeros(L.WEDGE_STATES)
    d = np.zeros(L.WEDGE_STATES)
    dt, v = 1e-4, 0.01  # 1 cm/s of slip for 0.1 s: 1 mm, far past the stick deflection
    for _ in range(1000):
        fz, fy, dfy, fx = friction_wedges(
            0.0, 0.0, 0.0, v, 0.0, f0, 1.538e6, tan_a, cos_a, mu, 0.2, 1.0, 20e6, 0.0, state,
            d, 0,
        )  # fmt: skip
        state += dt * d
    limit = mu * f0 / tan_a
    assert fy == pytest.approx(0.0, abs=1e-9 * limit)
    assert dfy == pytest.approx(limit, rel=1e-9)  # front +limit/2, rear -limit/2
    assert fz == 0.0 and fx == 0.0
    state[:] = 0.0
    for _ in range(1000):
        fz, fy, dfy, fx = friction_wedges(
            0.0, 0.0, v, 0.0, 0.0, f0, 1.538e6, tan_a, cos_a, mu, 0.2, 1.0, 20e6, 0.0, state,
            d, 0,
        )  # fmt: skip
        state += dt * d
    assert fy == pytest.approx(limit, rel=1e-9)
    assert dfy == 0.0


@pytest.mark.parametrize(
    ("spacing", "wedges", "needle"),
    [
        (
            "0.7",
            "2",
            "secondary.wedge_half_spacing = 0.7: accepted [0, 0.5] (Input should be less than",
        ),
        (
            "-0.1",
            "2",
            "secondary.wedge_half_spacing = -0.1: accepted [0, 0.5] (Input should be greater",
        ),
        ("0.25", "1", "wedges_per_nest = 1: accepted an even number of wedges"),
    ],
)
def test_wedge_half_spacing_is_checked_in_the_wagon_file(tmp_path, spacing, wedges, needle):
    import re
    from importlib import resources

    from railsusp.errors import RailsuspInputError

    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    text, n1 = re.subn(r"(?m)^wedge_half_spacing = \S+", f"wedge_half_spacing = {spacing}", text)
    text, n2 = re.subn(r"(?m)^wedges_per_nest = 2", f"wedges_per_nest = {wedges}", text)
    assert n1 == n2 == 1
    path = tmp_path / "wagon.toml"
    path.write_text(text)
    with pytest.raises(RailsuspInputError) as err:
        load_wagon(path)
    msg = str(err.value)
    assert needle in msg and "\n" not in msg, msg
