"""Long runs as real loggers write them (stop 61's audit of the recordings reader): stretches
running backwards, odometer resets, dropouts, a section table whose range the run passes
twice, noisy geometry channels near a band's edge, a logger that goes on in a new data
group, rates at the limit, and field folders that name one condition twice. Each was a
silent wrong result or a refusal with a remedy that did not work."""

import json

import numpy as np
import pandas as pd
import pytest
from asammdf import MDF, Signal

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured import Recording, RecordingError, read_field, read_recording
from railsusp.measured.channels import channel_map_from
from railsusp.measured.run import read_run
from railsusp.measured.sections import SectionRules, cut_sections

RATE = 50.0


def write_run(path, speed_kmh, *, distance=None, curvature=None, grade=None, rate=RATE):
    """A CSV run with the documented column names: speed (signed), optional distance,
    curvature (1/km) and grade (permille), and plausible forces of both leading wheels."""
    v = np.asarray(speed_kmh, float)
    t = np.arange(v.size) / rate
    rng = np.random.default_rng(4)
    cols = {"time_s": t, "speed_kmh": v}
    if distance is not None:
        cols["distance_m"] = distance
    if curvature is not None:
        cols["curvature_1_per_km"] = curvature
    if grade is not None:
        cols["grade_permille"] = grade
    for w in ("w1R", "w1L"):
        cols[f"Y_{w}_kN"] = 5.0 + rng.standard_normal(t.size)
        cols[f"Q_{w}_kN"] = 120.0 + rng.standard_normal(t.size)
    pd.DataFrame(cols).to_csv(path, index=False)
    return path


def travelled(speed_kmh, rate=RATE):
    v = np.abs(np.asarray(speed_kmh, float)) / 3.6
    return np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / rate)])


def kept(sections):
    return [s for s in sections if s.kept]


def test_a_stretch_running_backwards_is_left_out_with_its_reason(tmp_path):
    """54 km/h for 100 s, a stop, -36 km/h for 100 s, a stop, 54 km/h: the reversing
    kilometre was kept as a tangent section at 36 km/h (only a run backwards on the median
    was refused)."""
    v = np.concatenate(
        [
            np.full(5000, 54.0),
            np.zeros(1500),
            np.full(5000, -36.0),
            np.zeros(1000),
            np.full(5000, 54.0),
        ]
    )
    run = read_run(write_run(tmp_path / "rev.csv", v))
    assert run.backwards is not None and run.backwards.sum() == 5000
    secs = cut_sections(run)
    assert [round(s.speed_kmh) for s in kept(secs)] == [54, 54]
    left = [s for s in secs if not s.kept]
    assert len(left) == 1 and "running backwards (wheelset 1 trailing" in left[0].reason
    assert all(not run.backwards[s.start : s.end].any() for s in kept(secs))


def test_a_section_table_range_passed_twice_gives_two_sections_never_the_samples_between(
    tmp_path,
):
    """A section table's row 200-500 m, on a run whose odometer resets at 1500 m: the
    section spanned from its first to its last sample in range, 1800 m of run between."""
    v = np.full(10000, 54.0)  # 200 s, 3000 m
    s = np.mod(travelled(v), 1500.0)
    run = read_run(write_run(tmp_path / "reset.csv", v, distance=s))
    assert run.breaks.size == 1  # the reset
    table = pd.DataFrame({"start_m": [200.0], "end_m": [500.0], "name": ["a"], "radius_m": [0.0]})
    secs = kept(cut_sections(run, table=table))
    assert [x.name for x in secs] == ["a-1", "a-2"]
    for x in secs:
        assert 200.0 <= run.position[x.start] and run.position[x.end - 1] < 500.0
        assert x.end - x.start < 20.5 * RATE + 2  # 300 m at 15 m/s: 20 s
        assert np.all(np.diff(run.position[x.start : x.end]) > 0)


def test_sections_are_cut_at_an_odometer_reset_and_a_distance_alone_reads_through_it(tmp_path):
    """A distance channel that resets (no speed channel): the speed derived across the reset
    was 5346 km/h, refused as "a unit error?" naming channel None; a section on a line
    description spanned the reset, its length taken from its two ends."""
    v = np.full(10000, 54.0)
    s = np.mod(travelled(v), 1500.0)
    path = tmp_path / "pos.csv"
    write_run(path, v, distance=s)
    df = pd.read_csv(path).drop(columns="speed_kmh")
    df.to_csv(path, index=False)
    run = read_run(path)
    assert np.abs(run.speed * 3.6 - 54.0).max() < 0.5  # no spike at the reset
    assert run.breaks.size == 1
    secs = cut_sections(run)
    assert all(not (x.start < run.breaks[0] < x.end) for x in secs)
    assert [round(x.end_m - x.start_m, -1) for x in kept(secs)] == [1500, 1500]


