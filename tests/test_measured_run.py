"""Long runs: MDF4 and unit-aware tables read through a channel map, units converted from
what the file states, channels of different rates put on one time base, sections cut by
track and speed and written as a field folder; the shipped example run."""

import itertools
from importlib import resources

import numpy as np
import pandas as pd
import pytest
from asammdf import MDF, Signal

from railsusp.condition_files import load_conditions
from railsusp.errors import RailsuspInputError
from railsusp.measured import RecordingError, read_field
from railsusp.measured.channels import channel_map_from, is_documented, read_channel_map
from railsusp.measured.run import MeasuredRun, read_run
from railsusp.measured.sections import (
    NO_TRACK_NOTE,
    SectionRules,
    cut_sections,
    geometry_from_line,
    read_line,
    read_section_table,
)
from railsusp.measured.sections_out import write_sections
from railsusp.measured.units import si_factor, split_header

MAP = {
    "speed": "v",
    "position": "s",
    "ignore": ["acc_bogie_y_g"],
    "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R"}},
}


def write_mdf(path, *, q_unit="kN", q_scale=1.0, v_unit="km/h", force_rate=200.0, q_rate=None):
    """A 20 s run: forces at ``force_rate`` (Q at ``q_rate``), speed/position at 10 Hz."""
    rng = np.random.default_rng(0)
    t = np.arange(0, 20, 1 / force_rate)
    tq = np.arange(0, 20, 1 / (q_rate or force_rate))
    ts = np.arange(0, 20.1, 0.1)
    mdf = MDF(version="4.10")
    mdf.append(
        [Signal(5 + rng.standard_normal(t.size), t, name="Y_R", unit="kN")],
        comment="Y",
    )
    mdf.append(
        [Signal((120 + rng.standard_normal(tq.size)) * q_scale, tq, name="Q_R", unit=q_unit)],
        comment="Q",
    )
    mdf.append(
        [
            Signal(np.full(ts.size, 54.0), ts, name="v", unit=v_unit),
            Signal(15.0 * ts, ts, name="s", unit="m"),
        ],
        comment="speed",
    )
    mdf.append([Signal(rng.standard_normal(t.size), t, name="acc_bogie_y_g", unit="g")])
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


def test_split_header_reads_the_usual_unit_spellings():
    assert split_header("Y [kN]") == ("Y", "kN")
    assert split_header("Q_w1R (N)") == ("Q_w1R", "N")
    assert split_header("Y_w1L_kN") == ("Y_w1L", "kN")
    assert split_header("curvature_1_per_km") == ("curvature", "1/km")
    assert split_header("speed_kmh") == ("speed", "kmh")
    assert split_header("speed_kph") == ("speed", "kph")  # an accepted unit, as a suffix too
    assert split_header("speed_kmph") == ("speed", "kmph")
    assert split_header("acc_bogie_y_g") == ("acc_bogie_y", "g")
    assert si_factor("force", "kN", "x") == 1e3 and si_factor("speed", "km/h", "v") == 1 / 3.6
    with pytest.raises(RailsuspInputError, match="channel 'x': no unit stated"):
        si_factor("force", "", "x")


def test_mdf4_through_a_channel_map_in_si_on_the_force_time_base(tmp_path):
    path = write_mdf(tmp_path / "run.mf4", q_unit="N", q_scale=1e3)
    run = read_run(path, channel_map_from(MAP))
    assert run.rate_hz == pytest.approx(200.0)
    assert np.median(run.Q["w1R"]) == pytest.approx(120e3, rel=0.01)  # N, from N
    assert np.median(run.Y["w1R"]) == pytest.approx(5e3, rel=0.1)  # N, from kN
    np.testing.assert_allclose(run.speed, 15.0)  # m/s, from km/h
    assert run.rates_hz["v"] == pytest.approx(10.0)
    assert any("'v' (10 Hz) interpolated onto 200 Hz" in n for n in run.notes)
    assert not any("acc_bogie_y_g" in n for n in run.notes)  # ignored by the map
    run = read_run(path, channel_map_from({**MAP, "ignore": []}))
    assert any("not used: acc_bogie_y_g" in n for n in run.notes)  # allowed, noted


def test_y_sign_minus_one_reads_a_vehicle_fixed_lateral_channel_as_railsusps_sign(tmp_path):
    """A wheel recorded + towards the track centre (vehicle-fixed) is read negated through
    ``Y_sign = -1`` and noted; anything but 1 or -1 names the key and the accepted values."""
    path = write_mdf(tmp_path / "run.mf4")
    plain = read_run(path, channel_map_from(MAP))
    flipped_map = {**MAP, "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R", "Y_sign": -1}}}
    flipped = read_run(path, channel_map_from(flipped_map))
    np.testing.assert_array_equal(flipped.Y["w1R"], -plain.Y["w1R"])
    np.testing.assert_array_equal(flipped.Q["w1R"], plain.Q["w1R"])
    assert "Y of w1R ('Y_R') negated: Y_sign = -1 in the map" in flipped.notes
    assert not any("negated" in n for n in plain.notes)
    for bad in (0, 2, True, "-1", -1.5):
        doc = {**MAP, "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R", "Y_sign": bad}}}
        with pytest.raises(RailsuspInputError, match=r"wheels.w1R.Y_sign = .*: accepted 1 .* -1"):
            channel_map_from(doc)
    with pytest.raises(RailsuspInputError, match="optionally Y_sign"):
        channel_map_from({**MAP, "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R", "sign": -1}}})


def test_meganewtons_are_converted_when_stated_and_refused_when_not(tmp_path):
    run = read_run(write_mdf(tmp_path / "a.mf4", q_unit="MN", q_scale=1e-3), channel_map_from(MAP))
    assert np.median(run.Q["w1R"]) == pytest.approx(120e3, rel=0.01)
    with pytest.raises(RecordingError, match="'Q_R': median wheel load 0.12 kN.*look like MN"):
        read_run(write_mdf(tmp_path / "b.mf4", q_unit="kN", q_scale=1e-3), channel_map_from(MAP))


