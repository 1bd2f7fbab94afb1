"""A field table read as a field engineer writes one (measured.field_table): a distance
jump, forces mostly missing, an unused column of text, and the messages of a damaged file,
each refused (or noted) in the project's words, naming the column and the rows."""

import json

import numpy as np
import pandas as pd
import pytest

from railsusp.measured import RecordingError, read_recording
from test_measured import make_recording

N, RATE = 200, 50.0
T = np.arange(N) / RATE


def table(tmp_path, frame: dict, name="rec", meta_edit=None, fmt="csv"):
    """A table of ``frame``'s columns beside a valid sidecar (the 50 Hz sine recording's,
    its record and rate taken from the table)."""
    path = make_recording(N, RATE).write(tmp_path / name, fmt)
    if fmt == "csv":
        pd.DataFrame(frame).to_csv(path, index=False)
    else:
        pd.DataFrame(frame).to_parquet(path)
    side = path.with_suffix(".json")
    meta = json.loads(side.read_text())
    meta.pop("sampling_rate_hz")
    for key in ("duration_s", "n_steps"):
        meta["condition"].pop(key)
    if meta_edit:
        meta_edit(meta)
    side.write_text(json.dumps(meta))
    return path


def forces(t=T):
    return {
        "Y_w1L_kN": 5 + 3 * np.sin(2 * np.pi * 1.5 * t),
        "Q_w1L_kN": 122 + 10 * np.cos(2 * np.pi * 2.0 * t),
    }


def problems(path) -> str:
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    return str(info.value)


def along_distance(speed_kmh=60.0):
    d = T * speed_kmh / 3.6
    return {"distance_m": d, "speed_kmh": np.full(N, speed_kmh), **forces()}


def test_a_distance_jump_is_refused_naming_distance_m_and_its_rows(tmp_path):
    """50 m added from row 200 on: the jump became 3 s of interpolated forces, accepted."""
    frame = along_distance()
    frame["distance_m"] = frame["distance_m"] + np.where(np.arange(N) >= 100, 50.0, 0.0)
    msg = problems(table(tmp_path, frame))
    assert "column 'distance_m', rows 101-102: a step of 50.33 m against the median 0.3333 m" in (
        msg
    )
    assert "3.02 s at 60 km/h" in msg and "1 such step(s)" in msg
    # a sound table along distance still reads, on its own time base
    rec = read_recording(table(tmp_path, along_distance()))
    assert rec.time.size == N and rec.sampling_rate == pytest.approx(RATE)


def test_a_table_sampled_every_metre_at_a_varying_speed_is_no_jump(tmp_path):
    """Uniform in distance, the time steps vary with the speed (within its tolerance of the
    condition's): no step is long in both distance and time."""
    v = 60.0 * (1 + 0.08 * np.sin(np.linspace(0, 3, N)))
    d = np.arange(N) * 0.3
    frame = {"distance_m": d, "speed_kmh": v, **forces(np.arange(N) / RATE)}
    rec = read_recording(table(tmp_path, frame))
    travel = np.sum(np.diff(d) / (0.5 * (v[1:] + v[:-1]) / 3.6))  # s, the integral of ds / v
    assert abs(rec.time[-1] - travel) < 1.0 / rec.sampling_rate


def test_a_repeated_distance_names_distance_m_not_time_s(tmp_path):
    frame = along_distance()
    frame["distance_m"][100] = frame["distance_m"][99]
    msg = problems(table(tmp_path, frame))
    assert "column 'distance_m', rows 101-102: distance not strictly increasing" in msg
    assert "time_s" not in msg


def test_forces_in_every_sixth_row_only_are_refused_with_their_rate(tmp_path):
    """Each gap of 5 passed the 5-sample rule: 83 % of the samples were interpolated and
    the 8.3 Hz channel read as 50 Hz data. It is refused by its rate of finite values, below
    the lowest usable rate, as a long run's column is."""
    frame = {"time_s": T, **forces()}
    thin = np.arange(N) % 6 != 0
    for c in ("Y_w1L_kN", "Q_w1L_kN"):
        frame[c] = np.where(thin, np.nan, frame[c])
    msg = problems(table(tmp_path, frame))
    assert (
        "column 'Y_w1L_kN': forces sampled at 8.333 Hz (a finite value about every 6 samples "
        "of its 50 Hz, the others empty); accepted at least 50 Hz, the lowest usable rate "
        "(check-recording --min-rate"
    ) in msg
    assert "column 'Q_w1L_kN': forces sampled at 8.333 Hz" in msg


