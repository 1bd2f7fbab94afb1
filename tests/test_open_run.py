"""railsusp.open_run on runs that did not end well: a stage that failed after an earlier run
finished, files changed since, a damaged stage table; the tolerances a run recorded."""

import json
import shutil
import tomllib
from pathlib import Path

import pytest

import railsusp
import test_pipeline
from railsusp.errors import RailsuspInputError
from railsusp.pipeline import STAGES, StageError, load_config, run_pipeline
from railsusp.suspension_tolerances import Tolerances

TINY, _up_to_date_copy = test_pipeline.TINY, test_pipeline._up_to_date_copy
tiny = test_pipeline.tiny  # the tiny pipeline run, this module's own (module scope)


def _fail_estimate(monkeypatch):
    from railsusp.estimate.route import EstimateRoute

    def failing(*args, **kwargs):
        raise RailsuspInputError("surrogates/bp: no bundle")

    monkeypatch.setattr(EstimateRoute, "run", failing)


def test_a_failed_rerun_leaves_no_stale_answer(tiny, tmp_path, monkeypatch):
    """The audit of stop 58: a rerun with another truth whose estimate stage failed left
    validate and report 'done' in pipeline.json, and open_run served the earlier run's
    estimate, recovery and report as if they were this run's."""
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    before = railsusp.open_run(copy)
    assert before.estimate.loc["X13", "estimate"] > 0 and before.recovery is not None
    changed = tmp_path / "changed.toml"
    changed.write_text(TINY.replace("truth = { X13 = 16.1 }", "truth = { X13 = 9.0 }"))
    _fail_estimate(monkeypatch)
    with pytest.raises(StageError, match="stage 'estimate' failed"):
        run_pipeline(load_config(changed), copy)
    result = railsusp.open_run(copy)
    states = result.stages.set_index("stage")["state"].to_dict()
    assert list(result.stages["stage"]) == list(STAGES)  # in the pipeline's order
    assert states == {
        "campaign": "done",
        "sensitivity": "done",
        "surrogate": "done",
        "field": "done",
        "estimate": "failed",
        "validate": "stale",
        "report": "stale",
    }
    assert "surrogates/bp: no bundle" in result.stages.set_index("stage").loc["estimate", "error"]
    with pytest.raises(RailsuspInputError, match="estimate stage failed .*no bundle.*older run"):
        _ = result.estimate
    for attribute in ("validation", "agreement", "recovery"):
        with pytest.raises(RailsuspInputError, match="validate stage is stale"):
            getattr(result, attribute)
    with pytest.raises(RailsuspInputError, match="report stage is stale"):
        _ = result.report_path
    assert result.key_parameters == before.key_parameters  # earlier stages still read
    monkeypatch.undo()
    run_pipeline(load_config(changed), copy)  # the rerun brings every stage up to date
    assert set(railsusp.open_run(copy).stages["state"]) == {"done"}
    assert railsusp.open_run(copy).recovery is not None


def test_an_interrupted_stage_and_changed_files_are_refused(tiny, tmp_path):
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    state_path = copy / "pipeline.json"
    state = json.loads(state_path.read_text())
    state["stages"]["validate"]["state"] = "running"  # killed while validating
    state_path.write_text(json.dumps(state))
    with pytest.raises(RailsuspInputError, match="validate stage was interrupted"):
        _ = railsusp.open_run(copy).validation
    state["stages"]["validate"]["state"] = "done"
    state_path.write_text(json.dumps(state))
    est = copy / "estimate" / "estimate.json"
    est.write_text("{}")  # another tool wrote over it
    with pytest.raises(RailsuspInputError, match="estimate.json changed or is gone since"):
        _ = railsusp.open_run(copy).estimate
    (copy / "estimate" / "validation" / "recovery.csv").unlink()
    with pytest.raises(RailsuspInputError, match="no estimate/validation/recovery.csv"):
        _ = railsusp.open_run(copy).recovery  # synthetic recordings: missing, not "measured"
    state["stages"]["campaign"] = "done"
    state_path.write_text(json.dumps(state))
    with pytest.raises(RailsuspInputError, match=r"stages.campaign = 'done': a table"):
        _ = railsusp.open_run(copy).stages


