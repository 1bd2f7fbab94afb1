"""A run directory's state: whether a folder is a railsusp run (its ``pipeline.json``), where
each stage writes, and whether what a finished stage wrote is still there and reads.

:mod:`railsusp.pipeline` runs the stages; this module answers its questions about the
folder, so that the API (:func:`railsusp.api.open_run`) can read a run without running one.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable
from pathlib import Path, PurePosixPath, PureWindowsPath

from railsusp._version import __version__
from railsusp.errors import RailsuspInputError, first_listed
from railsusp.integrity import changed_files, files_under, unreadable_files
from railsusp.numbers import is_real, is_whole
from railsusp.pipeline_config import PipelineConfig
from railsusp.stages import STAGES
from railsusp.store import read_json

log = logging.getLogger("railsusp.pipeline")

#: the layout of ``pipeline.json`` and of the run directory this railsusp writes (its
#: ``format``; a run made before it was recorded states none: format 0). Raised when a
#: change would make an older railsusp misread a run directory; a run directory of a
#: higher format, made by a newer railsusp, is refused rather than rerun and written over
#: (:func:`run_state`). 1: the field ``format`` itself, and each finished stage's files'
#: ``sha256`` beside their sizes (an older railsusp reading it compares the sizes alone)
PIPELINE_FORMAT = 1


#: what the stages write at the top of a run directory (a run whose pipeline.json was lost
#: holds only these, and resumes: its campaign's batches are still matched by campaign.json)
RUN_ENTRIES = (
    "campaign",
    "field",
    "estimate",
    "surrogate-campaign",
    "surrogate-pretrained",
    "report.html",
    "report.md",
    "report_assets",
)


def _ignorable(entry: Path) -> bool:
    """A file a new run directory may already hold: hidden (``.gitkeep``, ``.DS_Store``) or
    a configuration (the study's TOML kept beside its run); the stages write neither."""
    return entry.name.startswith(".") or (entry.is_file() and entry.suffix == ".toml")


def _lost_its_state(out: Path, entries: list[Path]) -> bool:
    """A railsusp run directory whose ``pipeline.json`` was lost: nothing but the stages'
    own outputs, its campaign's ``campaign.json`` among them (a user's own ``report.html``
    alone is not that)."""
    try:
        made_here = read_json(out / "campaign" / "campaign.json").get("kind")
    except (RailsuspInputError, AttributeError):
        return False
    return made_here == "railsusp campaign" and all(e.name in RUN_ENTRIES for e in entries)


def run_state(out: Path, option: str) -> dict:
    """The state of the run directory ``out`` (its ``pipeline.json``), or a new state for a
    folder that does not exist or holds nothing the stages could write over; refuse a
    folder of other files, or one whose ``pipeline.json`` is not a railsusp run's."""
    state_path = out / "pipeline.json"
    if not state_path.exists():
        others = [p for p in out.iterdir() if not _ignorable(p)] if out.is_dir() else []
        if others and not _lost_its_state(out, others):
            raise RailsuspInputError(
                f"{option} {out}: a folder holding other files and no pipeline.json; give a "
                "new or empty folder, or a railsusp run directory to resume"
            )
        _refuse_newer_campaigns(out, option)
        return {"stages": {}}
    state = read_run_state(
        out,
        f"{option} {out}",
        "; give a new or empty folder",
        damaged="; delete it to resume: a run directory without pipeline.json resumes from "
        "its stages' outputs",
    )
    made = state.get("format", 0)  # a whole number from 0: read_run_state checked it
    if made > PIPELINE_FORMAT:
        raise RailsuspInputError(
            f"{option} {out}: its pipeline.json is of format {made!r}, written by a newer "
            f"railsusp than this one (format {PIPELINE_FORMAT}, railsusp {__version__}), "
            "whose stages this one would run again and write over; run it with that "
            f"railsusp, or give a new {option}"
        )
    _refuse_newer_campaigns(out, option)
    return state


def _refuse_newer_campaigns(out: Path, option: str) -> None:
    """Refuse a run directory holding a campaign simulated with force laws newer than this
    railsusp's (a newer railsusp's run): the pipeline runs its campaigns with ``force``,
    which discards a campaign of other force laws as outdated, and so discarded hours of a
    newer railsusp's simulations (the standalone ``railsusp campaign`` refused the same
    folder). Campaigns of older force laws are simulated again, as before."""
    from railsusp.vehicle.revision import made_with, revision_newer

    for entry in RUN_ENTRIES:
        meta_path = out / entry / "campaign.json"
        if not meta_path.is_file():
            continue
        try:
            revision = read_json(meta_path).get("model_revision")
        except (RailsuspInputError, AttributeError):  # damaged: the campaign decides
            continue
        if revision_newer(revision):
            raise RailsuspInputError(
                f"{option} {out}: the campaign in its {entry}/ was simulated with "
                f"{made_with(revision)} (a newer railsusp's run, which this one would "
                f"discard); run it with that railsusp, or give a new {option}"
            )


def read_run_state(out: Path, where: str, hint: str = "", damaged: str = "") -> dict:
    """The ``pipeline.json`` of the run directory ``out``; one that is not a railsusp run's
    (no table of stages) is a one-line error naming ``where``, ``hint`` appended; one that
    does not read (a full disk, a copy cut short) is :func:`~railsusp.store.read_json`'s
    error, ``damaged`` (the remedy) appended."""
    try:
        state = read_json(out / "pipeline.json")
    except RailsuspInputError as exc:
        if not damaged:
            raise
        raise RailsuspInputError(f"{exc}{damaged}") from None
    if not isinstance(state, dict) or not isinstance(state.get("stages"), dict):
        raise RailsuspInputError(
            f"{where}: its pipeline.json is not a railsusp run's (no stages table){hint}"
        )
    check_run_state(state, where, damaged)
    return state


#: the keys of a stage's record in ``pipeline.json`` that the pipeline and
#: :class:`~railsusp.run_result.RunResult` read, with what each must be
_ENTRY_TEXT = ("state", "hash", "error", "finished", "model_revision", "method_revision")
_ENTRY_TABLES = ("info", "made_by")
#: the stage record's tables of its files (relative path -> size, SHA-256, time in ns)
_FILE_TABLES = {
    "files": "a whole number of bytes",
    "sha256": "a hash",
    "mtime_ns": "a whole number of ns",
}
_TOP_TABLES = ("config", "provenance", "tolerances", "wagon_data")


def check_run_state(state: dict, where: str, remedy: str = "") -> None:
    """``pipeline.json``'s structure, as the pipeline and :class:`~railsusp.run_result.
    RunResult` read it, checked in one place: its ``format`` a whole number, ``config`` and
    the other records tables, each stage's record a table of text, numbers and tables of
    files whose paths lie inside the run directory. A damaged one (edited by hand, written
    by another tool) failed deep in a stage or the summary with an AttributeError or a
    ValueError, or had a file outside the run folder checked as the run's; now it is one
    line naming ``where`` and the key, ``remedy`` appended. Keys it does not know are left
    alone."""

    def damaged(key: str, value: object, needed: str, told: str = " =") -> RailsuspInputError:
        return RailsuspInputError(
            f"{where}: its pipeline.json is damaged: {key}{told} {value!r:.80}: {needed} is "
            f"needed{remedy}"
        )

    made = state.get("format", 0)
    if not is_whole(made) or made < 0:
        raise damaged("format", made, "a whole number (0 or more)")
    if made > PIPELINE_FORMAT:  # a newer railsusp's layout: its readers refuse it as such
        return  # (called damaged, it was deleted on that advice and written over)
    for key in _TOP_TABLES:
        if key in state and not isinstance(state[key], dict):
            raise damaged(key, state[key], "a table")
    load = state.get("static_wheel_load_N")
    if load is not None and not (is_real(load) and math.isfinite(load) and load > 0):
        raise damaged("static_wheel_load_N", load, "a positive number of newtons")
    surrogate = state.get("config", {}).get("surrogate", {})
    if not isinstance(surrogate, dict):
        raise damaged("config.surrogate", surrogate, "a table")
    for name, entry in state["stages"].items():
        _check_stage_entry(f"stages.{name}", entry, damaged)


def _check_stage_entry(at: str, entry: object, damaged: Callable) -> None:
    """One stage's record in ``pipeline.json`` (:func:`check_run_state`), ``at`` its key
    path; ``damaged(key, value, needed)`` makes the error."""
    if not isinstance(entry, dict):
        raise damaged(at, entry, "a table of the stage's state")
    for key in _ENTRY_TEXT:
        if key in entry and not isinstance(entry[key], str):
            raise damaged(f"{at}.{key}", entry[key], "text")
    for key in _ENTRY_TABLES:
        if key in entry and not isinstance(entry[key], dict):
            raise damaged(f"{at}.{key}", entry[key], "a table")
    seconds = entry.get("seconds", 0.0)
    if not (is_real(seconds) and math.isfinite(seconds) and seconds >= 0):
        raise damaged(f"{at}.seconds", seconds, "a number of seconds (0 or more)")
    for key, what in _FILE_TABLES.items():
        table = entry.get(key, {})
        if not isinstance(table, dict):
            raise damaged(f"{at}.{key}", table, "a table of the stage's files")
        for rel, value in table.items():
            if not _inside(rel):
                raise damaged(
                    f"{at}.{key}", rel, "a path inside the run directory", " names the file"
                )
            good = isinstance(value, str) if key == "sha256" else is_whole(value) and value >= 0
            if not good:
                raise damaged(f"{at}.{key}.{json.dumps(rel)}", value, what)


def _inside(rel: object) -> bool:
    """A file's path as a stage records it: relative to the run directory, and in it (an
    absolute path, or one climbing out with ``..``, named a file of elsewhere)."""
    if not isinstance(rel, str) or not rel.strip():
        return False
    path = PurePosixPath(rel.replace("\\", "/"))
    return not (path.is_absolute() or PureWindowsPath(rel).drive or ".." in path.parts)


_OUTPUTS = {
    "campaign": "campaign/features.parquet",
    "sensitivity": "campaign/sensitivity/key_parameters.json",
    "surrogate": "surrogates/compare.csv",  # under surrogate_campaign_dir
    "field": "field/index.json",
    "estimate": "estimate/estimate.json",
    "validate": "estimate/validation/validation.json",
    "report": "report.html",
}


def blame(config: PipelineConfig, out: Path, stage: str, message: str) -> str:
    """Where a stage's error names a file in an earlier stage's output folder (a damaged
    ``features.parquet`` failing the sensitivity stage), the hint to remake that stage:
    rerunning the failed one alone would fail the same way."""
    earlier = {s: str(_marked_output(config, out, s).parent) for s in STAGES[: STAGES.index(stage)]}
    named = [s for s, folder in earlier.items() if folder + "/" in message]
    if not named:
        return ""
    culprit = max(named, key=lambda s: len(earlier[s]))  # the most specific folder
    return f"; the file it names is stage {culprit!r}'s output: --from {culprit} remakes it"


def _marked_output(config: PipelineConfig, out: Path, stage: str) -> Path:
    """The file whose presence marks ``stage`` done (:data:`_OUTPUTS`)."""
    base = surrogate_campaign_dir(config, out) if stage == "surrogate" else out
    return base / _OUTPUTS[stage]


def surrogate_campaign_dir(config: PipelineConfig, out: str | Path) -> Path:
    """The run directory whose ``surrogates/`` the estimation uses."""
    from railsusp.surrogate.pretrained import surrogates_run

    s = config.surrogate
    return Path(out) / surrogates_run(s.pretrained, s.samples)


#: what other work keeps in a campaign folder: a sensitivity analysis, surrogates, the
#: train/validation/test splits (drawn when a surrogate first trains on the campaign) and
#: twin campaigns (made outside the pipeline, each with its own marks)
_CAMPAIGN_EXTRAS = ("sensitivity", "surrogates", "splits", "nominal", "perturbed")


def _stage_folders(config: PipelineConfig, out: Path, stage: str) -> list[tuple[Path, tuple]]:
    """The folders a stage writes, each with the subfolders in it that are not its own."""
    sur = surrogate_campaign_dir(config, out)
    # the surrogates trained on the sensitivity campaign: theirs are its surrogates and splits
    own_campaign = [] if sur == out / "campaign" else [(sur, _CAMPAIGN_EXTRAS)]
    folders: dict[str, list[tuple[Path, tuple]]] = {
        "campaign": [(out / "campaign", _CAMPAIGN_EXTRAS)],
        "sensitivity": [(out / "campaign" / "sensitivity", ())],
        "surrogate": [(sur / "surrogates", ()), (sur / "splits", ()), *own_campaign],
        "field": [(out / "field", ())],
        "estimate": [(out / "estimate", ("validation",))],
        "validate": [(out / "estimate" / "validation", ())],
        "report": [(out / "report_assets", ())],
    }
    return folders[stage]


#: files not checked: a training checkpoint is only a resume point, and one that does not
#: read is trained past (:func:`railsusp.surrogate.train.train_network`)
_UNCHECKED = ("checkpoint.pt",)


def stage_files(config: PipelineConfig, out: Path, stage: str) -> list[Path]:
    """The files a stage wrote (the marked output among them), without other stages' and
    without resume points."""
    files = [_marked_output(config, out, stage)]
    if stage == "report":  # its Markdown twin beside report.html (a lost one was not remade)
        files.append(out / "report.md")
    for folder, others in _stage_folders(config, out, stage):
        files += files_under(folder, skip_folders=others, skip_names=_UNCHECKED)
    return list(dict.fromkeys(files))


def outputs_exist(
    config: PipelineConfig,
    out: Path,
    stage: str,
    recorded: dict[str, int] | None = None,
    hashes: dict[str, str] | None = None,
    mtimes: dict[str, int] | None = None,
) -> bool:
    """The stage's output file is present, the files the run recorded when the stage finished
    (``recorded``, sizes by path; ``hashes``, their SHA-256 by path, each hashed where its
    modification time differs from ``mtimes``') are there with those sizes and contents,
    and they read (:mod:`railsusp.integrity`: Parquet footers, JSON, whole CSV lines, the
    zips of networks): a file damaged or edited after the run (a copy
    cut short, a number changed in place) makes the stage run again rather than fail a
    later one, or be shown as its answer. A run made before hashes were recorded has its
    files compared by size alone (and stays up to date); one made before sizes were has
    every file in the stage's folders checked by its format alone."""
    path = _marked_output(config, out, stage)
    if not path.is_file():  # said as a changed file is (it ran again without a word: the
        # interrupt/resume QA of stop 74, a field/ or estimate.json removed)
        log.warning("stage %s: %s is gone; the stage runs again", stage, path)
        return False
    if isinstance(recorded, dict) and recorded:
        bad = changed_files(recorded, out, hashes, mtimes)
        to_read = [path, *(out / rel for rel in recorded)]
    else:
        bad, to_read = [], stage_files(config, out, stage)
    if stage == "field":
        to_read = _field_files_read(out / "field", to_read)
    bad += [p for p in unreadable_files(dict.fromkeys(to_read)) if p not in bad]
    if bad:
        names = first_listed(bad, 3)
        verb = "is" if len(bad) == 1 else "are"
        log.warning(
            "stage %s: %s %s damaged, changed or gone; the stage runs again", stage, names, verb
        )
    return not bad


def _field_files_read(field: Path, files: list[Path]) -> list[Path]:
    """Of the field stage's files, those railsusp reads: its index, the recordings it names
    with their sidecars, and a synthetic field's truth. The stage copies a measured folder
    whole, and the user's other files in it (notes, logs, in any encoding) are checked by
    their recorded size alone: their format is not railsusp's to judge."""
    try:
        names = read_json(field / "index.json").get("recordings", [])
    except (RailsuspInputError, AttributeError):
        return files  # no index that reads: every file is checked (and the stage reruns)
    read = {"index.json", "truth.json"}
    for name in names if isinstance(names, list) else []:
        read |= {str(name), Path(str(name)).with_suffix(".json").as_posix()}
    return [p for p in files if p.is_relative_to(field) and p.relative_to(field).as_posix() in read]
