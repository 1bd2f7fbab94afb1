"""A pipeline whose surrogates are a network set trained on many tracks and shipped with
railsusp (``[surrogate] pretrained``, issue 19 item 5): the set is checked before any stage
runs, copied into the run, read by NSGA-II on the recordings' track, and described in the
report; the parameters it does not take are listed as varied in its training."""

from __future__ import annotations

import json

import pytest

from railsusp.config import ConfigError
from railsusp.pipeline import STAGES, load_config, run_pipeline
from railsusp.pipeline_inputs import METHOD_REVISIONS, stage_section
from railsusp.surrogate.network_set import read_network_set, resolve_network_set
from railsusp.surrogate.pretrained import PRETRAINED_RUN

RUN = """
name = "pretrained"
conditions = [{{base="straight", duration_s=4.0, n_steps=200}}]
[campaign]
samples = 8
batch_size = 8
parameters = ["X13", "X14", "X17"]
[sensitivity]
base_samples = 64
statistics = ["mean"]
max_keys = 2
[surrogate]
model = "{model}"
pretrained = "{pretrained}"
[field]
truth = {{ X13 = 16.1, X18 = 45.0 }}
with_track = {with_track}
track_noise_mm = {track_noise}
[estimate]
pop_size = 6
n_gen = 2
statistic = "{statistic}"
refine = false
{draws}"""


def config(tmp_path, model="cnn-gru-seq", pretrained="c80_k6", with_track="true", stat="aligned"):
    path = tmp_path / "c.toml"
    noise = 0.5 if with_track == "true" else 0.0  # the geometry's error, stated
    path.write_text(
        RUN.format(
            model=model,
            pretrained=pretrained,
            with_track=with_track,
            statistic=stat,
            track_noise=noise,
            # NSGA-II draws the geometry's error only on time-aligned forces (else refused)
            draws="geometry_draws = 3\n" if stat == "aligned" else "",
        )
    )
    return path


@pytest.mark.parametrize(
    "change, match",
    [
        ({"model": "bp"}, r"surrogate.pretrained = 'c80_k6' holds 'cnn-gru-seq' networks"),
        ({"pretrained": "no-such-set"}, r"'no-such-set': neither a network set shipped"),
        (
            {"with_track": "false", "stat": "mean"},
            "surrogate.pretrained needs recordings with their measured track geometry",
        ),
    ],
)
def test_a_network_set_that_cannot_serve_is_refused_before_any_stage(tmp_path, change, match):
    path = config(tmp_path, **change)
    with pytest.raises(ConfigError, match=match) as err:
        load_config(path)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "run").exists()


def test_a_condition_outside_the_set_s_training_is_refused(tmp_path):
    path = config(tmp_path)
    path.write_text(
        path.read_text().replace('base="straight"', 'base="curve", curve_radius_m=900.0')
    )
    with pytest.raises(ConfigError, match="curve_radius_m = 900.0, outside"):
        load_config(path)


def test_without_a_network_set_the_surrogate_stage_hashes_as_before(tmp_path):
    from railsusp.pipeline import PipelineConfig

    # the demo's surrogate section as hashed before [surrogate] pretrained existed
    before = {
        "model": "bp",
        "samples": 128,
        "seed": 1,
        "epochs": 8,
        "fine_tune_epochs": 0,
        "batches_per_epoch": 60,
        "batch_size": 512,
        "device": "cpu",
    }
    own = PipelineConfig.model_validate({"surrogate": before})
    assert stage_section(own, "surrogate") == before