def test_a_speed_in_the_wrong_unit_is_caught_by_the_distance_it_covers(tmp_path):
    """54 km/h headed m/s: 54 m/s (194 km/h) is under any speed limit of the reader, but
    20 s of it cover 1080 m where the distance channel spans 300 m. Before stop 57 such a
    run was cut into 194 km/h sections, which failed only at --write without the channel
    named (the audit's 234 km/h case)."""
    path = write_mdf(tmp_path / "run.mf4", v_unit="m/s")
    with pytest.raises(RecordingError) as info:
        read_run(path, channel_map_from(MAP))
    assert (
        "channels 's' and 'v': the distance runs over 300 m while the speed integrates to 1080 m"
        in (str(info.value))
    )
    assert "a unit error in one?" in str(info.value)
    read_run(write_mdf(tmp_path / "ok.mf4"), channel_map_from(MAP))  # km/h: consistent


def test_a_cant_or_grade_no_line_has_is_refused_with_the_channel(tmp_path):
    from railsusp.measured.breaks import compared_steps, distance_path, speed_path
    from railsusp.measured.run_checks import check_track_channels

    t = np.arange(100) / 10.0
    names = {"cant": "cant_x", "grade": "grade_x"}
    assert (
        check_track_channels(
            {"cant": np.full(100, 0.11), "grade": np.full(100, 0.012)}, names, None
        )
        == []
    )
    (one,) = check_track_channels({"cant": np.full(100, 110.0)}, names, None)  # mm as m
    assert one.startswith("channel 'cant_x': cant up to 1.1e+05 mm, beyond a working")
    # a run that backs up: the distance's path, not its span, is what the speed covers
    t = np.linspace(0.0, 30.0, 301)
    position = np.where(t <= 20.0, 15.0 * t, 300.0 - 10.0 * (t - 20.0))
    speed = np.where(t <= 20.0, 15.0, 10.0)
    both = {"speed": speed, "position": position}
    steps = compared_steps(t, [], np.zeros(0, dtype=np.int64), t, [])
    path = distance_path(position, steps)
    assert path == pytest.approx(400.0)  # 300 m out, 100 m back: not the 200 m span
    paths = (path, speed_path(speed, t, t, steps), False)
    assert paths[1] == pytest.approx(400.0, abs=1.0)
    assert check_track_channels(both, {"speed": "v", "position": "s"}, paths) == []
    (one,) = check_track_channels({"grade": np.full(100, 0.12)}, names, None)
    assert one.startswith("channel 'grade_x': grade up to 120 ‰, beyond a working condition's 40")


def test_units_missing_or_contradicting_are_refused_with_the_channel(tmp_path):
    path = write_mdf(tmp_path / "run.mf4", v_unit="")
    with pytest.raises(RecordingError, match="channel 'v': no unit stated"):
        read_run(path, channel_map_from(MAP))
    run = read_run(path, channel_map_from({**MAP, "units": {"v": "km/h"}}))
    np.testing.assert_allclose(run.speed, 15.0)
    path = write_mdf(tmp_path / "run2.mf4")
    with pytest.raises(RecordingError, match="'v': the file states unit 'km/h', the channel map"):
        read_run(path, channel_map_from({**MAP, "units": {"v": "m/s"}}))


def test_a_force_channel_far_slower_than_the_others_is_refused(tmp_path):
    path = write_mdf(tmp_path / "run.mf4", force_rate=100.0, q_rate=1.0)
    with pytest.raises(RecordingError, match="'Q_R': 1 Hz against 100 Hz of 'Y_R'"):
        read_run(path, channel_map_from(MAP))


def test_channel_map_errors_name_the_key(tmp_path):
    with pytest.raises(RailsuspInputError, match="wheel 'w9R' not known"):
        channel_map_from({**MAP, "wheels": {"w9R": {"Y": "a", "Q": "b"}}})
    with pytest.raises(RailsuspInputError, match="key 'sped' not recognised.*'speed'"):
        channel_map_from({**MAP, "sped": "v"})
    with pytest.raises(RailsuspInputError, match="channel 'v' mapped to two quantities"):
        channel_map_from({**MAP, "position": "v"})
    bad = tmp_path / "map.toml"
    bad.write_bytes(b"\xff\xfe garbage")
    with pytest.raises(RailsuspInputError, match="cannot read it"):
        read_channel_map(bad)
    path = write_mdf(tmp_path / "run.mf4")
    with pytest.raises(RecordingError, match="channel 'Q_r' of the .* not in the file.*'Q_R'"):
        read_run(path, channel_map_from({**MAP, "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_r"}}}))


def test_a_map_naming_a_tables_channels_without_their_units_suggests_the_headers(tmp_path):
    """A table's channels are its headers whole (``t [s]``); a map written with the bare
    names (``time = "t"``, as docs/data-format.md's example had it) was refused with no hint
    for the time and speed channels (the docs audit of stop 65)."""
    t = np.arange(0, 4, 0.02)
    table = tmp_path / "run.csv"
    rng = np.random.default_rng(0)
    pd.DataFrame(
        {
            "t [s]": t,
            "v (km/h)": np.full(t.size, 54.0),
            "Y_R [kN]": 5.0 + rng.standard_normal(t.size),
            "Q_R [kN]": 120.0 + rng.standard_normal(t.size),
        }
    ).to_csv(table, index=False)
    bare = {"time": "t", "speed": "v", "wheels": {"w1R": {"Y": "Y_R [kN]", "Q": "Q_R [kN]"}}}
    with pytest.raises(RecordingError, match=r"no time column \(t\) \(did you mean 't \[s\]'\?\)"):
        read_run(table, channel_map_from(bare))
    with pytest.raises(RecordingError, match=r"channel 'v' .*did you mean 'v \(km/h\)'"):
        read_run(table, channel_map_from({**bare, "time": "t [s]"}))
    run = read_run(table, channel_map_from({**bare, "time": "t [s]", "speed": "v (km/h)"}))
    np.testing.assert_allclose(run.speed, 15.0)


