"""The Python API's checks found missing by stop 61's audit: a configuration object changed
with ``model_copy`` ran four stages before its bad value failed, an empty dict ran the
whole default, a run's recorded configuration could not run again, an empty key-parameter
list was silently replaced, and several objects took wrong types to a traceback later."""

import json
from pathlib import Path

import numpy as np
import pytest

import railsusp
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured import Recording, read_recording
from railsusp.pipeline import PipelineConfig, load_config

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_a_configuration_changed_with_model_copy_is_checked_before_any_stage(tmp_path):
    cfg = load_config(EXAMPLES / "tiny.toml")
    bad = cfg.model_copy(update={"estimate": cfg.estimate.model_copy(update={"pop_size": 2})})
    with pytest.raises(RailsuspInputError, match=r"estimate.pop_size = 2: accepted \[4, 10000\]"):
        railsusp.run(bad, out=tmp_path / "run")
    assert not (tmp_path / "run" / "pipeline.json").exists()  # no stage ran
    few = cfg.model_copy(update={"campaign": cfg.campaign.model_copy(update={"samples": 3})})
    with pytest.raises(RailsuspInputError, match="campaign.samples"):
        railsusp.run(few, out=tmp_path / "run")


def test_an_empty_configuration_dict_is_refused_like_an_empty_file(tmp_path):
    with pytest.raises(RailsuspInputError, match="configuration: an empty dict; accepted at"):
        railsusp.run({}, out=tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_a_runs_recorded_configuration_runs_again(tmp_path):
    """pipeline.json writes every field, defaults included; the checks took a present
    field.noise/seed (or conditions) for the user's and refused the record."""
    from railsusp.config import check_config
    from railsusp.input_checks import validate_document

    field = tmp_path / "field"
    t = np.arange(400) / 50.0
    rec = Recording(t, {"w1R": 5.0 + np.cos(t)}, {"w1R": 120.0 + np.sin(t)},
                    get_condition("straight", duration_s=8.0, n_steps=400))  # fmt: skip
    rec.write(field / "straight.csv")
    (field / "index.json").write_text(json.dumps({"recordings": ["straight.csv"]}))
    cfg = validate_document(PipelineConfig, {"field": {"measured": str(field)}})
    check_config(cfg)
    again = validate_document(PipelineConfig, cfg.model_dump(mode="json"))
    check_config(again)  # refused before: "field.noise and field.seed set ..."
    noisy = validate_document(PipelineConfig, {"field": {"measured": str(field), "noise": 0.1}})
    with pytest.raises(RailsuspInputError, match="field.noise set the synthetic"):
        check_config(noisy)


def test_a_sensitivity_that_keeps_no_parameter_stops_the_run_and_says_why(tmp_path):
    from railsusp.store import write_json
    from railsusp.surrogate import key_parameters

    write_json(
        tmp_path / "sensitivity" / "key_parameters.json",
        {"key_parameters": {"keys": [], "threshold": 0.99, "max_st": {"X13": 0.41, "X18": 0.6}}},
    )
    with pytest.raises(
        RailsuspInputError,
        match=r"kept no key parameter: no total Sobol index reached sensitivity.threshold = "
        r"0.99 \(the largest: X18 0.6\); lower the threshold",
    ):
        key_parameters(tmp_path)


def test_a_pipeline_config_takes_condition_objects_and_paths():
    cfg = PipelineConfig(conditions=[get_condition("straight", duration_s=2.0)], wagon=Path("w"))
    assert cfg.wagon == "w"
    assert cfg.working_conditions()[0] == get_condition("straight", duration_s=2.0)


def test_wrong_types_are_one_line_errors_naming_the_argument(tmp_path):
    with pytest.raises(RailsuspInputError, match=r"tolerances = \{'X13': 20\}: a railsusp"):
        railsusp.RunResult(tmp_path, tolerances={"X13": 20})
    t = np.arange(400) / 50.0
    rec = Recording(t, {"w1R": 5.0 + np.cos(t)}, {"w1R": 120.0 + np.sin(t)},
                    get_condition("straight", duration_s=8.0, n_steps=400))  # fmt: skip
    rec.write(tmp_path / "r.csv")
    with pytest.raises(RailsuspInputError, match="wagon = 5: a wagon file"):
        read_recording(tmp_path / "r.csv", wagon=5)
    from railsusp.vehicle.setup import SolverSettings

    with pytest.raises(RailsuspInputError, match="flange_substeps = True: accepted an integer"):
        SolverSettings(flange_substeps=True)


def test_small_things_of_the_api():
    assert {"run", "open_run", "RunResult", "Tolerances"} <= set(dir(railsusp))
    a, b = railsusp.Tolerances(20, {"X13": 10}), railsusp.Tolerances(20, {"X13": 10})
    assert a == b and hash(a) == hash(b)
    # a failing stage says how to resume in the caller's own terms
    from railsusp.pipeline import _resume as resume

    assert resume("--from", "estimate") == "--from estimate"
    assert resume("start_from", "estimate") == "start_from='estimate'"
