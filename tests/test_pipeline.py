"""The one-command pipeline: stages, skipping, restarts, failures, report, configuration."""

import io
import json
import tomllib
from pathlib import Path

import pandas as pd
import pytest
import torch
from typer.testing import CliRunner

from railsusp.api import open_run
from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.pipeline import STAGES, StageError, demo_config, load_config, run_pipeline

ROOT = Path(__file__).resolve().parents[1]

TINY = """
name = "tiny"
conditions = [{base="straight", name="short", duration_s=1.0, n_steps=50, lead_in_m=20.0}]
[campaign]
samples = 10
batch_size = 10
parameters = ["X13", "X14", "X17"]
[sensitivity]
base_samples = 64
statistics = ["mean"]
max_keys = 2
[surrogate]
samples = 8
epochs = 1
fine_tune_epochs = 2
batches_per_epoch = 3
batch_size = 32
[field]
truth = { X13 = 16.1 }
[estimate]
pop_size = 6
n_gen = 2
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("pipe")
    cfg_path = root / "tiny.toml"
    cfg_path.write_text(TINY)
    out = root / "run"
    seen = []
    state = run_pipeline(load_config(cfg_path), out, progress=lambda s, m: seen.append((s, m)))
    return cfg_path, out, state, seen


def test_every_stage_runs_and_writes_its_outputs(tiny):
    _, out, state, seen = tiny
    assert [s for s, _ in seen] == list(STAGES)
    assert all(state["stages"][s]["state"] == "done" for s in STAGES)
    for rel in (
        "campaign/features.parquet",
        "campaign/sensitivity/key_parameters.json",
        "surrogate-campaign/surrogates/compare.csv",
        "field/index.json",
        "field/truth.json",
        "estimate/estimate.json",
        "estimate/validation/recovery.csv",
        "report.html",
        "report.md",
    ):
        assert (out / rel).exists(), rel
    # each stage records the code that made it (stop 61's audit: one SHA for stages two
    # commits made, no sign of a modified tree, torch and pymoo unlisted)
    from railsusp.provenance import code_identity

    assert all(state["stages"][s]["made_by"] == code_identity() for s in STAGES if s != "report")
    assert {"torch", "pymoo", "SALib", "git_dirty"} <= set(state["provenance"])


def test_surrogates_train_on_their_own_campaign_of_the_key_parameters(tiny, tmp_path):
    """The surrogate stage samples only the sensitivity step's keys (others nominal), and the
    estimate uses the surrogates trained there; ``samples = 0`` trains on the sensitivity
    campaign instead."""
    import shutil

    _, out, state, _ = tiny
    keys = json.loads((out / "campaign/sensitivity/key_parameters.json").read_text())
    keys = keys["key_parameters"]["keys"]
    sur = json.loads((out / "surrogate-campaign" / "campaign.json").read_text())["config"]
    assert sur["parameters"] == keys and sur["samples"] == 8
    design = pd.read_parquet(out / "surrogate-campaign" / "design.parquet")
    assert [c for c in design.columns if c != "sample_id"] == keys
    assert state["stages"]["surrogate"]["info"]["runs"] == 8
    sj = out / "surrogate-campaign" / "surrogates" / "bp" / "short" / "surrogate.json"
    history = json.loads(sj.read_text())["meta"]["history"]
    assert [h["phase"] for h in history] == ["main", "fine-tune", "fine-tune"]
    assert "Trained on their own campaign" in (out / "report.html").read_text("utf-8")
    assert not (out / "campaign" / "surrogates").exists()

    run = tmp_path / "run"
    shutil.copytree(out, run)
    cfg = tmp_path / "zero.toml"
    cfg.write_text(TINY.replace("samples = 8\n", "samples = 0\n"))
    seen = []
    run_pipeline(load_config(cfg), run, progress=lambda s, m: seen.append((s, m)))
    assert dict(seen)["surrogate"] == "running"
    assert (run / "campaign" / "surrogates" / "compare.csv").exists()
    assert "Trained on the sensitivity campaign" in (run / "report.html").read_text("utf-8")
    cfg.write_text(TINY.replace("samples = 8\n", "samples = 3\n"))
    with pytest.raises(RailsuspInputError, match="surrogate.samples.*at least 8"):
        load_config(cfg)


def test_report_is_self_contained(tiny):
    _, out, _, _ = tiny
    page = (out / "report.html").read_text()
    md = (out / "report.md").read_text()
    n_figures = md.count("![")
    assert n_figures >= 5 and page.count("src='data:image/png;base64,") == n_figures
    for heading in ("Sobol", "Surrogates", "NSGA-II", "Validation", "recovery", "Provenance"):
        assert heading in page
    assert "figure missing" not in page
    assert "made by" in page and "were made by different railsusp code" not in page


def test_unchanged_stages_are_skipped_and_from_restarts(tiny):
    cfg_path, out, _, _ = tiny
    seen = []
    run_pipeline(load_config(cfg_path), out, progress=lambda s, m: seen.append(m))
    assert seen == ["up to date"] * len(STAGES)
    seen.clear()
    run_pipeline(
        load_config(cfg_path), out, start_from="estimate", progress=lambda s, m: seen.append((s, m))
    )
    assert [m for _, m in seen] == ["up to date"] * 4 + ["running"] * 3


def test_changed_section_reruns_downstream_only(tiny, tmp_path):
    _cfg_path, out, _, _ = tiny
    changed = tmp_path / "c.toml"
    changed.write_text(TINY.replace("n_gen = 2", "n_gen = 3"))
    seen = []
    run_pipeline(load_config(changed), out, progress=lambda s, m: seen.append((s, m)))
    assert dict(seen) == {
        **dict.fromkeys(STAGES[:4], "up to date"),
        **dict.fromkeys(STAGES[4:], "running"),
    }


def test_statistics_gp_force_model_with_combined_statistics(tiny, tmp_path):
    """The statistics GPs (saved by the surrogate stage) serve as the force model; the
    objectives combine mean and std, per condition; validation reports both statistics."""
    import shutil

    _cfg_path, out, _, _ = tiny
    run = tmp_path / "run"
    shutil.copytree(out, run)
    text = TINY.replace("epochs = 1", 'model = "gp-stats"\nepochs = 1').replace(
        "n_gen = 2", 'n_gen = 2\nstatistic = "mean+std"\nper_condition = true\nweighting = "noise"'
    )
    cfg = tmp_path / "g.toml"
    cfg.write_text(text)
    run_pipeline(load_config(cfg), run)
    gp = run / "surrogate-campaign" / "surrogates" / "gp-stats" / "short" / "statistics.json"
    assert gp.exists()
    est = json.loads((run / "estimate" / "estimate.json").read_text())
    assert est["config"]["statistic"] == "mean+std" and est["config"]["per_condition"]
    assert est["config"]["weighting"] == "noise"
    assert est["model"] == "gp-stats"
    # the Cramér-Rao bound of each key parameter comes with it, and the report explains it
    assert set(est["cramer_rao_pct_range"]) == set(est["parameters"])
    assert "Cramér-Rao bound" in (run / "report.html").read_text("utf-8")
    forces = pd.read_csv(run / "estimate" / "validation" / "validation.csv")
    assert sorted(set(forces.statistic)) == ["mean", "std"]
    cfg.write_text(TINY.replace("n_gen = 2", 'n_gen = 2\nstatistic = "mean+median"'))
    with pytest.raises(RailsuspInputError, match="estimate.statistic"):
        load_config(cfg)


def test_failing_stage_keeps_earlier_outputs_and_says_how_to_resume(tiny, tmp_path, monkeypatch):
    import railsusp.pipeline_field as pipeline_field

    _cfg_path, out, _, _ = tiny
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY.replace("truth = { X13 = 16.1 }", "truth = { X13 = 16.2 }"))

    def failing(*args, **kwargs):  # a measured folder damaged while the run went on, say
        raise RailsuspInputError("index.json: not valid JSON")

    monkeypatch.setattr(pipeline_field, "field_stage", failing)
    with pytest.raises(StageError, match="stage 'field' failed.*run the same command again"):
        run_pipeline(load_config(bad), out)
    state = json.loads((out / "pipeline.json").read_text())
    assert state["stages"]["field"]["state"] == "failed"
    assert state["stages"]["campaign"]["state"] == "done"
    assert (out / "campaign" / "features.parquet").exists()


def test_configuration_errors_name_the_field(tmp_path):
    p = tmp_path / "x.toml"
    p.write_text("[campaign]\nsamples = 2\n")
    with pytest.raises(RailsuspInputError, match="campaign.samples"):
        load_config(p)
    p.write_text("[estimate]\nwhat = 1\n")
    with pytest.raises(RailsuspInputError, match="estimate.what"):
        load_config(p)
    with pytest.raises(RailsuspInputError, match="does not exist"):
        load_config(tmp_path / "missing.toml")


def test_quick_example_is_the_demo_default_and_study_example_loads():
    assert load_config(ROOT / "examples" / "quick.toml") == demo_config()
    study = load_config(ROOT / "examples" / "study.toml")
    assert study.campaign.samples == 1000 and study.surrogate.model == "cnn-gru"
    assert study.surrogate.samples == 1000
    assert (study.estimate.pop_size, study.estimate.n_gen) == (50, 100)


def test_run_command(tiny, tmp_path):
    cfg_path, _, _, _ = tiny
    result = CliRunner().invoke(app, ["run", str(cfg_path), "--out", str(tmp_path / "r")])
    assert result.exit_code == 0, result.output
    assert "Stage timings" in result.output and "report.html" in result.output
    assert result.output.index("Answer") < result.output.index("Estimate (study Table 5")
    bad = CliRunner().invoke(app, ["run", str(cfg_path), "--from", "nowhere"])
    assert bad.exit_code == 2 and "--from 'nowhere'" in bad.output


def _chromium() -> str | None:
    import shutil

    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(
    _chromium() is None,
    reason="headless Chromium absent (Debian package "
    "'chromium': apt-get install chromium) - report rendering not checked",
)
def test_report_renders_every_figure_in_headless_chromium(tiny, tmp_path):
    """Open report.html in headless Chromium; the page's own load check marks every image
    that decoded (data-ok="true")."""
    import subprocess

    _, out, _, _ = tiny
    n_figures = (out / "report.md").read_text().count("![")
    proc = subprocess.run(
        [
            _chromium(),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--virtual-time-budget=5000",
            "--dump-dom",
            (out / "report.html").as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.count('data-ok="true"') == n_figures
    assert 'data-ok="false"' not in proc.stdout


def test_stage_hashes_follow_the_model_not_only_the_configuration(monkeypatch, tmp_path):
    """A run directory made with another model is simulated again: the force laws' revision
    and the wagon's data as read (a wagon file edited in place) are in the simulated stages'
    hashes. (A demo folder of an older railsusp was reused, and its estimate stage failed.)"""
    from importlib import resources

    import railsusp.vehicle
    from railsusp import pipeline_inputs
    from railsusp.store import content_hash

    cfg = demo_config()

    def hashes(config):
        return {
            s: content_hash(pipeline_inputs.stage_section(config, s)) for s in ("campaign", "field")
        }

    before = hashes(cfg)
    monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", "another")
    after = hashes(cfg)
    assert all(before[s] != after[s] for s in before)
    monkeypatch.undo()
    wagon = tmp_path / "wagon.toml"
    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    wagon.write_text(text)
    own = cfg.model_copy(update={"wagon": str(wagon)})
    first = hashes(own)
    wagon.write_text(text.replace("gib_stiffness = 50.0e6", "gib_stiffness = 40.0e6"))
    assert all(first[s] != hashes(own)[s] for s in first)


def test_a_profile_file_edited_in_place_is_simulated_again(tmp_path):
    """A wagon's wheel profile file edited in place left every stage of ``railsusp run``
    skipped, the old profile's results presented as up to date (the wagon hunt of stop 79):
    the wagon's hash held the file's path alone. Its contents are now in the simulated
    stages' hashes, in the campaign's (a forced campaign kept its batches) and in the
    contact table's cache."""
    from importlib import resources

    import numpy as np

    from railsusp import pipeline_inputs
    from railsusp.campaign import make_config
    from railsusp.conditions import get_condition
    from railsusp.store import content_hash
    from railsusp.vehicle import layout as L
    from railsusp.vehicle.profile_shapes import lm_worn_wheel
    from railsusp.vehicle.profiles import write_profile
    from railsusp.vehicle.setup import contact_arrays
    from railsusp.vehicle.wagon import load_wagon

    profile = tmp_path / "wheel.txt"
    write_profile(lm_worn_wheel(), profile)
    wagon = tmp_path / "wagon.toml"
    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    wagon.write_text(text + '\n[profiles]\nwheel = "wheel.txt"\n')
    own = demo_config().model_copy(update={"wagon": str(wagon)})

    def hashes():
        return [content_hash(pipeline_inputs.stage_section(own, s)) for s in ("campaign", "field")]

    def campaign_hash():
        cond = get_condition("straight", duration_s=1.0, n_steps=50)
        return make_config([cond], samples=4, wagon=load_wagon(wagon)).hash()

    first, first_campaign = hashes(), campaign_hash()
    first_radius = contact_arrays(load_wagon(wagon)).table[L.CT_R].copy()
    write_profile(lm_worn_wheel(flange_thickness=0.026, tread_radii=(0.3, 0.15, 0.1)), profile)
    assert all(a != b for a, b in zip(first, hashes(), strict=True))
    assert campaign_hash() != first_campaign
    assert not np.allclose(contact_arrays(load_wagon(wagon)).table[L.CT_R], first_radius)


