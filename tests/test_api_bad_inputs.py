"""Bad input to the Python API (a read-only fuzzing pass of stop 54 found each of these): a
one-line RailsuspInputError naming the argument, before any work, and no user file lost.
Before, each was a bare AttributeError / IndexError / ZeroDivisionError, silent nonsense
(NaN forces from an out-of-range fixed parameter, a negative tolerance) or, for ``run``
into a folder of the user's files, their report.html overwritten."""

from __future__ import annotations

import json

import numpy as np
import pytest

import railsusp
from railsusp.conditions import get_condition
from railsusp.errors import ParameterError, RailsuspInputError
from railsusp.measured import read_recording
from railsusp.params import ParameterSet
from railsusp.suspension_tolerances import Tolerances
from railsusp.vehicle.simulate import simulate, simulate_batch, simulate_conditions
from test_measured import make_recording

COND = get_condition("straight", duration_s=1.0, n_steps=50)
CFG = {"conditions": [{"base": "straight", "name": "s", "duration_s": 1.0, "n_steps": 50}]}


def one_line(exc_info) -> str:
    text = str(exc_info.value)
    assert "\n" not in text
    return text


def test_run_never_writes_into_a_folder_of_other_files(tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "report.html").write_text("MY OWN REPORT")
    with pytest.raises(RailsuspInputError) as info:
        railsusp.run(CFG, out=mine)
    assert "out " in one_line(info) and "a folder holding other files and no pipeline.json" in (
        str(info.value)
    )
    assert (mine / "report.html").read_text() == "MY OWN REPORT"
    assert sorted(p.name for p in mine.iterdir()) == ["report.html"]


@pytest.mark.parametrize("state", [{"name": "my CI pipeline"}, [1, 2], {"stages": []}])
def test_run_and_open_run_refuse_a_foreign_pipeline_json(tmp_path, state):
    (tmp_path / "pipeline.json").write_text(json.dumps(state))
    with pytest.raises(RailsuspInputError, match="pipeline.json is not a railsusp run's"):
        railsusp.run(CFG, out=tmp_path)
    with pytest.raises(RailsuspInputError, match="pipeline.json is not a railsusp run's"):
        railsusp.open_run(tmp_path)
    assert json.loads((tmp_path / "pipeline.json").read_text()) == state


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"out": 5}, "out = 5: a folder path"),
        ({"progress": 5}, "progress = 5: a function"),
        ({"start_from": "campain"}, "start_from 'campain': accepted"),
    ],
)
def test_run_names_its_python_arguments(tmp_path, kwargs, needle):
    out = tmp_path / "run"
    with pytest.raises(RailsuspInputError) as info:
        railsusp.run(CFG, **{"out": out, **kwargs})
    assert needle in one_line(info)
    assert not out.exists()


def test_run_of_a_dict_with_a_key_that_is_not_text_is_an_input_error(tmp_path):
    with pytest.raises(RailsuspInputError, match="configuration: "):
        railsusp.run({1: 2}, out=tmp_path / "run")


def test_open_run_checks_its_arguments(tmp_path):
    with pytest.raises(RailsuspInputError, match="path = None"):
        railsusp.open_run(None)
    (tmp_path / "pipeline.json").write_text('{"stages": {}}')
    with pytest.raises(RailsuspInputError, match="tolerances = {'X13': 20}: a railsusp.Tol"):
        railsusp.open_run(tmp_path, tolerances={"X13": 20})


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        ((-5,), "tolerances.default_pct = -5: accepted a number in (0, 100]"),
        ((float("nan"),), "tolerances.default_pct = nan"),
        ((10, {"X99": 5}), "tolerances.X99: accepted a main suspension parameter (X11"),
        ((10, {"X13": 0}), "tolerances.X13 = 0: accepted a number in (0, 100]"),
        ((10, [("X13", 5)]), "a mapping {symbol: %} is needed, not list"),
    ],
)
def test_tolerances_are_checked(args, needle):
    with pytest.raises(RailsuspInputError) as info:
        Tolerances(*args)
    assert needle in one_line(info)


def test_tolerances_take_names_and_any_case_as_symbols():
    assert Tolerances(10, {"x13": 5}).of("X13") == 5.0
    named = Tolerances(10, {"primary_longitudinal_stiffness": 7})
    assert named.of("X13") == 7.0 and named.of("X14") == 10.0
    with pytest.raises(RailsuspInputError, match="tolerances.x13: X13 is given twice"):
        Tolerances(10, {"X13": 5, "x13": 6})


