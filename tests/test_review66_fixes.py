"""Findings 2, 5 and 6 of the review of stop 66, each test failing on the code it reviewed:

* the stale banner a standalone command puts on a run directory's report went by the
  folder the command names, not what it writes there (``train RUN/campaign`` writes
  ``campaign/surrogates`` and ``campaign/splits``, which no stage records where the
  pipeline's surrogates are ``surrogate-campaign``'s, and named stage 'campaign'), and
  stayed when the command was refused by its own checks after its locks (``open_run(RUN)
  .report_path`` then refused a report whose run directory nothing had changed);
* ``open_run`` warned of a run whose stages are all current (``OutdatedModelWarning``)
  from a ``surrogate-campaign/campaign.json`` of older force laws left behind by a switch
  of the surrogate route;
* the pipeline's field stage read and copied a ``[field] measured`` folder without its
  shared lock, so a ``railsusp synth-field --out F`` could rewrite it under the copy.

The run directories are made by hand (a few small files and the ``pipeline.json`` that
records them), so each test takes a second or two."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest
from typer.testing import CliRunner

import railsusp
import railsusp.vehicle
from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.store import atomic_write_text, file_hash
from test_locks_cli import held

runner = CliRunner()
OLD = "2000-01-01.1"  # a force-law revision before this railsusp's

#: each stage's files in a run directory made with the default ``[surrogate] samples``
#: (its surrogates trained on their own campaign, ``surrogate-campaign``)
DEFAULT_FILES = {
    "campaign": {"campaign/features.parquet": "features"},
    "sensitivity": {"campaign/sensitivity/key_parameters.json": '{"keys": []}'},
    "surrogate": {"surrogate-campaign/surrogates/compare.csv": "model,nrmse\nbp,0.1\n"},
    "estimate": {"estimate/estimate.json": None},  # this revision's estimate
}

#: the same with ``samples = 0``: the surrogates trained on the sensitivity campaign
OWN_CAMPAIGN_FILES = {
    **DEFAULT_FILES,
    "surrogate": {
        "campaign/surrogates/compare.csv": "model,nrmse\nbp,0.1\n",
        "campaign/splits/seed-0.json": '{"test": []}',
    },
}

REPORT_HTML = "<html><head><title>r</title></head><body><h1>Answer</h1></body></html>\n"
REPORT_MD = "# Answer\n"


def _record(run: Path, stages: dict[str, list[str]], config: dict | None = None) -> None:
    """``run``'s pipeline.json: each stage done with ``stages``' files as they are now (sizes
    and SHA-256), as the pipeline records a finished stage."""
    state: dict = {"format": 1, "stages": {}}
    if config is not None:
        state["config"] = config
    for stage, files in stages.items():
        state["stages"][stage] = {
            "hash": "h",
            "state": "done",
            "files": {f: (run / f).stat().st_size for f in files},
            "sha256": {f: file_hash(run / f) for f in files},
        }
    (run / "pipeline.json").write_text(json.dumps(state))


def _fake_run(tmp_path: Path, layout: dict[str, dict[str, str | None]]) -> Path:
    """A finished run directory of ``layout`` (stage -> file -> text) with its report."""
    run = tmp_path / "run"
    stages: dict[str, list[str]] = {}
    for stage, files in layout.items():
        for rel, text in files.items():
            path = run / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            if text is None:
                text = json.dumps({"model_revision": railsusp.vehicle.MODEL_REVISION})
            path.write_text(text)
        stages[stage] = list(files)
    (run / "report.html").write_text(REPORT_HTML)
    (run / "report.md").write_text(REPORT_MD)
    stages["report"] = ["report.html", "report.md"]
    _record(run, stages)
    return run


def _report(run: Path) -> tuple[str, str]:
    return (run / "report.html").read_text(), (run / "report.md").read_text()


def _invoke(*args) -> object:
    return runner.invoke(app, ["-q", *map(str, args)])


def test_train_on_the_campaign_leaves_a_report_whose_surrogates_are_elsewhere(tmp_path):
    """With the default ``samples``, ``train RUN/campaign`` writes nothing a stage recorded:
    the report stays, and it still answers for the run. Before, it was marked stale naming
    stage 'campaign' (whose files lie under ``campaign/``), here by a command that failed at
    once on a campaign with no ``campaign.json``."""
    run = _fake_run(tmp_path, DEFAULT_FILES)
    result = _invoke("train", run / "campaign", "--model", "gp-stats")
    assert result.exit_code == 2, result.output
    assert "campaign.json" in result.output
    assert _report(run) == (REPORT_HTML, REPORT_MD)
    assert railsusp.open_run(run).report_path == run.resolve() / "report.html"


@pytest.mark.parametrize("command", ["train", "compare"])
def test_a_command_refused_by_its_own_checks_takes_its_banner_off_again(tmp_path, command):
    """With ``samples = 0`` the surrogate stage's files are ``campaign/surrogates`` and
    ``campaign/splits``, which train and compare write: the report is marked before they
    write, and put back as it was when they end without having changed any of them (here:
    refused, no ``campaign.json``). Before, the banner stayed and ``report_path`` refused
    the report."""
    run = _fake_run(tmp_path, OWN_CAMPAIGN_FILES)
    extra = ["--model", "gp-stats"] if command == "train" else ["--models", "gp-stats"]
    result = _invoke(command, run / "campaign", *extra)
    assert result.exit_code == 2, result.output
    assert "campaign.json" in result.output
    assert _report(run) == (REPORT_HTML, REPORT_MD)
    assert railsusp.open_run(run).report_path.is_file()


@pytest.fixture
def analysing(monkeypatch):
    """``railsusp sensitivity``'s analysis replaced: it notes the report's banner while it
    works, runs ``state["write"]`` (if set), then fails as bad input."""
    import railsusp.sensitivity

    state: dict = {"write": None, "seen": None}

    def analyse(run, **kwargs):
        state["seen"] = (Path(run).parent / "report.md").read_text()
        if state["write"] is not None:
            state["write"](Path(run))
        raise RailsuspInputError("stopped here")

    monkeypatch.setattr(railsusp.sensitivity, "analyse", analyse)
    return state


def test_the_banner_stands_while_the_command_works_and_goes_if_it_wrote_nothing(
    tmp_path, analysing
):
    """``sensitivity RUN/campaign`` on the default run: the report carries the banner
    (naming stage 'sensitivity') while the analysis works, and is the run's again once it
    failed without writing."""
    run = _fake_run(tmp_path, DEFAULT_FILES)
    result = _invoke("sensitivity", run / "campaign")
    assert result.exit_code == 2 and "stopped here" in result.output, result.output
    assert "STALE" in analysing["seen"] and "stage 'sensitivity'" in analysing["seen"]
    assert "`railsusp sensitivity` was started on" in analysing["seen"]
    assert _report(run) == (REPORT_HTML, REPORT_MD)
    assert railsusp.open_run(run).report_path.is_file()


def test_a_command_that_failed_after_writing_a_stages_file_leaves_the_banner(tmp_path, analysing):
    """Its analysis replaced ``key_parameters.json`` before failing: the report no longer
    shows what the folder holds, so the banner stays (and report_path refuses it)."""
    run = _fake_run(tmp_path, DEFAULT_FILES)
    analysing["write"] = lambda camp: atomic_write_text(
        camp / "sensitivity" / "key_parameters.json", '{"keys": ["X13"]}'
    )
    result = _invoke("sensitivity", run / "campaign")
    assert result.exit_code == 2, result.output
    html, md = _report(run)
    assert "stage 'sensitivity'" in md and "STALE" in html
    with pytest.raises(RailsuspInputError, match="report"):
        _ = railsusp.open_run(run).report_path


def _revision_run(tmp_path: Path, surrogate: dict, recorded: dict[str, str]) -> Path:
    """A run directory whose campaign, estimate and surrogates (``recorded``: file ->
    revision) are of this railsusp's revision or as given, its configuration's
    ``[surrogate]`` being ``surrogate``, and a ``surrogate-campaign`` of older force laws
    left beside it (no stage records it)."""
    run = tmp_path / "run"
    now = railsusp.vehicle.MODEL_REVISION
    stages = {
        "campaign": {"campaign/campaign.json": now},
        "estimate": {"estimate/estimate.json": now},
        "surrogate": recorded,
    }
    for files in stages.values():
        for rel, revision in files.items():
            (run / rel).parent.mkdir(parents=True, exist_ok=True)
            (run / rel).write_text(json.dumps({"model_revision": revision}))
    left = run / "surrogate-campaign" / "campaign.json"
    if not left.exists():
        left.parent.mkdir(parents=True)
        left.write_text(json.dumps({"model_revision": OLD}))
    _record(run, {s: list(f) for s, f in stages.items()}, {"surrogate": surrogate})
    return run


def _opened(run: Path) -> tuple[object, list[str]]:
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        result = railsusp.open_run(run)
    return result, [str(w.message) for w in seen if "force-law revision" in str(w.message)]


@pytest.mark.parametrize(
    "surrogate, files",
    [
        (
            {"pretrained": "c80-loaded", "samples": 128},
            {"surrogate-pretrained/surrogates/networks.json": "now"},
        ),
        ({"pretrained": None, "samples": 0}, {"campaign/surrogates/bp/meta.json": "now"}),
    ],
    ids=["pretrained", "samples-0"],
)
def test_a_left_behind_surrogate_campaign_of_older_force_laws_is_not_the_runs(
    tmp_path, surrogate, files
):
    now = railsusp.vehicle.MODEL_REVISION
    run = _revision_run(tmp_path, surrogate, {f: now for f in files})
    result, seen = _opened(run)
    assert seen == []
    assert result.model_revision == now


def test_the_surrogate_campaign_the_run_records_is_still_read(tmp_path):
    """The default route: its own campaign of older force laws, recorded by the surrogate
    stage, is warned of as before."""
    run = _revision_run(
        tmp_path,
        {"pretrained": None, "samples": 128},
        {"surrogate-campaign/campaign.json": OLD},
    )
    _, seen = _opened(run)
    assert len(seen) == 1
    assert (
        f"force-law revision {OLD}, older than this railsusp's {railsusp.vehicle.MODEL_REVISION} "
        "(surrogate-campaign/campaign.json)"
    ) in seen[0]


def test_a_run_recording_no_files_reads_the_route_its_configuration_takes(tmp_path):
    """A run made before files were recorded: the configuration's route decides."""
    now = railsusp.vehicle.MODEL_REVISION
    run = _revision_run(
        tmp_path,
        {"pretrained": "c80-loaded", "samples": 128},
        {"surrogate-pretrained/surrogates/networks.json": now},
    )
    state = json.loads((run / "pipeline.json").read_text())
    for entry in state["stages"].values():
        for key in ("files", "sha256"):
            entry.pop(key)
    (run / "pipeline.json").write_text(json.dumps(state))
    assert _opened(run)[1] == []
    state["config"]["surrogate"] = {"pretrained": None, "samples": 128}
    (run / "pipeline.json").write_text(json.dumps(state))
    (line,) = _opened(run)[1]
    assert f"{OLD}, older than" in line and "(surrogate-campaign/campaign.json)" in line


