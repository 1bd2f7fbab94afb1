"""A long run's reader's refusals as the QA of stop 68 found them worded: a run whose every
force channel misses the sections' rate is told so (not "too slow to interpolate" against a
channel as fast as itself), a constant channel's value is given in the file's unit, and a
channel map's stray key in a wheel's table is named."""

import numpy as np
import pytest
from asammdf import MDF, Signal

from railsusp.errors import RailsuspInputError
from railsusp.measured import RecordingError
from railsusp.measured.channels import channel_map_from, read_channel_map
from railsusp.measured.run import read_run
from railsusp.measured.run_checks import check_force_rates

MAP = {"speed": "v", "position": "s", "wheels": {"w1R": {"Y": "Y_R", "Q": "Q_R"}}}


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
    mdf.append(
        [Signal(np.full(ts.size, 54.0), ts, name="v", unit="km/h"),
         Signal(15.0 * ts, ts, name="s", unit="m")]
    )  # fmt: skip
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


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
