"""Every bad recording of issues 21/22 is refused with one line per problem naming the
file, the column and the rows, exit status 2 from the CLI; what is right is accepted."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.measured import Recording, RecordingError, read_field, read_recording
from test_measured import make_recording

runner = CliRunner()


def recording(n=200, rate=100.0) -> Recording:
    """The sine recording of test_measured, longer and faster sampled."""
    return make_recording(n, rate)


def write_table(tmp_path, header, columns, name="rec"):
    """A recording with the given header and columns, and a valid sidecar."""
    path = recording().write(tmp_path / name)
    lines = [",".join(header)] + [
        ",".join(f"{v:.6g}" for v in row) for row in zip(*columns, strict=True)
    ]
    path.write_text("\n".join(lines) + "\n")
    side = path.with_suffix(".json")
    meta = json.loads(side.read_text())
    meta.pop("sampling_rate_hz")
    side.write_text(json.dumps(meta))
    return path


def problems(path) -> str:
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    return str(info.value)


def cli_refuses(path, *needles):
    """check-recording: exit 2, one line per problem (file, column, rows), no traceback."""
    result = runner.invoke(app, ["check-recording", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output and result.exception.__class__ is SystemExit
    for needle in needles:
        line = next(ln for ln in result.output.splitlines() if needle in ln)
        assert str(path) in line


T = np.arange(200) / 100.0
Y = 5 + 3 * np.sin(2 * np.pi * 1.5 * T)
Q = 122 + 10 * np.cos(2 * np.pi * 2.0 * T)


def test_an_extra_channel_is_left_unused_not_refused(tmp_path):
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN", "acc_bogie_y_g"], [T, Y, Q, Y])
    with pytest.warns(UserWarning, match="'acc_bogie_y_g' not used"):
        rec = read_recording(p)
    assert rec.wheels == ("w1L",)


def test_forces_in_newtons_are_accepted_when_the_header_says_so(tmp_path):
    p = write_table(tmp_path, ["time_s", "Y_w1L [N]", "Q_w1L [N]"], [T, Y * 1e3, Q * 1e3])
    rec = read_recording(p)
    np.testing.assert_allclose(rec.Q["w1L"], Q, rtol=1e-5)  # kN inside the Recording


def test_forces_in_meganewtons_under_a_kn_header_are_refused(tmp_path):
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [T, Y / 1e3, Q / 1e3])
    msg = problems(p)
    assert "'Q_w1L_kN': median wheel load 0.122 kN" in msg
    assert "the values look like MN, not kN" in msg
    cli_refuses(p, "Q_w1L_kN")
    # ... and read right when the header states MN
    p = write_table(tmp_path, ["time_s", "Y_w1L [MN]", "Q_w1L [MN]"], [T, Y / 1e3, Q / 1e3])
    np.testing.assert_allclose(read_recording(p).Q["w1L"], Q, rtol=1e-5)


def test_newtons_under_a_kn_header_are_refused(tmp_path):
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [T, Y * 1e3, Q * 1e3])
    assert "the values look like N, not kN" in problems(p)


def test_a_lateral_force_in_kn_under_an_n_header_is_refused(tmp_path):
    """Y in kN marked N read as a few newtons and passed: only Q's magnitude was checked
    (stop 77's hunt). Refused against the wheel load, with the unit it looks like."""
    p = write_table(tmp_path, ["time_s", "Y_w1L [N]", "Q_w1L [N]"], [T, Y, Q * 1e3])
    msg = problems(p)
    assert "'Y_w1L [N]': |Y| at most 8 N (read as N) against a median wheel load of 122" in msg
    assert "the values look like kN, not N" in msg
    cli_refuses(p, "Y_w1L [N]")


def test_a_force_without_a_known_unit_is_refused(tmp_path):
    p = write_table(tmp_path, ["time_s", "Y_w1L [lbf]", "Q_w1L [N]"], [T, Y, Q * 1e3])
    assert "unit 'lbf' is not a force unit; accepted N, kN, MN, daN" in problems(p)


def test_all_zero_and_constant_channels_are_refused(tmp_path):
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [T, 0 * Y, 0 * Q])
    msg = problems(p)
    assert "column 'Y_w1L_kN': all 200 samples are zero" in msg
    assert "column 'Q_w1L_kN': all 200 samples are zero" in msg
    cli_refuses(p, "Y_w1L_kN", "Q_w1L_kN")
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [T, Y, 0 * Q + 120])
    assert "column 'Q_w1L_kN': constant at 120" in problems(p)


def test_infinite_values_are_refused_not_interpolated(tmp_path):
    y = Y.copy()
    y[[10, 11, 50]] = [np.inf, np.inf, -np.inf]
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [T, y, Q])
    msg = problems(p)
    assert "column 'Y_w1L_kN', rows 12-13: infinite value(s)" in msg
    assert "column 'Y_w1L_kN', row 52: infinite value(s)" in msg
    cli_refuses(p, "rows 12-13")


