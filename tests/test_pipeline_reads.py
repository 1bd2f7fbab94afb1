"""What makes a pipeline stage run again (stop 66, after the rerun audit of stop 65): the
settings it reads on the route it takes, and the stages whose outputs it reads
(:func:`railsusp.pipeline_inputs.stage_inputs`), not every earlier stage; a run directory
hashed before stays up to date once, re-hashed."""

from __future__ import annotations

import json
import os
import shutil
import sys
from importlib import resources

import pytest

from railsusp.pipeline import STAGES, PipelineConfig, load_config, run_pipeline, stage_hashes
from railsusp.pipeline_inputs import (
    METHOD_REVISIONS,
    stage_dependents,
    stage_inputs,
    stage_section,
)
from railsusp.vehicle import MODEL_REVISION
from test_pipeline import TINY, _up_to_date_copy, tiny  # noqa: F401  (the module's run)


def _config(**sections) -> PipelineConfig:
    return PipelineConfig.model_validate({"field": {"truth": {"X13": 16.1}}, **sections})


def test_each_stage_reads_the_stages_it_names():
    """The dependency table's shape on the two surrogate routes (what each stage opens is
    checked by the tests below): a network set reads no campaign, so neither does an
    estimate on it; the report reads everything; stale marking follows the table."""
    trained, pretrained = _config(), _config(surrogate={"pretrained": "c80_k6"})
    assert stage_inputs(pretrained, "surrogate") == ()
    assert stage_inputs(pretrained, "estimate") == ("surrogate", "field")
    assert set(stage_inputs(trained, "estimate")) > set(stage_inputs(pretrained, "estimate"))
    assert stage_inputs(trained, "report") == STAGES[:-1]
    assert stage_dependents(trained, "campaign") == STAGES[1:3] + STAGES[4:]
    assert stage_dependents(pretrained, "campaign") == ("sensitivity", "validate", "report")
    assert stage_dependents(trained, "field") == ("estimate", "validate", "report")
    for cfg in (trained, pretrained):  # every stage reads only earlier ones
        for i, stage in enumerate(STAGES):
            assert set(stage_inputs(cfg, stage)) <= set(STAGES[:i])


def test_a_change_reruns_the_stages_that_read_it_and_only_them():
    """A changed field (another noise) changes the field's hash and those of the stages
    reading it, not the campaign's, sensitivity's or surrogate's (before: the chain held
    every earlier stage, so the field's change reached them all the same, but a campaign's
    change reached the field)."""
    base = stage_hashes(_config())
    noisier = stage_hashes(_config(field={"truth": {"X13": 16.1}, "noise": 0.05}))
    changed = {s for s in STAGES if base[s] != noisier[s]}
    assert changed == {"field", "estimate", "validate", "report"}
    seeded = stage_hashes(_config(campaign={"seed": 3}))
    assert {s for s in STAGES if base[s] != seeded[s]} == set(STAGES) - {"field"}


def test_settings_a_route_never_reads_run_nothing_again():
    """``[field] rate_hz`` (read by a long run's cut alone) with a synthetic truth, and the
    refinement's settings without the refinement, ran the field or estimate stage and every
    stage after it again (the estimate came out byte-identical). They count where read."""
    base = _config()
    rate = _config(field={"truth": {"X13": 16.1}, "rate_hz": 1000.0})
    assert stage_section(rate, "field") == stage_section(base, "field")
    assert stage_section(rate, "field", legacy=True) != stage_section(base, "field", legacy=True)
    more = _config(estimate={"refine_evaluations": 80, "refine_starts": 3})
    assert stage_section(more, "estimate") == stage_section(base, "estimate")
    refined = _config(estimate={"refine": True})
    more_refined = _config(estimate={"refine": True, "refine_evaluations": 80})
    assert stage_section(refined, "estimate") != stage_section(more_refined, "estimate")
    assert stage_section(base, "field")["route"] == "truth"
    seeded = _config(field={"truth": {"X13": 16.1}, "seed": 8})
    assert stage_section(seeded, "field") != stage_section(base, "field")