def test_a_dropout_cuts_the_run_and_no_section_straddles_it(tmp_path):
    v = np.full(5000, 54.0)
    path = write_run(tmp_path / "drop.csv", v)
    df = pd.read_csv(path)
    df.drop(index=range(2500, 2550)).to_csv(path, index=False)  # one second lost at 50 s
    run = read_run(path)
    assert run.breaks.tolist() == [2500]
    secs = kept(cut_sections(run))
    assert len(secs) == 2 and secs[0].end == 2500 and secs[1].start == 2500
    # a section table over the dropout gets two pieces, as the remedy says
    table = pd.DataFrame({"start_m": [100.0], "end_m": [1200.0], "name": ["x"], "radius_m": [0.0]})
    assert [x.name for x in kept(cut_sections(run, table=table))] == ["x-1", "x-2"]


@pytest.mark.parametrize("rate", [500.0, 1000.0, 2000.0])
def test_a_run_sampled_exactly_at_the_least_rate_is_accepted(tmp_path, rate):
    """600 s at 1000 Hz read as 999.99999... Hz and was refused against --min-rate 1000."""
    n = round(600 * rate)
    t = np.arange(n) / rate
    mdf = MDF(version="4.10")
    mdf.append(
        [
            Signal(5.0 + np.sin(t), t, name="Y", unit="kN"),
            Signal(120.0 + np.cos(t), t, name="Q", unit="kN"),
            Signal(np.full(n, 54.0), t, name="v", unit="km/h"),
        ]
    )
    mdf.save(tmp_path / "r.mf4", overwrite=True)
    mdf.close()
    cmap = channel_map_from({"speed": "v", "wheels": {"w1R": {"Y": "Y", "Q": "Q"}}})
    run = read_run(tmp_path / "r.mf4", cmap, min_rate_hz=rate)
    assert run.rate_hz == pytest.approx(rate)


def test_a_csv_recording_at_2400_hz_reads_back_its_own_time(tmp_path):
    """Sections written above 1 kHz had their time at 6 digits (100.0004 s as 100): the
    reader refused them, "time not strictly increasing"."""
    c = get_condition("straight", duration_s=20.0, n_steps=48000)
    t = 100.0 + np.arange(48000) / 2400.0
    rec = Recording(t, {"w1R": 5.0 + np.cos(t)}, {"w1R": 120.0 + np.sin(t)}, c)
    rec.write(tmp_path / "s.csv")
    back = read_recording(tmp_path / "s.csv", min_rate_hz=2400.0)
    np.testing.assert_allclose(back.time, t, rtol=0, atol=1e-9)


def test_noise_on_a_steady_curve_or_tangent_does_not_cut_it_into_pieces(tmp_path):
    """Curvature noise of 0.001 1/km on a tangent split it by the noise's sign; 1 % noise on a
    steady R600 (a band's edge) flipped its band, and its per-sample gradient read as a
    spiral: the whole run a transition. Grade noise at a band's edge flipped the grade band."""
    rng = np.random.default_rng(5)
    n = 6000  # 120 s at 54 km/h: 1800 m
    v = np.full(n, 54.0)
    cases = {
        "tangent": (0.001 * rng.standard_normal(n), np.zeros(n)),
        "R600": (1000 / 600 * (1 + 0.01 * rng.standard_normal(n)), np.zeros(n)),
        "R800": (1000 / 800 + 0.002 * rng.standard_normal(n), np.zeros(n)),
        "grade 2.5": (np.zeros(n), 2.5 + 0.1 * rng.standard_normal(n)),
    }
    for name, (curv, grade) in cases.items():
        run = read_run(write_run(tmp_path / "n.csv", v, curvature=curv, grade=grade))
        secs = cut_sections(run, SectionRules(max_duration_s=600.0))
        assert len(secs) == 1 and secs[0].kept, (name, [(x.kind, x.reason) for x in secs])
    # a real spiral is still a transition
    spiral = np.concatenate(
        [np.zeros(2000), np.linspace(0, 1000 / 600, 2000), np.full(2000, 1000 / 600)]
    )
    secs = cut_sections(read_run(write_run(tmp_path / "s.csv", v, curvature=spiral)))
    assert [x.kind for x in kept(secs)] == ["tangent", "curve R600"]
    assert any("transition" in x.reason for x in secs if not x.kept)


