"""Recordings a logger writes that were misread silently (the recordings audit of stop 58):
a distance master read as time, samples marked invalid used as forces, a time column in
minutes or microseconds read as seconds, a 2 Hz run upsampled into 50 Hz sections, a run
going backwards, a saturated amplifier, a field table whose columns start with the wheel
the model does not compare; and a section too short for the EN 14363 filter."""

import re

import numpy as np
import pandas as pd
import pytest
from asammdf import MDF, Signal

from railsusp.conditions import get_condition
from railsusp.en14363 import lowpass
from railsusp.errors import RailsuspInputError
from railsusp.measured import RecordingError, read_recording
from railsusp.measured.channels import channel_map_from
from railsusp.measured.checks import check_time
from railsusp.measured.raw import read_raw
from railsusp.measured.run import read_run
from test_measured import make_recording
from test_measured_run import MAP, write_mdf


def _rewritten(path, change=None, extra=(), master=None):
    """The write_mdf run at ``path``, written again: each channel through ``change(name,
    time, values, unit) -> (values, unit, invalidation bits or None)``, ``extra`` groups
    (lists of Signals) appended, every group's master set to ``master`` (a sync type, in
    m) where given (a negative type: the last group's alone)."""
    src = MDF(write_mdf(path))
    out = MDF(version="4.10")
    for group in range(len(src.groups)):
        sigs = []
        for sig in src.iter_channels(skip_master=True):
            if sig.group_index != group:
                continue
            values, unit, bits = sig.samples.copy(), sig.unit, None
            if change is not None:
                values, unit, bits = change(sig.name, sig.timestamps, values, unit)
            sigs.append(
                Signal(values, sig.timestamps, name=sig.name, unit=unit, invalidation_bits=bits)
            )
        out.append(sigs)
    src.close()
    for group in extra:
        out.append(group)
    if master is not None:
        for g in out.groups if master > 0 else out.groups[-1:]:
            g.channels[0].sync_type = abs(master)
            g.channels[0].unit = "m"
    out.save(path, overwrite=True)
    out.close()
    return path


def _groups(path, *, sync_type=None, invalid=None, clip=None):
    """The write_mdf run with its masters set to ``sync_type``, the lateral force's samples
    ``invalid`` marked so (and zero there), or it clipped."""

    def change(name, t, values, unit):
        bits = None
        if name == "Y_R" and invalid is not None:
            bits = np.zeros(values.size, bool)
            bits[invalid] = True
            values[bits] = 0.0
        if name == "Y_R" and clip is not None:
            values = np.clip(values, None, clip)
        return values, unit, bits

    return _rewritten(path, change, master=sync_type)


def test_a_master_channel_of_distance_is_refused_not_read_as_time(tmp_path):
    path = _groups(tmp_path / "d.mf4", sync_type=3)
    with pytest.raises(RecordingError, match="master channel 'time' of distance, not time"):
        read_run(path, channel_map_from(MAP))


def test_an_unused_channel_on_a_distance_master_does_not_count(tmp_path):
    """The reviewer of stop 58: one group on a distance master made the whole file
    unreadable, though the channel map did not use it."""
    grid = np.arange(0.0, 300.0, 0.5)
    gauge = [Signal(1435.0 + 0 * grid, grid, name="gauge_mm", unit="mm")]
    path = _rewritten(tmp_path / "b.mf4", extra=[gauge], master=-3)
    run = read_run(path, channel_map_from({**MAP, "ignore": ["acc_bogie_y_g", "gauge_mm"]}))
    assert run.rate_hz == pytest.approx(200.0)


def test_samples_the_logger_marked_invalid_are_gaps_not_zeros(tmp_path):
    short = _groups(tmp_path / "short.mf4", invalid=slice(1000, 1003))
    raw = read_raw(short)
    assert np.isnan(raw["Y_R"].values[1000:1003]).all()
    assert np.isfinite(raw["Y_R"].values[:1000]).all()
    run = read_run(short, channel_map_from(MAP))  # 3 samples: interpolated, with a note
    assert np.all(run.Y["w1R"][1000:1003] != 0.0)
    assert any("interpolated" in n for n in run.notes)
    # 100 samples, more than are interpolated: the run is cut there, the gap left out (a
    # whole run was refused before stop 63; test_measured_gaps.py)
    long = read_run(
        _groups(tmp_path / "long.mf4", invalid=slice(1000, 1100)), channel_map_from(MAP)
    )
    assert long.gaps == ((1000, 1100, "Y_R"),) and {1000, 1100} <= set(long.breaks.tolist())
    assert any("samples 1000-1099 (5.000-5.495 s, 100 samples)" in n for n in long.data_notes)