M2 = np.array([[16.1e6, 8.3e6]])


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda: simulate_batch(M2, COND), "a matrix of shape (1, 2) without symbols="),
        (lambda: simulate({"X13": 16.1e6}, COND), "params: a dict is not a ParameterSet"),
        (lambda: simulate_batch([[16.1e6, 8.3e6]], COND), "is not a ParameterSet"),
        (lambda: simulate_batch({"X13": 1.0}, COND), "sets: a dict is not a parameter set"),
        (lambda: simulate_conditions(M2, COND, symbols=["X13", "X14"]), "accepted a list of"),
        (lambda: simulate(None, "curve"), "condition 'curve': a WorkingCondition is needed"),
        (lambda: simulate(None, COND, wagon=5), "wagon = 5: accepted a WagonData"),
        (lambda: simulate(None, COND, settings={"dt": 1}), "settings = {'dt': 1}: accepted"),
        (lambda: simulate_batch(np.empty((0, 2)), COND, symbols=["X13", "X14"]), "empty"),
        (lambda: simulate_batch(M2, COND, symbols=["X13", "X14"], seeds=3), "seeds = 3"),
        (lambda: simulate_batch(M2, COND, symbols=["X13", "X14"], seeds=[1.5]), "integers"),
        (lambda: simulate_batch(M2, COND, symbols=["X13", "X13"]), "X13 given twice"),
        (lambda: simulate_batch(np.array([[1e9]]), COND, symbols=["X1"]), "X1 "),
        (lambda: simulate_batch(M2, COND, symbols="X13"), "symbols = 'X13'"),
    ],
)
def test_the_simulators_entry_points_refuse_notebook_mistakes(call, needle):
    with pytest.raises(RailsuspInputError) as info:
        call()
    assert needle in one_line(info)


def test_an_out_of_range_fixed_parameter_in_a_matrix_is_refused_as_in_a_set():
    """Before: simulate_batch ran X1 = 1e9 kg into a penetration failure with NaN forces."""
    with pytest.raises(ParameterError) as a:
        simulate_batch(np.array([[1e9]]), COND, symbols=["X1"])
    with pytest.raises(ParameterError) as b:
        ParameterSet({"X1": 1e9})
    assert str(a.value) == f"row 0: {b.value}"


def test_a_wagon_file_is_taken_where_a_wagon_goes(tmp_path):
    from importlib import resources

    p = tmp_path / "w.toml"
    p.write_text(resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8"))
    a = simulate(None, COND, wagon=p)
    assert a.Q.shape[0] == 1 and np.isfinite(a.Q).all()


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda: ParameterSet([("X13", 16.1)]), "a mapping {symbol: value} is needed, not list"),
        (lambda: ParameterSet("X13=16.1"), "a mapping {symbol: value} is needed, not str"),
        (lambda: ParameterSet({13: 16.1}), "parameter 13: a symbol or name"),
        (lambda: ParameterSet().replace({"X13": "abc"}, units="display"), "X13 ("),
        (lambda: ParameterSet().replace({"X13": np.ones(2)}), "is not a number"),
        (lambda: ParameterSet().replace({"X13": 16.1}, units="MN/m"), "units must be 'si' or"),
    ],
)
def test_parameter_sets_name_the_mistake(call, needle):
    with pytest.raises(ParameterError) as info:
        call()
    assert needle in one_line(info)


def test_with_duration_takes_numpy_scalars():
    c = get_condition("curve").with_duration(np.float32(4.0))
    assert c.duration_s == 4.0 and isinstance(c.duration_s, float)
    with pytest.raises(RailsuspInputError, match="duration_s = 0.5"):
        get_condition("curve").with_duration(np.float64(0.5))


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"wheel_load_N": 0.0}, "wheel_load_N = 0.0: accepted a static wheel load"),
        ({"wheel_load_N": -1.0}, "wheel_load_N = -1.0"),
        ({"min_rate_hz": -1}, "min_rate_hz = -1: accepted 1 to 100000 Hz"),
        ({"min_rate_hz": float("nan")}, "min_rate_hz = nan"),
        ({"min_rate_hz": "50"}, "min_rate_hz = '50'"),
    ],
)
def test_read_recording_checks_its_arguments(tmp_path, kwargs, needle):
    p = make_recording(200, 100.0).write(tmp_path / "rec")
    with pytest.raises(RailsuspInputError) as info:
        read_recording(p, **kwargs)
    assert needle in one_line(info)


