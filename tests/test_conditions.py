"""Working conditions: the study's Table 6, documented choices, validation, TOML input."""

import pytest

from railsusp.condition_files import load_conditions, resolve_conditions
from railsusp.conditions import STANDARD_CONDITIONS, WorkingCondition, get_condition, make_condition
from railsusp.errors import ConditionError


def test_three_study_conditions_at_60_kmh():
    assert set(STANDARD_CONDITIONS) == {"straight", "curve", "uphill"}
    for c in STANDARD_CONDITIONS.values():
        assert c.speed_kmh == 60.0
        assert c.speed == pytest.approx(16.6667, rel=1e-4)
        assert c.duration_s == 20.0 and c.n_steps == 1000
        assert c.sample_interval == pytest.approx(0.02)
        assert c.irregularity_class == 5


def test_curve_balance_cant_and_deficiency():
    c = get_condition("curve")
    assert c.curve_radius_m == 300.0
    # 11.8 V^2 / R (V km/h) = 141.6 mm; ours uses g = 9.81 and the 1.5 m base: 141.6 mm
    assert c.balance_cant_mm == pytest.approx(141.6, abs=0.3)
    assert c.cant_deficiency_mm == pytest.approx(141.6 - 110.0, abs=0.3)
    assert c.entry_spiral_m > 0 and c.exit_spiral_m > 0
    # the recording starts after the entry spiral, with the rear bogie (10 m back) in the arc
    assert c.lead_in_m - 10.1 >= c.curve_start_m + c.entry_spiral_m


def test_uphill_grade_and_coupler_force():
    c = get_condition("uphill")
    assert c.grade_permille == 12.0
    assert c.grade == pytest.approx(0.012)
    assert c.coupler_force == pytest.approx(650e3)


def test_overrides_are_validated():
    c = get_condition("curve", speed_kmh=80)
    assert c.speed_kmh == 80 and c.curve_radius_m == 300
    with pytest.raises(ConditionError, match=r"speed_kmh = -5.*\[1, 200\] km/h"):
        get_condition("straight", speed_kmh=-5)


@pytest.mark.parametrize(
    ("fields", "pattern"),
    [
        ({"curve_radius_m": 0}, r"curve_radius_m = 0.*\[50, 100000\] m"),
        ({"speed_kmh": 0}, r"speed_kmh = 0"),
        ({"grade_permille": 100}, r"grade_permille = 100.*\[-40, 40\]"),
        ({"irregularity_class": 7}, r"irregularity_class = 7.*\[1, 6\] or \"none\""),
        ({"speed_kmh": True}, r"^condition 'bad': speed_kmh = true: a boolean is not"),
        ({"cant_mm": 100}, "need a curve_radius_m"),
        ({"speed_kmh": float("nan")}, "speed_kmh"),
        ({"wavelength_min_m": 30, "wavelength_max_m": 20}, "must be below"),
        ({"colour": "red"}, "unknown field 'colour'"),
    ],
)
def test_bad_conditions_give_one_line_errors(fields, pattern):
    with pytest.raises(ConditionError, match=pattern) as info:
        make_condition({"name": "bad", **fields})
    assert "\n" not in str(info.value)


def test_unknown_standard_condition():
    with pytest.raises(ConditionError, match="accepted: straight, curve, uphill"):
        get_condition("spiral")


def test_toml_conditions_with_base(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text(
        '[[condition]]\nname = "tight"\nbase = "curve"\ncurve_radius_m = 250\n\n'
        '[[condition]]\nname = "fast"\nspeed_kmh = 80\nirregularity_class = 6\n'
    )
    tight, fast = load_conditions(f)
    assert tight.curve_radius_m == 250 and tight.cant_mm == 110
    assert fast.speed_kmh == 80 and fast.curve_radius_m is None
    assert [c.name for c in resolve_conditions(str(f))] == ["tight", "fast"]
    f.write_text("[condition.bad]\nspeed_kmh = 900\n")
    with pytest.raises(ConditionError, match=r"c\.toml: condition 'bad': speed_kmh = 900"):
        load_conditions(f)


def test_perfect_track_in_a_file_is_none(tmp_path):
    """TOML has no null: docs/conditions.md promised perfect track by leaving the class out,
    which gives the base's class 5; "none" is the file's spelling of None."""
    f = tmp_path / "c.toml"
    f.write_text('[[condition]]\nname = "smooth"\nirregularity_class = "none"\n')
    (smooth,) = load_conditions(f)
    assert smooth.irregularity_class is None and "perfect track" in smooth.describe()
    assert make_condition(smooth.model_dump(mode="json")) == smooth
    f.write_text('[[condition]]\nname = "smooth"\nirregularity_class = "nine"\n')
    with pytest.raises(ConditionError, match='accepted range \\[1, 6\\] or "none"'):
        load_conditions(f)


def test_derived_lengths():
    c = WorkingCondition(speed_kmh=72, duration_s=10, lead_in_m=50)
    assert c.record_length_m == pytest.approx(200.0)
    assert c.section_length_m == pytest.approx(250.0)
    assert c.curvature == 0.0
    right = get_condition("curve", curve_direction="right")
    assert right.curvature == pytest.approx(-1 / 300)


def test_measured_track_field_keeps_old_dumps_and_is_compared():
    """Without measured track the dump has no track_geometry key, so run directories and
    content hashes made before the field existed stay valid; with it, the field counts."""
    c = get_condition("straight")
    assert "track_geometry" not in c.model_dump()
    on_track = c.with_changes(track_geometry="runs/km123.track.csv")
    assert on_track.model_dump()["track_geometry"] == "runs/km123.track.csv"
    assert on_track.differences(c) == ["track_geometry"] == c.differences(on_track)
    assert WorkingCondition(**on_track.model_dump()) == on_track


def test_track_accuracy_needs_a_track_file_and_keeps_old_dumps():
    """The geometry's stated accuracy (which sets the band of the time-aligned comparison)
    is left out of the dump when 0, refused without a track file, and range-checked."""
    c = get_condition("straight")
    assert "track_accuracy_mm" not in c.model_dump()
    on_track = c.with_changes(track_geometry="km123.track.csv", track_accuracy_mm=0.5)
    assert on_track.model_dump()["track_accuracy_mm"] == 0.5
    assert WorkingCondition(**on_track.model_dump()) == on_track
    assert "±0.5 mm RMS" in on_track.describe()
    with pytest.raises(ValueError, match="track_accuracy_mm = 0.5 needs a track_geometry"):
        c.with_changes(track_accuracy_mm=0.5)
    # and the offset, which was taken and ignored (command-line audit of stop 60)
    with pytest.raises(ValueError, match="track_offset_m = 12 needs a track_geometry file"):
        c.with_changes(track_offset_m=12.0)
    assert on_track.with_changes(track_offset_m=12.0).track_offset_m == 12.0
    with pytest.raises(ValueError, match="track_accuracy_mm"):
        on_track.with_changes(track_accuracy_mm=20.0)


def test_a_named_condition_table_with_another_name_is_refused(tmp_path):
    """``[condition.fast]`` holding ``name = "slow"`` became "slow" without a word (the
    command-line audit of stop 60)."""
    from railsusp.condition_files import load_conditions

    path = tmp_path / "c.toml"
    path.write_text('[condition.fast]\nbase = "straight"\nname = "slow"\n')
    with pytest.raises(ValueError, match=r"\[condition.fast\] with name = 'slow': accepted"):
        load_conditions(path)
    path.write_text('[condition.fast]\nbase = "straight"\nname = "fast"\nspeed_kmh = 80\n')
    assert [c.name for c in load_conditions(path)] == ["fast"]