@pytest.mark.parametrize(("unit", "factor"), [("msec", 1e-3), ("us", 1e-6), ("min", 60.0)])
def test_a_table_time_column_in_other_units_is_converted(tmp_path, unit, factor):
    t = np.arange(0.0, 20.0, 1 / 200)
    df = pd.DataFrame({f"time [{unit}]": t / factor, "Y_w1R_kN": 5.0 + 0 * t})
    df.to_csv(tmp_path / "r.csv", index=False)
    raw = read_raw(tmp_path / "r.csv")
    assert raw["Y_w1R_kN"].rate_hz == pytest.approx(200.0)


def test_a_long_runs_distance_column_named_as_its_time_is_refused_not_read_as_seconds(tmp_path):
    """A map's ``time = "distance_m"`` read the metres as seconds: a 2 km run sampled every
    centimetre at 60 km/h read as 2000 s at 100 Hz, its position integrated to 33 km, and
    was cut into sections of that length without a word."""
    s = np.arange(0.0, 2000.0, 0.01)
    rng = np.random.default_rng(0)
    df = pd.DataFrame(
        {
            "distance_m": s,
            "speed_kmh": np.full(s.size, 60.0),
            "Y_w1R_kN": 5.0 + rng.standard_normal(s.size),
            "Q_w1R_kN": 120.0 + rng.standard_normal(s.size),
        }
    )
    df.to_csv(tmp_path / "r.csv", index=False)
    wheels = {"w1R": {"Y": "Y_w1R_kN", "Q": "Q_w1R_kN"}}
    cmap = channel_map_from({"time": "distance_m", "speed": "speed_kmh", "wheels": wheels})
    with pytest.raises(RecordingError, match="'distance_m', the time column, is a distance"):
        read_run(tmp_path / "r.csv", cmap)


def test_a_table_time_column_in_an_unknown_unit_is_refused(tmp_path):
    pd.DataFrame({"time [fortnight]": [0.0, 1.0], "Y_kN": [1.0, 2.0]}).to_csv(
        tmp_path / "r.csv", index=False
    )
    with pytest.raises(RailsuspInputError, match="unit 'fortnight' is not a time unit"):
        read_raw(tmp_path / "r.csv")


def test_a_long_run_below_the_minimum_rate_is_refused(tmp_path):
    path = write_mdf(tmp_path / "slow.mf4", force_rate=20.0)
    with pytest.raises(RecordingError, match="forces sampled at 20 Hz; accepted at least 50 Hz"):
        read_run(path, channel_map_from(MAP))
    assert read_run(path, channel_map_from(MAP), min_rate_hz=10.0).rate_hz == pytest.approx(20.0)


def test_a_run_going_backwards_is_refused(tmp_path):
    def backwards(name, t, values, unit):
        return (-values if name in ("v", "s") else values), unit, None

    with pytest.raises(RecordingError, match="median speed -54 km/h, negative"):
        read_run(_rewritten(tmp_path / "back.mf4", backwards), channel_map_from(MAP))


def test_a_saturated_force_channel_is_refused(tmp_path):
    path = _groups(tmp_path / "clip.mf4", clip=5.5)
    with pytest.raises(
        RecordingError, match=r"sit at its largest value 5.5 kN.*saturated \(clipped\)"
    ):
        read_run(path, channel_map_from(MAP))
    read_run(write_mdf(tmp_path / "fine.mf4"), channel_map_from(MAP))  # unclipped: read