def test_a_logger_that_goes_on_in_a_new_data_group_is_one_channel(tmp_path):
    t = np.arange(6000) / 100.0
    h = t.size // 2
    mdf = MDF(version="4.10")
    for part in (slice(0, h), slice(h, None)):
        mdf.append(
            [
                Signal(5.0 + np.sin(t[part]), t[part], name="Y", unit="kN"),
                Signal(120.0 + np.cos(t[part]), t[part], name="Q", unit="kN"),
                Signal(np.full(t[part].size, 54.0), t[part], name="v", unit="km/h"),
            ]
        )
    mdf.save(tmp_path / "split.mf4", overwrite=True)
    mdf.close()
    cmap = channel_map_from({"speed": "v", "wheels": {"w1R": {"Y": "Y", "Q": "Q"}}})
    run = read_run(tmp_path / "split.mf4", cmap)
    np.testing.assert_allclose(run.time, t)
    np.testing.assert_allclose(run.Y["w1R"], (5.0 + np.sin(t)) * 1e3)


def test_a_field_folder_naming_one_condition_twice_is_refused(tmp_path):
    """Two recordings of condition 'straight': align-track --write put one's offset into
    both sidecars, and the validation drew one figure for the two."""
    c = get_condition("straight", duration_s=8.0, n_steps=400)
    t = np.arange(400) / 50.0
    for stem in ("a", "b"):
        Recording(t, {"w1R": 5.0 + np.cos(t)}, {"w1R": 120.0 + np.sin(t)}, c).write(
            tmp_path / f"{stem}.csv"
        )
    (tmp_path / "index.json").write_text(json.dumps({"recordings": ["a.csv", "b.csv"]}))
    with pytest.raises(
        RailsuspInputError,
        match="a.csv and b.csv are both recordings of "
        "condition 'straight'; accepted one condition name per recording",
    ):
        read_field(tmp_path)
    # the posterior took the later of the two, dropping the other unsaid
    from railsusp.estimate.posterior_recordings import recording_summaries

    rec = read_recording(tmp_path / "a.csv")
    with pytest.raises(RailsuspInputError, match="two recordings of condition 'straight'"):
        recording_summaries(None, [rec, rec])


def test_a_table_along_distance_with_a_stop_names_the_speed(tmp_path):
    """A distance_m table whose speed stands at zero: "column 'time_s' ... time is not a
    number" about a column the file does not have, and a numpy warning."""
    v = np.full(2000, 54.0)
    v[1000:1010] = 0.0
    d = np.arange(2000) * 0.25
    pd.DataFrame(
        {
            "distance_m": d,
            "speed_kmh": v,
            "Y_w1R_kN": 5.0 + np.cos(d),
            "Q_w1R_kN": 120.0 + np.sin(d),
        }
    ).to_csv(tmp_path / "stop.csv", index=False)
    (tmp_path / "stop.json").write_text(json.dumps({"condition": "straight"}))
    with pytest.raises(RecordingError) as info:
        read_recording(tmp_path / "stop.csv")
    text = str(info.value)
    assert "column 'speed_kmh', rows 1002-1011: speed 0 km/h" in text
    assert "time_s" not in text.split("speed 0 km/h")[0]


def test_a_force_given_twice_is_named_as_such(tmp_path):
    t = np.arange(1000) / 50.0
    pd.DataFrame(
        {
            "time_s": t,
            "Y_w1R_kN": 5.0 + np.cos(t),
            "Y_w1R [N]": 5e3 + np.cos(t),
            "Q_w1R_kN": 120.0 + np.sin(t),
        }
    ).to_csv(tmp_path / "two.csv", index=False)
    (tmp_path / "two.json").write_text(json.dumps({"condition": "straight"}))
    with pytest.raises(RecordingError, match="the force Y_w1R is given twice"):
        read_recording(tmp_path / "two.csv")


