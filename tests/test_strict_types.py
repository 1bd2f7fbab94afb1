"""Values of the wrong type in a file are refused, not converted (stop 53's fuzzing found
pydantic's lax mode turning ``samples = "10"`` into 10 and ``with_track = 1`` into true):
configuration, conditions, wagon and recording sidecar files are validated in strict mode
(:func:`railsusp.input_checks.validate_document`). An integer still stands for a float."""

from __future__ import annotations

from importlib import resources

import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.condition_files import load_conditions
from railsusp.conditions import ConditionError, WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.pipeline import load_config
from railsusp.vehicle.wagon import load_wagon

BASE = """
name = "t"
conditions = [{base="straight", name="short", duration_s=1.0, n_steps=50}]
[campaign]
samples = 10
[surrogate]
epochs = 4
[field]
truth = { X13 = 16.1 }
with_track = true
[estimate]
n_gen = 20
refine = true
"""


def _write(tmp_path, name: str, text: str):
    p = tmp_path / name
    p.write_text(text)
    return p


#: (text in BASE, its replacement, the error's words)
WRONG_TYPES = [
    (
        "samples = 10",
        'samples = "10"',
        'campaign.samples = "10": a whole number is needed, not a string (write it without quotes)',
    ),
    (
        "refine = true",
        'refine = "false"',
        'estimate.refine = "false": true or false is needed, not a string',
    ),
    (
        "with_track = true",
        "with_track = 1",
        "field.with_track = 1: true or false is needed, not an integer",
    ),
    (
        "n_gen = 20",
        "n_gen = 2.0",
        "estimate.n_gen = 2.0: a whole number is needed, not a float",
    ),
    ("epochs = 4", "epochs = 1979-05-27", 'surrogate.epochs = "1979-05-27": a whole number'),
    ("X13 = 16.1", 'X13 = "16.1"', 'field.truth.X13 = "16.1": a number is needed'),
    ("n_steps=50", 'n_steps="50"', "n_steps = '50': a whole number is needed, not a string"),
    ('name = "t"', "name = 5", "name = 5: a string is needed, not an integer"),
    ('name = "t"', 'name = "t"\nsensitivity = 5', "sensitivity = 5: a table is needed"),
]


@pytest.mark.parametrize(("old", "new", "needle"), WRONG_TYPES)
def test_a_configuration_value_of_the_wrong_type_is_refused(tmp_path, old, new, needle):
    assert old in BASE
    p = _write(tmp_path, "c.toml", BASE.replace(old, new))
    with pytest.raises(RailsuspInputError) as info:
        load_config(p)
    assert needle in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize(("old", "new", "needle"), WRONG_TYPES)
def test_a_dict_given_to_the_python_api_is_checked_as_strictly(tmp_path, old, new, needle):
    """api.md: a dict of the same sections as a TOML file. Before stop 56 it was validated
    in pydantic's lax mode: ``{"campaign": {"samples": "10"}}`` ran a whole pipeline of 10
    samples. The same values are now refused, in the same words, and nothing is written."""
    import tomllib

    import railsusp

    doc = tomllib.loads(BASE.replace(old, new))
    with pytest.raises(RailsuspInputError) as info:
        railsusp.run(doc, out=tmp_path / "run")
    assert needle in str(info.value) and "\n" not in str(info.value)
    assert str(info.value).startswith("configuration: ")
    assert not (tmp_path / "run").exists()


def test_a_dict_of_numpy_numbers_and_paths_is_still_accepted(tmp_path):
    """What a script builds: NumPy scalars and Path objects stand for the numbers, the
    booleans and the strings a file would hold."""
    import tomllib

    import numpy as np

    from railsusp.input_checks import validate_document
    from railsusp.pipeline_config import PipelineConfig

    doc = tomllib.loads(BASE)
    doc["campaign"]["samples"] = np.int64(10)
    doc["field"]["truth"]["X13"] = np.float32(16.0)
    doc["estimate"]["refine"] = np.bool_(True)
    doc["wagon"] = tmp_path / "w.toml"
    cfg = validate_document(PipelineConfig, doc)
    assert type(cfg.campaign.samples) is int and cfg.campaign.samples == 10
    assert cfg.field.truth == {"X13": 16.0} and cfg.estimate.refine is True
    assert cfg.wagon == str(tmp_path / "w.toml")


