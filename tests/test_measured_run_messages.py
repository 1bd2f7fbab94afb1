"""A long run's reader's refusals as the QA of stop 68 found them worded: a run whose every
force channel misses the sections' rate is told so (not "too slow to interpolate" against a
channel as fast as itself), a constant channel's value is given in the file's unit, and a
channel map's stray key in a wheel's table is named."""

import numpy as np
import pandas as pd
import pytest
from asammdf import MDF, Signal

from railsusp.errors import RailsuspInputError
from railsusp.measured import RecordingError
from railsusp.measured.channels import channel_map_from, read_channel_map
from railsusp.measured.run import read_run
from railsusp.measured.run_checks import check_force_rates

MAP = {"speed": "v", "position": "s", "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R"}}}


def _with_speed_saved(mdf, path, ts):
    """``mdf`` with speed (54 km/h) and distance channels at the times ``ts``, saved."""
    mdf.append(
        [Signal(np.full(ts.size, 54.0), ts, name="v", unit="km/h"),
         Signal(15.0 * ts, ts, name="s", unit="m")]
    )  # fmt: skip
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


def _mdf(path, *, q=None):
    """A 20 s run, forces at 200 Hz (Q in N: ``q`` or noisy 120 kN), speed at 10 Hz."""
    rng = np.random.default_rng(0)
    t = np.arange(0, 20, 1 / 200)
    ts = np.arange(0, 20.1, 0.1)
    mdf = MDF(version="4.10")
    q_values = q if q is not None else 120e3 + 1e3 * rng.standard_normal(t.size)
    mdf.append(
        [
            Signal(5 + rng.standard_normal(t.size), t, name="Y_R", unit="kN"),
            Signal(q_values + 0 * t, t, name="Q_R", unit="N"),
        ]
    )
    return _with_speed_saved(mdf, path, ts)


def test_forces_as_fast_as_the_base_but_below_the_sections_rate_say_so(tmp_path):
    with pytest.raises(RecordingError) as err:
        read_run(_mdf(tmp_path / "r.mf4"), channel_map_from(MAP), min_rate_hz=400.0)
    said = str(err.value)
    for c in ("Y_R", "Q_R"):
        assert f"channel {c!r}: forces sampled at 200 Hz; accepted at least 400 Hz" in said
    assert "too slow to interpolate" not in said and "sections --rate" in said


def test_the_interpolation_wording_is_kept_for_the_tenth_of_the_fastest():
    rates = {"Y": 1000.0, "Q": 50.0, "Q2": 1000.0}
    (problem,) = check_force_rates(["Y", "Q", "Q2"], "Y", rates, 50.0)
    assert problem.startswith("channel 'Q': 50 Hz against 1000 Hz of 'Y': too slow to interp")
    assert "accepted at least 100 Hz, a tenth of the fastest" in problem
    (problem,) = check_force_rates(["Y", "Q"], "Y", {"Y": 200.0, "Q": 25.0}, 50.0)
    assert problem.startswith("channel 'Q': 25 Hz against 200 Hz of 'Y'; accepted at least 50")


def test_a_constant_force_channel_is_named_with_its_files_unit(tmp_path):
    with pytest.raises(RecordingError, match=r"'Q_R': constant at 107029 N over all samples"):
        read_run(_mdf(tmp_path / "c.mf4", q=np.full(4000, 107029.0)), channel_map_from(MAP))


def test_a_top_level_key_after_the_tables_is_named_in_the_wheels_error(tmp_path):
    """``recording = ...`` appended at the end of a map lands in the last table (TOML): the
    error said only that the wheel needs exactly Y and Q."""
    path = tmp_path / "map.toml"
    path.write_text('speed = "v"\n[wheels.w1L]\nY = "a"\nQ = "b"\nrecording = "run.mf4"\n')
    with pytest.raises(RailsuspInputError) as err:
        read_channel_map(path)
    assert str(err.value) == (
        f"{path}: wheels.w1L: unexpected key(s) 'recording' ('recording' belongs at the top "
        "level: write top-level keys before the first [table]); accepted exactly the keys Y "
        "and Q (channel names), and optionally Y_sign (1 or -1)"
    )
    with pytest.raises(RailsuspInputError, match=r"wheels.w1R: no key Q; unexpected key\(s\) 'q';"):
        channel_map_from({"speed": "v", "wheels": {"w1R": {"Y": "a", "q": "b"}}})


def _forces_of_spans(path, spans):
    """A run whose force channels each have their own (rate Hz, seconds), in a group of
    their own; speed and distance at 10 Hz over 20 s."""
    rng = np.random.default_rng(3)
    mdf = MDF(version="4.10")
    for name, (rate, seconds) in spans.items():
        t = np.arange(round(rate * seconds)) / rate
        mean = 120.0 if name.startswith("Q") else 5.0
        mdf.append([Signal(mean + rng.standard_normal(t.size), t, name=name, unit="kN")])
    ts = np.arange(0, 20.1, 0.1)
    return _with_speed_saved(mdf, path, ts)


def test_a_force_channel_beyond_the_fastest_ones_span_is_refused_not_dropped(tmp_path):
    """The bug hunt: the run is the fastest force channel's span, and one whose module
    stopped early cut a long run to its span without a word (the other force channels'
    rest dropped). Refused, naming both spans; speed and distance running longer are taken."""
    path = _forces_of_spans(tmp_path / "r.mf4", {"Y_R": (400.0, 6.0), "Q_R": (200.0, 20.0)})
    with pytest.raises(RecordingError) as err:
        read_run(path, channel_map_from(MAP))
    assert err.value.problems == [
        "channel 'Q_R': covers 0.000-19.995 s, beyond the 0.000-5.997 s of 'Y_R' (the "
        "forces' time base, the fastest): cut the file to the span every force channel covers"
    ]
    whole = _forces_of_spans(tmp_path / "ok.mf4", {"Y_R": (400.0, 20.0), "Q_R": (200.0, 20.0)})
    assert read_run(whole, channel_map_from(MAP)).time[-1] == pytest.approx(19.9975)