def synthetic_run(speed_kmh, curvature_per_km, grade_permille, rate=50.0) -> MeasuredRun:
    """A run of given per-sample speed, curvature and grade, with plausible forces of both
    leading wheels (a curve either way has its outer wheel, the compared one, recorded)."""
    v = np.asarray(speed_kmh, float) / 3.6
    t = np.arange(v.size) / rate
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / rate)])
    rng = np.random.default_rng(2)
    return MeasuredRun(
        "synthetic.csv",
        t,
        {w: 5e3 + 1e3 * rng.standard_normal(t.size) for w in ("w1R", "w1L")},
        {w: 120e3 + 5e3 * rng.standard_normal(t.size) for w in ("w1R", "w1L")},
        v,
        s,
        np.asarray(curvature_per_km, float) * 1e-3,
        np.zeros(t.size),
        np.asarray(grade_permille, float) * 1e-3,
    )


def test_a_run_without_any_track_geometry_is_cut_as_tangent_with_a_warning():
    """Without curvature, a line or a table every section is tangent: said once among the
    run's notes (and data notes: the pipeline warns of those), however often it is cut."""
    run = synthetic_run(np.full(3000, 60.0), np.zeros(3000), np.zeros(3000))
    cut_sections(run)
    assert NO_TRACK_NOTE not in run.notes  # a curvature channel of zeros is geometry
    run.curvature = None
    assert [s.kind for s in cut_sections(run)] == ["tangent"]
    cut_sections(run)
    assert run.notes.count(NO_TRACK_NOTE) == 1 and NO_TRACK_NOTE in run.data_notes


def test_sections_by_track_and_speed():
    """tangent 60 km/h (40 s) | spiral (10 s) | left R500 at 50 km/h (40 s) | tangent with
    the speed ramping 50 -> 80 km/h (30 s) | 10 permille up-grade at 80 km/h (40 s)."""
    n = {"tan": 2000, "spi": 500, "arc": 2000, "ramp": 1500, "up": 2000}
    speed = np.concatenate(
        [
            np.full(n["tan"], 60.0),
            np.linspace(60, 50, n["spi"]),
            np.full(n["arc"], 50.0),
            np.linspace(50, 80, n["ramp"]),
            np.full(n["up"], 80.0),
        ]
    )
    curv = np.concatenate(
        [
            np.zeros(n["tan"]),
            np.linspace(0, 2, n["spi"]),
            np.full(n["arc"], 2.0),
            np.zeros(n["ramp"] + n["up"]),
        ]
    )
    grade = np.concatenate([np.zeros(sum(n.values()) - n["up"]), np.full(n["up"], 10.0)])
    run = synthetic_run(speed, curv, grade)
    secs = cut_sections(run, SectionRules(min_length_m=100.0))
    kept = [s for s in secs if s.kept]
    assert [s.kind for s in kept] == ["tangent", "curve R500", "tangent", "tangent", "tangent"]
    assert kept[0].speed_kmh == pytest.approx(60.0, abs=0.01)
    assert kept[1].speed_kmh == pytest.approx(50.0, abs=0.01) and kept[1].direction == "left"
    # the ramp is split into pieces that hold the 10 % tolerance
    ramp = kept[2:4]
    assert all(50 < s.speed_kmh < 80 and s.speed_spread <= 0.1 + 1e-9 for s in ramp)
    assert kept[-1].grade_permille == pytest.approx(10.0)
    assert kept[-1].speed_kmh == pytest.approx(80.0)
    left_out = [s for s in secs if not s.kept]
    assert any(s.reason.startswith("transition") for s in left_out)  # the spiral
    assert any("speed varies" in s.reason for s in left_out)  # the ramp's short rest
    # a wider tolerance keeps the ramp's pieces longer; a speed-steady run is not split
    assert len([s for s in cut_sections(run, SectionRules(speed_tolerance=0.5)) if s.kept]) < 5


def test_a_line_description_gives_the_same_track_as_the_channels(tmp_path):
    line = tmp_path / "line.csv"
    line.write_text(
        "km_start,km_end,radius_m,direction,cant_mm,grade_permille\n"
        "0,0.5,,left,0,0\n0.5,2,400,right,90,0\n2,3,,left,0,5\n"
    )
    df = read_line(line)
    s = np.linspace(0, 2999, 3000)
    geo = geometry_from_line(s, df)
    assert geo["curvature"][700] == pytest.approx(-1 / 400) and geo["cant"][700] == 0.09
    assert geo["grade"][2500] == pytest.approx(5e-3)
    run = synthetic_run(np.full(9000, 60.0), np.zeros(9000), np.zeros(9000))
    secs = [s for s in cut_sections(run, line=df) if s.kept]
    assert [s.kind for s in secs][:3] == ["tangent", "curve R400", "tangent"]
    assert secs[1].direction == "right" and secs[1].cant_mm == pytest.approx(90.0)
    line.write_text("km_start,km_end,radius_m,cant_mm,grade_permille\n1,0.5,,0,0\n")
    with pytest.raises(
        RailsuspInputError,
        match="row 2: km_end = 0.5 is not above km_start = 1: accepted km_end > km_start",
    ):
        read_line(line)


@pytest.mark.parametrize(
    ("row", "needle"),
    [
        ("0,0.5,-300,left,0,0", "radius_m = -300: accepted 50 to 100000, or empty (0 or empty"),
        ("0,0.5,30,left,0,0", "radius_m = 30: accepted 50 to 100000"),
        ("0,0.5,400,up,90,0", "direction = 'up': accepted left or right (empty on a tangent"),
        ("0,0.5,400,,90,0", "radius_m = 400 with no hand (direction empty): accepted direction"),
        ("0,0.5,400,left,900,0", "cant_mm = 900: accepted 0 to 200"),
        ("0,0.5,,left,0,120", "grade_permille = 120: accepted -40 to 40"),
        ("0,nan,,left,0,0", "km_end = 'nan' not a number"),  # nan: read, refused
        ("0,,,left,0,0", "km_end = nan (or empty): accepted a finite number in every row"),
    ],
)
def test_a_line_description_outside_what_a_condition_takes_is_refused(tmp_path, row, needle):
    """Before stop 57 a negative radius was taken for tangent, a direction "up" for left, a
    section ending at NaN kept nothing (numpy's "Mean of empty slice"), and a grade in
    per cent or a cant in the wrong unit failed at --write without naming the column."""
    line = tmp_path / "line.csv"
    line.write_text(f"km_start,km_end,radius_m,direction,cant_mm,grade_permille\n{row}\n")
    with pytest.raises(RailsuspInputError) as info:
        read_line(line)
    assert f"line description {line}, row 2: {needle}" in str(info.value)


