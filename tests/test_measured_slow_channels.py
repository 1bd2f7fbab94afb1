"""A long run's slow channels and dropouts as loggers write them (the bug hunt's four left
over): a speed, position or track column written only every k rows of a table, a slow
channel's timestamps jittering on a CAN bus, a force column filled every second row noted
twice, and a dropout of the forces that another channel does not share."""

import warnings

import numpy as np
import pandas as pd
import pytest
from asammdf import MDF, Signal

from railsusp.measured import RecordingError, read_recording
from railsusp.measured.channels import channel_map_from
from railsusp.measured.run import read_run
from railsusp.measured.sections import cut_sections
from test_measured_field_table import forces, table
from test_measured_gaps import MAP, RATE

N = 12000  # 60 s (the table runs: test_measured_gaps's map and rate)
#: the map of the MDF runs: forces Y and Q of one wheel, a speed v
MDF_MAP = {"speed": "v", "wheels": {"w1R": {"Y": "Y", "Q": "Q"}}}


def table_run(path, empty=None):
    """A 60 s tangent run at 54 km/h, a 200 Hz table; ``empty``: {column: rows} left
    empty."""
    rng = np.random.default_rng(7)
    t = np.arange(N) / RATE
    frame = {
        "time_s": t,
        "Y_R": 5.0 + rng.standard_normal(N),
        "Q_R": 120.0 + rng.standard_normal(N),
        "Y_L": 5.0 + rng.standard_normal(N),
        "Q_L": 120.0 + rng.standard_normal(N),
        "v": np.full(N, 54.0),
        "s": 15.0 * t,
        "curv": np.zeros(N),
    }
    for column, rows in (empty or {}).items():
        frame[column][rows] = np.nan
    pd.DataFrame(frame).to_csv(path, index=False)
    return path


def off_step(k, *also):
    """The rows of a column written every ``k`` rows that are empty, and the rows ``also``."""
    empty = np.arange(N) % k != 0
    for rows in also:
        empty[rows] = True
    return empty


def test_a_slow_column_written_every_twentieth_row_is_read_at_its_rate(tmp_path):
    """Speed, distance and curvature at 10 Hz in a 200 Hz table, the other cells empty:
    refused as "95 % of its samples missing (NaN)"; read as 10 Hz channels now,
    interpolated onto the forces' time base."""
    slow = off_step(20)
    path = table_run(tmp_path / "slow.csv", {"v": slow, "s": slow, "curv": slow})
    run = read_run(path, channel_map_from(MAP))
    for c in ("v", "s", "curv"):
        assert (
            f"channel {c!r}: a finite value about every 20 samples of its 200 Hz (the others "
            "empty): sampled at 10 Hz, interpolated between them"
        ) in run.notes
    assert not run.gaps and not run.breaks.size and not run.data_notes
    assert np.abs(run.speed - 15.0).max() < 1e-9
    inside = run.time <= 59.9  # its last value, at row 11981 (held after it)
    assert np.abs(run.position - 15.0 * run.time)[inside].max() < 1e-9
    assert [s.kept for s in cut_sections(run)] == [True]


def test_only_a_slow_columns_genuine_gaps_are_missing(tmp_path):
    """Two values of the 10 Hz speed lost (a gap of 60 rows, three of its steps) are two
    samples missing, interpolated with a note; 40 lost (8 s) a gap the run is cut at."""
    path = table_run(tmp_path / "short.csv", {"v": off_step(20, [2000, 2020])})
    run = read_run(path, channel_map_from(MAP))
    assert "channel 'v': 2 missing sample(s) interpolated" in run.data_notes
    assert not run.gaps
    path = table_run(tmp_path / "long.csv", {"v": off_step(20, slice(4000, 4800))})
    run = read_run(path, channel_map_from(MAP))
    assert run.gaps == ((3981, 4800, "v"),)  # between its values at rows 3980 and 4800
    note = next(n for n in run.notes if "missing values (NaN)" in n)
    assert "channel 'v': 1 gap(s)" in note and "rows 4002-4782" in note  # its file lines