def test_the_time_base_of_force_channels_as_fast_is_the_longest_then_the_first_by_name():
    """Rates that differ by float noise alone chose the base by the noise; the same rate
    to 6 digits is a tie, broken by the samples (the most), then the name, whatever the
    map's order."""
    from railsusp.measured.run import time_base

    hz = {"Y_R": 200.0000001, "Q_R": 199.9999999}
    n = {"Y_R": 4000, "Q_R": 4000}
    assert time_base(["Y_R", "Q_R"], hz, hz, n) == "Q_R" == time_base(["Q_R", "Y_R"], hz, hz, n)
    assert time_base(["Q_R", "Y_R"], hz, hz, {"Y_R": 4000, "Q_R": 3999}) == "Y_R"
    faster = {"Y_R": 400.0, "Q_R": 200.0}
    assert time_base(["Q_R", "Y_R"], faster, faster, n) == "Y_R"
    # the finite samples' rate first: a 400 Hz column of values in every second row is 200
    assert time_base(["Y_R", "Q_R"], {"Y_R": 200.0, "Q_R": 300.0}, faster, n) == "Q_R"


def _table(path, columns):
    """A 20 s table at 200 Hz: time_s, Y_w1R_kN, Q_w1R_kN, speed_kmh and ``columns``."""
    rng = np.random.default_rng(4)
    t = np.arange(4000) / 200.0
    frame = {
        "time_s": t,
        "Y_w1R_kN": 5.0 + rng.standard_normal(t.size),
        "Q_w1R_kN": 120.0 + rng.standard_normal(t.size),
        "speed_kmh": np.full(t.size, 54.0),
    }
    frame |= {c: f(t) for c, f in columns.items()}
    pd.DataFrame(frame).to_csv(path, index=False)
    return path


def test_a_quantity_in_two_columns_without_a_map_is_refused_naming_both(tmp_path):
    """The bug hunt: `Q_w1R_kN` beside `Q_w1R [N]` (or `speed_kmh` beside `speed [m/s]`) read
    without a map took the last column without a word, as the field reader does not."""
    path = _table(
        tmp_path / "twice.csv",
        {"Q_w1R [N]": lambda t: 100e3 + 0 * t, "speed [m/s]": lambda t: 50 / 3.6 + 0 * t,
         "distance_m": lambda t: 15.0 * t, "position_km": lambda t: 0.015 * t},
    )  # fmt: skip
    with pytest.raises(RecordingError) as err:
        read_run(path)
    assert err.value.problems == [
        f"column {c!r}: the {what} is given twice (also as {first!r}); accepted one column "
        "per quantity (or a channel map naming the one to use)"
        for c, what, first in (
            ("Q_w1R [N]", "force Q_w1R", "Q_w1R_kN"),
            ("speed [m/s]", "speed", "speed_kmh"),
            ("position_km", "position", "distance_m"),
        )
    ]
    run = read_run(_table(tmp_path / "once.csv", {"distance_m": lambda t: 15.0 * t}))
    assert run.speed.mean() == pytest.approx(15.0)


def test_a_negative_cant_channel_is_refused_when_the_run_is_read(tmp_path):
    """The bug hunt: a signed cant (-100 mm in a right-hand curve) passed check-recording
    and sections, and `sections --write` failed on the condition ("cant_mm = -100.0:
    accepted range [0, 200] mm"); the cant is the outer rail's height, its magnitude."""
    path = tmp_path / "c.csv"
    rng = np.random.default_rng(5)
    t = np.arange(4000) / 200.0
    pd.DataFrame(
        {"time_s": t, "Y_w1R_kN": 5.0 + rng.standard_normal(t.size),
         "Q_w1R_kN": 120.0 + rng.standard_normal(t.size), "speed_kmh": np.full(t.size, 54.0),
         "cant_mm": np.where(t > 10.0, -100.0, 0.0)}
    ).to_csv(path, index=False)  # fmt: skip
    with pytest.raises(RecordingError) as err:
        read_run(path)
    assert err.value.problems == [
        "channel 'cant_mm': cant down to -100 mm, negative; accepted 0 to 200 mm, the cant's "
        "magnitude (the outer rail's height above the inner's): a signed cant? give its "
        "magnitude"
    ]


def test_a_speed_channel_starting_after_the_forces_says_what_is_accepted(tmp_path):
    """A 10 Hz speed from a CAN bus whose first message came 0.5 s after the logger started
    was refused naming the spans alone ("not the 0.000-19.995 s of the forces"): neither
    what is accepted nor what to do."""
    rng = np.random.default_rng(0)
    t = np.arange(0, 20, 1 / 200)
    mdf = MDF(version="4.10")
    mdf.append(
        [
            Signal(5 + rng.standard_normal(t.size), t, name="Y_R", unit="kN"),
            Signal(120 + rng.standard_normal(t.size), t, name="Q_R", unit="kN"),
        ]
    )
    path = _with_speed_saved(mdf, tmp_path / "late.mf4", np.arange(0.5, 20.1, 0.1))
    with pytest.raises(RecordingError) as err:
        read_run(path, channel_map_from(MAP))
    assert err.value.problems[0] == (
        "channel 'v': covers 0.500-20.000 s, not the 0.000-19.995 s of the forces; accepted "
        "a channel covering their span to within 0.125 s at either end (its sampling interval "
        "and jitter): cut the file to the span every used channel covers"
    )