def test_a_set_is_hashed_by_its_content_and_not_by_unused_training_settings(tmp_path):
    import shutil

    cfg = load_config(config(tmp_path))
    first = stage_section(cfg, "surrogate")
    # what it is checked against: the conditions' names and the wagon (since stop 66)
    assert set(first) == {"model", "pretrained", "network_set", "conditions", "model_identity"}
    more = cfg.model_copy(update={"surrogate": cfg.surrogate.model_copy(update={"epochs": 99})})
    assert stage_section(more, "surrogate") == first  # not used with a set: nothing reruns
    # the same set under its folder with one network's weights replaced: another set
    copy = tmp_path / "set"
    shutil.copytree(resolve_network_set("c80_k6"), copy)
    mine = cfg.model_copy(
        update={"surrogate": cfg.surrogate.model_copy(update={"pretrained": str(copy)})}
    )
    same = stage_section(mine, "surrogate")["network_set"]
    assert same == first["network_set"]
    weights = copy / "curve" / "model.pt"
    data = bytearray(weights.read_bytes())
    data[len(data) // 2] ^= 0xFF  # one byte of the weights changed
    weights.write_bytes(bytes(data))
    assert stage_section(mine, "surrogate")["network_set"] != same


@pytest.fixture(scope="module")
def pretrained_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("pre")
    out = root / "run"
    seen = []
    state = run_pipeline(load_config(config(root)), out, progress=lambda s, m: seen.append((s, m)))
    return out, state, seen


def test_the_run_estimates_with_the_shipped_networks(pretrained_run):
    out, state, seen = pretrained_run
    assert [s for s, _ in seen] == list(STAGES)
    ns = read_network_set(resolve_network_set("c80_k6"))
    sur = out / PRETRAINED_RUN / "surrogates"
    assert (sur / "compare.csv").exists()
    assert (sur / "cnn-gru-seq" / "straight" / "model.pt").exists()
    assert state["stages"]["surrogate"]["info"]["pretrained"] == "c80_k6"
    est = json.loads((out / "estimate" / "estimate.json").read_text())
    # the set's own key parameters, not the sensitivity stage's two
    assert tuple(est["parameters"]) == ns.parameters
    assert est["config"]["statistic"] == "aligned"
    # the geometry's stated 0.5 mm error drawn, its bias taken off NSGA-II's choice
    assert est["nsga_geometry"]["draws"] == 3 and est["nsga_geometry"]["bias_removed"]
    assert "errors in variables" in (out / "report.html").read_text("utf-8")
    held = {e["symbol"]: e["assumed"] for e in est["not_estimated"]}
    assert set(held) == {f"X{i}" for i in range(11, 21)} - set(ns.parameters)
    assert set(held.values()) == {"varied"}
    report = (out / "report.html").read_text("utf-8")
    assert "Network set &#x27;c80_k6&#x27;" in report or "Network set 'c80_k6'" in report
    # a set carried over to today's force laws says so, and what its commands train on
    assert "carried over without training" in report
    assert "Trained by (on the force laws of its training)" in report


def test_an_unchanged_run_keeps_its_copied_networks(pretrained_run, tmp_path):
    out, _, _ = pretrained_run
    seen = []
    run_pipeline(load_config(config(tmp_path)), out, progress=lambda s, m: seen.append((s, m)))
    assert dict(seen) == dict.fromkeys(STAGES, "up to date")


def test_the_pretrained_example_loads_with_the_shipped_set():
    from pathlib import Path

    cfg = load_config(Path(__file__).resolve().parents[1] / "examples" / "pretrained.toml")
    assert cfg.surrogate.pretrained == "c80_k6" and cfg.surrogate.model == "cnn-gru-seq"
    assert cfg.estimate.statistic == "aligned" and cfg.field.with_track


def test_the_answer_says_why_the_set_s_other_parameters_are_not_estimated(pretrained_run):
    """The set's training varied X15 and X17 (X17 also sampled by this run's campaign, X15
    not): the answer says they are not the force model's inputs, rather than "not a key
    parameter" or "not varied", which described surrogates trained in the run."""
    from railsusp import summary

    out, _, _ = pretrained_run
    table = summary.estimate_table(out)
    note = "not an input of the force model (varied in its training)"
    assert table.loc["X17"].note == note and table.loc["X15"].note == note
    assert table.loc["X17"].verdict.startswith(summary.NOT_ESTIMATED + ": held at")
    assert "(varied over" in table.loc["X17"].verdict


def test_a_time_aligned_run_estimates_again_for_the_geometry_bias(tmp_path):
    """Runs on time-aligned forces hash their estimate stage with NSGA-II's geometry route
    (since the choice gets the geometry error's bias taken off, such a run estimates again);
    runs on record statistics hash as before."""
    aligned = load_config(config(tmp_path))
    assert stage_section(aligned, "estimate")["nsga_geometry"] == "first SIMEX step"
    means = load_config(config(tmp_path, stat="mean"))
    section = stage_section(means, "estimate", legacy=True)  # as hashed before stop 66
    assert "nsga_geometry" not in section
    unset = {
        "held_prior",
        "channel_gains",
        "expected_draws",
        "expected_generations",
        "simulator_corrections",
        "correction_slopes",
        "slope_update",
        "preview_generations",
        "preview_s",
    }
    assert section == means.estimate.model_dump(exclude=unset)
    # since: without the refinement its settings are not read, the wagon's name is
    refine = {"refine_evaluations", "refine_screen", "refine_starts"}
    assert not means.estimate.refine
    assert stage_section(means, "estimate") == {
        **means.estimate.model_dump(exclude=unset | refine),
        "wagon": None,
        "method_revision": METHOD_REVISIONS["estimate"],
    }


def test_first_order_corrections_hash_the_simulators_check_of_their_steps(tmp_path):
    """With correction_slopes the section names the trust region's check (since it came,
    such a run estimates again); without it the section has no such entry. slope_update
    counts only when not the default ('simulated', as before it existed), and Broyden's
    update names its step floor (a run made before the floor estimates again)."""
    import tomllib

    from railsusp.pipeline_config import PipelineConfig

    text = tomllib.loads(config(tmp_path).read_text())
    assert "correction_steps" not in stage_section(PipelineConfig.model_validate(text), "estimate")
    text["estimate"].update(simulator_corrections=2, correction_slopes=True)
    section = stage_section(PipelineConfig.model_validate(text), "estimate")
    assert section["correction_steps"] == "checked by the simulator's cost (trust region)"
    assert "slope_update" not in section
    text["estimate"]["slope_update"] = "broyden"
    broyden = stage_section(PipelineConfig.model_validate(text), "estimate")
    assert broyden["slope_update"] == "broyden"
    assert broyden["broyden_min_step"] == 0.01  # the floor of the update, since it came
    assert "broyden_min_step" not in section


def test_expected_draws_hash_their_route_and_whether_the_generations_use_them(tmp_path):
    """Without expected draws the estimate section hashes as before they existed; with them
    it names the expected-forces polish as NSGA-II's geometry route and always carries
    expected_generations (before 2026-11-29 expected draws meant NSGA-II's generations, so a
    run hashed then estimates again), and turning the generations on changes the hash."""
    import tomllib

    from railsusp.pipeline_config import PipelineConfig

    text = tomllib.loads(config(tmp_path).read_text())
    plain = stage_section(PipelineConfig.model_validate(text), "estimate")
    assert "expected_generations" not in plain and "expected_draws" not in plain
    text["estimate"]["expected_draws"] = 8
    polished = stage_section(PipelineConfig.model_validate(text), "estimate")
    assert polished["nsga_geometry"] == "expected-forces polish"
    assert polished["expected_draws"] == 8 and polished["expected_generations"] is False
    text["estimate"]["expected_generations"] = True
    assert stage_section(PipelineConfig.model_validate(text), "estimate") != polished


def test_a_run_with_expected_draws_polishes_and_validates_on_them(pretrained_run, tmp_path):
    """The same run with ``expected_draws = 2`` and one simulator correction: only the
    estimate and what follows run again; NSGA-II's choice is polished on the shipped
    networks' expected forces instead of the SIMEX step, then corrected for their level
    error by one simulation of it on the same draws; the validation averages its
    re-simulations over the same draws, and the report says all three."""
    import shutil
    import tomllib

    from railsusp.pipeline_config import PipelineConfig

    out, _, _ = pretrained_run
    run = tmp_path / "run"
    shutil.copytree(out, run)
    text = tomllib.loads(config(tmp_path).read_text())
    text["estimate"]["expected_draws"] = 2
    del text["estimate"]["geometry_draws"]  # (not used with expected_draws: refused)
    text["estimate"]["simulator_corrections"] = 1
    seen = []
    cfg = PipelineConfig.model_validate(text)
    run_pipeline(cfg, run, progress=lambda s, m: seen.append((s, m)))
    rerun = [s for s, m in seen if m != "up to date"]
    assert rerun == ["estimate", "validate", "report"], seen
    est = json.loads((run / "estimate" / "estimate.json").read_text())
    assert est["expected_polish"]["draws"] == 2 and est["nsga_geometry"]["draws"] == 0
    assert est["nsga_estimate_display"] == est["expected_polish"]["polished_display"]
    (step,) = est["simulator_corrections"]
    assert step["expected_draws"] == 2
    assert est["estimate_display"] == step["corrected_display"]
    val = json.loads((run / "estimate" / "validation" / "validation.json").read_text())
    assert val["expected_draws"] == 2
    report = (run / "report.html").read_text("utf-8")
    assert "polished by the force model" in report and "mean over 2 draws" in report
    assert "level error at NSGA-II&#x27;s estimate" in report


def test_a_changed_campaign_leaves_the_estimate_on_a_network_set_standing(pretrained_run, tmp_path):
    """The rerun audit of stop 65: every stage's hash held every earlier one's, so a
    changed ``[campaign]`` estimated again on a network set that never reads the campaign
    (the estimate came out byte-identical). Now the stages reading the campaign run again,
    directly or through the sensitivity (the validation reads its indices), and the
    estimate stands, done, while the campaign runs."""
    import shutil

    out, _, _ = pretrained_run
    run = tmp_path / "run"
    shutil.copytree(out, run)
    estimate = (run / "estimate/estimate.json").read_bytes()
    path = config(tmp_path)
    path.write_text(path.read_text().replace("samples = 8\n", "samples = 9\n", 1))
    seen: list = []
    during: list = []

    def progress(stage, message):
        seen.append((stage, message))
        if (stage, message) == ("sensitivity", "running"):  # the campaign has run
            during.append(json.loads((run / "pipeline.json").read_text())["stages"])

    state = run_pipeline(load_config(path), run, progress=progress)
    ran = [s for s, m in seen if m == "running"]
    assert ran == ["campaign", "sensitivity", "validate", "report"], seen
    assert (run / "estimate/estimate.json").read_bytes() == estimate
    assert state["stages"]["estimate"]["state"] == "done"
    (stages,) = during
    assert {s: stages[s]["state"] for s in ("surrogate", "field", "estimate")} == dict.fromkeys(
        ("surrogate", "field", "estimate"), "done"
    )
    assert stages["validate"]["state"] == stages["report"]["state"] == "stale"
    assert json.loads((run / "campaign/campaign.json").read_text())["config"]["samples"] == 9


@pytest.mark.parametrize("stage", ["surrogate", "estimate", "validate"])
def test_with_a_network_set_each_stage_runs_on_the_stages_it_names(pretrained_run, tmp_path, stage):
    """The dependency table on the network set's route, checked against what each stage
    opens (test_pipeline_reads.runs_on_its_inputs_alone): the surrogate reads no campaign,
    the estimate neither campaign nor sensitivity."""
    from test_pipeline_reads import runs_on_its_inputs_alone

    out, _, _ = pretrained_run
    assert runs_on_its_inputs_alone(load_config(config(tmp_path)), out, tmp_path, stage)