def _synthetic(folder: Path) -> Path:
    """A small synthetic field folder (one condition, 50 steps) at ``folder``."""
    from railsusp.conditions import get_condition
    from railsusp.measured import synthesise_field
    from railsusp.params import ParameterSet

    cond = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    return synthesise_field(ParameterSet({"X13": 16.1}, units="display"), [cond], folder)


@pytest.fixture
def measured(tmp_path) -> Path:
    """Another run directory's field folder (made by hand), as ``[field] measured``."""
    return _synthetic(tmp_path / "other" / "field")


def _measured_config(folder: Path):
    from railsusp.pipeline_config import PipelineConfig

    return PipelineConfig.model_validate({"field": {"measured": str(folder)}})


def test_the_field_stage_is_refused_while_a_writer_works_in_the_measured_folder(tmp_path, measured):
    """A ``synth-field --out F`` holding F (another process here): the field stage is
    refused at once, in one line naming F and the holder, and copies nothing. Before, it
    read and copied F beside the writer."""
    from railsusp.pipeline_field import field_stage

    out = tmp_path / "run"
    with held("exclusive", measured) as pid:
        with pytest.raises(RailsuspInputError) as refused:
            field_stage(_measured_config(measured), out)
    line = str(refused.value)
    assert line.startswith(f"field.measured {measured}: another railsusp run is working")
    assert f"(process {pid})" in line and "\n" not in line
    assert not (out / "field").exists()