def test_one_rule_for_sparse_forces_in_a_recording_and_a_long_run(tmp_path):
    """A 100 Hz table with Q in every other row (50 Hz data, meeting the 50 Hz least rate)
    was refused as 50 % missing, where a long run's table of the same pattern was read with
    a note: both read it now at 50 Hz, interpolated between its values, with the note; at
    --min-rate 60 both refuse it by its rate."""
    from railsusp.measured.run import read_run

    t = np.arange(400) / 100.0
    frame = {"time_s": t, "speed_kmh": np.full(t.size, 60.0), **forces(t)}
    frame["Q_w1L_kN"] = np.where(np.arange(t.size) % 2 == 1, np.nan, frame["Q_w1L_kN"])
    path = table(tmp_path, frame)
    with pytest.warns(UserWarning) as caught:
        rec = read_recording(path)
    said = [str(w.message) for w in caught]
    assert any("a finite value about every 2 samples of its 100 Hz" in w for w in said)
    q = 122 + 10 * np.cos(2 * np.pi * 2.0 * t)
    assert np.abs(rec.Q["w1L"] - q)[:-1].max() < 0.1  # between its 50 Hz values (the last held)
    with pytest.raises(RecordingError) as err:
        read_recording(path, min_rate_hz=60.0)
    assert "'Q_w1L_kN': forces sampled at 50 Hz" in str(err.value)
    run = read_run(path)  # the same table read as a long run
    assert any("a finite value about every 2 samples" in n for n in run.data_notes)
    with pytest.raises(RecordingError) as err:
        read_run(path, min_rate_hz=60.0)
    assert "'Q_w1L_kN': forces sampled at 50 Hz" in str(err.value)
    # scattered single samples missing, 20 % of them: refused by both (a long run's were
    # interpolated and written as measured sections by sections --write)
    frame["Q_w1L_kN"] = forces(t)["Q_w1L_kN"]
    frame["Q_w1L_kN"][np.arange(2, t.size - 2, 5)] = np.nan
    path = table(tmp_path, frame)
    said = "column 'Q_w1L_kN': 80 of its 400 samples (20 %) missing (NaN), in gaps of up to 5"
    assert said in problems(path)
    with pytest.raises(RecordingError) as err:
        read_run(path)
    assert said.replace("column", "channel") in str(err.value)


def test_scattered_short_gaps_within_the_share_are_interpolated(tmp_path):
    frame = {"time_s": T, **forces()}
    frame["Q_w1L_kN"] = frame["Q_w1L_kN"].copy()
    frame["Q_w1L_kN"][[20, 21, 90, 150]] = np.nan  # 2 %
    with pytest.warns(UserWarning, match="4 missing sample"):
        rec = read_recording(table(tmp_path, frame))
    assert np.isfinite(rec.Q["w1L"]).all()
    frame["Q_w1L_kN"][np.arange(3, N, 12)] = np.nan  # 17 single samples more: 10.5 %
    msg = problems(table(tmp_path, frame))
    assert "column 'Q_w1L_kN': 21 of its 200 samples (10.5 %) missing (NaN), in gaps" in msg
    assert "accepted at most 5 % of a force channel's samples in such gaps" in msg
    assert "forces sampled at" not in msg


def test_empty_cells_of_a_table_along_distance_are_counted_as_in_the_file(tmp_path):
    """A table along distance_m was put on time before its cells were checked: each empty
    cell spread to the samples around it, 30 empty Q cells of 1000 (3 %) refused as "61 of
    its 1000 samples (6.1 %) missing". They are counted on the file's rows, named by line."""
    n = 1000
    d = np.arange(n) / 3.0
    v = np.linspace(57.0, 63.0, n)  # the times uneven, as measured
    t = np.concatenate([[0.0], np.cumsum(np.diff(d) / (0.5 * (v[1:] + v[:-1]) / 3.6))])
    frame = {"distance_m": d, "speed_kmh": v, **forces(t)}
    q = frame["Q_w1L_kN"]
    q[np.arange(10, 990, 33)[:30]] = np.nan  # 30 single empty cells, 3 %
    path = table(tmp_path, frame)
    with pytest.warns(UserWarning, match="column 'Q_w1L_kN': 30 missing sample"):
        rec = read_recording(path)
    assert np.isfinite(rec.Q["w1L"]).all()
    q[:] = forces(t)["Q_w1L_kN"]
    q[np.arange(10, 990, 16)[:60]] = np.nan  # 60 of 1000 (more than 5 %): refused, counted
    msg = problems(table(tmp_path, frame))
    assert "column 'Q_w1L_kN': 60 of its 1000 samples (6 %) missing (NaN)" in msg
    q[500:508] = np.nan  # a gap of 8 rows: named by its file lines (the header is line 1)
    assert "column 'Q_w1L_kN', rows 502-509: gap of 8 missing samples" in problems(
        table(tmp_path, frame)
    )


