"""Wheel-rail contact geometry: contact tables, flange contact, equivalent conicity."""

import math

import numpy as np
import pytest

from railsusp.vehicle.contact import (
    LEFT,
    RIGHT,
    ContactTable,
    equivalent_conicity,
    equivalent_conicity_curve,
    flange_split,
)
from railsusp.vehicle.profile_shapes import chn60_rail, conical_wheel, lm_worn_wheel
from railsusp.vehicle.rigid_profile_contact import contact_table


@pytest.fixture(scope="module")
def lm_table() -> ContactTable:
    return contact_table(lm_worn_wheel(), chn60_rail())


def _cone_table(slope: float, roll: bool) -> ContactTable:
    return contact_table(
        conical_wheel(slope), chn60_rail(), y_min=-0.005, y_max=0.005, step=2.5e-4,
        wheelset_roll=roll,
    )  # fmt: skip


# ---------------------------------------------------------------------------- conicity
@pytest.mark.parametrize("slope", [1 / 20, 1 / 40])
def test_cone_conicity_equals_cone_slope(slope):
    # EN 15302 / Klingel: a cone of slope tan(gamma) has dr = 2 tan(gamma) y when the contact
    # point on the rail stays put, so its equivalent conicity is tan(gamma). Decoupled wheels
    # (no roll) realise exactly that geometry.
    table = _cone_table(slope, roll=False)
    np.testing.assert_allclose(table.delta_r, 2 * slope * table.y, atol=1e-9)
    assert equivalent_conicity(table, 0.003) == pytest.approx(slope, rel=0.02)
    assert equivalent_conicity(table, 0.001) == pytest.approx(slope, rel=1e-6)


@pytest.mark.parametrize("slope", [1 / 20, 1 / 40])
def test_cone_conicity_with_wheelset_roll(slope):
    # Rigid wheelset on round rail heads (radius R) at contact half-distance l: the roll phi
    # moves both contact points by (r0 + R) phi along the profiles, so dr = 2 t (y + (r0 + R)
    # phi), and the rail contacts shift in height by -+ t R phi, so 2 (l + t R) phi = dr.
    # Hence lambda = t / (1 - t (r0 + R) / (l + t R)): Wickens' linearised geometry of a cone
    # on a round rail; the cone slope t itself is recovered only for R, r0 << l / t.
    table = _cone_table(slope, roll=True)
    i = int(np.argmin(np.abs(table.y)))
    half = table.contact_y[i, LEFT]
    r0 = table.rolling_radius[i, LEFT]
    rail_radius = 1.0 / table.rail_curvature_lat[i, LEFT]
    assert rail_radius == pytest.approx(0.300, rel=1e-3)  # contact on the R300 crown
    expected = slope / (1.0 - slope * (r0 + rail_radius) / (half + slope * rail_radius))
    assert equivalent_conicity(table, 0.003) == pytest.approx(expected, rel=0.002)
    # roll: the wheel on the larger radius (left for y > 0) rises
    expected_roll = table.delta_r / (2 * (half + slope * rail_radius))
    np.testing.assert_allclose(table.roll, expected_roll, rtol=0.002, atol=1e-9)


def test_lm_conicity_in_published_range(lm_table):
    # physics notes: equivalent conicity of LM on 60 kg/m rail, 1:40, about 0.1-0.2
    lam = equivalent_conicity(lm_table, 0.003)
    assert 0.05 < lam < 0.25
    amps, curve = equivalent_conicity_curve(lm_table)
    np.testing.assert_allclose(amps * 1e3, np.arange(1, 11))
    assert curve[2] == pytest.approx(lam)
    assert np.all((curve > 0.05) & (curve < 0.25))


def test_bad_inputs_are_rejected(lm_table):
    with pytest.raises(ValueError, match="beyond the table range"):
        equivalent_conicity(lm_table, 0.025)
    with pytest.raises(ValueError, match="kind='rail'"):
        contact_table(lm_worn_wheel(), lm_worn_wheel())


# ---------------------------------------------------------------------------- LM / CHN60 table
def test_table_is_mirror_symmetric(lm_table):
    # symmetric wheelset on a symmetric track: left wheel at +y is the right wheel at -y
    t = lm_table
    np.testing.assert_allclose(t.y, -t.y[::-1], atol=1e-12)
    for name in ("rolling_radius", "contact_angle", "wheel_y", "rail_y", "wheel_curvature_lat"):
        arr = getattr(t, name)
        np.testing.assert_allclose(arr[:, LEFT], arr[::-1, RIGHT], atol=1e-7, err_msg=name)
    np.testing.assert_allclose(t.roll, -t.roll[::-1], atol=1e-9)
    np.testing.assert_allclose(t.rise, t.rise[::-1], atol=1e-9)
    np.testing.assert_allclose(t.contact_y[:, LEFT], -t.contact_y[::-1, RIGHT], atol=1e-9)