def test_a_value_off_a_slow_columns_step_is_refused_naming_the_rows(tmp_path):
    empty = off_step(20)
    empty[1010] = False  # half way between two of its values
    with pytest.raises(RecordingError) as err:
        read_run(table_run(tmp_path / "off.csv", {"v": empty}), channel_map_from(MAP))
    assert (
        "channel 'v', rows 1002-1022: sampling-interval jitter 50 % of the 0.1 s interval, "
        "more than the 25 % accepted (a speed, position or track channel's"
    ) in str(err.value)


def mdf_run(path, *, v_time=None, v_keep=None, f_time=None, f_keep=None):
    """A 20 s run: Y and Q at 1000 Hz (times ``f_time``, samples ``f_keep``), a speed v
    in a group of its own (times ``v_time``, 1000 Hz by default; samples ``v_keep``)."""
    t = np.arange(20000) / 1000.0 if f_time is None else f_time
    t = t if f_keep is None else t[f_keep]
    tv = np.arange(20000) / 1000.0 if v_time is None else v_time
    tv = tv if v_keep is None else tv[v_keep]
    forces = [Signal(5.0 + np.sin(t), t, name="Y", unit="kN"),
              Signal(120.0 + np.cos(t), t, name="Q", unit="kN")]  # fmt: skip
    v = Signal(np.full(tv.size, 54.0), tv, name="v", unit="km/h")
    mdf = MDF(version="4.10")
    mdf.append(forces)
    mdf.append([v])
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


def jittered(rate, seconds, ms, seed=3):
    """Times at ``rate`` over ``seconds``, each off its place by up to ``ms`` ms."""
    n = round(rate * seconds)
    jitter = np.random.default_rng(seed).uniform(-ms, ms, n) * 1e-3
    jitter[[0, -1]] = 0.0
    return np.arange(n) / rate + jitter


def test_a_slow_channels_can_jitter_is_tolerated_up_to_a_quarter_of_its_step(tmp_path):
    """A 10 Hz speed stamped on a CAN bus's receipt, each stamp up to 4 ms off (8 % of an
    interval): the whole run was refused as "sampling-interval jitter 7.9 % ... more than
    1 %". Up to a quarter of its step is read; beyond, refused, naming the bound."""
    cmap = channel_map_from(MDF_MAP)
    run = read_run(mdf_run(tmp_path / "can.mf4", v_time=jittered(10.0, 20.0, 4.0)), cmap)
    assert np.abs(run.speed * 3.6 - 54.0).max() < 1e-9
    with pytest.raises(RecordingError) as err:
        read_run(mdf_run(tmp_path / "bad.mf4", v_time=jittered(10.0, 20.0, 20.0)), cmap)
    said = str(err.value)
    assert "channel 'v', samples" in said
    assert "more than the 25 % accepted (a speed, position or track channel's, only " in said
    assert "a force channel's 1 %)" in said


def test_force_channels_are_still_held_to_one_percent(tmp_path):
    t = jittered(1000.0, 20.0, 0.04)  # 4 % of the interval
    with pytest.raises(RecordingError) as err:
        read_run(mdf_run(tmp_path / "f.mf4", f_time=t), channel_map_from(MDF_MAP))
    assert "channel 'Y', samples" in str(err.value)
    assert "more than the 1 % accepted (" in str(err.value)


def test_a_jittered_slow_channels_dropout_is_still_found(tmp_path):
    """A second of the jittered 10 Hz speed lost where the forces have samples: its
    dropout was only found on a time base within 1 % of one rate."""
    tv = jittered(10.0, 20.0, 4.0)
    keep = (tv < 9.95) | (tv > 11.05)
    with pytest.raises(RecordingError) as err:
        read_run(mdf_run(tmp_path / "d.mf4", v_time=tv, v_keep=keep), channel_map_from(MDF_MAP))
    assert "channel 'v': samples lost between 9.897 and 11.099 s where the forces" in str(err.value)
    assert "accepted dropouts of all channels together (one logger)" in str(err.value)