def test_a_table_made_from_a_changed_input_stage_is_refused(tiny, tmp_path):
    """QA of stop 73: with a recording of the field stage edited since, ``report_path``
    was refused and ``railsusp run`` made field, estimate and validate again, but
    ``estimate``, ``validation``, ``recovery`` and ``agreement`` were read as this run's.
    And a validation removed by a command run on the folder since (a standalone estimate
    into RUN/estimate drops it) was said never to have run."""
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    result = railsusp.open_run(copy)
    _ = result.sensitivity  # reads nothing of the field stage: unaffected below
    recording = sorted((copy / "field").glob("*.csv"))[0]
    lines = recording.read_text().splitlines()
    cells = lines[2].split(",")
    cells[1] = "99.0"  # a measured force edited in place
    recording.write_text("\n".join([*lines[:2], ",".join(cells), *lines[3:]]) + "\n")
    for table in ("estimate", "validation", "recovery", "agreement"):
        with pytest.raises(
            RailsuspInputError,
            match=rf"field/{recording.name} changed or is gone since the field stage wrote it.*"
            r"was made from that stage's outputs, so it is not this run's answer either",
        ):
            getattr(railsusp.open_run(copy), table)
    _ = railsusp.open_run(copy).sensitivity
    _, _, again = _up_to_date_copy(tiny, tmp_path / "again")
    (again / "estimate" / "validation" / "validation.csv").unlink()
    with pytest.raises(
        RailsuspInputError,
        match="no estimate/validation/validation.csv; it is gone although pipeline.json "
        "records the stage done",
    ):
        _ = railsusp.open_run(again).validation


def test_open_run_judges_with_the_tolerances_the_run_recorded(tmp_path, monkeypatch):
    """A relative wagon path in the configuration was read again from open_run's working
    folder: another folder's wagon.toml re-judged every verdict, none failed it."""
    wagon = (Path(railsusp.__file__).parent / "data" / "c80_k6.toml").read_text()
    first, second = tmp_path / "a", tmp_path / "b"
    first.mkdir(), second.mkdir()
    (first / "wagon.toml").write_text(wagon + "\n[tolerances]\ndefault_pct = 50.0\n")
    (second / "wagon.toml").write_text(wagon + "\n[tolerances]\ndefault_pct = 5.0\n")
    cfg = tomllib.loads(TINY)
    cfg["wagon"] = "wagon.toml"
    monkeypatch.chdir(first)
    run = tmp_path / "run"
    assert set(railsusp.run(cfg, out=run).estimate["tolerance_pct"]) == {50.0}
    monkeypatch.chdir(second)
    assert set(railsusp.open_run(run).estimate["tolerance_pct"]) == {50.0}
    shutil.rmtree(second)
    monkeypatch.chdir(tmp_path)
    assert set(railsusp.open_run(run).estimate["tolerance_pct"]) == {50.0}
    recorded = json.loads((run / "pipeline.json").read_text())["tolerances"]
    assert recorded == {"default_pct": 50.0, "parameters": {}, "from_wagon": True}


def test_tolerances_of_takes_a_name_and_refuses_what_is_not_a_parameter():
    tol = Tolerances(10.0, {"X13": 5.0})
    assert tol.of("primary_longitudinal_stiffness") == tol.of("X13") == 5.0
    assert tol.of("X14") == 10.0
    with pytest.raises(RailsuspInputError, match="X99.*main suspension parameter"):
        tol.of("X99")
    assert Tolerances.from_dict(tol.to_dict()) == tol
    with pytest.raises(RailsuspInputError, match="accepted a table of default_pct"):
        Tolerances.from_dict({"default_pct": 10.0})