def test_a_distance_held_between_its_updates_is_travel_not_jumps(tmp_path):
    """A 5 Hz odometer in a 50 Hz table steps 3 m every tenth row: the first version took
    every step for a jump (the median step is 0) and read a wagon that does not run."""
    v = np.full(5000, 54.0)
    s = travelled(v)
    s = s[(np.arange(s.size) // 10) * 10]
    path = write_run(tmp_path / "held.csv", v, distance=s)
    pd.read_csv(path).drop(columns="speed_kmh").to_csv(path, index=False)
    run = read_run(path)
    assert run.breaks.size == 0 and np.median(run.speed) * 3.6 == pytest.approx(54.0, rel=0.01)
    # with the speed too, the held steps are travel
    write_run(path, v, distance=s)
    assert read_run(path).breaks.size == 0


@pytest.mark.parametrize("where", ["first", "last", "glitch"])
def test_a_jump_at_either_end_or_one_wrong_sample_reads(tmp_path, where):
    v = np.full(5000, 54.0)
    s = travelled(v)
    if where == "first":
        s[1:] += 5000.0
    elif where == "last":
        s[-1] += 5000.0
    else:
        s[2500] += 5000.0
    path = write_run(tmp_path / "j.csv", v, distance=s)
    pd.read_csv(path).drop(columns="speed_kmh").to_csv(path, index=False)
    run = read_run(path)  # was "speed up to 1.8e4 km/h ... a unit error?"
    assert np.abs(run.speed * 3.6 - 54.0).max() < 1.0


def test_a_change_of_rate_is_not_a_dropout_and_a_lost_sample_of_another_channel_is_refused(
    tmp_path,
):
    from railsusp.measured.checks import check_time

    t = np.concatenate([np.arange(6000) * 0.01, 59.99 + np.arange(1, 4001) * 0.02])
    assert "mixed sampling rates" in " ".join(check_time(t, "x", 0))
    # Q in its own group loses one sample the forces' Y keeps: it would be interpolated
    # across the loss, silently
    t = np.arange(20000) / 1000.0
    keep = np.ones(t.size, bool)
    keep[10000] = False
    mdf = MDF(version="4.10")
    mdf.append([Signal(5.0 + np.sin(t), t, name="Y", unit="kN"),
                Signal(np.full(t.size, 54.0), t, name="v", unit="km/h")])  # fmt: skip
    mdf.append([Signal(120.0 + np.cos(t[keep]), t[keep], name="Q", unit="kN")])
    mdf.save(tmp_path / "q.mf4", overwrite=True)
    mdf.close()
    cmap = channel_map_from({"speed": "v", "wheels": {"w1R": {"Y": "Y", "Q": "Q"}}})
    with pytest.raises(RecordingError, match="channel 'Q': samples lost between 9.999 and"):
        read_run(tmp_path / "q.mf4", cmap)


def test_a_slow_distance_channels_jump_is_no_unit_error(tmp_path):
    """The distance at 1 Hz with a +300 m chainage jump: on the forces' 500 Hz the jump is a
    ramp of small steps, counted as travel: "a unit error in one?"."""
    t = np.arange(30000) / 500.0
    ts = np.arange(61) * 1.0
    s = 15.0 * ts + np.where(ts >= 30.0, 300.0, 0.0)
    mdf = MDF(version="4.10")
    mdf.append([Signal(5.0 + np.sin(t), t, name="Y", unit="kN"),
                Signal(120.0 + np.cos(t), t, name="Q", unit="kN"),
                Signal(np.full(t.size, 54.0), t, name="v", unit="km/h")])  # fmt: skip
    mdf.append([Signal(s, ts, name="s", unit="m")])
    mdf.save(tmp_path / "s.mf4", overwrite=True)
    mdf.close()
    cmap = channel_map_from(
        {"speed": "v", "position": "s", "wheels": {"w1R": {"Y": "Y", "Q": "Q"}}}
    )
    run = read_run(tmp_path / "s.mf4", cmap)
    assert run.breaks.size == 2 and run.jumping is not None


def test_a_table_row_the_distance_jumps_over_in_part_says_which_part_was_kept(tmp_path):
    """A row wholly inside the run's positions, over which the distance jumps by 300 m (a
    chainage jump): its two stretches were kept under the row's name as if it were whole,
    without a note (only a row beyond the run's first or last position said so)."""
    from railsusp.measured.line import read_section_table

    v = np.full(6000, 54.0)  # 120 s, 1800 m travelled
    s = travelled(v)
    s = np.where(s >= 750.0, s + 300.0, s)  # positions 0-750, 1050-2100
    run = read_run(write_run(tmp_path / "jump.csv", v, distance=s, curvature=np.zeros(v.size)))
    table = tmp_path / "t.csv"
    table.write_text("start_m,end_m,name\n300,1400,across\n1500,2000,after\n")
    secs = cut_sections(run, table=read_section_table(table))
    got = [(s.name, s.reason) for s in kept(secs)]
    assert got == [
        ("across-1", "kept, 300-750, 1050-1400 m of 300-1400 m on the run (row 2 of the table)"),
        ("across-2", "kept, 300-750, 1050-1400 m of 300-1400 m on the run (row 2 of the table)"),
        ("after", ""),
    ]