def test_the_estimate_refuses_a_recording_of_another_wheel_where_it_matters():
    """A two-wheel recording whose columns began with the inner wheel of a curve was
    compared on it, silently; on tangent a recording of either wheel is compared (their
    statistics are alike; the reviewer of stop 58: one instrumented wheel is common)."""
    from types import SimpleNamespace

    from railsusp.estimate.problem import check_measured_wheel

    curve = get_condition("curve", duration_s=2.0, n_steps=100)
    assert curve.curve_direction == "left"  # its outer wheel: w1R

    def rec_of(condition, wheels):
        rec = make_recording(100)
        rec.condition = condition
        rec.Y = {w: rec.Y["w1L"] for w in wheels}
        rec.Q = {w: rec.Q["w1L"] for w in wheels}
        return rec

    plain = object()  # a force model of the automatically chosen wheel
    with pytest.raises(RailsuspInputError, match="its first wheel is w1L, the force model gives"):
        check_measured_wheel(plain, [rec_of(curve, ["w1L"])], aligned=False)
    with pytest.raises(RailsuspInputError, match=r"\(it holds w1R: list it first\)"):
        check_measured_wheel(plain, [rec_of(curve, ["w1L", "w1R"])], aligned=False)
    check_measured_wheel(plain, [rec_of(curve, ["w1R", "w1L"])], aligned=False)
    tangent = get_condition("straight", duration_s=2.0, n_steps=100)
    check_measured_wheel(plain, [rec_of(tangent, ["w1R"])], aligned=False)  # either wheel
    # ... of the same wheelset: another wheelset steers otherwise (accepted until stop 62)
    for other in ("w2L", "w3L", "w4R"):
        with pytest.raises(RailsuspInputError, match=r"wheels\) is w1L or w1R"):
            check_measured_wheel(plain, [rec_of(tangent, [other])], aligned=False)
    with pytest.raises(RailsuspInputError, match="its first wheel is w1R"):
        check_measured_wheel(plain, [rec_of(tangent, ["w1R"])], aligned=True)
    simulator = SimpleNamespace(wheel="w1R")  # SimulatorForces(wheel="w1R")
    check_measured_wheel(simulator, [rec_of(tangent, ["w1R", "w1L"])], aligned=True)
    trained_on_w1l = SimpleNamespace(  # surrogates of a campaign --wheel w1L
        conditions=["curve"], surrogate=lambda name: SimpleNamespace(meta={"wheel": "w1L"})
    )
    check_measured_wheel(trained_on_w1l, [rec_of(curve, ["w1L"])], aligned=True)


def test_the_en14363_filter_takes_a_short_section():
    x = np.sin(np.arange(8.0))
    assert np.isfinite(lowpass(x, 200.0)).all() and lowpass(x, 200.0).shape == (8,)


def test_a_run_towards_decreasing_km_posts_sees_the_line_mirrored():
    """A line description states direction and grade towards increasing km; a run whose
    position fell had its left-hand curves cut as left-hand and its climbs as descents."""
    from railsusp.measured.sections import geometry_from_line

    line = pd.DataFrame(
        {
            "km_start": [0.0, 1.0],
            "km_end": [1.0, 2.0],
            "radius_m": [600.0, np.nan],
            "direction": ["right", "left"],
            "cant_mm": [60.0, 0.0],
            "grade_permille": [0.0, -12.0],
        }
    )
    up = geometry_from_line(np.array([500.0, 1500.0]), line)
    down = geometry_from_line(np.array([1500.0, 500.0]), line)
    assert up["curvature"][0] == pytest.approx(-1 / 600) and up["grade"][1] == -0.012
    assert down["curvature"][1] == pytest.approx(1 / 600) and down["grade"][0] == 0.012
    assert up["cant"][0] == down["cant"][1] == pytest.approx(0.06)


def test_a_map_unit_restating_the_files_in_another_spelling_is_accepted(tmp_path):
    path = write_mdf(tmp_path / "a.mf4")
    same = channel_map_from({**MAP, "units": {"v": "kmh", "Y_R": "KN"}})
    assert read_run(path, same).speed.max() == pytest.approx(15.0)  # 54 km/h
    other = channel_map_from({**MAP, "units": {"Y_R": "N"}})
    with pytest.raises(RecordingError, match="the file states unit 'kN', the channel map 'N'"):
        read_run(path, other)


def test_a_run_that_stood_for_most_of_its_time_is_read(tmp_path):
    """A run standing 70 % of its time was refused ("median speed 0 km/h; the wagon does not
    run"); its standing stretches are for the cut to leave out."""

    def stood(name, t, values, unit):
        if name == "v":
            values = np.where(t < 14.0, 0.0, values)
        if name == "s":
            values = 15.0 * np.clip(t - 14.0, 0.0, None)
        return values, unit, None

    run = read_run(_rewritten(tmp_path / "stood.mf4", stood), channel_map_from(MAP))
    assert np.mean(run.speed < 0.5) > 0.6