def test_a_column_along_distance_goes_on_time_missing_only_where_its_nearest_row_is():
    """np.interp spread each empty cell to the samples on either side of it."""
    from railsusp.measured.field_table import FieldTable, row_times, uniform_time

    d = np.arange(12) * 1.0
    v = np.linspace(15.0, 17.0, d.size)
    table = FieldTable(None, [], "distance_m", None, distance=d, row_time=row_times(d, v))
    table.time, table.lines = uniform_time(table.row_time)
    x = 3.0 * table.row_time  # linear in time: interpolated exactly, across the empty row too
    x[5] = np.nan
    out = table.on_time(x)
    nearest = table.lines - 2
    assert np.array_equal(np.isnan(out), nearest == 5)
    assert np.allclose(out[nearest != 5], 3.0 * table.time[nearest != 5])


def test_the_messages_of_a_distance_axis_give_what_is_accepted(tmp_path):
    frame = along_distance()
    frame["speed_kmh"] = frame["speed_kmh"].copy()
    frame["speed_kmh"][[40, 41, 90]] = np.nan
    msg = problems(table(tmp_path, frame))
    assert "column 'speed_kmh', rows 42-43: speed empty (3 row(s) in all); a table along" in msg
    assert "nan" not in msg
    frame = along_distance()
    frame["distance_m"][7] = np.nan
    msg = problems(table(tmp_path, frame))
    assert (
        "column 'distance_m', row 9: distance empty or not finite (1 row(s) in all); "
        "accepted a finite distance, m, in every row, strictly increasing"
    ) in msg


def test_an_unused_text_or_boolean_column_is_noted_not_refused(tmp_path):
    frame = {"time_s": T, **forces(), "note": ["x"] * N}
    with pytest.warns(UserWarning, match=r"column 'note' not used \(text, 'x' in row 2"):
        rec = read_recording(table(tmp_path, frame))
    assert rec.wheels == ("w1L",)
    path = table(tmp_path, {"time_s": T, **forces(), "flag": [True] * N}, "flag", fmt="parquet")
    with pytest.warns(UserWarning, match=r"column 'flag' not used \(booleans, not numbers\)"):
        read_recording(path)
    # a used column of text is still refused, and every such column is named at once
    frame = {"time_s": T, **forces()}
    frame["Y_w1L_kN"] = frame["Y_w1L_kN"].astype(str)
    frame["Q_w1L_kN"] = frame["Q_w1L_kN"].astype(str)
    frame["Y_w1L_kN"][5] = "abc"
    frame["Q_w1L_kN"][7] = "1,5"
    msg = problems(table(tmp_path, frame))
    assert "column 'Y_w1L_kN', row 7: 'abc' is not a number (1 such cell(s))" in msg
    assert "column 'Q_w1L_kN', row 9: '1,5' is not a number (',' as decimal mark?" in msg


