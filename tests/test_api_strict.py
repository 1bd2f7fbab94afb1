"""The Python API converts nothing silently (the bad-input audit of stop 58 found each of these
accepted or a bare traceback): numbers given as text are refused by ParameterSet, the
conditions and the simulator; a failed set's NaN statistics come with a warning; a result's
set and wheel indices are checked; to_parquet leaves no temporary file."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from railsusp.conditions import get_condition, make_condition
from railsusp.errors import ConditionError, ParameterError, RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle.simulate import simulate, simulate_batch

COND = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
#: a curve of 50 m at 120 km/h without cant: every wagon derails within a second
DERAILING = {
    "curve_radius_m": 50.0,
    "speed_kmh": 120.0,
    "cant_mm": 0.0,
    "duration_s": 2.0,
    "n_steps": 100,
    "lead_in_m": 80.0,
    "entry_spiral_m": 10.0,
    "exit_spiral_m": 10.0,
}


def one_line(info) -> str:
    text = str(info.value)
    assert "\n" not in text
    return text


@pytest.mark.parametrize(
    "call",
    [
        lambda: ParameterSet({"X13": "16.1"}, units="display"),
        lambda: ParameterSet({"X13": " 1.61e7 "}),
        lambda: ParameterSet({"X13": b"16.1"}, units="display"),
        lambda: ParameterSet().replace({"X13": "16.1"}, units="display"),
    ],
)
def test_a_parameter_given_as_text_is_refused_not_converted(call):
    with pytest.raises(ParameterError) as info:
        call()
    assert "X13 (primary longitudinal stiffness" in one_line(info)
    assert "is not a number; accepted range [7, 21] MN/m" in str(info.value)


def test_numpy_numbers_are_numbers_and_the_set_keeps_the_mapping_contract():
    p = ParameterSet({"X13": np.float32(16.1), "X14": np.int64(8)}, units="display")
    assert p.display("X13") == pytest.approx(16.1, rel=1e-6) and p.display("X14") == 8.0
    assert "X13" in p and "primary_longitudinal_stiffness" in p
    assert 13 not in p and "X99" not in p
    assert p.get("X99", 0.0) == 0.0 and p.get("x13") == p["X13"]
    with pytest.raises(ParameterError, match="parameter 13: a symbol or name"):
        p[13]


@pytest.mark.parametrize(
    ("changes", "needle"),
    [
        ({"speed_kmh": "80"}, "speed_kmh = '80': a number is needed, not a string"),
        ({"n_steps": "500"}, "n_steps = '500': a whole number is needed"),
        ({"seed": "3"}, "seed = '3': a whole number is needed"),
        ({"irregularity_class": "4"}, "irregularity_class = '4'"),
        ({"n_steps": 500.5}, "n_steps = 500.5: a whole number is needed"),
    ],
)
def test_condition_fields_given_in_python_are_read_as_strictly_as_a_files(changes, needle):
    for call in (
        lambda: get_condition("straight", **changes),
        lambda: get_condition("straight").with_changes(**changes),
        lambda: make_condition({"name": "c", **changes}),
    ):
        with pytest.raises(ConditionError) as info:
            call()
        assert needle in one_line(info)


def test_get_condition_renames_as_the_api_page_shows_and_takes_numpy_values():
    c = get_condition("straight", speed_kmh=80, name="straight80")
    assert (c.name, c.speed_kmh) == ("straight80", 80.0)
    d = get_condition("curve", speed_kmh=np.float64(70.0), seed=np.int64(4))
    assert (d.speed_kmh, d.seed) == (70.0, 4)
    for fields in (None, [("speed_kmh", 80)]):
        with pytest.raises(ConditionError, match="a mapping {field: value} is needed"):
            make_condition(fields)


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (
            lambda: simulate_batch([["1.61e7", "8.3e6"]], COND, symbols=["X13", "X14"]),
            "sets: a matrix of text; accepted real numbers (SI), not converted",
        ),
        (
            lambda: simulate_batch(np.array([[1.4e7 + 5j, 8e6]]), COND, symbols=["X13", "X14"]),
            "sets: a matrix of complex numbers",
        ),
        (lambda: simulate_batch(None, COND), "sets: a NoneType is not a parameter set"),
        (lambda: simulate(None, COND, progress=5), "progress = 5: accepted a function"),
        (lambda: simulate(None, COND, chunk_size=0), "chunk_size = 0: accepted a whole number"),
        (lambda: simulate(None, COND, chunk_size="4"), "chunk_size = '4'"),
    ],
)
def test_the_simulator_refuses_text_complex_numbers_and_bad_options(call, needle):
    with pytest.raises(RailsuspInputError) as info:
        call()
    assert needle in one_line(info)


@pytest.fixture(scope="module")
def result():
    return simulate(None, COND)


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda r: r.statistics(set_index=5), "set_index = 5: accepted a whole number 0..0"),
        (lambda r: r.statistics(set_index="0"), "set_index = '0'"),
        (lambda r: r.to_dataframe(5), "set_index = 5"),
        (lambda r: r.statistics(wheel=True), "measured wheel True: accepted 'auto'"),
        (lambda r: r.statistics(wheel=9), "measured wheel index 9 outside 0..7"),
    ],
)
def test_a_results_set_and_wheel_are_checked(result, call, needle):
    with pytest.raises(RailsuspInputError) as info:
        call(result)
    assert needle in one_line(info)


def test_a_numpy_wheel_index_is_the_same_wheel(result):
    assert result.statistics(wheel=np.int64(1)) == result.statistics(wheel=1)


def test_to_parquet_into_a_folder_is_refused_and_leaves_nothing(result, tmp_path):
    folder = tmp_path / "outdir"
    folder.mkdir()
    with pytest.raises(RailsuspInputError, match="is a folder, not a file"):
        result.to_parquet(folder)
    assert sorted(os.listdir(tmp_path)) == ["outdir"] and not os.listdir(folder)
    written = result.to_parquet(tmp_path / "x.parquet")
    assert sorted(os.listdir(tmp_path)) == ["outdir", "x.parquet"] and written.stat().st_size
    import pandas as pd

    back = pd.read_parquet(written)
    assert np.allclose(back["Q_w1L_kN"].to_numpy(), result.Q[0, 0] / 1e3)


def test_a_failed_sets_nan_statistics_come_with_a_warning():
    """A derailing set's series are NaN from the start; its statistics were NaN without a
    word (the command line's table says so in its status column)."""
    failed = simulate(None, get_condition("curve", **DERAILING))
    assert not failed.ok[0]
    with pytest.warns(RuntimeWarning, match=r"set 0 failed \(.*derailment.* at .* s\)"):
        stats = failed.statistics()
    assert np.isnan(stats["Y_mean"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a set that ran gives no warning
        simulate(None, COND).statistics()


def test_a_campaign_whose_every_run_fails_stops_the_sensitivity_in_one_line(tmp_path):
    """Every simulation of a curve of 50 m at 120 km/h derails: the campaign stage finished,
    then the sensitivity stage failed with sklearn's "Found array with 0 sample(s)"."""
    import railsusp
    from railsusp.pipeline import StageError

    cfg = {
        "conditions": [{"base": "curve", "name": "tight", **DERAILING}],
        "campaign": {"samples": 6, "batch_size": 6, "parameters": ["X13", "X14"]},
    }
    with pytest.raises(StageError) as info:
        railsusp.run(cfg, out=tmp_path / "run")
    text = one_line(info)
    assert "stage 'sensitivity' failed" in text
    assert "condition 'tight': 0 of 6 simulations ran through (6 failed" in text
    assert "check the condition (speed against curve radius and cant)" in text


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda: ParameterSet.from_toml(None), "parameter file None: a path (str or Path)"),
        (lambda: ParameterSet.from_toml(5), "parameter file 5: a path"),
        (lambda: ParameterSet.from_toml("/nonexistent/x"), "/nonexistent/x does not exist"),
        (lambda: __import__("railsusp").parse_overrides(None), "overrides None: accepted text"),
        (lambda: __import__("railsusp").parse_overrides([1]), "overrides [1]: accepted text"),
    ],
)
def test_parameter_files_and_overrides_name_what_they_accept(call, needle):
    with pytest.raises(ParameterError) as info:
        call()
    assert needle in one_line(info)
    assert ParameterSet.from_toml("X13 = 16.1").display("X13") == 16.1  # text still read