def test_a_curve_whose_hand_is_not_stated_is_refused_not_taken_as_left(tmp_path):
    """A line description or section table without a direction column took every curve as
    left-hand: a right-hand curve's inner wheel was then compared as its outer one, without
    a word (the docs audit of stop 72). A tangent row needs no direction."""
    line = tmp_path / "line.csv"
    line.write_text("km_start,km_end,radius_m,cant_mm,grade_permille\n0,0.5,,0,0\n0.5,1,350,60,0\n")
    with pytest.raises(RailsuspInputError) as info:
        read_line(line)
    assert (
        f"line description {line}, row 3: radius_m = 350 with no hand (it has no direction "
        "column): accepted direction = left or right on each curve row (as seen running "
        "towards increasing km posts; it decides which wheel is outer)"
    ) == str(info.value)
    line.write_text("km_start,km_end,radius_m,cant_mm,grade_permille\n0,0.5,,0,0\n")
    assert len(read_line(line)) == 1  # tangent only: nothing to state
    table = tmp_path / "t.csv"
    table.write_text("start_m,end_m,radius_m,direction\n0,300,,\n300,900,600,\n")
    with pytest.raises(RailsuspInputError, match="row 3: radius_m = 600 with no hand .direction "
                       "empty.: accepted .* increasing positions"):  # fmt: skip
        read_section_table(table)


def test_a_section_table_needs_both_ends_in_every_row(tmp_path):

    table = tmp_path / "t.csv"
    table.write_text("start_m,end_m\n50,nan\n")
    with pytest.raises(RailsuspInputError, match=r"row 2: end_m = 'nan' not a number"):
        read_section_table(table)
    table.write_text("start_m,end_m\n50,\n")
    with pytest.raises(
        RailsuspInputError, match=r"row 2: end_m = nan \(or empty\): accepted a finite"
    ):
        read_section_table(table)
    table.write_text("start_m,end_m\n,500\n")
    with pytest.raises(RailsuspInputError, match="row 2: start_m = nan"):
        read_section_table(table)


def test_written_sections_are_a_field_folder_the_estimation_reads(tmp_path):
    run = synthetic_run(np.full(3000, 54.0), np.full(3000, 1.25), np.zeros(3000), rate=200.0)
    secs = cut_sections(run)
    write_sections(run, secs, tmp_path / "field", rate_hz=50.0)
    recs = read_field(tmp_path / "field")
    assert len(recs) == 1 and recs[0].sampling_rate == pytest.approx(50.0)
    c = recs[0].condition
    assert c.curve_radius_m == 800.0 and c.speed_kmh == 54.0 and c.n_steps == len(recs[0].time)
    assert load_conditions(tmp_path / "field" / "conditions.toml") == [c]
    en = pd.read_csv(tmp_path / "field" / "en14363.csv")
    q = en[(en.force == "Q") & (en.wheel == "w1R")].iloc[0]
    # N(120, 5) kN white noise: the 2 m mean (about 7 samples at 15 m/s, 200 Hz) leaves
    # the median and narrows the spread well inside the raw +-3 sigma (105-135 kN)
    assert q.p50_kN == pytest.approx(120.0, abs=0.3)
    assert 105.0 < q["p0.15_kN"] < q["p99.85_kN"] < 135.0
    # ... and a `railsusp run` configuration on the same conditions and recordings
    from railsusp.pipeline import load_config

    cfg = load_config(tmp_path / "field" / "pipeline.toml")
    assert cfg.working_conditions() == [c]
    assert cfg.field.measured == str((tmp_path / "field").resolve())
    assert np.median(recs[0].Q["w1R"]) == pytest.approx(120.0, rel=0.01)  # kN again


def test_a_left_out_rows_reason_names_what_was_left_out():
    """Stop 56: a transition's row read "transition ...; 0 m, shorter than 150 m (a
    transition)" (a piece of a few samples at the band's edge given as a reason of its own),
    and with a 5000 m minimum the tangents and curves left out were each called "(a
    transition)". Edge pieces now fold into their neighbour's row; the stretches left out
    for their length are named, and counted where there are several."""
    data = resources.files("railsusp") / "data"
    run = read_run(data / "example_run.mf4", read_channel_map(data / "example_run.map.toml"))
    left = [s for s in cut_sections(run) if not s.kept]
    assert len(left) == 4
    assert {s.reason for s in left} == {"transition (curvature or grade changing)"}
    (whole,) = cut_sections(run, SectionRules(min_length_m=5000.0))  # one left-out stretch
    assert whole.reason.split("; ") == [
        "tangent: 3 pieces of 316-571 m, each shorter than the 5000 m minimum",
        "transition (curvature or grade changing)",
        "curve R600 of 437 m, shorter than the 5000 m minimum",
        "curve R350 of 354 m, shorter than the 5000 m minimum",
    ]


def test_a_stop_is_named_with_its_duration_not_folded_away():
    """A review of the edge-piece folding: a standing wagon covers no length, so a stop
    judged by metres was folded into its neighbours unseen; the "standing" reason could
    never show, as the length came first."""
    dt = 0.02  # cruise 15 m/s 60 s, brake over 30 s, stand 180 s, start over 30 s, cruise
    v = np.concatenate([np.full(3000, 15.0), np.linspace(15, 0, 1500), np.zeros(9000),
                        np.linspace(0, 15, 1500), np.full(3000, 15.0)])  # fmt: skip
    t = np.arange(v.size) * dt
    x = np.concatenate([[0.0], np.cumsum(v[:-1] * dt)])
    z = np.zeros_like(t)
    run = MeasuredRun("stop", t, {"w1R": z}, {"w1R": z + 1e5}, v, x)
    secs = cut_sections(run)
    assert [s.kept for s in secs] == [True, False, True]
    # below 1.8 km/h for 182 s: the 180 s at rest, and a second of braking and of starting
    assert secs[1].reason.endswith("; standing (182 s)")
    # the braking's and the starting's pieces, those under a second near the stop too (a
    # piece cut by the speed is no band's edge: the QA of stop 68), with the speed's range
    assert secs[1].reason.startswith(
        "tangent: 64 pieces of 0-33 m, each shorter than the 150 m minimum (speed varies "
        "from 1.8 to 48.8 km/h (186 %) there, beyond the 10 % tolerance)"
    )