def test_header_faults_are_said_as_such(tmp_path):
    path = make_recording().write(tmp_path / "rec")
    lines = path.read_text().splitlines()
    path.write_text("\n".join(["time_s,Y_w1L_kN,Y_w1L_kN", *lines[1:]]) + "\n")
    msg = problems(path)
    assert "column 'Y_w1L_kN' appears 2 times in the header (columns 2, 3)" in msg
    assert "Y_w1L_kN.1" not in msg
    path.write_text("\n".join(line + "," for line in lines) + "\n")  # a trailing comma
    with warnings_as_errors():
        read_recording(path)  # the empty unnamed column: left out without a word
    path.write_text("\n".join(line.replace(",", ";") for line in lines) + "\n")
    assert "its cells are separated by ';'; accepted a comma-separated table" in problems(path)
    path.write_text("\n".join(["time_s,Y_w1L_kN,Q_wlL_kN", *lines[1:]]) + "\n")
    assert "'Q_wlL_kN' not recognised (did you mean 'Q_w1L_kN'?)" in problems(path)
    # one cell more than the header on a line: its first column was taken for row labels
    path.write_text("\n".join([lines[0], *(line + ",7" for line in lines[1:])]) + "\n")
    assert "lines 2, 3, 4 (100 in all): more cells than the header's 3" in problems(path)
    path.write_text("\n".join([*lines[:5], lines[5] + ",7", *lines[6:]]) + "\n")
    assert "line 6: more cells than the header's 3" in problems(path)


def test_lines_that_are_not_utf8_are_named_by_number(tmp_path):
    path = make_recording().write(tmp_path / "rec")
    data = path.read_bytes().split(b"\n")
    data[50] = data[50] + b"\xe9"
    path.write_bytes(b"\n".join(data))
    assert "line 51: not UTF-8 text (byte 0xe9)" in problems(path)
    data[0] = data[0] + b"\xe9"
    path.write_bytes(b"\n".join(data))
    assert "lines 1, 51 (the header): not UTF-8 text" in problems(path)


def test_a_stem_with_both_tables_is_ambiguous(tmp_path):
    rec = make_recording()
    rec.write(tmp_path / "rec", "csv")
    rec.write(tmp_path / "rec", "parquet")
    msg = problems(tmp_path / "rec")
    assert "both rec.csv and rec.parquet exist" in msg
    assert read_recording(tmp_path / "rec.parquet").time.size == rec.time.size  # named


def test_a_condition_that_is_not_a_table_is_said_so(tmp_path):
    def edit(meta):
        meta["condition"] = [1]

    msg = problems(table(tmp_path, {"time_s": T, **forces()}, meta_edit=edit))
    assert "rec.json: condition = [1]: accepted a table (a JSON object" in msg


def test_a_constant_channel_states_its_unit(tmp_path):
    frame = {"time_s": T, **forces()}
    frame["Q_w1L_kN"] = np.full(N, 107.029)
    assert "column 'Q_w1L_kN': constant at 107.029 kN over all samples" in problems(
        table(tmp_path, frame)
    )


class warnings_as_errors:
    """No warning at all inside (a note would be one)."""

    def __enter__(self):
        import warnings

        self._cm = warnings.catch_warnings()
        self._cm.__enter__()
        warnings.simplefilter("error")

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)


def test_a_column_named_twice_is_refused_only_where_the_format_reads_it(tmp_path):
    """A logger's ``status`` repeated across its groups: an unknown column of the format,
    noted (its first copy unused, as a long run's); a column of the format named twice is
    refused, which copy meant unknown. Both were refused, the unknown one since the reader
    shared the long run's (and refused a whole long run with it)."""
    frame = {"time_s": T, **forces(), "status": np.ones(N), "GPS_fix": np.ones(N)}
    path = table(tmp_path, frame)
    text = path.read_text().replace("status,GPS_fix", "status,status", 1)
    path.write_text(text)
    with pytest.warns(UserWarning) as caught:
        rec = read_recording(path)
    said = [str(w.message) for w in caught]
    assert rec.wheels == ("w1L",)
    assert any(
        "column 'status' appears 2 times in the header (columns 4, 5): the later ones left out" in w
        for w in said
    ), said
    assert any("column 'status' not used" in w for w in said), said
    path.write_text(text.replace("status,status", "speed_kmh,speed_kmh", 1))
    msg = problems(path)
    assert (
        "column 'speed_kmh' appears 2 times in the header (columns 4, 5); accepted each "
        "column once (which copy is meant cannot be told)"
    ) in msg