def test_a_dict_of_arrays_mappings_and_sections_reads_as_the_file_would(tmp_path):
    """The review of stop 56: values JSON cannot write were validated as their printed text
    (an array's '[1. 2.]', a section object's repr) and refused as strings, or a Decimal
    with advice about quotes; a tuple key was a TypeError traceback."""
    import tomllib
    from decimal import Decimal
    from types import MappingProxyType

    import numpy as np

    import railsusp
    from railsusp.config_sections import CampaignSection
    from railsusp.input_checks import validate_document
    from railsusp.pipeline_config import PipelineConfig

    doc = tomllib.loads(BASE)
    doc["campaign"] = CampaignSection(samples=10)
    doc["field"]["truth"] = MappingProxyType({"X13": np.float64(16.1)})
    doc["estimate"]["held_prior"] = {"X19": np.array([20000.0, 40000.0])}
    cfg = validate_document(PipelineConfig, doc)
    assert cfg.campaign.samples == 10 and cfg.field.truth == {"X13": 16.1}
    assert cfg.estimate.held_prior == {"X19": [20000.0, 40000.0]}
    for value, needle in (
        ({"X13": Decimal("16.1")}, "configuration: a Decimal (Decimal('16.1')) where a number"),
        ({("X13",): 16.1}, "configuration: keys must be str"),
    ):
        bad = tomllib.loads(BASE)
        bad["field"]["truth"] = value
        with pytest.raises(
            RailsuspInputError, match=needle.replace("(", r"\(").replace(")", r"\)")
        ):
            railsusp.run(bad, out=tmp_path / "run")
        assert not (tmp_path / "run").exists()


def test_integers_stand_for_floats_and_the_types_are_kept(tmp_path):
    text = BASE.replace("X13 = 16.1", "X13 = 16").replace("duration_s=1.0", "duration_s=1")
    cfg = load_config(_write(tmp_path, "c.toml", text))
    assert cfg.field.truth == {"X13": 16.0} and cfg.campaign.samples == 10
    assert cfg.field.with_track is True and cfg.estimate.refine is True
    assert cfg.working_conditions()[0].duration_s == 1.0