def test_overrides_from_a_generator_are_read_once():
    from railsusp import parse_overrides

    assert parse_overrides(f"X1{i}=8.{i}" for i in (3, 4)) == {"X13": 8.3, "X14": 8.4}


def test_recordings_paths_rates_and_solver_settings_are_checked(tmp_path):
    from railsusp.measured import read_recording
    from railsusp.vehicle.setup import SolverSettings
    from test_measured import make_recording

    for bad in (None, 5):
        with pytest.raises(RailsuspInputError, match=f"path = {bad}: a recording's path"):
            read_recording(bad)
    rec = make_recording()
    rec.write(tmp_path / "up.csv")
    (tmp_path / "up.csv").rename(tmp_path / "up.CSV")  # a Windows tool's capitals
    assert np.allclose(read_recording(tmp_path / "up.CSV").Q["w1L"], rec.Q["w1L"], atol=1e-6)
    for rate in ("100", 0, -50, float("nan"), 1e9):
        with pytest.raises(RailsuspInputError) as info:
            rec.resampled(rate)
        assert f"rate_hz = {rate!r}: accepted a number from 0.05 to 50000 Hz" in one_line(info)
    assert rec.resampled(100).sampling_rate == pytest.approx(100.0)
    with pytest.raises(RailsuspInputError, match="run_in_m = '60': accepted a finite number"):
        SolverSettings(start="settled", run_in_m="60")


def test_run_result_paths_plot_axes_and_a_dangling_link(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import railsusp

    assert railsusp.RunResult(str(tmp_path)).path == tmp_path
    with pytest.raises(RailsuspInputError, match="path = 5: a run directory"):
        railsusp.RunResult(5)
    for ax in ("x", [1]):
        with pytest.raises(RailsuspInputError, match="accepted one matplotlib Axes"):
            railsusp.run_result._check_axes(ax)
    link = tmp_path / "gone"
    link.symlink_to(tmp_path / "nowhere")
    with pytest.raises(RailsuspInputError) as info:
        railsusp.run({"conditions": ["straight"]}, out=link)
    assert "is a link to" in one_line(info) and "which does not exist" in str(info.value)


def test_a_sidecar_rate_of_nan_is_refused(tmp_path):
    """Python's json.dump writes NaN; the rate check compared it false and let it pass."""
    import json

    from railsusp.measured import read_recording
    from railsusp.measured.recording import RecordingError
    from test_measured import make_recording

    make_recording().write(tmp_path / "r.csv")
    side = tmp_path / "r.json"
    doc = json.loads(side.read_text())
    doc["sampling_rate_hz"] = float("nan")
    side.write_text(json.dumps(doc))
    with pytest.raises(RecordingError, match=r"sampling_rate_hz: nan: accepted a positive"):
        read_recording(tmp_path / "r.csv")