def test_a_table_on_distance_at_varying_speed_is_put_on_time(tmp_path):
    """time = distance / speed, sample by sample, held at constant speed only: a table
    sampled every 0.33 m at 60 km/h +- 3 % was refused for a 7 % jitter of its times."""
    rate = 50.0
    t = np.arange(0.0, 20.0, 1 / rate)
    v = 16.7 * (1.0 + 0.03 * np.sin(2 * np.pi * 0.1 * t))
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    grid = np.arange(0.0, s[-1], 16.7 / rate)  # uniform in distance
    tg = np.interp(grid, s, t)

    def force(time):
        return 5.0 + 3.0 * np.sin(2 * np.pi * 0.7 * time)

    rec = make_recording(t.size, rate)
    rec.condition = rec.condition.with_duration(float(tg[-1] + 1 / rate))  # the table's
    rec.write(tmp_path / "d.csv")
    pd.DataFrame(
        {
            "distance_m": grid,
            "speed_kmh": 3.6 * np.interp(tg, t, v),
            "Y_w1L_kN": force(tg),
            "Q_w1L_kN": 120.0 + force(tg),
        }
    ).to_csv(tmp_path / "d.csv", index=False)
    back = read_recording(tmp_path / "d.csv")
    assert np.ptp(np.diff(back.time)) < 1e-9  # uniform
    assert back.sampling_rate == pytest.approx(rate, rel=0.02)
    assert np.abs(back.Y["w1L"] - force(back.time)).max() < 0.05


def test_a_distance_tables_problems_name_the_files_lines_not_resampled_samples(tmp_path):
    """A table on ``distance_m`` is put on time before its checks; their messages counted
    the resampled samples (rows 1250-1251 for a fault at file lines 951-952: 150 km/h, then
    60 km/h, sampled for 60 km/h), now the file's lines nearest to them."""
    t = np.arange(0.0, 20.0, 1 / 50)
    v = np.where(t < 6.0, 41.7, 16.7)  # 150 km/h, then 60 km/h, sampled every 0.334 m
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    grid = np.arange(0.0, s[-1], 16.7 / 50)
    tg = np.interp(grid, s, t)
    y = 5.0 + np.sin(tg)
    fault = np.flatnonzero(tg > 10.0)[0]  # 12.5 m/s after the change: about 300 lines in
    y[fault : fault + 2] = np.inf
    make_recording().write(tmp_path / "d.csv")
    frame = {"distance_m": grid, "speed_kmh": 3.6 * np.interp(tg, t, v), "Y_w1L_kN": y}
    pd.DataFrame({**frame, "Q_w1L_kN": 120.0 + 0 * tg}).to_csv(tmp_path / "d.csv", index=False)
    with pytest.raises(RecordingError) as info:
        read_recording(tmp_path / "d.csv")
    found = re.search(r"column 'Y_w1L_kN', rows? (\d+)(?:-(\d+))?: infinite", str(info.value))
    assert found, str(info.value)
    first, last = int(found[1]), int(found[2] or found[1])
    assert first - 1 <= fault + 2 and last + 1 >= fault + 3  # file line = index + 2


def test_a_channel_name_in_two_groups_is_refused_only_where_it_is_used(tmp_path):
    t = np.arange(0, 20, 1 / 200)
    for name in ("acc_bogie_y_g", "Y_R"):  # a second group holding the name again
        _rewritten(tmp_path / f"{name}.mf4", extra=[[Signal(0 * t, t, name=name, unit="kN")]])
    read_run(tmp_path / "acc_bogie_y_g.mf4", channel_map_from(MAP))  # ignored: read
    with pytest.raises(RecordingError, match="channel 'Y_R' appears in 2 groups"):
        read_run(tmp_path / "Y_R.mf4", channel_map_from(MAP))