def test_the_shipped_example_reads_and_cuts_into_its_five_sections(tmp_path):
    data = resources.files("railsusp") / "data"
    path = data / "example_run.mf4"
    assert path.is_file() and path.stat().st_size < 2e6
    run = read_run(path, read_channel_map(data / "example_run.map.toml"))
    assert run.rate_hz == pytest.approx(200.0) and run.wheels == ("w1R", "w1L")
    assert run.rates_hz["v_train"] == pytest.approx(10.0)
    for secs in (cut_sections(run), cut_sections(run, line=read_line(data / "example_line.csv"))):
        kept = [s for s in secs if s.kept]
        got = [
            (
                s.radius_m and round(s.radius_m),
                s.direction if s.radius_m else "",
                round(s.speed_kmh),
                round(s.grade_permille),
            )
            for s in kept
        ]
        assert got == [
            (None, "", 65, 0),
            (600, "left", 55, 0),
            (350, "right", 45, 0),
            (None, "", 40, 12),
            (None, "", 70, 0),
        ]
        assert all(s.end_m - s.start_m > 300 for s in kept)
    write_sections(run, secs, tmp_path / "field")
    recs = read_field(tmp_path / "field")
    # the measured wheel of each condition first: the outer wheel in a curve
    assert [r.wheels[0] for r in recs] == ["w1L", "w1R", "w1L", "w1L", "w1L"]


def test_every_stretch_of_the_run_has_a_row_also_where_the_line_description_ends():
    """Cut against a line description, the stretches it does not cover (about 720 m of the
    example, between its km posts) got no row and no reason; the rows now cover the run."""
    from railsusp.measured.sections import OUTSIDE_LINE

    data = resources.files("railsusp") / "data"
    run = read_run(data / "example_run.mf4", read_channel_map(data / "example_run.map.toml"))
    secs = cut_sections(run, line=read_line(data / "example_line.csv"))
    assert secs[0].start == 0 and secs[-1].end == run.time.size
    assert all(a.end == b.start for a, b in itertools.pairwise(secs))
    outside = [s for s in secs if OUTSIDE_LINE in s.reason]
    assert outside and not any(s.kept for s in outside)
    assert sum(s.end_m - s.start_m for s in outside) > 300.0


