"""A long run's NaN gaps longer than the samples interpolated (an amplifier's overload, a
stretch a logger marked invalid): the run is cut there as at a dropout, the gap's samples
left out of the sections with the channel named, where before stop 63 one such gap of
0.3 s refused a whole run. A channel (or the channels together) without a stretch of
values as long as a working condition's shortest is still refused."""

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.measured import RecordingError, read_recording
from railsusp.measured.channels import channel_map_from
from railsusp.measured.checks import MAX_GAP_SAMPLES
from railsusp.measured.run import read_run
from railsusp.measured.sections import cut_sections, sections_table

RATE = 200.0
MAP = {
    "speed": "v",
    "position": "s",
    "curvature": "curv",
    "time": "time_s",
    "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R"}, "w1L": {"Y": "Y_L", "Q": "Q_L"}},
    "units": {"v": "km/h", "s": "m", "curv": "1/km", "Y_R": "kN", "Q_R": "kN", "Y_L": "kN",
              "Q_L": "kN"},
}  # fmt: skip


def long_run(path, *, seconds=60.0, nan=None, speed_kmh=54.0):
    """A tangent run at ``speed_kmh`` (its channel; the distance at 54 km/h), forces at 200
    Hz; ``nan``: {channel: index or mask} set to NaN."""
    rng = np.random.default_rng(5)
    t = np.arange(round(seconds * RATE)) / RATE
    frame = {
        "time_s": t,
        "Y_R": 5.0 + rng.standard_normal(t.size),
        "Q_R": 120.0 + rng.standard_normal(t.size),
        "Y_L": 5.0 + rng.standard_normal(t.size),
        "Q_L": 120.0 + rng.standard_normal(t.size),
        "v": np.full(t.size, speed_kmh),
        "s": 15.0 * t,
        "curv": np.zeros(t.size),
    }
    for channel, where in (nan or {}).items():
        frame[channel][where] = np.nan
    pd.DataFrame(frame).to_csv(path, index=False)
    return path


def test_a_long_nan_gap_cuts_the_run_and_is_left_out_with_the_channel_named(tmp_path):
    """300 samples (1.5 s) of Q_R missing at 30 s of a 60 s run: read, cut on either side
    of the gap, the gap a left-out row naming the channel; the note gives rows, times and
    length. Refused whole before ("gap of 300 missing samples")."""
    path = long_run(tmp_path / "run.csv", nan={"Q_R": slice(6000, 6300)})
    run = read_run(path, channel_map_from(MAP))
    assert run.gaps == ((6000, 6300, "Q_R"),)
    assert {6000, 6300} <= set(run.breaks.tolist())
    note = next(n for n in run.notes if "missing values (NaN)" in n)
    assert note.startswith("channel 'Q_R': 1 gap(s) of missing values (NaN) longer than the 5 ")
    assert "rows 6002-6301 (30.000-31.495 s, 300 samples)" in note  # file lines, header 1
    assert note in run.data_notes  # warned of by the pipeline's field stage
    assert np.isfinite(run.Q["w1R"]).all()  # the run's channels go on through it
    secs = cut_sections(run)
    kept = [s for s in secs if s.kept]
    assert kept and all(s.end <= 6000 or s.start >= 6300 for s in kept)
    gap = [s for s in secs if not s.kept and s.start < 6300 and s.end > 6000]
    assert len(gap) == 1 and (gap[0].start, gap[0].end) == (6000, 6300)
    assert gap[0].reason == (
        "no values: a gap of missing values (NaN) in channel(s) 'Q_R', longer than those "
        "interpolated"
    )
    assert "no values" in sections_table(secs).reason.tolist()[secs.index(gap[0])]


def test_a_short_gap_is_still_interpolated_without_a_break(tmp_path):
    path = long_run(tmp_path / "run.csv", nan={"Y_L": slice(4000, 4000 + MAX_GAP_SAMPLES)})
    run = read_run(path, channel_map_from(MAP))
    assert run.gaps == () and run.breaks.size == 0
    assert "channel 'Y_L': 5 missing sample(s) interpolated" in run.notes