def test_a_dropout_is_named_a_dropout_not_mixed_rates(tmp_path):
    t = np.arange(0.0, 20.0, 1 / 200)
    t = np.concatenate([t[:2000], t[2200:]])  # a second lost at 10 s
    table = {"time_s": t, "Y_w1R_kN": 5.0 + np.sin(t), "Q_w1R_kN": 120.0 + np.cos(t)}
    pd.DataFrame({**table, "speed_kmh": 54.0 + 0 * t}).to_csv(tmp_path / "r.csv", index=False)
    # a recording to estimate from is one stretch: refused, naming the dropout
    text = " ".join(check_time(t, "time_s", 2))
    assert "200 sample(s) missing (1 such gap(s)): a dropout cannot be interpolated" in text
    assert "railsusp sections cuts a long run at its dropouts" in text
    assert "mixed sampling rates" not in text
    # a long run is cut there (stop 61: one dropout made a whole run unusable)
    run = read_run(tmp_path / "r.csv")
    assert run.breaks.tolist() == [2000]
    assert any("1 dropout(s)" in n for n in run.data_notes)
    # many single lost samples are dropouts too, not two rates (the 1 % limit is gone)
    keep = np.ones(t.size, bool)
    keep[5::40] = False  # 2.5 % of the samples lost, one at a time
    lossy = {k: v[keep] for k, v in table.items()}
    pd.DataFrame({**lossy, "speed_kmh": 54.0 + 0 * lossy["time_s"]}).to_csv(
        tmp_path / "many.csv", index=False
    )
    text = " ".join(check_time(lossy["time_s"], "time_s", 2))
    assert "1 sample(s) missing" in text and "mixed" not in text
    assert read_run(tmp_path / "many.csv").breaks.size == (~keep).sum() + 1  # and the second


def test_an_odometer_reset_is_no_unit_error_and_a_capital_kn_gets_its_hint(tmp_path):
    def reset(name, t, values, unit):
        if name == "s":
            return np.mod(values, 100.0), unit, None  # the odometer resets every 100 m
        if name == "Q_R":
            return values * 1e3, "KN", None  # in N, stated as KN
        return values, unit, None

    with pytest.raises(RecordingError) as info:
        read_run(_rewritten(tmp_path / "b.mf4", reset), channel_map_from(MAP))
    assert "the values look like N, not KN" in str(info.value)
    assert "a unit error in one" not in str(info.value)  # the resets: not travel


def test_a_slow_smooth_extreme_written_at_six_digits_is_not_taken_for_clipping(tmp_path):
    """The reviewer of stop 58: a noise-free 0.16 Hz wave at 200 Hz, written with 6
    significant digits, holds its peak over about 12 samples (1 % of the record)."""
    rate = 200.0
    t = np.arange(int(20 * rate)) / rate
    rec = make_recording(t.size, rate)
    rec.condition = rec.condition.with_duration(20.0)
    rec.Y = {"w1L": 5 + np.sin(t)}
    rec.Q = {"w1L": 120 + np.cos(t)}
    rec.write(tmp_path / "r.csv")
    read_recording(tmp_path / "r.csv")


def test_a_one_row_distance_table_and_spelled_out_seconds(tmp_path):
    pd.DataFrame(
        {"distance_m": [0.0], "speed_kmh": [60.0], "Y_w1L_kN": [1.0], "Q_w1L_kN": [120.0]}
    ).to_csv(tmp_path / "one.csv", index=False)
    make_recording().write(tmp_path / "x.csv")
    (tmp_path / "one.json").write_text((tmp_path / "x.json").read_text())
    with pytest.raises(RecordingError, match="1 sample"):
        read_recording(tmp_path / "one.csv")
    t = np.arange(0.0, 20.0, 1 / 200)
    for unit in ("seconds", "secs", "milliseconds"):
        scale = 1e3 if unit == "milliseconds" else 1.0
        pd.DataFrame({f"time [{unit}]": t * scale, "Y_kN": 0 * t}).to_csv(
            tmp_path / "u.csv", index=False
        )
        assert read_raw(tmp_path / "u.csv")["Y_kN"].rate_hz == pytest.approx(200.0)