def test_a_truncated_mdf_file_is_one_error_and_nothing_on_stderr(tmp_path):
    """asammdf's half-built MDF4 failed again in its __del__ ("Exception ignored in
    MDF4.__del__", a traceback on stderr after the clean error); that message is silenced
    (in a process of its own: pytest replaces the hook that prints it) and the hook is
    restored."""
    import subprocess
    import sys

    whole = write_mdf(tmp_path / "run.mf4").read_bytes()
    cut = tmp_path / "cut.mf4"
    cut.write_bytes(whole[: len(whole) // 2])
    script = (
        "import gc, sys\n"
        "from railsusp.measured.raw import read_raw\n"
        "hook = sys.unraisablehook\n"
        "try:\n"
        f"    read_raw({str(cut)!r})\n"
        "except Exception as exc:\n"
        "    print(type(exc).__name__, exc)\n"
        "gc.collect()\n"
        "assert sys.unraisablehook is hook\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "RailsuspInputError" in done.stdout and "not a readable MDF file" in done.stdout
    assert "Exception ignored" not in done.stderr and "Traceback" not in done.stderr


def test_a_damaged_mdf_file_names_where_it_breaks_and_what_to_do(tmp_path):
    """Bytes overwritten inside an MDF4 file: asammdf fails on a block it cannot find
    (``KeyError: (2, 1)``, which the error used to show alone: "cannot read its channels
    ((2, 1))"); the one line now says the file is damaged, after which channel, and what to
    do. A truncated file says it may be truncated."""
    from railsusp.measured.raw import read_raw

    whole = (resources.files("railsusp") / "data" / "example_run.mf4").read_bytes()
    for at, where in ((1000, "its first channel"), (570000, "the channel after 'track_grade'")):
        bad = bytearray(whole)
        bad[at : at + 64] = b"\xff" * 64  # a block's links overwritten
        (tmp_path / "bad.mf4").write_bytes(bytes(bad))
        with pytest.raises(RailsuspInputError) as err:
            read_raw(tmp_path / "bad.mf4")
        text = str(err.value)
        assert f"damaged MDF file: cannot read {where}" in text and "KeyError" in text
        assert text.endswith("export it again from the logger") and "\n" not in text
    (tmp_path / "cut.mf4").write_bytes(whole[: len(whole) // 2])
    with pytest.raises(RailsuspInputError, match="truncated or damaged; copy it again"):
        read_raw(tmp_path / "cut.mf4")


def test_a_run_against_the_km_posts_gives_positive_lengths_and_a_radius_below_50_m_is_left_out():
    """Stop 53's fuzzing: a decreasing distance gave a section of -2000 m in the table, and a
    curvature of 1000 1/km (R1, a unit slip) was cut as a kept 'curve R1'."""
    from railsusp.measured.sections import MIN_RADIUS_M, cut_sections, sections_table

    n = 3000
    run = synthetic_run(np.full(n, 60.0), np.zeros(n), np.zeros(n))
    backwards = MeasuredRun(**{**run.__dict__, "position": 5000.0 - run.position})
    table = sections_table(cut_sections(backwards))
    assert (table["length_m"] > 0).all() and table["length_m"].max() > 900
    absurd = synthetic_run(np.full(n, 60.0), np.full(n, 1000.0), np.zeros(n))
    (sec,) = cut_sections(absurd)
    assert not sec.kept and f"below the {MIN_RADIUS_M:g} m a working condition takes" in sec.reason


def test_routine_resampling_is_a_note_not_a_warning_in_the_field_stage(tmp_path):
    """The pipeline warned five times ("warning: ... channel 'v_train' (10 Hz) interpolated
    onto 200 Hz") where check-recording and sections print a note; a fault of the data
    (NaN gaps interpolated) still warns."""
    import warnings

    from railsusp.measured.cut import RunSource, write_run_field

    data = resources.files("railsusp") / "data"
    source = RunSource(data / "example_run.mf4", data / "example_run.map.toml")
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        write_run_field(source, tmp_path / "field")
    assert not [w for w in seen if "interpolated onto" in str(w.message)]
    run = read_run(data / "example_run.mf4", read_channel_map(data / "example_run.map.toml"))
    assert any("interpolated onto" in n for n in run.notes) and not run.data_notes
    # a gap of the data is a data note (warned of), beside the routine ones
    t = np.arange(0.0, 20.0, 1 / 200)
    q = 120.0 + np.cos(t)
    q[500:503] = np.nan
    frame = {"time_s": t, "Y_w1R_kN": 5.0 + np.sin(t), "Q_w1R_kN": q, "speed_kmh": 54.0 + 0 * t}
    pd.DataFrame(frame).to_csv(tmp_path / "gap.csv", index=False)
    gap = read_run(tmp_path / "gap.csv")
    assert [n for n in gap.data_notes if "3 missing sample(s) interpolated" in n]
    assert set(gap.data_notes) <= set(gap.notes)


def test_a_channel_map_whose_units_or_ignore_name_the_wrong_channels_is_refused(tmp_path):
    """[units] naming a channel the file lacks (a misspelling leaves the real one without
    its unit) and ``ignore`` naming a mapped channel were accepted silently (the
    command-line audit of stop 60)."""
    path = write_mdf(tmp_path / "run.mf4")
    with pytest.raises(RecordingError, match=r"\[units\] channel 'Q_RR' of the channel map"):
        read_run(path, channel_map_from({**MAP, "units": {"Q_RR": "kN"}}))
    with pytest.raises(RailsuspInputError, match="ignore: channel 'Y_R' is mapped too"):
        channel_map_from({**MAP, "ignore": ["Y_R"]})
    run = read_run(path, channel_map_from({**MAP, "ignore": ["acc_bogie_y_g", "gone"]}))
    assert any("ignore: channel(s) not in the file: gone" in n for n in run.notes)


def test_every_force_channel_must_reach_the_sections_rate_not_only_the_fastest(tmp_path):
    """Y at 200 Hz, Q at 25 Hz, sections at 50 Hz: only the fastest force channel was held
    to the sections' rate, and Q was interpolated onto 200 Hz with a note, its dynamics
    above 12.5 Hz gone (the audit of stop 63)."""
    path = write_mdf(tmp_path / "run.mf4", force_rate=200.0, q_rate=25.0)
    with pytest.raises(RecordingError) as info:
        read_run(path, channel_map_from(MAP))
    assert "channel 'Q_R': 25 Hz against 200 Hz of 'Y_R'" in str(info.value)
    assert "accepted at least 50 Hz, the rate the sections are resampled to" in str(info.value)
    read_run(path, channel_map_from(MAP), min_rate_hz=25.0)  # sections at 25 Hz: read
    path = write_mdf(tmp_path / "fast.mf4", force_rate=200.0, q_rate=100.0)
    run = read_run(path, channel_map_from(MAP))  # slower than Y but above 50 Hz: read
    assert any("'Q_R' (100 Hz) interpolated onto 200 Hz" in n for n in run.notes)


# ---- the audit of stop 63: a long run cut into sections ----


def track_run(stand_s=0.0, *, rate=200.0, hold_m=None, stand_noise_kmh=0.0, curvature=True):
    """60 km/h after ``stand_s`` standing: tangent 600 m, a 60 m spiral, a left-hand R600 of
    900 m, a spiral, tangent 600 m (2100 m), the curvature channel with 1 % noise;
    ``hold_m``: the distance channel in steps of that many metres (an odometer's
    resolution); ``stand_noise_kmh``: noise on the standing wagon's speed."""
    rng = np.random.default_rng(3)
    t = np.arange(round((stand_s + 2100.0 / (60 / 3.6)) * rate)) / rate
    v = np.where(t < stand_s, 0.0, 60 / 3.6)
    if stand_noise_kmh:
        v = np.where(t < stand_s, np.abs(stand_noise_kmh / 3.6 * rng.standard_normal(t.size)), v)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / rate)])
    curv = np.interp(s, [630, 690, 1410, 1470], [0, 1 / 600, 1 / 600, 0])
    curv = curv * (1.0 + 0.01 * rng.standard_normal(t.size)) + 1e-5 * rng.standard_normal(t.size)
    position = s if hold_m is None else np.floor(s / hold_m) * hold_m
    forces = {w: 5e3 + 1e3 * rng.standard_normal(t.size) for w in ("w1R", "w1L")}
    loads = {w: 120e3 + 5e3 * rng.standard_normal(t.size) for w in ("w1R", "w1L")}
    zero = np.zeros(t.size)
    return MeasuredRun(
        "track.csv", t, forces, loads, v, position, curv if curvature else None, zero, zero
    )


def test_a_section_table_without_the_runs_track_is_refused_or_states_it(tmp_path):
    """Defect 1: a run without a curvature channel cut by a section table made every row a
    level tangent, a curve's too, without a word. Refused now, naming the remedies; or the
    table states its rows' track (optional columns as a line description's), which over a
    run's channels is the rows' track too."""

    run = track_run(rate=50.0, curvature=False)
    table = tmp_path / "t.csv"
    table.write_text("start_m,end_m,name\n50,500,straight\n800,1300,curve\n")
    with pytest.raises(RailsuspInputError) as info:
        cut_sections(run, table=read_section_table(table))
    assert str(info.value) == (
        f"section table {table}: the run has no curvature channel and the table no radius_m "
        "column: every section would be a level tangent; accepted a curvature channel in the "
        "map, a line description (--line, [field] line), or the table's columns radius_m, "
        "direction, cant_mm, grade_permille (radius empty or 0: tangent)"
    )
    table.write_text(
        "start_m,end_m,name,radius_m,direction,cant_mm,grade_permille\n"
        "50,500,straight,,,,\n800,1300,curve,450,right,60,4\n"
    )
    # without the curvature channel, and over it (R600 left there): the table's track wins
    for r in (run, track_run(rate=50.0)):
        secs = cut_sections(r, table=read_section_table(table))
        got = [
            (s.name, s.kind, s.direction, round(s.cant_mm), round(s.grade_permille)) for s in secs
        ]
        assert got == [
            ("straight", "tangent", "left", 0, 0),
            ("curve", "curve R450", "right", 60, 4),
        ]


def test_a_section_table_row_the_run_never_reaches_or_overlapping_another_is_refused(tmp_path):
    """Defect 2: a row beyond the run vanished from the cut without a line, and rows that
    overlap put the same samples into two sections."""

    run = track_run(rate=50.0)
    table = tmp_path / "t.csv"
    table.write_text("start_m,end_m,name\n50,500,straight\n800,1300,curve\n5000,5400,beyond\n")
    with pytest.raises(RailsuspInputError) as info:
        cut_sections(run, table=read_section_table(table))
    assert str(info.value) == (
        f"section table {table}, row 4: 5000-5400 m is not on the run (positions 0 to 2100 m); "
        "accepted rows the run passes"
    )
    table.write_text("start_m,end_m,name\n50,500,straight\n800,1300,curve\n200,450,again\n")
    with pytest.raises(RailsuspInputError) as info:
        read_section_table(table)
    assert str(info.value) == (
        f"section table {table}, rows 2 and 4 overlap (200 to 450 m): accepted rows that do "
        "not overlap (a gap is a stretch in no section)"
    )


def test_a_section_table_row_over_more_than_one_kind_of_track_is_left_out_with_the_shares():
    """Defect 4: a row over tangent, spiral and curve was kept as a steady curve of the
    median radius. A piece of which more than 10 % is another kind (or a transition) is
    left out, the shares in the reason; a row with a few per cent of spiral is kept."""
    run = track_run(rate=50.0)
    table = pd.DataFrame(
        {"start_m": [350.0, 700.0, 1000.0], "end_m": [1000.0, 1000.0, 1390.0],
         "name": ["mixed", "nearly", "arc"]}
    )  # fmt: skip
    secs = cut_sections(run, table=table)
    assert [(s.name, s.kept) for s in secs] == [("mixed", False), ("nearly", True), ("arc", True)]
    import re

    shares = re.fullmatch(
        r"more than one kind of track \(tangent (\d+) %, transition (\d+) %, curve R600 left "
        r"(\d+) %\): a section is one, with at most 10 % of others",
        secs[0].reason,
    )
    assert shares, secs[0].reason
    tangent, transition, curve = map(int, shares.groups())  # 350-615, 615-705, 705-1000 m
    assert 35 <= tangent <= 45 and 10 <= transition <= 20 and 40 <= curve <= 50
    from railsusp.measured.sections import sections_table

    assert sections_table(secs).kind.tolist() == ["mixed", "curve R600", "curve R600"]


def test_a_run_standing_half_its_time_or_with_an_odometer_in_metres_keeps_its_sections():
    """Defect 5: the 10 m average was taken over 10 m / the median distance step, 0 where
    the run stood for more than half its samples or the distance held between 1 m steps:
    10 samples, whose 1 % curvature noise read as a spiral, and nothing was kept."""
    from railsusp.measured.sections import sections_table

    expected = ["tangent", "curve R600", "tangent"]
    for run in (track_run(140.0), track_run(hold_m=1.0)):
        secs = cut_sections(run)
        assert [s.kind for s in secs if s.kept] == expected, sections_table(secs)


def test_a_noisy_stop_is_one_piece_of_its_whole_duration():
    """Defect 6: noise on a standing wagon's speed cut the stop into pieces of one or two
    samples, each merged into the row one at a time (the cut quadratic in time: 27 s for an
    80 s stop), and a one-sample piece counted 0 s: a 30 s stop read "standing (2 s)"."""
    secs = cut_sections(track_run(30.0, stand_noise_kmh=0.3))
    assert secs[0].reason == "standing (30 s)" and len(secs[0].pieces) == 1
    assert [s.kind for s in secs if s.kept] == ["tangent", "curve R600", "tangent"]


def test_a_steady_stretch_longer_than_the_maximum_duration_is_split_into_equal_parts():
    """Defect 11: 2100 m at a steady 60 km/h (126 s) was cut into 120 s and a 100 m rest,
    left out "(speed varies beyond the tolerance)" at 0 % spread. A piece too short after a
    split by duration alone now says so."""
    secs = cut_sections(synthetic_run(np.full(6300, 60.0), np.zeros(6300), np.zeros(6300)))
    assert [(s.kept, s.end - s.start) for s in secs] == [(True, 3150), (True, 3150)]
    # 300 s at 5 km/h: three equal parts of 139 m would all be too short; 120 s parts are not
    slow = cut_sections(synthetic_run(np.full(15000, 5.0), np.zeros(15000), np.zeros(15000)))
    assert [(s.kept, s.end - s.start) for s in slow] == [(True, 6000), (True, 6000), (False, 3000)]
    assert slow[2].reason == (
        "tangent of 83 m, shorter than the 150 m minimum (split at the 120 s maximum duration)"
    )


def test_a_wheel_whose_lateral_force_has_the_other_sign_is_refused():
    """Defect 12: a wheel's Y + to the right (vehicle-fixed, where the documented sign is +
    towards the field side) was cut and written without a word: the outer wheel of an R350
    read p50 -31 kN. A median clearly below 0 (by 5 kN or a tenth of the wheel load) in a
    curve of 450 m or less, where the leading outer wheel flanges, refuses the run naming
    the wheel; the inner wheel's sign is not judged. Near zero, or in a curve of up to
    600 m, where an empty or slow wagon's outer wheel can read a little below 0 (the review
    of stop 63: the model's tare wagon at R600 with cant excess), it is noted, not refused."""
    n = 3000  # 60 s at 45 km/h on a right-hand R350: 750 m
    run = synthetic_run(np.full(n, 45.0), np.full(n, -1000 / 350), np.zeros(n))
    run.Y["w1L"] = run.Y["w1L"] + 25e3  # the outer wheel flanging: +30 kN
    assert [s.kept for s in cut_sections(run)] == [True]
    run.Y["w1R"] = -run.Y["w1R"]  # the inner wheel
    assert [s.kept for s in cut_sections(run)] == [True]
    run.Y["w1L"] = -run.Y["w1L"]  # the outer wheel
    with pytest.raises(RecordingError) as info:
        cut_sections(run)
    (problem,) = info.value.problems
    assert problem.startswith(
        "wheel w1L: Y median -30.0 kN in s1-curve-R350 (right-hand R350, 0-750 m), where it is "
        "the leading outer wheel and flanges: accepted Y + towards the field side"
    )
    assert "Y_sign = -1 in the map's [wheels.w1L]" in problem
    # a zero offset on an empty wagon: -2 kN against a margin of 12 kN (120 kN wheel load)
    run.Y["w1L"] = run.Y["w1L"] + 28e3
    assert [s.kept for s in cut_sections(run)] == [True]
    (note,) = [x for x in run.notes if x.startswith("wheel w1L: Y median -2.0 kN")]
    assert "check its sign" in note and "Y_sign = -1 in the map's [wheels.w1L]" in note
    # R600: noted however negative, never refused
    wide = synthetic_run(np.full(n, 45.0), np.full(n, -1000 / 600), np.zeros(n))
    wide.Y["w1L"] = -wide.Y["w1L"] - 25e3
    assert [s.kept for s in cut_sections(wide)] == [True]
    assert any(x.startswith("wheel w1L: Y median -30.0 kN") for x in wide.notes)


def test_a_speed_from_an_odometer_counting_metres_is_steady_at_30_kmh(tmp_path):
    """A run with a distance channel only, the odometer counting whole metres: its speed was
    the staircase differenced over 1 s, 8 or 9 m a second at 30 km/h (a 27 % spread), and
    every section was broken by speed into pieces of a metre. Drawn through the times the
    odometer steps, the speed holds 30 km/h within the sampling."""
    from railsusp.measured.sections import sections_table

    rng = np.random.default_rng(1)
    t, ts = np.arange(0, 120, 1 / 200), np.arange(0, 120, 1 / 50)
    mdf = MDF(version="4.10")
    mdf.append([Signal(5 + rng.standard_normal(t.size), t, name="Y_R", unit="kN")])
    mdf.append([Signal(120 + rng.standard_normal(t.size), t, name="Q_R", unit="kN")])
    mdf.append([Signal(np.floor(30 / 3.6 * ts), ts, name="s", unit="m")])
    mdf.save(tmp_path / "odometer.mf4", overwrite=True)
    mdf.close()
    cmap = channel_map_from({"position": "s", "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R"}}})
    run = read_run(tmp_path / "odometer.mf4", cmap)
    inner = run.speed[200:-200] * 3.6  # a second in from either end
    assert np.abs(inner - 30.0).max() < 0.5
    secs = cut_sections(run)
    assert [s.kind for s in secs if s.kept] == ["tangent"], sections_table(secs)
    assert secs[0].end - secs[0].start > 0.95 * t.size