def test_a_stage_failing_on_an_earlier_stages_file_names_that_stage(tmp_path):
    """The kill/resume pass (stop 54): a truncated features.parquet failed the sensitivity
    stage, and the hint '--from sensitivity' failed the same way; it now names --from
    campaign (the most specific earlier output folder the message names)."""
    from railsusp.pipeline_config import PipelineConfig
    from railsusp.pipeline_state import blame

    cfg = PipelineConfig()
    msg = f"{tmp_path}/campaign/features.parquet is corrupt"
    assert blame(cfg, tmp_path, "sensitivity", msg).endswith("--from campaign remakes it")
    deeper = f"{tmp_path}/campaign/sensitivity/key_parameters.json is corrupt"
    assert "stage 'sensitivity'" in blame(cfg, tmp_path, "estimate", deeper)
    assert blame(cfg, tmp_path, "campaign", msg) == ""  # its own output: no earlier stage
    assert blame(cfg, tmp_path, "estimate", "X13 out of range") == ""


def _up_to_date_copy(tiny, tmp_path):
    """The tiny run's configuration, its folder, and a copy of it brought up to date for
    that configuration (other tests change the original's)."""
    import shutil

    cfg_path, out, _, _ = tiny
    cfg = load_config(cfg_path)
    copy = tmp_path / "run"
    shutil.copytree(out, copy)
    run_pipeline(cfg, copy)
    return cfg, out, copy