def test_a_gap_of_a_slower_channel_leaves_out_the_samples_interpolated_across_it(tmp_path):
    """The speed at 10 Hz beside 200 Hz forces, 10 of its samples (1 s) missing: the
    forces' samples between its last value before the gap (9.9 s) and its first after
    (11.0 s) are the gap on the run's time base; the speed filled across it."""
    from asammdf import MDF, Signal

    rng = np.random.default_rng(6)
    t = np.arange(0, 30, 1 / RATE)
    ts = np.arange(0, 30.05, 0.1)
    v = np.full(ts.size, 54.0)
    v[100:110] = np.nan  # 10.0-10.9 s
    mdf = MDF(version="4.10")
    mdf.append(
        [
            Signal(5 + rng.standard_normal(t.size), t, name="Y_R", unit="kN"),
            Signal(120 + rng.standard_normal(t.size), t, name="Q_R", unit="kN"),
        ]
    )
    mdf.append([Signal(v, ts, name="v", unit="km/h"), Signal(15.0 * ts, ts, name="s", unit="m")])
    mdf.save(tmp_path / "run.mf4", overwrite=True)
    mdf.close()
    doc = {"speed": "v", "position": "s", "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R"}}}
    run = read_run(tmp_path / "run.mf4", channel_map_from(doc))
    ((a, b, channel),) = run.gaps
    assert channel == "v"
    assert 9.9 < run.time[a] < 9.9 + 1.5 / RATE and run.time[a - 1] <= 9.9 + 1e-9
    assert run.time[b - 1] < 11.0 <= run.time[b] + 1e-9
    assert np.allclose(run.speed, 15.0)  # filled: the position goes on through the gap
    note = next(n for n in run.notes if "missing values (NaN)" in n)
    assert "samples 100-109 (10.000-10.900 s, 10 samples)" in note


@pytest.mark.parametrize(("where", "left_out"), [("first", (0, 4000)), ("last", (8000, 12000))])
def test_a_position_missing_at_either_end_is_cut_not_taken_for_a_unit_error(
    tmp_path, where, left_out
):
    """The distance channel NaN for the run's first or last 20 s: its filled values are held
    flat there, so its path (600 m) fell short of the integrated speed (900 m) and the run
    was refused as a unit error (ratio 0.667). Compared outside the gaps, the run is cut,
    the gap a left-out row; a speed in the wrong unit is still caught, the message saying
    what was compared."""
    nan = {"s": slice(*left_out)}
    run = read_run(long_run(tmp_path / "run.csv", nan=nan), channel_map_from(MAP))
    assert run.gaps == ((*left_out, "s"),)
    secs = cut_sections(run)
    (gap,) = [s for s in secs if s.reason.startswith("no values")]
    assert (gap.start, gap.end, gap.kept) == (*left_out, False)
    assert sum(s.end - s.start for s in secs if s.kept) == 8000
    wrong = long_run(tmp_path / "wrong.csv", nan=nan, speed_kmh=54.0 * 3.6)  # m/s as km/h
    with pytest.raises(RecordingError) as info:
        read_run(wrong, channel_map_from(MAP))
    assert (
        "channels 's' and 'v': the distance runs over 599.9 m while the speed integrates to "
        "2160 m outside their gaps of missing values (NaN) (ratio 0.278, accepted 0.8 to 1.25)"
    ) in str(info.value)


