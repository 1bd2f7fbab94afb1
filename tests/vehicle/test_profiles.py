"""Wheel and rail profiles: LM-like and CHN60 dimensions, validation, profile files."""

import math

import numpy as np
import pytest

from railsusp.errors import RailsuspInputError
from railsusp.vehicle.profile_shapes import (
    chn60_rail,
    conical_wheel,
    incline,
    lm_worn_wheel,
    round_rail,
)
from railsusp.vehicle.profiles import Profile, read_profile, write_profile


@pytest.fixture(scope="module")
def wheel() -> Profile:
    return lm_worn_wheel()


@pytest.fixture(scope="module")
def rail() -> Profile:
    return chn60_rail()


def _chord_angles(p: Profile) -> np.ndarray:
    return np.arctan(np.diff(p.z) / np.diff(p.y))


def test_lm_like_dimensions(wheel):
    # LM: flange height 27 mm, flange 32 mm thick 10 mm below the taping line, measured from
    # the back face 70 mm inside the taping line; rim 135 mm wide.
    assert wheel.z.max() == pytest.approx(0.027, abs=1e-6)
    tip = int(np.argmax(wheel.z))
    flank_y = np.interp(0.010, wheel.z[tip:][::-1], wheel.y[tip:][::-1])
    assert flank_y + 0.070 == pytest.approx(0.032, abs=1e-5)
    assert wheel.y[0] == pytest.approx(-0.070, abs=1e-5)  # back face
    assert wheel.y[-1] == pytest.approx(0.065, abs=1e-6)
    assert wheel.evaluate(0.0)[0] == pytest.approx(0.0, abs=1e-9)  # radius r0 at taping line


def test_lm_like_flank_root_and_tread_radii(wheel):
    _, slope, curv = wheel.evaluate(np.array([-0.0405, -0.034, -0.015, -0.005]))
    # straight 70 deg flank, concave R15 root, hollow R220 then R500 tread (curvature -1/R)
    assert math.degrees(math.atan(-slope[0])) == pytest.approx(70.0, abs=0.05)
    np.testing.assert_allclose(curv[1:], [1 / 0.015, 1 / 0.220, 1 / 0.500], rtol=1e-3)


def test_lm_like_is_c1(wheel):
    # tangent arcs and lines: the chord angle turns by no more than the sharpest arc allows
    # (R12 flange tip), i.e. no kink anywhere; on the running tread no more than R100 allows.
    turn = np.abs(np.diff(_chord_angles(wheel)))
    chord = np.hypot(np.diff(wheel.y), np.diff(wheel.z))
    assert np.max(turn / chord[1:]) < 1.02 / 0.012
    tread = ((wheel.y > -0.025) & (wheel.y < 0.045))[1:-1]  # R100..R500 and the cone
    assert np.max((turn / chord[1:])[tread]) < 1.02 / 0.100


def test_chn60_head(rail):
    # R300 crown, R80 shoulders, R13 gauge corners, 73 mm head width at the 1:20 side faces
    assert rail.evaluate(0.0)[0] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(rail.z, rail.z[::-1], atol=1e-12)  # symmetric head
    _, slope, curv = rail.evaluate(np.array([0.004, 0.018, 0.032, 0.0375]))
    np.testing.assert_allclose(curv[:3], [1 / 0.300, 1 / 0.080, 1 / 0.013], rtol=2e-3)
    assert slope[3] == pytest.approx(20.0, rel=1e-3)  # 1:20 side face
    y_pos = rail.y[rail.y > 0]
    corner_end = y_pos[np.argmax(rail.evaluate(y_pos)[1] >= 19.9)]
    assert 2 * corner_end == pytest.approx(0.073, abs=2e-4)


def test_incline_turns_crown_towards_track_centre(rail):
    tilted = incline(rail, 1 / 40)
    # rotation by atan(1/40): slope at the old crown origin -1/40 (rising to the field side),
    # and the highest point moves 300 mm / 40 = 7.5 mm to the field side on the R300 crown
    assert tilted.evaluate(0.0)[1] == pytest.approx(-1 / 40, rel=1e-3)
    assert tilted.y[np.argmin(tilted.z)] == pytest.approx(0.0075, abs=1e-4)
    assert chn60_rail(inclination=1 / 40).name == tilted.name


def test_reference_shapes():
    cone = conical_wheel(1 / 20)
    np.testing.assert_allclose(cone.evaluate(cone.y[5:-5])[1], -1 / 20, rtol=1e-9)
    arc = round_rail(0.3)
    np.testing.assert_allclose(arc.evaluate(np.array([0.0, 0.02]))[2], 1 / 0.3, rtol=1e-4)


@pytest.mark.parametrize(
    ("y", "z", "message"),
    [
        ([0.0, 1.0, 0.5, 2.0], [0, 0, 0, 0], "not strictly increasing at index 2"),
        ([0.0, 1.0, 2.0, 3.0], [0, np.nan, 0, 0], "z is not finite at index 1"),
        ([0.0, 1.0, 2.0], [0, 0, 0], "at least 4 points"),
        ([0.0, 1.0, 2.0, 3.0], [0, 0, 0], "but z has 3"),
    ],
)
def test_profile_validation(y, z, message):
    with pytest.raises(ValueError, match=message):
        Profile(np.array(y), np.array(z, dtype=float), name="bad")


def test_profile_file_round_trip(tmp_path, wheel):
    path = write_profile(wheel, tmp_path / "lm.csv")
    back = read_profile(path, name=wheel.name)
    np.testing.assert_allclose(back.y, wheel.y, atol=1e-9)
    np.testing.assert_allclose(back.z, wheel.z, atol=1e-9)
    assert back.name == wheel.name and back.kind == "wheel"


def test_read_profile_formats(tmp_path):
    path = tmp_path / "rail.txt"
    path.write_text("# measured head\n\n-1.0\t0.5\n0 ; 0\n1.0 0.5\n  2,2\n", encoding="utf-8")
    p = read_profile(path, kind="rail")
    np.testing.assert_allclose(p.y, [-1e-3, 0, 1e-3, 2e-3])
    np.testing.assert_allclose(p.z, [5e-4, 0, 5e-4, 2e-3])
    assert p.name == "rail" and p.kind == "rail"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("# y z\n0 0\n1 0.1\n2 x0.2\n3 0.3\n", r"line 4: z cell 'x0.2' is not a number"),
        ("0 0\n1 0.1\n0.5 0.2\n3 0.3\n", r"line 3: y = 0.5 mm does not increase"),
        ("0 0\n1 0.1 7\n2 0.2\n3 0.3\n", r"line 2: expected 2 columns"),
        ("0 0\n1 inf\n2 0.2\n3 0.3\n", r"line 2: z cell 'inf' not finite"),
        ("# only\n0 0\n1 1\n", r"at least 4 data lines"),
    ],
)
def test_bad_profile_file_names_file_and_line(tmp_path, text, message):
    path = tmp_path / "bad_profile.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(RailsuspInputError, match=message) as info:
        read_profile(path)
    assert "bad_profile.csv" in str(info.value)


def test_missing_profile_file(tmp_path):
    with pytest.raises(RailsuspInputError, match="cannot be read"):
        read_profile(tmp_path / "nope.csv")