def test_a_force_column_every_second_row_carries_only_its_rate_note(tmp_path):
    """Q_L in every second row of a 200 Hz table: read at 100 Hz with that note, and a
    note of "6000 missing sample(s) interpolated" beside it, of empty rows no data
    missing. Only samples missing at its rate are noted: two of them lost."""
    path = table_run(tmp_path / "two.csv", {"Q_L": off_step(2)})
    run = read_run(path, channel_map_from(MAP))
    assert [n for n in run.data_notes if "'Q_L'" in n] == [
        "channel 'Q_L': a finite value about every 2 samples of its 200 Hz (the others "
        "empty): sampled at 100 Hz, interpolated between them"
    ]
    path = table_run(tmp_path / "lost.csv", {"Q_L": off_step(2, [5000, 5002])})
    run = read_run(path, channel_map_from(MAP))
    assert "channel 'Q_L': 2 missing sample(s) (of its 100 Hz) interpolated" in run.data_notes
    assert not [n for n in run.data_notes if "'Q_L': 5 missing" in n]


def test_a_recordings_force_column_every_second_row_carries_only_its_rate_note(tmp_path):
    t = np.arange(400) / 100.0
    frame = {"time_s": t, "speed_kmh": np.full(t.size, 60.0), **forces(t)}
    frame["Q_w1L_kN"] = np.where(np.arange(t.size) % 2 == 1, np.nan, frame["Q_w1L_kN"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read_recording(table(tmp_path, frame))
    said = [str(w.message) for w in caught if "Q_w1L_kN" in str(w.message)]
    assert len(said) == 1 and "sampled at 50 Hz, interpolated between them" in said[0]


def test_a_dropout_of_the_forces_that_another_channel_does_not_share_is_refused(tmp_path):
    """The forces lose three samples at 10 s, the speed in its own group keeps them: the
    run was cut there without a word, where a speed that loses a sample the forces keep is
    refused; both are now. The same dropout in every channel still cuts the run."""
    cmap = channel_map_from(MDF_MAP)
    keep = np.ones(20000, bool)
    keep[10000:10003] = False
    with pytest.raises(RecordingError) as err:
        read_run(mdf_run(tmp_path / "f.mf4", f_keep=keep), cmap)
    assert (
        "channel 'v': 3 sample(s) between 9.999 and 10.003 s, where the forces of 'Q' lost "
        "theirs (a dropout); accepted dropouts of all channels together (one logger)"
    ) in str(err.value)
    with pytest.raises(RecordingError) as err:  # the other way round
        read_run(mdf_run(tmp_path / "v.mf4", v_keep=keep), cmap)
    assert (
        "channel 'v': samples lost between 9.999 and 10.003 s where the forces of 'Q' have 3"
        in (str(err.value))
    )
    both = read_run(mdf_run(tmp_path / "b.mf4", f_keep=keep, v_keep=keep), cmap)
    assert both.breaks.tolist() == [10000]


def test_a_dropout_of_every_channel_cuts_a_run_whose_speed_is_slower(tmp_path):
    """1000 Hz forces and a 10 Hz speed losing the same half second (one logger): the
    speed's last sample before lies up to a tenth of a second before the forces' last,
    which read as base samples inside a dropout of the speed's alone and refused the run.
    It is cut there now; a half second lost by the speed alone, the forces running on, is
    still refused."""
    cmap = channel_map_from(MDF_MAP)
    t = np.arange(20000) / 1000.0
    tv = np.arange(200) / 10.0 + 0.003  # (stamps between the forces')
    lost, lost_v = (t >= 9.95) & (t < 10.45), (tv >= 9.95) & (tv < 10.45)
    run = read_run(mdf_run(tmp_path / "all.mf4", f_keep=~lost, v_time=tv, v_keep=~lost_v), cmap)
    assert run.breaks.tolist() == [9950]
    with pytest.raises(RecordingError) as err:
        read_run(mdf_run(tmp_path / "v.mf4", v_time=tv, v_keep=~lost_v), cmap)
    assert "channel 'v': samples lost between 9.903 and 10.503 s where the forces" in str(err.value)