def test_many_gaps_are_looked_up_once_per_cut_not_once_per_piece(tmp_path):
    """240 gaps of Q_R, every fifth overlapped by one of Y_L: each piece's gap channels
    were found by walking every gap of the run (the cut of a 2 h run with 6857 gaps took
    9 s, quadratic in the gaps); the gaps are walked a few times per cut now, and a piece
    in two channels' gaps still names both."""

    class Walked(tuple):
        walks = 0

        def __iter__(self):
            Walked.walks += 1
            return super().__iter__()

    n = round(300.0 * RATE)
    q = (np.arange(n) % 250) >= 230  # 20 samples of every 250 (1.25 s)
    y = q & ((np.arange(n) // 250) % 5 == 0) & ((np.arange(n) % 250) >= 240)  # inside Q_R's
    run = read_run(long_run(tmp_path / "run.csv", seconds=300.0, nan={"Q_R": q, "Y_L": y}),
                   channel_map_from(MAP))  # fmt: skip
    assert len(run.gaps) == 240 + 48
    run.gaps = Walked(run.gaps)
    secs = cut_sections(run)
    assert Walked.walks <= 4  # 600 or so before: once per piece
    gaps = [p for s in secs if not s.kept for p in s.pieces if p[0] == "gap"]
    assert sum("channel(s) 'Q_R', 'Y_L', longer" in p[1] for p in gaps) == 48
    assert sum("channel(s) 'Q_R', longer" in p[1] for p in gaps) == 240
    assert sum(p[2] for p in gaps) * RATE == pytest.approx(q.sum())


@pytest.mark.parametrize(
    ("nan", "said"),
    [
        # every other 0.15 s missing: no stretch of 1 s in the channel
        (
            {"Q_L": (np.arange(round(60.0 * RATE)) // 30) % 2 == 1},
            "channel 'Q_L': 50 % of its samples missing (NaN) in 200 gap(s) of more than 5 "
            "samples, its longest stretch of values 0.145 s; accepted a channel with a stretch "
            "of at least 1 s (a working condition's shortest duration: no section can be cut "
            "from less)",
        ),
        # each force channel half missing, the other half: no stretch with both
        (
            {"Y_R": slice(0, 6000), "Q_R": slice(6000, None)},
            "channels 'Y_R', 'Q_R': 100 % of the samples missing (NaN) in one of them or more, "
            "their longest stretch with every channel's values 0 s; accepted a stretch of at "
            "least 1 s (a working condition's shortest duration)",
        ),
    ],
)
def test_a_run_mostly_missing_is_still_refused(tmp_path, nan, said):
    path = long_run(tmp_path / "run.csv", nan=nan)
    with pytest.raises(RecordingError) as info:
        read_run(path, channel_map_from(MAP))
    assert info.value.problems == [said]


def test_a_recording_to_estimate_from_is_one_stretch_its_long_gap_refused(tmp_path):
    """A field folder's recording is one condition: a long gap is refused there, pointing
    at the cut of a long run."""
    from test_measured import broken

    def blank(ls):
        out = list(ls)
        for r in range(30, 40):
            cells = out[r].split(",")
            cells[2] = ""
            out[r] = ",".join(cells)
        return out

    with pytest.raises(RecordingError) as info:
        read_recording(broken(tmp_path, blank))
    assert "gap of 10 missing samples, more than the 5 that are interpolated (a recording is " in (
        str(info.value)
    )
    assert "railsusp sections cuts a long run at such a gap" in str(info.value)


def test_check_recording_and_sections_report_a_long_gap(tmp_path):
    """``check-recording --map`` accepts the run with the gap's note; ``sections`` shows the
    gap's row and cuts around it."""
    path = long_run(tmp_path / "run.csv", nan={"Q_R": slice(6000, 6300)})
    mapping = tmp_path / "map.toml"
    units = "\n".join(f'{k} = "{v}"' for k, v in MAP["units"].items())
    mapping.write_text(
        'speed = "v"\nposition = "s"\ncurvature = "curv"\ntime = "time_s"\n'
        '[wheels.w1R]\nY = "Y_R"\nQ = "Q_R"\n[wheels.w1L]\nY = "Y_L"\nQ = "Q_L"\n'
        f"[units]\n{units}\n"
    )
    runner = CliRunner()
    result = runner.invoke(app, ["check-recording", str(path), "--map", str(mapping)])
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "note: channel 'Q_R': 1 gap(s) of missing values (NaN)" in text
    assert "rows 6002-6301 (30.000-31.495 s, 300 samples)" in text
    result = runner.invoke(
        app, ["sections", str(path), "--map", str(mapping), "--write", str(tmp_path / "f")]
    )
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / "f" / "sections.csv")
    gap = table[table.reason.fillna("").str.startswith("no values")]
    assert len(gap) == 1 and gap.kept.tolist() == ["no"]
    assert (table.kept == "yes").sum() >= 2  # before and after the gap


def test_a_force_column_with_a_value_every_sixth_row_is_refused_as_a_slow_channel(tmp_path):
    """QA: a 200 Hz table whose Q_L has a value in every sixth row (the others empty, each
    gap of 5 short enough to be interpolated) was read as 200 Hz, where a 33 Hz channel in
    an MDF4 file is refused: it is refused as one, named with its finite samples' rate."""
    sparse = np.arange(12000) % 6 != 0
    path = long_run(tmp_path / "run.csv", nan={"Q_L": sparse})
    with pytest.raises(RecordingError) as err:
        read_run(path, channel_map_from(MAP))
    assert (
        "channel 'Q_L': forces sampled at 33.33 Hz (a finite value about every 6 samples of "
        "its 200 Hz, the others empty); accepted at least 50 Hz, the rate the sections"
    ) in str(err.value)
    assert read_run(path, channel_map_from(MAP), min_rate_hz=25.0).rate_hz == pytest.approx(200.0)
    # every second row: 100 Hz, as an MDF4 file's 100 Hz channel is read, with a note
    run = read_run(long_run(tmp_path / "two.csv", nan={"Q_L": np.arange(12000) % 2 == 1}),
                   channel_map_from(MAP))  # fmt: skip
    assert any("'Q_L': a finite value about every 2 samples" in n for n in run.data_notes)


def test_a_force_column_with_a_value_every_second_row_keeps_its_sections(tmp_path):
    """The bug hunt: such a column is read at its rate of 100 Hz with a note, but every
    empty row was taken as interpolated across a gap, and every section was left out as
    "50 % of the samples ... interpolated". Only samples missing at its rate are: two
    values lost (a gap of 6 rows between values, two 100 Hz samples) are, their rows
    marked."""
    sparse = np.arange(12000) % 2 == 1
    run = read_run(long_run(tmp_path / "two.csv", nan={"Q_L": sparse}), channel_map_from(MAP))
    assert "Q_L" not in run.interpolated
    secs = cut_sections(run)
    assert secs and all(s.kept for s in secs)
    sparse[[5000, 5002]] = True  # rows 4998 and 5004 finite: 4999-5003 between them missing
    run = read_run(long_run(tmp_path / "gap.csv", nan={"Q_L": sparse}), channel_map_from(MAP))
    assert np.flatnonzero(run.interpolated["Q_L"]).tolist() == [4999, 5000, 5001, 5002, 5003]


def test_missing_rows_are_the_nan_rows_of_gaps_longer_than_the_step():
    from railsusp.measured.sampling import finite_sampling, missing_rows

    x = np.arange(20.0)
    x[1::2] = np.nan  # every second row: its step
    x[8] = np.nan  # rows 6 and 10 finite: one sample of that rate missing
    # (the last row, 19, is off the step at the end: no sample missing)
    assert finite_sampling(x, 100.0).step == 2.0
    assert np.flatnonzero(missing_rows(x, 2.0)).tolist() == [7, 8, 9]
    assert finite_sampling(x, 100.0).missing == 1
    y = np.arange(10.0)
    y[[0, 4, 5]] = np.nan  # a step of 1: every NaN is missing
    assert np.flatnonzero(missing_rows(y, 1.0)).tolist() == [0, 4, 5]