def test_a_condition_file_value_of_the_wrong_type_is_refused(tmp_path):
    good = _write(tmp_path, "good.toml", '[[condition]]\nname = "fast"\nspeed_kmh = 80\n')
    assert load_conditions(good)[0].speed_kmh == 80.0
    bad = _write(tmp_path, "c.toml", '[[condition]]\nname = "fast"\nspeed_kmh = "80"\n')
    needle = "speed_kmh = '80': a number is needed, not a string (write it without quotes); "
    with pytest.raises(ConditionError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        load_conditions(bad)
    assert "accepted range [1, 200] km/h" in _error(["conditions", str(bad)])
    based = _write(tmp_path, "b.toml", '[condition.c]\nbase = "curve"\ncurve_radius_m = "300"\n')
    assert "curve_radius_m = '300': a number is needed" in _error(["conditions", str(based)])


def test_a_wagon_file_value_of_the_wrong_type_is_refused(tmp_path):
    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    assert "mass = 91600.0" in text
    assert (
        load_wagon(_write(tmp_path, "int.toml", text.replace("91600.0", "91600"))).car_body.mass
        == 91600.0
    )
    bad = _write(tmp_path, "w.toml", text.replace("mass = 91600.0", 'mass = "91600"'))
    with pytest.raises(RailsuspInputError, match=r"car_body\.mass = '91600': a number is needed"):
        load_wagon(bad)


def _error(args: list[str]) -> str:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


@pytest.mark.parametrize(
    ("section", "key", "value", "accepted"),
    [
        ("campaign", "samples", 10_000_000, "less than or equal to 1000000"),
        ("campaign", "batch_size", 100_000, "less than or equal to 10000"),
        ("sensitivity", "base_samples", 1_000_000, "less than or equal to 65536"),
        ("surrogate", "samples", 10_000_000, "less than or equal to 1000000"),
        ("surrogate", "epochs", 100_000, "less than or equal to 10000"),
        ("surrogate", "fine_tune_epochs", 100_000, "less than or equal to 10000"),
        ("surrogate", "batches_per_epoch", 1_000_000, "less than or equal to 100000"),
        ("surrogate", "batch_size", 1_000_000, "less than or equal to 65536"),
    ],
)
def test_sizes_have_an_upper_bound(tmp_path, section, key, value, accepted):
    """A slip of the finger (a campaign of ten million) is refused before any stage."""
    base = BASE.replace("samples = 10\n", "").replace("epochs = 4\n", "")
    text = base.replace(f"[{section}]", f"[{section}]\n{key} = {value}")
    if f"[{section}]" not in base:
        text = base + f"[{section}]\n{key} = {value}\n"
    with pytest.raises(RailsuspInputError) as info:
        load_config(_write(tmp_path, "c.toml", text))
    upper = accepted.rsplit(" ", 1)[1]  # the range is given too (stop 57)
    assert f"{section}.{key} = {value}: accepted [" in str(info.value)
    assert f", {upper}] (Input should be {accepted})" in str(info.value)


def test_a_condition_file_naming_a_missing_track_geometry_is_refused(tmp_path, monkeypatch):
    """`railsusp conditions` passed it; the simulation failed on it later."""
    monkeypatch.chdir(tmp_path)
    text = '[[condition]]\nname = "km12"\ntrack_geometry = "km12.track.csv"\n'
    p = _write(tmp_path, "c.toml", text)
    needle = "condition 'km12': track_geometry km12.track.csv does not exist"
    with pytest.raises(ConditionError, match=needle):
        load_conditions(p)
    assert needle in _error(["conditions", str(p)])
    (tmp_path / "km12.track.csv").write_text("distance_m\n")  # present: read when simulating
    assert load_conditions(p)[0].track_geometry == "km12.track.csv"


def test_the_configurations_base_samples_bounds_are_the_analysis_own():
    from railsusp.config_sections import SensitivitySection
    from railsusp.sensitivity import BASE_SAMPLES

    info = SensitivitySection.model_fields["base_samples"]
    ge = next(m.ge for m in info.metadata if hasattr(m, "ge"))
    le = next(m.le for m in info.metadata if hasattr(m, "le"))
    assert (ge, le) == BASE_SAMPLES


def test_a_toml_date_is_called_a_date(tmp_path):
    p = _write(tmp_path, "c.toml", BASE.replace("epochs = 4", "epochs = 1979-05-27"))
    with pytest.raises(RailsuspInputError, match="a whole number is needed, not a date or time"):
        load_config(p)


def test_a_held_prior_or_parameter_file_of_strings_is_refused(tmp_path):
    from railsusp.params import ParameterError, ParameterSet

    prior = BASE + 'held_prior = {X19 = ["20000", "40000"]}\n'
    needle = r"held_prior: X19 = \['20000', '40000'\]: numbers are needed"
    with pytest.raises(RailsuspInputError, match=needle):
        load_config(_write(tmp_path, "c.toml", prior))
    with pytest.raises(ParameterError, match="X13 = '16.1': a number is needed, not a string"):
        ParameterSet.from_toml(_write(tmp_path, "p.toml", 'X13 = "16.1"\n'))
    assert ParameterSet.from_toml(_write(tmp_path, "q.toml", "X13 = 16\n")).display("X13") == 16


def test_a_sidecar_whole_number_may_be_written_as_a_float(tmp_path):
    """JSON has one number type: MATLAB and pandas write 1000.0 for 1000."""
    import json

    from railsusp.measured import read_recording
    from test_measured import make_recording

    p = make_recording(200, 100.0).write(tmp_path / "rec")
    side = p.with_suffix(".json")
    doc = json.loads(side.read_text())
    doc["condition"]["n_steps"] = float(doc["condition"]["n_steps"])
    doc["condition"]["seed"] = 3.0
    side.write_text(json.dumps(doc))
    assert read_recording(p).condition.seed == 3


def test_a_condition_file_is_strict_through_make_condition():
    """A custom WorkingCondition.__init__ would be called by pydantic's strict validation
    and validate laxly inside it (tried at stop 54): this pins that it is not."""
    from railsusp.conditions import make_condition

    with pytest.raises(ConditionError, match="speed_kmh = '80': a number is needed"):
        make_condition({"name": "c", "speed_kmh": "80"})  # from a file or from Python alike
    assert WorkingCondition(name="c", speed_kmh="80").speed_kmh == 80.0  # pydantic's own: lax


def test_an_unknown_key_holding_a_boolean_is_named_as_unknown_in_one_line():
    """Hypothesis found it (stop 54): the boolean check named the raw key, a newline in it."""
    from railsusp.conditions import make_condition

    with pytest.raises(ConditionError) as info:
        make_condition({"\n": False})
    assert "unknown field '\\n'" in str(info.value) and "\n" not in str(info.value)
