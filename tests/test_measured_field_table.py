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
    the 8.3 Hz channel read as 50 Hz data."""
    frame = {"time_s": T, **forces()}
    thin = np.arange(N) % 6 != 0
    for c in ("Y_w1L_kN", "Q_w1L_kN"):
        frame[c] = np.where(thin, np.nan, frame[c])
    msg = problems(table(tmp_path, frame))
    assert "column 'Y_w1L_kN': 166 of its 200 samples (83 %) missing (NaN)" in msg
    assert "a finite value about every 6 samples: effectively 8.333 Hz, not the written 50 Hz" in (
        msg
    )
    assert "at most 5 % of the samples missing" in msg and "column 'Q_w1L_kN'" in msg


def test_scattered_short_gaps_within_the_share_are_interpolated(tmp_path):
    frame = {"time_s": T, **forces()}
    frame["Q_w1L_kN"] = frame["Q_w1L_kN"].copy()
    frame["Q_w1L_kN"][[20, 21, 90, 150]] = np.nan  # 2 %
    with pytest.warns(UserWarning, match="4 missing sample"):
        rec = read_recording(table(tmp_path, frame))
    assert np.isfinite(rec.Q["w1L"]).all()
    frame["Q_w1L_kN"][np.arange(3, N, 12)] = np.nan  # 17 single samples more: 10.5 %
    msg = problems(table(tmp_path, frame))
    assert "column 'Q_w1L_kN': 21 of its 200 samples (10.5 %) missing (NaN); accepted" in msg
    assert "effectively" not in msg


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