def test_rolling_radius_difference_grows_with_shift(lm_table):
    dr = lm_table.delta_r
    assert np.all(np.diff(dr) > 0.0)
    assert np.all(dr[lm_table.y > 0] > 0.0)
    i = int(np.argmin(np.abs(lm_table.y)))
    assert lm_table.rise[i] == 0.0 and lm_table.roll[i] == 0.0
    assert np.all(lm_table.rise >= -1e-12)  # the centred wheelset sits lowest


def test_flange_contact_jumps_on_the_correct_side(lm_table):
    t = lm_table
    y_left, y_right = t.flangeway_clearance()
    assert 0.006 < y_left < 0.012
    assert y_right == pytest.approx(-y_left, abs=1e-12)
    assert not t.flange[t.y > 0, RIGHT].any() and not t.flange[t.y < 0, LEFT].any()
    k = int(np.flatnonzero(np.isclose(t.y, y_left))[0])
    # jump: from the tread (< 10 deg, wheel point near the taping line) to the flange root
    assert math.degrees(t.contact_angle[k - 1, LEFT]) < 10.0
    assert math.degrees(t.contact_angle[k, LEFT]) > 45.0
    assert t.wheel_y[k, LEFT] - t.wheel_y[k - 1, LEFT] < -0.015
    # the contact then runs up the root onto the 70 deg flank within a fraction of a mm
    near = (t.y >= y_left) & (t.y <= y_left + 0.001)
    assert math.degrees(t.contact_angle[near, LEFT].max()) > 60.0
    assert math.degrees(t.contact_angle[near, LEFT].max()) == pytest.approx(70.0, abs=0.5)
    assert t.delta_r[k] - t.delta_r[k - 1] > 0.005  # r_L jumps by millimetres


def test_table_interpolation_and_file_round_trip(lm_table, tmp_path):
    t = lm_table
    mid = t.at(0.5 * (t.y[10] + t.y[11]))
    np.testing.assert_allclose(
        mid.rolling_radius[0], 0.5 * (t.rolling_radius[10] + t.rolling_radius[11])
    )
    same = t.at(t.y)
    np.testing.assert_array_equal(same.flange, t.flange)
    with pytest.raises(ValueError, match="outside the table range"):
        t.at(0.03)
    assert t.at(0.03, clip=True).rolling_radius[0, LEFT] == t.rolling_radius[-1, LEFT]
    back = ContactTable.load(t.save(tmp_path / "lm.npz"))
    np.testing.assert_array_equal(back.contact_angle, t.contact_angle)
    np.testing.assert_array_equal(back.flange, t.flange)
    assert back.meta == t.meta
    df = t.to_dataframe()
    assert len(df) == t.y.size and "rolling_radius_L" in df and "flange_R" in df


# ---------------------------------------------------------------------------- two-point contact
def test_tread_and_flange_parts_rebuild_the_single_point_table():
    """Two-point contact splits the wheel profile in the stretch that the single contact
    point jumps over; the higher of the two parts' touching heights is the whole profile's,
    so on rigid profiles the two models agree, and they differ only by elasticity."""
    kw = {"wheelset_roll": False, "y_min": -0.014, "y_max": 0.014, "step": 2e-4}
    whole = contact_table(lm_worn_wheel(), chn60_rail(), **kw)
    split = flange_split(whole)
    y_left, _ = whole.flangeway_clearance()
    k = int(np.flatnonzero(np.isclose(whole.y, y_left))[0])
    # the split lies between the last tread contact and the first flange contact
    assert whole.wheel_y[k, LEFT] < split < whole.wheel_y[k - 1, LEFT]
    tread = contact_table(lm_worn_wheel(), chn60_rail(), wheel_range=(split, 1.0), **kw)
    flange = contact_table(lm_worn_wheel(), chn60_rail(), wheel_range=(-1.0, split), **kw)
    rise = {
        n: t.contact_z + t.rolling_radius for n, t in (("w", whole), ("t", tread), ("f", flange))
    }
    highest = np.fmax(rise["t"], rise["f"])  # NaN: the flange part has no rail below it
    np.testing.assert_allclose(highest, rise["w"], atol=2e-7)
    # the tread part alone never climbs the flank, the flange part touches only on the flange
    assert math.degrees(np.nanmax(tread.contact_angle[:, LEFT])) < 15.0
    touching = rise["f"][:, LEFT] >= rise["t"][:, LEFT]
    assert np.all(flange.contact_angle[touching, LEFT] > math.radians(45.0))
    assert np.isnan(flange.contact_z[:, LEFT]).any()  # far from the flange: no rail below it
    with pytest.raises(ValueError, match="wheel_range needs wheelset_roll=False"):
        contact_table(lm_worn_wheel(), chn60_rail(), wheel_range=(split, 1.0))
    with pytest.raises(ValueError, match="fewer than three points"):
        contact_table(lm_worn_wheel(), chn60_rail(), wheel_range=(0.0, 1e-5), **kw)


def test_a_cone_has_no_flange_split():
    table = _cone_table(1 / 40, roll=False)
    assert flange_split(table) is None