@pytest.mark.parametrize("n", [3000, 3001])
def test_every_third_sample_missing_is_a_third_missing_at_any_length(n):
    """The step between finite samples was their median: with every third row empty the
    steps 1 and 2 are as many, and one row more (3001) made it 1.5, read as 133 Hz data
    with nothing missing and accepted, where 3000 rows were a third missing, refused."""
    from railsusp.measured.sampling import check_sparse, finite_sampling

    x = np.ones(n)
    x[2::3] = np.nan
    s = finite_sampling(x, 200.0)
    assert (s.step, s.rate_hz, s.missing) == (1.0, 200.0, n // 3)
    assert check_sparse(s, "Q") != []
    # a whole step of most rows stays the channel's rate, its other steps counted missing
    y = np.full(n, np.nan)
    y[::2] = 1.0
    y[[10, 500, 1000]] = np.nan  # 3 samples of 100 Hz missing
    s = finite_sampling(y, 200.0)
    assert (s.step, s.rate_hz, s.missing) == (2.0, 100.0, 3)


@pytest.mark.parametrize("column", ["speed_mps", "speed [m/s]", "speed_kph"])
def test_a_table_along_distance_takes_its_speed_in_any_stated_unit(tmp_path, column):
    """The track-column check read `speed_mps` or `speed [m/s]` as the speed, but a table
    along distance wanted `speed_kmh` by name ("without a speed_kmh column") and `speed_kph`
    was no column at all, though kph is an accepted speed unit."""
    v = 60.0 if column == "speed_kph" else 60.0 / 3.6
    frame = {"distance_m": T * 60.0 / 3.6, column: np.full(N, v), **forces()}
    rec = read_recording(table(tmp_path, frame))
    assert rec.time.size == N and rec.sampling_rate == pytest.approx(RATE)
    frame[column] = np.where(np.arange(N) == 7, -5.0, v)  # named by its own column, unit
    msg = problems(table(tmp_path, frame, name="stop"))
    unit = "km/h" if column == "speed_kph" else "m/s"  # the column's unit, as spelt here
    assert f"column {column!r}, row 9: speed -5 {unit} (1 row(s) in all)" in msg
    del frame[column]
    msg = problems(table(tmp_path, frame, name="none"))
    assert "without a speed column (speed_kmh, speed_mps or speed [m/s]); give time_s" in msg
    frame[column] = np.full(N, 60.0)
    frame["speed"] = frame.pop(column)  # no unit: which speed is it?
    assert "column 'speed': no unit stated; a speed channel needs one of m/s, km/h" in problems(
        table(tmp_path, frame, name="bare")
    )


def test_a_table_with_old_mac_line_ends_reads_as_with_unix_ones(tmp_path):
    # bare carriage returns (old Mac Excel): the header's csv reader raised "new-line
    # character seen in unquoted field" (a traceback) where pandas reads them as line ends
    path = make_recording().write(tmp_path / "rec")
    unix = read_recording(path)
    path.write_bytes(path.read_bytes().replace(b"\r\n", b"\n").replace(b"\n", b"\r"))
    mac = read_recording(path)
    np.testing.assert_array_equal(mac.time, unix.time)
    np.testing.assert_array_equal(mac.Q["w1L"], unix.Q["w1L"])
    path.write_bytes(b"\r\x00")  # the bytes the fuzz test found
    assert problems(path)


def test_a_giant_cell_is_refused_in_a_short_line(tmp_path):
    path = make_recording().write(tmp_path / "rec")
    lines = path.read_text().splitlines()
    giant = "x" * 200_000  # beyond the csv module's field size limit (131 072)
    path.write_text("\n".join([lines[0] + "," + giant, *lines[1:]]) + "\n")
    msg = problems(path)
    assert "cannot read the table (field larger than field limit" in msg and len(msg) < 400
    path.write_text("\n".join([lines[0], giant + lines[1][lines[1].index(",") :], *lines[2:]]))
    msg = problems(path)
    assert "row 2: 'xxxxx" in msg and "is not a number" in msg and len(msg) < 400


def test_a_one_column_header_is_quoted_cut(tmp_path):
    """The review of stop 72: an 800-column header separated by ';' was quoted whole in its
    refusal (5656 characters)."""
    from railsusp.measured import RecordingError, read_recording

    path = tmp_path / "rec.csv"
    path.write_text(";".join(f"col{i}" for i in range(800)) + "\n" + ";".join("1" * 800) + "\n")
    path.with_suffix(".json").write_text(
        '{"format": "railsusp-recording/1", "wheels": ["w1L"], "sampling_rate_hz": 50, '
        '"condition_name": "straight"}'
    )
    with pytest.raises(RecordingError, match=r"the header 'col0;col1;.*\.\.\. is one column") as e:
        read_recording(path)
    assert len(str(e.value)) < 400