def test_a_damaged_stage_output_makes_that_stage_run_again(tiny, tmp_path):
    """The kill/resume pass (stop 54): a truncated features.parquet or estimate.json in a
    finished run passed as done (the next stage, or the summary, then failed on it with a
    hint that looped); now the stage whose output does not read runs again, and the stages
    after it, as after any rerun."""
    from railsusp.pipeline_state import outputs_exist

    cfg, out, copy = _up_to_date_copy(tiny, tmp_path)
    reference = json.loads((copy / "estimate/estimate.json").read_text())
    for rel, stage in (("campaign/features.parquet", "campaign"), ("estimate/estimate.json",
                                                                    "estimate")):  # fmt: skip
        assert outputs_exist(cfg, copy, stage)
        f = copy / rel
        f.write_bytes(f.read_bytes()[:200])
        assert not outputs_exist(cfg, copy, stage)
    features = "campaign/features.parquet"
    (copy / features).write_bytes((out / features).read_bytes())
    seen = []
    run_pipeline(cfg, copy, progress=lambda s, m: seen.append((s, m)))
    assert [s for s, m in seen if m == "running"] == ["estimate", "validate", "report"], seen
    est = json.loads((copy / "estimate/estimate.json").read_text())
    assert est["estimate_display"] == reference["estimate_display"]