def test_the_wagon_counts_by_its_data_not_by_its_name(tmp_path):
    """The packaged wagon and a path to a copy of its file simulated the campaign again;
    now the simulated stages hash the wagon's data. The estimate, which records the wagon
    by name for a later validation, runs again; an edited copy simulates again."""
    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    copy = tmp_path / "wagon.toml"
    copy.write_text(text)
    packaged, mine = _config(), _config(wagon=str(copy))
    same = ("campaign", "sensitivity", "surrogate", "field")
    for stage in same:
        assert stage_section(mine, stage) == stage_section(packaged, stage), stage
        assert stage_section(mine, stage, legacy=True) != stage_section(
            packaged, stage, legacy=True
        ) or stage in ("sensitivity", "surrogate")
    assert stage_section(mine, "estimate")["wagon"] == str(copy.resolve())
    assert stage_section(mine, "estimate") != stage_section(packaged, "estimate")
    copy.write_text(text.replace("gib_stiffness = 50.0e6", "gib_stiffness = 40.0e6"))
    assert stage_section(mine, "campaign") != stage_section(packaged, "campaign")


def test_a_measured_folder_counts_by_its_files_contents(tmp_path):
    """A measured folder counted its files by size and modification time: a ``touch``
    copied it and estimated again, and recordings replaced by others of the same size
    with their times kept (``cp -p``) were not seen. Now by their contents."""
    folder = tmp_path / "measured"
    folder.mkdir()
    rec = folder / "straight.csv"
    rec.write_text("t [s],Y [kN]\n0.0,1.0\n")
    cfg = _config(field={"measured": str(folder)})
    first = stage_section(cfg, "field")
    legacy = stage_section(cfg, "field", legacy=True)
    st = rec.stat()
    os.utime(rec, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # touched
    assert stage_section(cfg, "field") == first
    assert stage_section(cfg, "field", legacy=True) != legacy
    stamped = rec.stat().st_mtime_ns
    rec.write_text("t [s],Y [kN]\n0.0,2.0\n")  # other contents, the same size and time
    os.utime(rec, ns=(st.st_atime_ns, stamped))
    replaced = stage_section(cfg, "field")
    assert replaced != first
    (folder / ".hidden").write_text("x")  # a hidden file is not the user's recording
    assert stage_section(cfg, "field") == replaced
    (folder / "notes.txt").write_text("x")  # the user's own file is copied: it counts
    assert stage_section(cfg, "field") != replaced


def test_a_run_directory_hashed_before_keeps_its_simulations_and_estimates_again(
    tiny,  # noqa: F811
    tmp_path,
    caplog,
):
    """A run directory of before stop 66 holds each stage's hash with every earlier stage's
    (``stage_hashes(..., legacy=True)``): its campaign, sensitivity, surrogates and field are
    taken as up to date for the same configuration and re-hashed, so that an upgrade does
    not simulate a campaign again; the stages railsusp computes otherwise since
    (``METHOD_REVISIONS``: a run of before 9f0bf17 kept estimates on record statistics
    counted otherwise, the upgrade audit) run again, saying why. A legacy hash of another
    configuration is not taken."""
    cfg_path, out, _, _ = tiny
    cfg = load_config(cfg_path)
    run = tmp_path / "run"
    shutil.copytree(out, run)
    run_pipeline(cfg, run)  # up to date for this configuration (other tests change it)
    state_path = run / "pipeline.json"
    state = json.loads(state_path.read_text())
    old = stage_hashes(cfg, legacy=True)
    new = stage_hashes(cfg)
    assert all(old[s] != new[s] for s in STAGES)
    for s in STAGES:
        state["stages"][s]["hash"] = old[s]
        state["stages"][s].pop("method_revision", None)
    state_path.write_text(json.dumps(state))
    seen: list = []
    with caplog.at_level("INFO", logger="railsusp.pipeline"):
        run_pipeline(cfg, run, progress=lambda s, m: seen.append((s, m)))
    kept = [s for s in STAGES if s not in METHOD_REVISIONS]
    assert seen == [(s, "up to date") for s in kept] + [(s, "running") for s in METHOD_REVISIONS]
    assert "stage estimate: runs again: its settings changed, or railsusp computes it " in (
        caplog.text
    )
    assert "stage validate: runs again: it reads the outputs of estimate" in caplog.text
    stages = json.loads(state_path.read_text())["stages"]
    assert {s: stages[s]["hash"] for s in STAGES} == new
    assert stages["estimate"]["method_revision"] == METHOD_REVISIONS["estimate"]
    # an old hash of another configuration is not taken
    for s in STAGES:
        stages[s]["hash"] = old[s]
    state_path.write_text(json.dumps({**state, "stages": stages}))
    changed = tmp_path / "changed.toml"
    changed.write_text(TINY.replace("truth = { X13 = 16.1 }", "truth = { X13 = 16.2 }"))
    seen = []
    run_pipeline(load_config(changed), run, progress=lambda s, m: seen.append((s, m)))
    assert [s for s, m in seen if m == "running"] == ["field", "estimate", "validate", "report"]


def test_a_changed_force_law_revision_is_named_as_the_reason(tiny, tmp_path, caplog):  # noqa: F811
    """An upgrade of the force laws simulated the campaign again (hours, for a real one)
    with no word of why: the first stage that runs again names both revisions."""
    cfg, _, run = _up_to_date_copy(tiny, tmp_path)
    state_path = run / "pipeline.json"
    state = json.loads(state_path.read_text())
    assert state["stages"]["campaign"]["model_revision"] == MODEL_REVISION
    assert "model_revision" not in state["stages"]["sensitivity"]  # it simulates nothing
    state["stages"]["campaign"]["model_revision"] = "2000-01-01.1"
    state["stages"]["campaign"]["hash"] = "of the force laws before"
    state_path.write_text(json.dumps(state))
    with caplog.at_level("INFO", logger="railsusp.pipeline"):
        run_pipeline(cfg, run)
    assert (
        f"stage campaign: runs again: the force laws' revision changed (2000-01-01.1 -> "
        f"{MODEL_REVISION})" in caplog.text
    )
    assert "stage sensitivity: runs again: it reads the outputs of campaign" in caplog.text


def test_a_format_0_record_kept_up_to_date_gets_its_hashes(tiny, tmp_path):  # noqa: F811
    """A run recorded before the files' SHA-256 were (format 0) kept up to date was
    relabelled format 1 without them, so an edit keeping a file's size went unseen from
    then on (the upgrade audit). Its stages now get their files' hashes recorded."""
    cfg, _, run = _up_to_date_copy(tiny, tmp_path)
    state_path = run / "pipeline.json"
    state = json.loads(state_path.read_text())
    recorded = {s: state["stages"][s]["sha256"] for s in STAGES}
    for s in STAGES:
        del state["stages"][s]["sha256"], state["stages"][s]["mtime_ns"]
    del state["format"]
    state_path.write_text(json.dumps(state))
    seen: list = []
    run_pipeline(cfg, run, progress=lambda s, m: seen.append((s, m)))
    assert {m for _, m in seen} == {"up to date"}
    again = json.loads(state_path.read_text())
    assert again["format"] == 1
    assert {s: again["stages"][s]["sha256"] for s in STAGES} == recorded


@pytest.mark.parametrize("start", ["campaign", "field"])
def test_a_restart_from_a_stage_runs_every_later_stage(tiny, tmp_path, start):  # noqa: F811
    """``--from`` is the user's word: it runs that stage and every one after it, read or
    not (the dependency table decides only what a changed input runs again)."""
    cfg_path, out, _, _ = tiny
    run = tmp_path / "run"
    shutil.copytree(out, run)
    cfg = load_config(cfg_path)
    run_pipeline(cfg, run)
    seen: list = []
    run_pipeline(cfg, run, start_from=start, progress=lambda s, m: seen.append((s, m)))
    assert [s for s, m in seen if m == "running"] == list(STAGES[STAGES.index(start) :])


def _measured_run(tiny, tmp_path):  # noqa: F811
    """A copy of the tiny run brought up to date on a measured folder (a copy of its field)."""
    _, out, _, _ = tiny
    measured = tmp_path / "measured"
    shutil.copytree(out / "field", measured)
    head, _ = TINY.split("[field]")
    estimate = TINY[TINY.index("[estimate]") :]
    path = tmp_path / "measured.toml"
    path.write_text(f"{head}[field]\nmeasured = {str(measured)!r}\n{estimate}")
    cfg = load_config(path)
    run = tmp_path / "run"
    shutil.copytree(out, run)
    run_pipeline(cfg, run)
    return cfg, run, measured


def _as_hashed_before(cfg, run) -> None:
    """pipeline.json's hashes made as before stop 66 (``legacy``)."""
    path = run / "pipeline.json"
    state = json.loads(path.read_text())
    for s, h in stage_hashes(cfg, legacy=True).items():
        state["stages"][s]["hash"] = h
    path.write_text(json.dumps(state))


def test_a_measured_copy_of_before_is_taken_only_if_its_contents_are_the_folders(
    tiny,  # noqa: F811
    tmp_path,
):
    """The review of stop 66: a field hash of before took a measured folder's files by size
    and modification time, so recordings replaced by others of the same size with their
    times kept were taken as up to date by it, and then locked in by the new hash (of the new
    contents) while RUN/field held the old copy. It is taken only where each file's SHA-256
    is its copy's as recorded."""
    cfg, run, measured = _measured_run(tiny, tmp_path)
    _as_hashed_before(cfg, run)
    seen: list = []
    run_pipeline(cfg, run, progress=lambda s, m: seen.append((s, m)))
    assert ("field", "up to date") in seen  # the same contents: kept
    _as_hashed_before(cfg, run)
    rec = measured / "truth.json"
    st = rec.stat()
    text = rec.read_text()
    swapped = text.replace("1", "2", 1)
    assert len(swapped) == len(text) and swapped != text
    rec.write_text(swapped)  # other contents, the same size, the time kept (cp -p)
    os.utime(rec, ns=(st.st_atime_ns, st.st_mtime_ns))
    seen = []
    run_pipeline(cfg, run, progress=lambda s, m: seen.append((s, m)))
    assert ("field", "running") in seen
    assert (run / "field/truth.json").read_text() == swapped


def test_a_failed_rerun_leaves_no_stage_of_other_inputs_standing(tiny, tmp_path, monkeypatch):  # noqa: F811
    """The review of stop 66: a rerun marked stale only the stages reading the first stage
    that ran, so after that stage failed a later stage whose own settings had changed stayed
    `done` and open_run served it as this configuration's. Now it is stale too (a stage
    whose inputs did not change stands: the network-set test of test_pipeline_pretrained)."""
    import railsusp.pipeline as pipeline

    cfg_path, out, _, _ = tiny
    run = tmp_path / "run"
    shutil.copytree(out, run)
    run_pipeline(load_config(cfg_path), run)
    changed = tmp_path / "changed.toml"  # the campaign and the field changed
    changed.write_text(
        TINY.replace("samples = 10\n", "samples = 11\n").replace("X13 = 16.1", "X13 = 16.2")
    )
    cfg = load_config(changed)
    assert "field" not in stage_dependents(cfg, "campaign")

    def runners(config, out, run_progress):
        def fail() -> dict:
            raise RuntimeError("out of memory")

        return dict.fromkeys(STAGES, fail)

    monkeypatch.setattr(pipeline, "stage_runners", runners)
    with pytest.raises(pipeline.StageError, match="out of memory"):
        run_pipeline(cfg, run)
    stages = json.loads((run / "pipeline.json").read_text())["stages"]
    assert stages["campaign"]["state"] == "failed"
    # the field reads no campaign, but its truth changed: not this configuration's either
    assert {stages[s]["state"] for s in STAGES[1:]} == {"stale"}


#: the files opened while a hook below is listening (sys.addaudithook cannot be removed)
_OPENED: list[str] | None = None


def _listen(event: str, args: tuple) -> None:
    if _OPENED is not None and event == "open" and isinstance(args[0], str | os.PathLike):
        _OPENED.append(os.path.realpath(args[0]))


def runs_on_its_inputs_alone(cfg, out, tmp_path, stage):
    """Run ``stage`` twice on copies of the finished run directory ``out``, listening to the
    files it opens: once with every file there, once with those of the stages it does not
    read (:func:`stage_inputs`) removed. A stage that opens an undeclared stage's outputs
    (in the copy, or in ``out``: a result records the field folder by its absolute path)
    fails the first, one that reads them otherwise (Parquet through Arrow) the second; a
    stage that looks for one and falls back without it fails the first (it would be left
    up to date on stale ones)."""
    global _OPENED
    from railsusp.pipeline_stages import stage_runners
    from railsusp.pipeline_state import stage_files

    keep = {stage, *stage_inputs(cfg, stage)}
    if _listen not in _HOOKED:
        sys.addaudithook(_listen)
        _HOOKED.append(_listen)
    result = None
    for removed in (False, True):
        run = tmp_path / f"only-{stage}-{removed}"
        shutil.copytree(out, run)
        forbidden = set()
        for other in STAGES:
            if other not in keep:
                for f in stage_files(cfg, run, other):
                    forbidden.add(os.path.realpath(f))
                    if removed:
                        f.unlink(missing_ok=True)
                forbidden |= {os.path.realpath(f) for f in stage_files(cfg, out, other)}
        _OPENED = []
        try:
            result = stage_runners(cfg, run)[stage]()
            read = sorted(forbidden.intersection(_OPENED))
        finally:
            _OPENED = None
        assert not read, f"{stage} read outputs of stages it does not name: {read}"
    return result


_HOOKED: list = []


@pytest.mark.parametrize("stage", ["sensitivity", "surrogate", "estimate", "validate"])
def test_a_stage_runs_on_the_outputs_of_the_stages_it_names(tiny, tmp_path, stage):  # noqa: F811
    """The dependency table checked against what the stages read (trained surrogates):
    each runs with the outputs of its inputs alone."""
    cfg_path, out, _, _ = tiny
    cfg = load_config(cfg_path)
    assert runs_on_its_inputs_alone(cfg, out, tmp_path, stage) is not None


def test_another_campaign_batch_size_runs_nothing_again(tiny, tmp_path, caplog):  # noqa: F811
    """``[campaign] batch_size`` only groups the same simulations into files: changed on a
    finished run it simulated the campaign again and ran every stage after it (the stop 67
    note). The stored batches are kept, said, and the run stays up to date; the campaign
    changed otherwise still runs again, in the batch size asked for."""
    cfg, _, run = _up_to_date_copy(tiny, tmp_path)
    regrouped = cfg.model_copy(
        update={"campaign": cfg.campaign.model_copy(update={"batch_size": 4})}
    )
    seen: list = []
    with caplog.at_level("WARNING", logger="railsusp.pipeline"):
        run_pipeline(regrouped, run, progress=lambda s, m: seen.append((s, m)))
    assert {m for _, m in seen} == {"up to date"}
    assert caplog.text.count("holds the campaign in batches of 10: kept (batch_size = 4") == 1
    state = json.loads((run / "pipeline.json").read_text())
    assert state["config"]["campaign"]["batch_size"] == 10  # what the stages ran with
    reseeded = regrouped.model_copy(
        update={"campaign": regrouped.campaign.model_copy(update={"seed": 5})}
    )
    seen.clear()
    run_pipeline(reseeded, run, progress=lambda s, m: seen.append((s, m)))
    assert ("campaign", "running") in seen
    batches = sorted(p.name for p in (run / "campaign" / "batches" / "short").iterdir())
    assert len(batches) == 2 * 3  # 10 samples in batches of 4: series and features files