@pytest.mark.parametrize("rows", [1, 2])
def test_one_or_two_rows_are_refused(tmp_path, rows):
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [T[:rows], Y[:rows], Q[:rows]])
    assert f"column 'time_s': {rows} sample(s); at least 10 are needed" in problems(p)
    cli_refuses(p, "at least 10")


def test_a_header_only_table_is_refused(tmp_path):
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [[], [], []])
    assert "column 'time_s': 0 sample(s); at least 10 are needed" in problems(p)
    cli_refuses(p, "0 sample(s)")


def test_mixed_sampling_rates_are_refused(tmp_path):
    t = np.concatenate([np.arange(100) / 100.0, 1.0 + np.arange(1, 101) * 1.0])
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [t, Y, Q])
    msg = problems(p)
    assert "column 'time_s', rows" in msg and "mixed sampling rates (100 Hz and 0.99" in msg
    cli_refuses(p, "mixed sampling rates")


def test_sampling_jitter_is_refused(tmp_path):
    t = T.copy()
    t[60:] += 0.003  # the interval between file lines 61 and 62 is 30 % long
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [t, Y, Q])
    assert "column 'time_s', rows 61-62: sampling-interval jitter 30 %" in problems(p)


def test_a_sidecar_rate_that_contradicts_the_data_is_refused(tmp_path):
    rec = recording(n=2000, rate=1000.0)
    p = rec.write(tmp_path / "fast")
    side = p.with_suffix(".json")
    meta = json.loads(side.read_text())
    meta["sampling_rate_hz"] = 50.0
    side.write_text(json.dumps(meta))
    assert "sidecar sampling_rate_hz 50 Hz, the time column 1000 Hz" in problems(p)
    cli_refuses(p, "sampling_rate_hz")


def test_a_sidecar_that_is_a_list_or_gives_text_for_a_number_is_refused(tmp_path):
    p = recording().write(tmp_path / "rec")
    side = p.with_suffix(".json")
    good = side.read_text()
    side.write_text("[1, 2, 3]")
    assert "rec.json: a JSON object {...} is needed, not a list" in problems(p)
    cli_refuses(p, "rec.json")
    side.write_text(good.replace('"speed_kmh": 60.0', '"speed_kmh": "60"'))
    assert "speed_kmh = '60': a number is needed, not a string" in problems(p)
    side.write_text(good.replace('"speed_kmh": 60.0', '"speed_kmh": true'))
    assert "speed_kmh = true: a boolean is not accepted" in problems(p)


def test_paths_in_sidecars_and_index_must_stay_inside_the_folder(tmp_path):
    folder = tmp_path / "field"
    p = recording().write(folder / "rec")
    (tmp_path / "elsewhere.track.csv").write_text("distance_m\n0\n")
    side = p.with_suffix(".json")
    meta = json.loads(side.read_text())
    for bad in ("../elsewhere.track.csv", str(tmp_path / "elsewhere.track.csv")):
        meta["condition"]["track_geometry"] = bad
        side.write_text(json.dumps(meta))
        assert "track_geometry" in problems(p) and "outside the folder" in problems(p)
    meta["condition"].pop("track_geometry")
    side.write_text(json.dumps(meta))
    index = folder / "index.json"
    for entry in ("../rec.csv", "/etc/passwd", "sub/../../x.csv"):
        index.write_text(json.dumps({"recordings": [entry]}))
        with pytest.raises(RailsuspInputError, match="outside the folder"):
            read_field(folder)
    index.write_text(json.dumps(["rec.csv"]))
    with pytest.raises(RailsuspInputError, match='a JSON object with a "recordings" list'):
        read_field(folder)
    index.write_text(json.dumps({"recordings": ["rec.csv"]}))
    assert len(read_field(folder)) == 1


@pytest.mark.parametrize(
    ("key", "value", "needle"),
    [
        ("wheels", '"w1L"', 'wheels = "w1L": accepted a list of distinct wheel names w1L .. w4R'),
        ("wheels", '["w1R", "w9X"]', 'wheels = ["w1R", "w9X"]: accepted a list'),
        ("wheels", '["w1R", "w1R"]', 'wheels = ["w1R", "w1R"]: accepted a list of distinct'),
        ("filter_bandwidth_hz", '"x"', 'filter_bandwidth_hz = "x": accepted a number of Hz'),
        ("filter_bandwidth_hz", "-20", "filter_bandwidth_hz = -20: accepted a number of Hz"),
        ("filter_bandwidth_hz", "0", "filter_bandwidth_hz = 0: accepted a number of Hz above 0"),
        ("filter_bandwidth_hz", "true", "filter_bandwidth_hz = true: accepted"),
    ],
)
def test_sidecar_wheels_and_bandwidth_are_checked(tmp_path, key, value, needle):
    """Passed check-recording before; the comparison then failed on them naming nothing."""
    p = recording().write(tmp_path / "rec")
    side = p.with_suffix(".json")
    doc = json.loads(side.read_text())
    doc[key] = json.loads(value)
    side.write_text(json.dumps(doc))
    assert needle in problems(p)
    cli_refuses(p, needle)