def test_a_long_runs_unused_mdf_channels_are_listed_without_their_samples(tmp_path):
    """Only the channels the map uses keep their samples (an instrumented wheelset's logger
    records many more, which held a long run's memory); the others are listed (name, unit,
    notes) without them, and the run read is the one read with every channel kept."""
    from dataclasses import fields

    import railsusp.measured.run as run_module
    from railsusp.measured.raw import read_raw

    path = write_mdf(tmp_path / "run.mf4")
    cmap = channel_map_from({**MAP, "ignore": []})
    raw = read_raw(path, keep=set(cmap.used()).__contains__)
    assert raw["acc_bogie_y_g"].listed and raw["acc_bogie_y_g"].values.size == 0
    assert raw["acc_bogie_y_g"].time.tolist() == pytest.approx([0.0, 19.995])
    assert not raw["Y_R"].listed and raw["Y_R"].values.size == 4000
    # the speed and position channels of one data group share its time base's array
    assert raw["v"].time is raw["s"].time

    def every_channel(path, time_column=None, keep=None):
        return read_raw(path, time_column)

    lean = read_run(path, cmap)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(run_module, "read_raw", every_channel)
        whole = read_run(path, cmap)
    assert "channel(s) not used: acc_bogie_y_g" in lean.notes
    for f in fields(lean):
        a, b = getattr(lean, f.name), getattr(whole, f.name)
        if isinstance(a, dict):
            assert a.keys() == b.keys()
            for k in a:
                np.testing.assert_array_equal(a[k], b[k])
        elif isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)
        else:
            assert a == b, f.name