def test_a_new_run_may_go_into_a_folder_of_hidden_files_and_its_configuration(tmp_path):
    from railsusp.pipeline_state import run_state

    (tmp_path / ".gitkeep").write_text("")
    (tmp_path / "study.toml").write_text("")
    assert run_state(tmp_path, "--out") == {"stages": {}}
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(RailsuspInputError, match="--out .*: a folder holding other files"):
        run_state(tmp_path, "--out")


def test_the_command_line_names_its_option_for_a_folder_of_other_files(tmp_path):
    from typer.testing import CliRunner

    from railsusp.cli import app

    cfg = tmp_path / "c.toml"
    cfg.write_text('conditions = [{base = "straight", name = "s", duration_s = 1.0}]\n')
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "report.html").write_text("MY OWN REPORT")
    result = CliRunner().invoke(app, ["run", str(cfg), "--out", str(mine)])
    assert result.exit_code == 2 and "--out" in result.output and "other files" in result.output
    assert (mine / "report.html").read_text() == "MY OWN REPORT"


def test_numpy_values_in_a_python_configuration_are_numbers():
    """Strictness is for files; a notebook's NumPy scalars are numbers as before."""
    from railsusp.pipeline_config import PipelineConfig

    cond = {"base": "curve", "name": "c", "seed": np.int64(3), "speed_kmh": np.float32(60)}
    cfg = PipelineConfig.model_validate({"conditions": [cond]})
    (c,) = cfg.working_conditions()
    assert c.seed == 3 and c.speed_kmh == 60.0
    assert Tolerances(np.int64(10)).default_pct == 10.0


def test_numpy_arguments_of_read_recording_and_path_likes_of_open_run(tmp_path):
    import os

    p = make_recording(200, 100.0).write(tmp_path / "rec")
    assert read_recording(p, min_rate_hz=np.float32(50), wheel_load_N=np.float32(1e5)).wheels

    class Where(os.PathLike):
        def __fspath__(self):
            return str(tmp_path)

    (tmp_path / "pipeline.json").write_text('{"stages": {}}')
    assert railsusp.open_run(Where()).path == tmp_path.resolve()


def test_tolerances_of_a_key_that_is_no_parameter_say_what_is_accepted():
    with pytest.raises(RailsuspInputError) as info:
        Tolerances(10, {"default_pct": 5})
    assert "tolerances.default_pct: accepted a main suspension parameter" in one_line(info)


def test_ragged_rows_are_an_input_error():
    with pytest.raises(RailsuspInputError, match="sets: not a matrix of numbers"):
        simulate_batch([[16.1e6, 8.3e6], [16.1e6]], COND, symbols=["X13", "X14"])


def test_an_empty_table_in_a_run_directory_is_an_input_error(tmp_path):
    """Before: pandas' EmptyDataError from .validation and .agreement."""
    (tmp_path / "pipeline.json").write_text('{"stages": {}}')
    table = tmp_path / "estimate" / "validation" / "validation.csv"
    table.parent.mkdir(parents=True)
    table.write_text("")
    result = railsusp.open_run(tmp_path)
    for name in ("validation", "agreement"):
        with pytest.raises(RailsuspInputError, match="validation.csv: not a readable table"):
            getattr(result, name)


def test_a_run_directory_that_lost_its_pipeline_json_resumes_and_a_lookalike_does_not(tmp_path):
    """The kill/resume pass (stop 54): a deleted pipeline.json read as 'a folder holding
    other files'. A folder of the stages' own outputs with its campaign.json resumes; a
    report.html of the user's, or any other file beside, is still refused."""
    from railsusp.pipeline_state import run_state

    (tmp_path / "campaign").mkdir()
    (tmp_path / "report.html").write_text("MY OWN REPORT")
    with pytest.raises(RailsuspInputError, match="a folder holding other files"):
        run_state(tmp_path, "--out")  # no campaign.json of railsusp's
    (tmp_path / "campaign" / "campaign.json").write_text('{"kind": "railsusp campaign"}')
    assert run_state(tmp_path, "--out") == {"stages": {}}
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(RailsuspInputError, match="a folder holding other files"):
        run_state(tmp_path, "--out")