def test_the_field_stage_is_refused_while_a_run_works_in_the_folders_run_directory(
    tmp_path, measured
):
    """F is another run directory's ``field``: ``railsusp run`` on that one (which holds it
    alone, not its field) rewrites F, so it is refused too."""
    from railsusp.pipeline_field import field_stage

    other = measured.parent
    (other / "pipeline.json").write_text('{"stages": {}}')
    with held("exclusive", other) as pid:
        with pytest.raises(RailsuspInputError, match=f"its run directory {other} .process {pid}"):
            field_stage(_measured_config(measured), tmp_path / "run")


def test_the_field_stage_copies_the_folder_beside_readers_and_its_own_run(tmp_path):
    """Readers of F (shared) do not stop it; nor does the run directory the pipeline holds
    itself (as ``railsusp run`` does), F lying in it. The copy leaves F's lock file out."""
    from railsusp.pipeline_field import field_stage
    from railsusp.run_lock import LOCK_NAME, run_lock

    out = tmp_path / "run"
    folder = _synthetic(out / "recordings")
    (out / "pipeline.json").write_text('{"stages": {}}')
    with held("shared", folder), run_lock(out, "--out"):
        info = field_stage(_measured_config(folder), out)
    assert info == {"recordings": 1, "synthetic": False}
    copied = out / "field"
    assert (copied / "index.json").read_bytes() == (folder / "index.json").read_bytes()
    assert not (copied / LOCK_NAME).exists()