def test_a_run_slower_than_50_hz_is_cut_into_slower_sections(tmp_path):
    """The reviewer of stop 58: the 50 Hz floor refused a 40 Hz run whose sections were
    asked at 20 Hz; the floor is the sections' rate."""
    from railsusp.measured.cut import RunSource, cut_run
    from railsusp.measured.sections import SectionRules

    path = write_mdf(tmp_path / "slow.mf4", force_rate=40.0)
    mapping = tmp_path / "map.toml"
    mapping.write_text(
        'speed = "v"\nposition = "s"\nignore = ["acc_bogie_y_g"]\n'
        '[wheels.w1R]\nY = "Y_R"\nQ = "Q_R"\n'
    )
    source = RunSource(path, mapping, None, None, SectionRules(), 20.0)
    run, _ = cut_run(source)
    assert run.rate_hz == pytest.approx(40.0)
    with pytest.raises(RecordingError, match="40 Hz; accepted at least 50 Hz"):
        cut_run(RunSource(path, mapping, None, None, SectionRules(), 50.0))


def test_a_curve_whose_outer_wheel_is_not_recorded_is_left_out_of_the_cut():
    """The reviewer of stop 58: with one instrumented wheel, the curves the other way have
    their outer wheel (the one the model compares) unrecorded; the estimate refuses such a
    section, so the cut leaves it out with the reason instead of failing the estimate."""
    import tomllib
    from importlib import resources

    from railsusp.measured.sections import SectionRules, cut_sections, read_line

    data = resources.files("railsusp") / "data"
    mapping = tomllib.loads((data / "example_run.map.toml").read_text())
    mapping["wheels"] = {"w1R": mapping["wheels"]["w1R"]}
    mapping["ignore"] = [*mapping.get("ignore", []), "WS1_Y_L", "WS1_Q_L"]
    run = read_run(data / "example_run.mf4", channel_map_from(mapping))
    secs = cut_sections(run, SectionRules(), line=read_line(data / "example_line.csv"))
    right = [s for s in secs if s.radius_m is not None and s.direction == "right"]
    left = [s for s in secs if s.radius_m is not None and s.direction == "left"]
    assert right and left
    assert all(not s.kept for s in right)
    assert all("outer wheel w1L, the one compared, is not recorded" in s.reason for s in right)
    assert all(s.kept for s in left)


def test_a_sidecar_condition_of_another_duration_is_refused_and_an_unstated_one_is_the_tables(
    tmp_path,
):
    """The bad-input audit of stop 58: a 4 s condition on a 1 s table was simulated for 4 s
    and compared with 1 s of measurement; a condition stating no duration took the default
    20 s whatever the table."""
    import json

    make_recording(100, 50.0).write(tmp_path / "r.csv")  # 2 s
    side = tmp_path / "r.json"
    doc = json.loads(side.read_text())
    doc["condition"]["duration_s"], doc["condition"]["n_steps"] = 4.0, 200
    side.write_text(json.dumps(doc))
    with pytest.raises(RecordingError, match="condition duration_s 4 s, the table 100 rows"):
        read_recording(tmp_path / "r.csv")
    doc["condition"] = {
        "name": "curve",
        "speed_kmh": 60,
        "curve_radius_m": 300,
        "curve_direction": "left",
        "cant_mm": 110,
    }
    side.write_text(json.dumps(doc))  # the documented sidecar: no duration stated
    back = read_recording(tmp_path / "r.csv")
    assert (back.condition.duration_s, back.condition.n_steps) == (2.0, 100)
    del doc["condition"]
    doc["condition_name"] = "uphill"
    side.write_text(json.dumps(doc))
    assert read_recording(tmp_path / "r.csv").condition.duration_s == 2.0


def test_a_boolean_force_column_is_refused_as_in_csv(tmp_path):
    """A Parquet force column of booleans was read as 0 and 1 kN with exit 0, where CSV's
    True/False was refused (the command-line audit of stop 60)."""
    path = make_recording().write(tmp_path / "r.parquet", fmt="parquet")
    df = pd.read_parquet(path)
    df["Y_w1L_kN"] = df["Y_w1L_kN"] > 5.0
    df.to_parquet(path)
    with pytest.raises(RailsuspInputError, match="column 'Y_w1L_kN' holds booleans"):
        read_recording(path)
    df.assign(Y_w1L_kN=df["Y_w1L_kN"].astype(str)).to_csv(tmp_path / "r.csv", index=False)
    with pytest.raises(RecordingError, match="'(True|False)' is not a number"):
        read_recording(tmp_path / "r.csv")