def test_a_damaged_file_beside_a_stages_output_makes_that_stage_run_again(tiny, tmp_path):
    """Stop 54's kill/resume pass left this open: a network (model.pt) or a field recording
    cut short in a finished run passed as done until a later stage read it. Now every file a
    stage wrote is checked by its format, and against the size recorded when the stage
    finished (a CSV cut inside its last number still has all its cells); a training
    checkpoint is not (only a resume point), and a run recorded before sizes were gets the
    format checks alone."""
    from railsusp.pipeline_state import outputs_exist

    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    state = json.loads((copy / "pipeline.json").read_text())
    model = next((copy / "surrogate-campaign/surrogates").rglob("model.pt"))
    recording = copy / "field/short.csv"
    assert model.relative_to(copy).as_posix() in state["stages"]["surrogate"]["files"]
    assert "field/short.csv" in state["stages"]["field"]["files"]
    assert not any("checkpoint" in f for f in state["stages"]["surrogate"]["files"])
    network, table = model.read_bytes(), recording.read_bytes()

    checkpoint = model.with_name("checkpoint.pt")
    checkpoint.write_bytes(checkpoint.read_bytes()[:100])
    assert outputs_exist(cfg, copy, "surrogate", state["stages"]["surrogate"]["files"])

    model.write_bytes(network[: len(network) // 2])
    assert not outputs_exist(cfg, copy, "surrogate", state["stages"]["surrogate"]["files"])
    recording.write_bytes(table[:-3])  # inside the last number: every cell is still there
    assert outputs_exist(cfg, copy, "field")  # the format alone cannot tell
    assert not outputs_exist(cfg, copy, "field", state["stages"]["field"]["files"])

    seen = []
    run_pipeline(cfg, copy, progress=lambda s, m: seen.append((s, m)))
    assert [s for s, m in seen if m == "running"] == list(STAGES[2:]), seen
    assert recording.read_bytes() == table  # remade as it was
    new, old = _weights(model.read_bytes()), _weights(network)
    assert new.keys() == old.keys()
    assert all(torch.equal(new[k], old[k]) for k in old)  # remade as it was


def _weights(data: bytes) -> dict:
    return torch.load(io.BytesIO(data), weights_only=True)


def test_surrogates_on_the_sensitivity_campaign_and_a_damaged_split(tmp_path):
    """A reviewer's finds: with the surrogates trained on the sensitivity campaign
    (``samples = 0``) the split they draw lies in the campaign's folder, and a damaged one
    made the campaign stage run again, which does not remake it, then fail (a dead end). The
    split is the surrogate stage's, and one that does not read is drawn again, as it was;
    the stages reading the surrogates run again after it, the field (which does not) not."""
    cfg_path = tmp_path / "shared.toml"
    cfg_path.write_text(TINY.replace("samples = 8\n", "samples = 0\n"))
    cfg = load_config(cfg_path)
    out = tmp_path / "run"
    run_pipeline(cfg, out)
    seen = []
    run_pipeline(cfg, out, progress=lambda s, m: seen.append((s, m)))
    assert all(m == "up to date" for _, m in seen), seen
    split = out / "campaign/splits/seed-0.json"
    drawn = split.read_bytes()
    split.write_bytes(drawn[:40])
    seen = []
    run_pipeline(cfg, out, progress=lambda s, m: seen.append((s, m)))
    again = ["surrogate", "estimate", "validate", "report"]
    assert [s for s, m in seen if m == "running"] == again, seen
    assert split.read_bytes() == drawn


def test_a_measured_folder_with_a_users_own_files_stays_up_to_date(tiny, tmp_path):
    """The field stage copies a measured folder as it is: a note of the user's (a CSV with
    a quoted comma and no last line end) read as damaged made that stage, and every one
    after it, run again on every run."""
    import shutil

    _, out, _, _ = tiny
    measured = tmp_path / "measured"
    shutil.copytree(out / "field", measured)
    (measured / "log.csv").write_bytes(b'id,"where, when",x\n1,Pinsk,2')
    # and files railsusp does not read: their format is not its to judge (a second review)
    (measured / "notes.json").write_bytes('{"line": "Kola"}'.encode("utf-16"))
    (measured / "extra.csv").write_bytes(b"id,a,b\n1,2,3\n4,5")
    cfg_path = tmp_path / "measured.toml"
    head, _ = TINY.split("[field]")
    estimate = TINY[TINY.index("[estimate]") :]
    cfg_path.write_text(f"{head}[field]\nmeasured = {str(measured)!r}\n{estimate}")
    cfg = load_config(cfg_path)
    run = tmp_path / "run"
    shutil.copytree(out, run)
    run_pipeline(cfg, run)
    seen = []
    run_pipeline(cfg, run, progress=lambda s, m: seen.append((s, m)))
    assert all(m == "up to date" for _, m in seen), seen


def test_a_run_checks_its_configuration_once(tiny, monkeypatch):
    """load_config checks the configuration (a measured folder's recordings are read in full
    by that check); the command line and railsusp.run(path or dict) do not check it again,
    a PipelineConfig built in Python is checked by run_pipeline itself."""
    import railsusp
    import railsusp.config

    cfg_path, out, _, _ = tiny
    calls = []
    check = railsusp.config.check_config
    monkeypatch.setattr(
        railsusp.config, "check_config", lambda *a, **k: (calls.append(a[1:]), check(*a, **k))
    )
    result = CliRunner().invoke(app, ["run", str(cfg_path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert len(calls) == 1
    for config in (cfg_path, load_config(cfg_path), dict(tomllib.loads(TINY))):
        calls.clear()
        railsusp.run(config, out=out)
        assert len(calls) == 1, config


def test_recordings_replaced_in_a_measured_folder_make_the_field_stage_run_again(tiny, tmp_path):
    """The interrupt/resume audit of stop 58: the field stage hashed the measured folder's
    path alone, so recordings replaced in it kept the old copy and the estimate on it."""
    import shutil

    _, out, _, _ = tiny
    measured = tmp_path / "measured"
    shutil.copytree(out / "field", measured)
    cfg_path = tmp_path / "measured.toml"
    head, _ = TINY.split("[field]")
    estimate = TINY[TINY.index("[estimate]") :]
    cfg_path.write_text(f"{head}[field]\nmeasured = {str(measured)!r}\n{estimate}")
    run = tmp_path / "run"
    shutil.copytree(out, run)
    run_pipeline(load_config(cfg_path), run)
    table = measured / "short.csv"
    lines = table.read_text().splitlines()
    first = lines[1].split(",")
    first[1] = f"{float(first[1]) + 0.5:.6g}"  # another recording of the same length
    table.write_text("\n".join([lines[0], ",".join(first), *lines[2:]]) + "\n")
    seen = []
    with pytest.warns(UserWarning, match="its truth.json is left out of the run") as said:
        run_pipeline(load_config(cfg_path), run, progress=lambda s, m: seen.append((s, m)))
    assert [s for s, m in seen if m == "running"] == ["field", "estimate", "validate", "report"]
    assert (run / "field" / "short.csv").read_text() == table.read_text()
    # the copied truth is no longer that of the edited recording: left out, not scored
    # (kept, validate refused it after the whole estimate: stop 74)
    assert "short.csv is none of the tables" in str(said[0].message)
    assert not (run / "field" / "truth.json").exists() and (measured / "truth.json").exists()
    assert open_run(run).recovery is None


def test_a_deleted_markdown_report_is_written_again(tiny, tmp_path):
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    (copy / "report.md").unlink()
    cfg_path, _, _, _ = tiny
    seen = []
    run_pipeline(load_config(cfg_path), copy, progress=lambda s, m: seen.append((s, m)))
    assert [s for s, m in seen if m == "running"] == ["report"]
    assert (copy / "report.md").is_file()


def test_a_second_run_in_a_folder_is_refused_while_one_works(tiny, tmp_path):
    """The interrupt/resume audit of stop 58: two runs on one folder wrote over each other's
    stages, one failing on a file the other had replaced."""
    import os

    from railsusp.run_lock import run_lock

    cfg_path, _, _, _ = tiny
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    with run_lock(copy, "--out"):  # as another process holds it while it runs
        with pytest.raises(RailsuspInputError) as info:
            run_pipeline(load_config(cfg_path), copy)
    text = str(info.value)
    assert "another railsusp run is working in this folder" in text
    assert f"(process {os.getpid()})" in text
    seen = []
    run_pipeline(load_config(cfg_path), copy, progress=lambda s, m: seen.append(m))
    assert seen == ["up to date"] * len(STAGES)  # released: the next run goes on


def test_a_damaged_pipeline_json_says_how_to_resume(tiny, tmp_path):
    cfg_path, _, _, _ = tiny
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    (copy / "pipeline.json").write_text("{not json")
    with pytest.raises(RailsuspInputError, match="delete it to resume: a run directory without"):
        run_pipeline(load_config(cfg_path), copy)
    (copy / "pipeline.json").unlink()
    run_pipeline(load_config(cfg_path), copy)
    assert json.loads((copy / "pipeline.json").read_text())["stages"]["report"]["state"] == "done"


def test_a_stage_failing_on_a_full_disk_exits_1_not_2():
    import errno

    from railsusp.cli.common import exit_code

    try:
        try:
            raise OSError(errno.ENOSPC, "No space left on device")
        except OSError as full:
            raise StageError("stage 'surrogate' failed: [Errno 28]") from full
    except StageError as exc:
        assert exit_code(exc) == 1
    assert exit_code(RailsuspInputError("bad")) == 2


def test_the_surrogate_comparison_json_is_strict_json(tiny):
    """The docs audit of stop 58: compare.json held bare NaN, which strict parsers refuse."""
    _, out, _, _ = tiny

    def refuse(name):
        raise ValueError(f"{name} is not JSON")

    for path in out.rglob("compare.json"):
        rows = json.loads(path.read_text(), parse_constant=refuse)
        assert rows and any(v is None for r in rows for v in r.values())


def test_the_stage_hashes_follow_the_conditions_as_simulated(tmp_path, monkeypatch):
    """The campaign and field stages hashed the conditions as written: a packaged condition
    changed by an upgrade, or a track-geometry file edited in place, left every stage up to
    date on the old results (interrupt/resume audit of stop 60)."""
    import pandas as pd

    from railsusp import conditions as conditions_module
    from railsusp.conditions import get_condition
    from railsusp.pipeline_inputs import stage_section
    from railsusp.vehicle.track_geometry import write_track_geometry
    from railsusp.vehicle.track_grid import section_irregularities
    from railsusp.vehicle.wagon import load_wagon

    base = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    irr = section_irregularities(base, [base.seed], load_wagon())
    geo = write_track_geometry(tmp_path / "track.csv", irr, origin_m=base.lead_in_m)
    cfg = tmp_path / "c.toml"
    cfg.write_text(
        f'conditions = ["curve", {{base = "straight", name = "short", duration_s = 1.0, '
        f'n_steps = 50, lead_in_m = 20.0, track_geometry = "{geo}"}}]\n'
    )
    config = load_config(cfg)
    before = {s: stage_section(config, s) for s in ("campaign", "field")}
    assert before["campaign"]["conditions"][0]["curve_radius_m"] == 300.0  # resolved
    table = pd.read_csv(geo)
    table[[c for c in table.columns if c != "distance_m"]] *= 3.0
    table.to_csv(geo, index=False)
    edited = {s: stage_section(config, s) for s in ("campaign", "field")}
    for s in ("campaign", "field"):
        assert edited[s] != before[s] and edited[s]["conditions"] == before[s]["conditions"]
    upgraded = dict(conditions_module.STANDARD_CONDITIONS)
    upgraded["curve"] = upgraded["curve"].with_changes(speed_kmh=70.0)
    monkeypatch.setattr(conditions_module, "STANDARD_CONDITIONS", upgraded)
    assert (
        stage_section(load_config(cfg), "campaign")["conditions"]
        != edited["campaign"]["conditions"]
    )


def _edit_in_place(path: Path, old: str, new: str) -> None:
    """Replace ``old`` (once, inside the ``estimate_display`` table) by ``new`` of the same
    length: the file keeps its size."""
    text = path.read_text()
    at = text.index(old, text.index('"estimate_display"'))
    assert len(old) == len(new)
    path.write_text(text[:at] + new + text[at + len(old) :])


def test_a_same_size_edit_of_a_stages_output_is_found_by_its_hash(tiny, tmp_path):
    """The run-directory store audit: the stages recorded their files' sizes alone, so an
    estimate.json edited in place (15.917 made 25.917) was shown by the summary and
    open_run().estimate as the run's answer while report.html showed the number written.
    Now each stage records its files' SHA-256 too: open_run refuses the edited file, and the
    next run remakes it and the stages after it."""
    from railsusp import open_run
    from railsusp.pipeline_state import outputs_exist

    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    path = copy / "estimate/estimate.json"
    written = path.read_bytes()
    shown = str(json.loads(written)["estimate_display"]["X13"])
    _edit_in_place(path, shown, str(int(shown[0]) % 9 + 1) + shown[1:])  # 15.9 -> 25.9
    assert path.stat().st_size == len(written)
    with pytest.raises(RailsuspInputError, match="estimate/estimate.json changed or is gone"):
        open_run(copy).estimate  # noqa: B018
    entry = json.loads((copy / "pipeline.json").read_text())["stages"]["estimate"]
    assert set(entry.get("sha256", ())) == set(entry["files"])
    assert not outputs_exist(cfg, copy, "estimate", entry["files"], entry["sha256"])
    seen = []
    run_pipeline(cfg, copy, progress=lambda s, m: seen.append((s, m)))
    assert [s for s, m in seen if m == "running"] == ["estimate", "validate", "report"], seen
    remade = json.loads(path.read_text())["estimate_display"]
    assert remade == json.loads(written)["estimate_display"]  # as the stage wrote it
    assert open_run(copy).estimate.loc["X13", "estimate"] == remade["X13"]


def test_a_run_recorded_before_hashes_is_compared_by_size_and_a_bad_estimate_is_one_line(
    tiny, tmp_path
):
    """A run directory written before hashes were recorded (sizes alone) stays up to date
    (its files are compared by size, as they were). An estimate.json edited in it so that
    a key is gone is then no longer a KeyError's traceback (``railsusp run`` ended so, exit
    1): the summary says, in one line, which field of which file and how to remake it."""
    from railsusp import open_run
    from railsusp.summary import estimate_table

    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    state = json.loads((copy / "pipeline.json").read_text())
    for entry in state["stages"].values():
        entry.pop("sha256", None)
    state.pop("format", None)
    (copy / "pipeline.json").write_text(json.dumps(state))
    _edit_in_place(copy / "estimate/estimate.json", '"X13"', '"X93"')
    seen = []
    run_pipeline(cfg, copy, progress=lambda s, m: seen.append(m))
    assert seen == ["up to date"] * len(STAGES)
    for read in (lambda: open_run(copy).estimate, lambda: estimate_table(copy)):
        with pytest.raises(RailsuspInputError) as info:
            read()
        text = str(info.value)
        assert text.startswith(f"{copy / 'estimate/estimate.json'}: estimate_display.X13 = ")
        assert "missing: accepted a finite number" in text and "--from estimate" in text
        assert "\n" not in text


def test_a_run_directory_of_a_newer_railsusp_is_refused_not_run_again(tiny, tmp_path):
    """The run-directory store audit: a run directory made by a newer railsusp (its campaign of
    newer force laws) was run again from the start, its campaign discarded, where the
    standalone `railsusp campaign` refused the folder. pipeline.json states its format now,
    and a run directory of a newer format, or holding a campaign of a newer revision, is
    refused in one line and left as it is. Older ones run again, as before."""
    import shutil

    cfg_path, out, _, _ = tiny
    copy = tmp_path / "run"
    shutil.copytree(out, copy)
    state = json.loads((copy / "pipeline.json").read_text())
    meta_path = copy / "campaign" / "campaign.json"
    meta = json.loads(meta_path.read_text())
    before = {p: p.read_bytes() for p in copy.rglob("*") if p.is_file()}
    cases = [
        ({**state, "format": state.get("format", 0) + 1}, meta, "written by a newer railsusp"),
        (  # the audit's: made by railsusp 9.0.0, before pipeline.json stated a format
            {**{k: v for k, v in state.items() if k != "format"}, "made_by": "9.0.0"},
            {**meta, "model_revision": "2099-01-01.1"},
            # (it read "its campaign campaign was simulated with ...")
            "the campaign in its campaign/ was simulated with force-law revision "
            "2099-01-01.1, newer than this railsusp's",
        ),
    ]
    for doc, campaign, said in cases:
        (copy / "pipeline.json").write_text(json.dumps(doc))
        meta_path.write_text(json.dumps(campaign))
        before[copy / "pipeline.json"] = (copy / "pipeline.json").read_bytes()
        before[meta_path] = meta_path.read_bytes()
        with pytest.raises(RailsuspInputError) as info:
            run_pipeline(load_config(cfg_path), copy)
        assert said in str(info.value) and "\n" not in str(info.value)
        assert str(info.value).startswith(f"out {copy}: ") or f"--out {copy}" in str(info.value)
        assert {p: p.read_bytes() for p in copy.rglob("*") if p.is_file()} == before
    from railsusp.pipeline_state import PIPELINE_FORMAT, run_state

    assert state["format"] == PIPELINE_FORMAT  # what this railsusp writes
    meta_path.write_text(json.dumps({**meta, "model_revision": "2000-01-01.1"}))
    assert run_state(copy, "--out")["stages"]  # an older campaign: run again, as before


def test_an_up_to_date_run_hashes_only_the_files_whose_time_moved(tiny, tmp_path, monkeypatch):
    """Resuming hashed every recorded file (a campaign's gigabytes at the study's scale) on
    each run: a file whose size and modification time are as recorded is now taken as
    unchanged (as make does), and only a file written since is hashed, so a same-size edit
    is still found (the review of stop 64)."""
    import railsusp.integrity as integrity

    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    hashed = []
    own = integrity.file_hash_cached
    monkeypatch.setattr(integrity, "file_hash_cached", lambda p: hashed.append(p) or own(p))
    seen = []
    run_pipeline(cfg, copy, progress=lambda s, m: seen.append((s, m)))
    assert {m for _, m in seen} == {"up to date"} and hashed == []
    path = copy / "estimate/estimate.json"
    shown = str(json.loads(path.read_bytes())["estimate_display"]["X13"])
    _edit_in_place(path, shown, str(int(shown[0]) % 9 + 1) + shown[1:])
    seen.clear()
    run_pipeline(cfg, copy, progress=lambda s, m: seen.append((s, m)))
    assert path in hashed and len(set(hashed)) == 1  # the edited file alone
    assert [s for s, m in seen if m == "running"] == ["estimate", "validate", "report"], seen


def test_a_swallowed_ctrl_c_stops_the_run_at_the_next_stage(tiny, tmp_path):
    """A Ctrl-C raised inside a garbage-collector callback is printed by Python ("Exception
    ignored in: ... KeyboardInterrupt") and lost: the run went on to its end. The command
    line's handler records each Ctrl-C (railsusp.interrupts), and the pipeline stops at the
    next stage boundary where one was recorded, the stages before it kept."""
    from railsusp.interrupts import catch_interrupts, record_interrupt

    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    seen = []

    def swallowed(stage: str, message: str) -> None:
        seen.append(stage)
        if stage == "campaign":
            record_interrupt()  # as the handler does, its KeyboardInterrupt then lost

    restore = catch_interrupts()
    try:
        with pytest.raises(KeyboardInterrupt):
            run_pipeline(cfg, copy, progress=swallowed)
    finally:
        restore()
    assert seen == ["campaign"]
    state = json.loads((copy / "pipeline.json").read_text())
    assert {e["state"] for e in state["stages"].values()} == {"done"}  # nothing half-made
    run_pipeline(cfg, copy, progress=lambda s, m: seen.append(m))  # forgotten after
    assert seen[1:] == ["up to date"] * len(STAGES)


def test_a_refused_printout_in_a_stage_is_said_as_the_streams_not_the_stages(
    tiny, tmp_path, monkeypatch
):
    """The review of stop 69: a write to a full or closed stdout inside a stage (its
    progress) was wrapped as "stage ... failed: [Errno 28]", so the command said the stage
    failed, not the printout. It reaches the command line as itself now (which says the
    stream), the stage recorded as failed so that the next run makes it again."""
    import errno

    import railsusp.pipeline as pipeline
    from railsusp.errors import OutputStreamError

    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    (copy / "report.md").unlink()  # the report stage runs again
    real = pipeline.stage_runners

    def runners(*args, **kwargs):
        made = real(*args, **kwargs)

        def refused():
            raise OutputStreamError("stdout", OSError(errno.ENOSPC, "No space left on device"))

        return {**made, "report": refused}

    monkeypatch.setattr(pipeline, "stage_runners", runners)
    with pytest.raises(OutputStreamError):
        run_pipeline(cfg, copy)
    entry = json.loads((copy / "pipeline.json").read_text())["stages"]["report"]
    assert entry["state"] == "failed"
    assert entry["error"] == "its printout to stdout failed: No space left on device"


def test_a_run_sweeps_the_temporaries_a_killed_run_left_of_its_files(tiny, tmp_path):
    """A kill while pipeline.json or a report was written left its temporary in the run
    directory for good (the interrupt/resume QA of stop 74)."""
    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    left = [copy / ".pipeline.json.abcd1234.tmp", copy / ".report.html.abcd1234.tmp"]
    for p in left:
        p.write_text("half")
    mine = copy / ".notes.tmp"  # no railsusp temporary: left alone
    mine.write_text("mine")
    run_pipeline(cfg, copy)
    assert not any(p.exists() for p in left) and mine.exists()


def test_a_stage_whose_output_is_gone_says_why_it_runs_again(tiny, tmp_path, caplog):
    """A removed estimate.json ran the stage again without a word, while a changed file was
    said ("is damaged" also for several files): the interrupt/resume QA of stop 74."""
    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    gone = copy / "estimate" / "estimate.json"
    gone.unlink()
    with caplog.at_level("WARNING"):
        run_pipeline(cfg, copy)
    assert f"stage estimate: {gone} is gone; the stage runs again" in caplog.text
    caplog.clear()
    field = sorted((copy / "field").glob("short.*"))  # the table and its sidecar
    assert len(field) == 2
    for p in field:
        p.write_text(p.read_text() + "\n")
    with caplog.at_level("WARNING"):
        run_pipeline(cfg, copy)
    assert "are damaged, changed or gone; the stage runs again" in caplog.text


def test_a_linked_field_folder_is_replaced_by_the_runs_own(tiny, tmp_path):
    """RUN/field linked to a folder of the user's recordings: the field stage wrote through
    the link and replaced them (the review of stop 74). The link is removed with a warning,
    the folder it named left as it was."""
    import shutil

    cfg, _, copy = _up_to_date_copy(tiny, tmp_path)
    mine = tmp_path / "mine"
    shutil.copytree(copy / "field", mine)
    (mine / "notes.txt").write_text("the user's")
    before = {p.name: p.read_bytes() for p in mine.iterdir()}
    shutil.rmtree(copy / "field")
    (copy / "field").symlink_to(mine, target_is_directory=True)
    with pytest.warns(UserWarning, match="was a link to"):
        run_pipeline(cfg, copy, start_from="field")
    assert not (copy / "field").is_symlink() and (copy / "field" / "index.json").is_file()
    assert {p.name: p.read_bytes() for p in mine.iterdir()} == before


def test_a_moved_run_directory_validates_its_own_recordings(tiny, tmp_path):
    """A run directory moved elsewhere (paths-and-formats hunt): its estimate recorded its
    recordings' folder as an absolute path, so `railsusp run --from validate` on the moved
    run, and `railsusp validate RUN/estimate`, read the folder no longer there ("no
    index.json listing the recordings") and failed, with no remedy in running again."""
    import shutil

    from railsusp.validate import validate

    cfg_path, out, _, _ = tiny
    cfg = load_config(cfg_path)
    before = tmp_path / "before"
    shutil.copytree(out, before)
    run_pipeline(cfg, before, start_from="estimate")  # its estimate records this folder's
    moved = tmp_path / "Prüf stand" / "moved run"
    moved.parent.mkdir()
    shutil.move(before, moved)
    run_pipeline(cfg, moved, start_from="validate")
    assert open_run(moved).validation is not None
    assert validate(moved / "estimate").recovery is None  # its own recordings, read
