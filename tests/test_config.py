"""The pipeline configuration is checked as a whole before any stage runs (railsusp.config)."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.config import ConfigError
from railsusp.errors import RailsuspInputError
from railsusp.pipeline import PipelineConfig, load_config, run_pipeline

BASE = """
name = "t"
conditions = [{base="straight", name="short", duration_s=1.0, n_steps=50, lead_in_m=20.0}]
[campaign]
samples = 10
[field]
truth = { X13 = 16.1 }
"""


def _write(tmp_path, text: str):
    p = tmp_path / "c.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (BASE.replace("X13 = 16.1", "X99 = 1.0"), "field.truth: unknown parameter 'X99'"),
        (BASE.replace("X13 = 16.1", "X13 = 99.0"), "field.truth: X13"),
        (
            BASE.replace("X13 = 16.1", "X13 = true"),
            "field.truth.X13 = true: a number is needed, not a boolean",
        ),
        (BASE + "with_track = false\n[estimate]\nrefine = true\n", "set field.with_track = true"),
        (
            BASE.replace("samples = 10", "samples = true"),
            "campaign.samples = true: a whole number is needed, not a boolean",
        ),
        (BASE.replace("samples = 10", "sample = 10"), "campaign.sample"),
        (BASE + "[estimate]\nweighting = 'noise'\n", "needs the predictive SD of surrogate.model"),
        (BASE + "[surrogate]\ndevice = 'tpu'\n", "surrogate.device = 'tpu'"),
        # the estimate's own ranges, at load time rather than after campaign and training
        (BASE + "[estimate]\nseed = -1\n", "estimate.seed"),
        (BASE + "[estimate]\nn_gen = 200000\n", "estimate.n_gen"),
        (BASE + "[estimate]\nrefine_evaluations = 501\n", "estimate.refine_evaluations"),
        (BASE.replace('name="short"', 'name="../../x"'), "condition name becomes a folder"),
        (BASE.replace('name="short"', 'name="/abs"'), "no absolute path"),
        (
            BASE.replace("conditions = [", 'conditions = ["straight", "straight", '),
            "names repeat (straight)",
        ),
        (  # one batch folder on a case-blind disk (Windows, macOS): stop 56's review
            BASE.replace("conditions = [", 'conditions = [{base="straight", name="SHORT"}, '),
            "names repeat (SHORT, short)",
        ),
        (BASE.replace("lead_in_m=20.0", "speed_kmh=true"), "a boolean is not accepted"),
        (BASE.replace("X13", "campaign.parameters") + "", "field.truth"),
        (BASE + 'wagon = "nowhere.toml"\n', "field.wagon"),  # after a table: nested
        ('wagon = "nowhere.toml"\n' + BASE, "wagon: wagon file nowhere.toml does not exist"),
        ('scheduler = "localhost:8786"\n' + BASE, "accepted tcp://host:port"),
        (
            BASE.replace("truth = { X13 = 16.1 }", 'measured = "nowhere"'),
            "field.measured = 'nowhere' is not a folder",
        ),
        (BASE.replace("samples = 10", "parameters = ['X1']"), "X1 is fixed"),
        (BASE.replace("samples = 10", "parameters = ['X13', 'X13']"), "X13 is given twice"),
        (BASE + "[sensitivity]\nstatistics = ['median']\n", "'median' unknown"),
        (  # only X11..X20 are sampled: "accepted: X1..X20" named the fixed ones too
            BASE.replace("samples = 10", "parameters = ['X13', 'X99']"),
            "campaign.parameters: unknown parameter 'X99'; accepted the sampled ones, "
            "X11..X20, or their names",
        ),
        # an empty path was the working folder ("wagon file . is a folder")
        (
            'wagon = ""\n' + BASE,
            "c.toml: wagon: empty: give a wagon data TOML or a packaged name (loaded, tare), "
            "or leave the key out",
        ),
        (
            BASE.replace("truth = { X13 = 16.1 }", 'measured = ""'),
            "c.toml: field.measured: empty: give a path, or leave the key out",
        ),
        (
            BASE.replace("truth = { X13 = 16.1 }", 'recording = " "'),
            "c.toml: field.recording: empty: give a path, or leave the key out",
        ),
        (
            BASE + '[surrogate]\npretrained = ""\n',
            "c.toml: surrogate.pretrained: empty: give a shipped network set's name or a "
            "folder with networks.json, or leave the key out",
        ),
    ],
)
def test_bad_configurations_fail_at_load_time_naming_the_field(tmp_path, text, needle):
    with pytest.raises(RailsuspInputError, match=None) as info:
        load_config(_write(tmp_path, text))
    assert needle in str(info.value)
    assert "\n" not in str(info.value)


def test_a_late_failing_configuration_runs_no_stage(tmp_path):
    """`[field] truth = {X99 = 1.0}` used to fail after campaign, sensitivity and surrogates."""
    cfg = PipelineConfig(**{"field": {"truth": {"X99": 1.0}}})
    out = tmp_path / "run"
    with pytest.raises(ConfigError, match="X99"):
        run_pipeline(cfg, out)
    assert not out.exists()
    result = CliRunner().invoke(
        app, ["run", str(_write(tmp_path, BASE.replace("X13", "X99"))), "--out", str(out)]
    )
    assert result.exit_code == 2 and "unknown parameter 'X99'" in result.output
    assert not out.exists()


def test_good_configurations_load(tmp_path):
    cfg = load_config(_write(tmp_path, BASE))
    assert cfg.field.truth == {"X13": 16.1}
    both = BASE + "with_track = true\n[estimate]\nrefine = true\n"
    assert load_config(_write(tmp_path, both)).estimate.refine


def test_an_empty_path_in_a_dict_configuration_is_refused_too(tmp_path):
    """railsusp.run's dicts go through the same models."""
    import railsusp

    with pytest.raises(RailsuspInputError, match="configuration: wagon: empty: give a wagon"):
        railsusp.run({"wagon": ""}, out=tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_a_cuda_refusal_names_the_configuration_file(tmp_path):
    """It began "configuration:" where every other check names the TOML file."""
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has a CUDA device")
    cfg = _write(tmp_path, BASE + '[surrogate]\ndevice = "cuda"\n')
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["run", str(cfg), "--out", str(out)])
    assert result.exit_code == 2
    assert f'error: {cfg}: surrogate.device = "cuda": no CUDA device' in " ".join(
        result.output.split()
    )
    import railsusp

    with pytest.raises(ConfigError, match=f'^{cfg}: surrogate.device = "cuda"'):
        railsusp.run(cfg, out=out)
    assert not out.exists()