def test_a_sidecar_naming_two_conditions_is_refused(tmp_path):
    """A sidecar with a 'condition' table and another condition_name was read as the
    table's, the name ignored (the command-line audit of stop 60)."""
    import json

    make_recording().write(tmp_path / "r.csv")
    side = tmp_path / "r.json"
    doc = json.loads(side.read_text())
    side.write_text(json.dumps({**doc, "condition_name": doc["condition"]["name"]}))
    read_recording(tmp_path / "r.csv")  # the same name in both: one condition
    side.write_text(json.dumps({**doc, "condition_name": "curve"}))
    with pytest.raises(RecordingError, match="a 'condition' table .* and condition_name 'curve'"):
        read_recording(tmp_path / "r.csv")


RUN_MAP = {
    "speed": "v [km/h]",
    "position": "s [m]",
    "wheels": {"w1R": {"Y": "Y_R [kN]", "Q": "Q_R [kN]"}},
}


def _table_run(path, header_end, cells):
    """A 20 s long run as a CSV table (forces at 200 Hz), the columns ``header_end`` with
    the same ``cells`` in every row appended."""
    rng = np.random.default_rng(0)
    t = np.arange(0, 20, 1 / 200)
    y, q = 5 + rng.standard_normal(t.size), 120 + rng.standard_normal(t.size)
    lines = ["time [s],Y_R [kN],Q_R [kN],v [km/h],s [m]," + header_end]
    lines += [
        f"{a:.4f},{b:.4f},{c:.4f},54,{15 * a:.3f},{cells}" for a, b, c in zip(t, y, q, strict=True)
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_an_unused_long_run_column_named_twice_or_of_text_is_noted_not_refused(tmp_path):
    """A logger's ``status`` repeated across its groups, or a ``state`` of text, refused a
    whole long run (the table reader shared with the field format's refused any); now only
    where the channel map, or the time axis, uses the column, and noted where not."""
    path = _table_run(tmp_path / "r.csv", "status,GPS_fix,status,state", "1,3,1,OK")
    run = read_run(path, channel_map_from(RUN_MAP))
    assert run.wheels == ("w1R",)
    assert (
        "channel(s) not used: status (in columns 6, 8), GPS_fix, state (text, 'OK' in row 2, "
        "not numbers)"
    ) in run.notes
    for used, said in [
        ("status", "column 'status' appears 2 times in the header (columns 6, 8); accepted "
                   "each column once"),
        ("state", "column 'state', row 2: 'OK' is not a number (4000 such cell(s))"),
    ]:  # fmt: skip
        with pytest.raises(RecordingError) as err:
            read_run(path, channel_map_from({**RUN_MAP, "grade": used}))
        assert said in str(err.value)
    twice = _table_run(tmp_path / "t.csv", "time [s]", "0")
    with pytest.raises(RecordingError, match=r"column 'time \[s\]' appears 2 times"):
        read_run(twice, channel_map_from(RUN_MAP))
    # a Parquet column of booleans, unused: noted as well
    frame = pd.read_csv(path).iloc[:, :5].assign(flag=True)
    frame.to_parquet(tmp_path / "r.parquet")
    run = read_run(tmp_path / "r.parquet", channel_map_from(RUN_MAP))
    assert "channel(s) not used: flag (booleans, not numbers)" in run.notes
    with pytest.raises(RecordingError, match="column 'flag' holds booleans"):
        read_run(tmp_path / "r.parquet", channel_map_from({**RUN_MAP, "grade": "flag"}))


def test_a_sidecar_curve_without_its_hand_is_refused(tmp_path):
    """The review of stop 72: a sidecar condition with a curve radius and no
    curve_direction was read as a left-hand curve without a word (a right-hand curve's
    inner wheel then compared as its outer one)."""
    import json

    make_recording().write(tmp_path / "r.csv")
    side = tmp_path / "r.json"
    doc = json.loads(side.read_text())
    curve = {**doc["condition"], "curve_radius_m": 600.0, "cant_mm": 50.0}
    curve.pop("curve_direction")
    side.write_text(json.dumps({**doc, "condition": curve}))
    with pytest.raises(RecordingError, match="curve_radius_m = 600.0 with no curve_direction"):
        read_recording(tmp_path / "r.csv")
    side.write_text(json.dumps({**doc, "condition": {**curve, "curve_direction": "right"}}))
    assert read_recording(tmp_path / "r.csv").condition.curve_direction == "right"