def test_an_mdf_run_by_its_documented_names_keeps_only_those_channels(tmp_path):
    """Without a channel map the documented names are the channels kept; others listed."""
    t = np.arange(0, 20, 1 / 200.0)
    ts = np.arange(0, 20.1, 0.1)
    mdf = MDF(version="4.10")
    mdf.append(
        [
            Signal(5.0 + np.sin(t), t, name="Y_w1R_kN", unit="kN"),
            Signal(120.0 + np.sin(t), t, name="Q_w1R_kN", unit="kN"),
            Signal(np.zeros(t.size), t, name="bridge_7_raw", unit="mV/V"),
        ]
    )
    mdf.append([Signal(np.full(ts.size, 54.0), ts, name="speed_kmh", unit="km/h")])
    mdf.save(tmp_path / "doc.mf4", overwrite=True)
    mdf.close()
    from railsusp.measured.raw import read_raw

    raw = read_raw(tmp_path / "doc.mf4", keep=is_documented)
    assert raw["bridge_7_raw"].listed and not raw["Q_w1R_kN"].listed
    run = read_run(tmp_path / "doc.mf4")
    np.testing.assert_allclose(run.Q["w1R"], 120e3 + 1e3 * np.sin(run.time), atol=1e-6)
    assert any("not used: bridge_7_raw" in n for n in run.notes)