def test_sidecar_bandwidth_may_be_null_or_a_number(tmp_path):
    p = recording().write(tmp_path / "rec")
    side = p.with_suffix(".json")
    doc = json.loads(side.read_text())
    for bw in (None, 20, 12.5):
        side.write_text(json.dumps({**doc, "filter_bandwidth_hz": bw}))
        assert read_recording(p).meta["filter_bandwidth_hz"] == bw


def test_a_wheel_with_one_force_column_is_reported_once(tmp_path):
    """Before: its Y column was also 'not recognised (did you mean 'Y_w1L_kN'?)', itself."""
    t = np.arange(200) / 100.0
    p = write_table(tmp_path, ["time_s", "Y_w1L_kN"], [t, 10.0 * np.sin(t)])
    text = problems(p)
    assert "wheel w1L: column 'Q_w1L_kN' missing" in text
    assert "not recognised" not in text


def test_a_csv_cut_inside_its_last_line_is_refused_and_one_without_a_line_end_is_not(tmp_path):
    """The Python API fuzzing (stop 54): a copy cut mid-line read its last Y digit-short and
    its Q as a gap to interpolate."""
    p = recording().write(tmp_path / "rec")
    whole = p.read_bytes()
    p.write_bytes(whole.rstrip(b"\n"))  # no final line end: fine
    assert read_recording(p).time.size == 200
    last = whole.rstrip(b"\n").rsplit(b"\n", 1)[-1]
    p.write_bytes(whole.rstrip(b"\n")[: -(len(last) - last.index(b",") - 2)])
    assert "the last line is cut short" in problems(p)


def test_dropouts_one_sample_apart_are_dropouts_and_a_rate_change_is_not(tmp_path):
    """Samples 10-19 lost but sample 15 kept (a logger's burst of losses): two long
    intervals in a row, of 6 and 5 intervals. Before stop 63 any two long intervals in a
    row were read as a change of rate, and a whole long run was refused as "mixed sampling
    rates"; a rate change is a run of long intervals of one multiple."""
    import pandas as pd

    from railsusp.measured import checks
    from railsusp.measured.checks import check_time, dropout_steps
    from railsusp.measured.run import read_run

    t = np.arange(20000) / 200.0
    keep = np.ones(t.size, bool)
    keep[10000:10010] = keep[10011:10020] = False  # sample 10010 kept between the two
    assert dropout_steps(t[keep]).tolist() == [9999, 10000]
    text = " ".join(check_time(t[keep], "Y", 0))  # a recording to estimate from: refused
    assert "10 sample(s) missing (2 such gap(s))" in text and "mixed" not in text
    # two samples lost in every three, five times over: dropouts too
    bursty = np.ones(t.size, bool)
    bursty[5000:5015:3] = bursty[5001:5015:3] = False
    assert dropout_steps(t[bursty]).size == 5
    # a run of one multiple is a rate change (200 Hz then 100 Hz)
    halved = np.concatenate([t[:10000], t[10000::2]])
    assert dropout_steps(halved) is None
    assert "mixed sampling rates" in " ".join(check_time(halved, "Y", 0))
    for n, changed in ((checks.RATE_CHANGE_INTERVALS, True), (3, False)):  # n at 100 Hz
        brief = np.concatenate([t[:10000], t[10001 : 10001 + 2 * n : 2], t[10001 + 2 * n :]])
        assert (dropout_steps(brief) is None) == changed
    # a long run is cut at both dropouts, not refused
    tk = t[keep]
    cols = {"time_s": tk, "Y_w1R_kN": 5.0 + np.sin(tk), "Q_w1R_kN": 120.0 + np.cos(tk)}
    pd.DataFrame({**cols, "speed_kmh": np.full(tk.size, 54.0)}).to_csv(
        tmp_path / "run.csv", index=False
    )
    run = read_run(tmp_path / "run.csv")
    assert run.breaks.tolist() == [10000, 10001]


def test_force_bounds_name_the_count_and_the_extreme_of_every_stretch(tmp_path):
    """Y x 20: only the first stretch was named, "row 108: |force| up to 301.1 kN", while
    14 rows were beyond and the largest was 678.8 kN; the negative-Q check was the same."""
    y = Y.copy()
    y[[10, 11, 50]] = [320.0, 310.0, 650.0]
    q = Q.copy()
    q[[30, 90, 91]] = [-5.0, -40.0, -8.0]
    msg = problems(write_table(tmp_path, ["time_s", "Y_w1L_kN", "Q_w1L_kN"], [T, y, q]))
    assert (
        "column 'Y_w1L_kN', rows 12-13: |force| up to 650 kN (at row 52; 3 such sample(s) in 2 "
        "stretch(es), the first named) beyond the physical bound 300 kN"
    ) in msg
    assert (
        "column 'Q_w1L_kN', row 32: negative wheel load down to -40 kN (at row 92; 3 such "
        "sample(s) in 2 stretch(es), the first named); accepted down to -2.44 kN"
    ) in msg
