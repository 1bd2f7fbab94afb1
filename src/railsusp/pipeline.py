"""The whole method in one run directory: campaign -> sensitivity -> surrogates -> field
recordings -> estimation -> validation -> report.

Each stage is skipped when its outputs exist and its inputs (its part of the configuration
and the hashes of the stages it reads) are unchanged; ``start_from`` forces a restart from a
stage. A failing stage leaves the previous stages' outputs intact; ``pipeline.json`` records
each stage's input hash, timing and state, and its files' sizes and SHA-256 (a file changed
since makes the stage run again), and the error says how to resume.

The configuration, its model and its reading, is :mod:`railsusp.pipeline_config`, its
sections' models :mod:`railsusp.config_sections`; what each stage hashes and reads is
:mod:`railsusp.pipeline_inputs`, what it does :mod:`railsusp.pipeline_stages`; this module
runs the stages in order and keeps ``pipeline.json``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from railsusp.errors import OutputStreamError, RailsuspInputError
from railsusp.integrity import file_hashes, file_mtimes, file_sizes
from railsusp.interrupts import stop_if_interrupted

# the configuration's public names, imported from here by users, tests, benches and docs
from railsusp.pipeline_config import PipelineConfig as PipelineConfig  # re-export
from railsusp.pipeline_config import demo_config as demo_config  # re-export
from railsusp.pipeline_config import load_config as load_config  # re-export
from railsusp.pipeline_inputs import (
    METHOD_REVISIONS,
    in_stored_batches,
    measured_copy_matches,
    stage_dependents,
    stage_inputs,
    stage_section,
)
from railsusp.pipeline_stages import stage_runners
from railsusp.pipeline_state import (
    PIPELINE_FORMAT,
    blame,
    outputs_exist,
    run_state,
    stage_files,
)
from railsusp.pipeline_state import STAGES as STAGES  # re-export
from railsusp.provenance import code_identity, provenance, utc_now
from railsusp.run_lock import run_lock
from railsusp.store import content_hash, remove_stale_temporaries, write_json
from railsusp.suspension_tolerances import read_tolerances
from railsusp.vehicle.revision import this_revision

#: stage finishes with their elapsed time (info) and starts (debug), for the command line
log = logging.getLogger("railsusp.pipeline")


class StageError(RailsuspInputError):
    """A stage failed; earlier stages' outputs are intact."""


def run_pipeline(
    config: PipelineConfig,
    out: str | Path,
    *,
    start_from: str | None = None,
    progress: Callable[[str, str], None] | None = None,
    run_progress: Callable[[int, int], None] | None = None,
    options: tuple[str, str] = ("--out", "--from"),
    checked: bool = False,
    finished: Callable[[dict], None] | None = None,
    source: str = "configuration",
) -> dict:
    """Run the stages in order, skipping the up-to-date ones; returns ``pipeline.json``.

    ``progress(stage, message)`` reports stage starts; ``run_progress(done, total)`` the
    campaign's simulations. ``out`` is a new or empty folder, or a run directory to resume:
    a folder holding other files is refused (the stages would write over them). ``options``
    name ``out`` and ``start_from`` in the errors (the command line's, or the API's).
    ``checked``: ``config`` has been through :func:`~railsusp.config.check_config` already
    (:func:`~railsusp.pipeline_config.load_config` does it), so it is not checked again: a
    measured folder's recordings are read in full by that check. ``finished(state)`` is
    called once the stages are done, before the run directory's lock is let go: what it
    reads there is this run's (``railsusp run``'s summary, read after, could print a second
    run's tables beside this one's). ``source`` names the configuration in its errors: the
    TOML file it was read from, as :func:`~railsusp.pipeline_config.load_config`'s checks
    name it.
    """
    from railsusp.config import check_config, check_cuda
    from railsusp.input_checks import check_output_folder

    out_option, from_option = options
    out = check_output_folder(out, out_option)
    if start_from is not None and start_from not in STAGES:
        raise RailsuspInputError(f"{from_option} {start_from!r}: accepted {', '.join(STAGES)}")
    state = run_state(out, out_option)
    if not checked:
        check_config(config, source)  # every combination, before any stage runs
    # the campaign's stored batch size, hashed as such (decided again under the lock)
    kept = _surrogate_kept(in_stored_batches(config, out, say=False), state, start_from)
    check_cuda(config, source, surrogate_done=kept)
    out.mkdir(parents=True, exist_ok=True)
    with run_lock(out, out_option):  # one run at a time in a folder
        # temporaries a killed run left of its own files (pipeline.json, the reports),
        # under the lock: kept for good before (the QA of stop 74)
        remove_stale_temporaries(out)
        # read again under the lock: another run may have ended meanwhile
        state = _run_stages(
            in_stored_batches(config, out),
            out,
            run_state(out, out_option),
            start_from,
            progress,
            run_progress,
            from_option,
        )
        if finished is not None:
            finished(state)
        return state


def stage_hashes(
    config: PipelineConfig, stages: Sequence[str] = STAGES, legacy: bool = False
) -> dict[str, str]:
    """The hash that decides whether each of ``stages`` (the first ones of :data:`STAGES`,
    in order) runs again: its section's (:func:`~railsusp.pipeline_inputs.stage_section`)
    with the hashes of the stages it reads (:func:`~railsusp.pipeline_inputs.stage_inputs`),
    so that a changed stage reruns those that read it, and only them. ``legacy``: the
    hashes as made before stop 66 (each with every earlier stage's), which a run directory
    of before holds; :func:`_run_stages` takes them as up to date, so that such a run
    directory is not made again from its campaign on."""
    hashes: dict[str, str] = {}
    for i, stage in enumerate(stages):
        section = stage_section(config, stage, legacy)
        if legacy:
            record = {"section": section, "upstream": {s: hashes[s] for s in stages[:i]}}
        else:
            record = {
                "section": section,
                "reads": {s: hashes[s] for s in stage_inputs(config, stage)},
            }
        hashes[stage] = content_hash({**record, "stage": stage})
    return hashes


def _recorded_current(entry: dict, h: str, legacy: str | None) -> bool:
    """Whether a stage's record in ``pipeline.json`` is done with the inputs of now: its
    hash, or the hash of before stop 66 for the same inputs (re-recorded as the new one
    once the stage is found up to date; None for a stage computed otherwise since)."""
    return entry.get("state") == "done" and entry.get("hash") in {h, legacy} - {None}


def _surrogate_kept(config: PipelineConfig, state: dict, start_from: str | None) -> bool:
    """Whether the surrogate stage will be skipped as up to date: done, and neither it nor a
    stage it reads changed, nor a restart from one of them. Done alone passed a run whose
    changed campaign then simulated again before its training failed on a missing CUDA
    device (the rerun audit of stop 65)."""
    forced = set(STAGES[STAGES.index(start_from) :]) if start_from else set()
    upto = STAGES[: STAGES.index("surrogate") + 1]
    hashes, legacy = stage_hashes(config, upto), stage_hashes(config, upto, legacy=True)

    def kept(stage: str) -> bool:
        entry = state["stages"].get(stage, {})
        return (
            stage not in forced
            and _recorded_current(entry, hashes[stage], legacy[stage])
            and all(kept(s) for s in stage_inputs(config, stage))
        )

    return kept("surrogate")


def _run_stages(
    config: PipelineConfig,
    out: Path,
    state: dict,
    start_from: str | None,
    progress: Callable[[str, str], None] | None,
    run_progress: Callable[[int, int], None] | None,
    from_option: str = "--from",
) -> dict:
    """:func:`run_pipeline`'s stages in order on the run directory ``out`` whose
    ``pipeline.json`` is ``state`` (its lock held), the up-to-date ones skipped. A long
    run's cut, read by the configuration check, is let go once the field stage is passed
    (run or skipped): a resumed run kept it (0.5 GB for 2 h at 1 kHz) to its end."""
    from railsusp.measured.cut import release_cut
    from railsusp.report_stale import mark_report_stale

    state_path = out / "pipeline.json"
    state["format"] = PIPELINE_FORMAT  # what this railsusp writes (run_state refuses newer)
    state["config"] = config.model_dump(mode="json")
    # the verdicts' tolerances as the run read them: open_run judges with these, not with
    # whatever wagon file a relative path names from its own working folder
    state["tolerances"] = read_tolerances(config.wagon).to_dict()
    # and the wagon its recordings are read as, for the same reason: its data (axle spread)
    # and its static wheel load (runs of stop 59 recorded this alone; summary reads both)
    state.update(_wagon_record(config))
    revisions = (_recorded_revision(out), this_revision())  # the campaign's, this railsusp's
    forced = set(STAGES[STAGES.index(start_from) :]) if start_from else set()
    hashes, legacy = stage_hashes(config), stage_hashes(config, legacy=True)
    for stage in METHOD_REVISIONS:  # computed otherwise since: made again, not taken
        legacy[stage] = None
    if not measured_copy_matches(config, out, state["stages"].get("field", {})):
        # the legacy hash took a measured folder's files by size and time: a copy of other
        # contents would be taken as up to date, and then locked in by the new hash
        legacy["field"] = None
    runners = stage_runners(config, out, run_progress)
    ran = False
    ran_stages: set[str] = set()  # those run now: the stages reading them run again
    for stage in STAGES:
        # a Ctrl-C swallowed meanwhile (raised inside a garbage-collector callback, Python
        # prints it and goes on) stops the run here, its finished stages recorded
        stop_if_interrupted()
        h = hashes[stage]
        prev = state["stages"].get(stage, {})
        up_to_date = (
            _recorded_current(prev, h, legacy[stage])
            and stage not in forced
            and not ran_stages.intersection(stage_inputs(config, stage))
            and outputs_exist(
                config, out, stage, prev.get("files"), prev.get("sha256"), prev.get("mtime_ns")
            )
        )
        if up_to_date:
            prev["hash"] = h  # a record of before stop 66, for the same inputs, re-hashed
            if "sha256" not in prev:  # a record of before the hashes (format 0): read as
                # its sizes say, and recorded as format 1 holds it from now on
                _record_files(prev, stage_files(config, out, stage), out)
            log.debug("stage %s: up to date", stage)
            if progress:
                progress(stage, "up to date")
        else:
            if not ran:  # who and what runs the stages, before the first of them: the
                # report stage shows it (set after the stages, the report showed the
                # invocation before, or nothing on a first run); a run of up-to-date
                # stages alone leaves the provenance of the one that made them
                made_by = code_identity()  # the code of this run's stages, asked git once
                state["provenance"] = provenance(made_by)
            ran = True
            why = _why_again(config, stage, prev, (h, legacy[stage]), ran_stages, forced, revisions)
            if why:  # a rerun of hours of simulation says why (the upgrade audit of stop 66)
                log.info("stage %s: runs again: %s", stage, why)
            log.debug("stage %s: running", stage)
            if progress:
                progress(stage, "running")
            t0 = time.perf_counter()
            state["stages"][stage] = {"hash": h, "state": "running"}
            # the stages reading it run again after it, and so do those whose own inputs
            # changed: neither's outputs stand as this run's meanwhile (the review of stop 66)
            changed = [
                s
                for s in STAGES[STAGES.index(stage) + 1 :]
                if not _recorded_current(state["stages"].get(s, {}), hashes[s], legacy[s])
            ]
            _mark_later_stale(state, (*stage_dependents(config, stage), *changed))
            # the report, rebuilt last, must not stand as this run's answer meanwhile (a
            # failed or interrupted run left it so): a stale banner until it is remade
            mark_report_stale(out, stage)
            write_json(state_path, state)
            try:
                info = runners[stage]() or {}
            except OutputStreamError as exc:  # the printout refused, not the stage: said so
                said = f"its printout to {exc.stream} failed: {exc.strerror}"
                state["stages"][stage] = {"hash": h, "state": "failed", "error": said}
                write_json(state_path, state)
                raise
            except Exception as exc:
                log.info("stage %s: failed after %.1f s", stage, time.perf_counter() - t0)
                state["stages"][stage] = {"hash": h, "state": "failed", "error": str(exc)}
                write_json(state_path, state)
                raise StageError(
                    f"stage {stage!r} failed: {exc}. Earlier stages are kept; fix the cause "
                    f"and run the same command again (or {_resume(from_option, stage)})"
                    + blame(config, out, stage, str(exc))
                ) from exc
            state["stages"][stage] = {
                "hash": h,
                "state": "done",
                "info": info,
                "seconds": time.perf_counter() - t0,
                "finished": utc_now(),
                "made_by": made_by,  # stages of one run may come from two commits
            }
            if stage in METHOD_REVISIONS:  # how railsusp computed it (its hash holds it too)
                state["stages"][stage]["method_revision"] = METHOD_REVISIONS[stage]
            if stage in _SIMULATED:  # the force laws it simulated with (or was checked on)
                state["stages"][stage]["model_revision"] = this_revision()
            _record_files(state["stages"][stage], stage_files(config, out, stage), out)
            write_json(state_path, state)
            log.info("stage %s: done in %.1f s", stage, state["stages"][stage]["seconds"])
            ran_stages.add(stage)  # the stages reading its outputs run again
        if stage == "field":  # written or up to date: later stages need only its conditions
            release_cut()
    if ran:
        state["provenance"]["finished"] = utc_now()
    write_json(state_path, state)
    return state


def _record_files(entry: dict, files: list[Path], out: Path) -> None:
    """A finished stage's record of its files in ``pipeline.json``: their sizes, their
    contents' SHA-256 (an edit that keeps a file's size is found too) and modification
    times (a file unchanged by stat is not hashed again)."""
    entry["files"] = file_sizes(files, out)
    entry["sha256"] = file_hashes(files, out)
    entry["mtime_ns"] = file_mtimes(files, out)


def _recorded_revision(out: Path) -> str | None:
    """The force laws' revision of the run directory's campaign (its ``campaign.json``), for
    the stages recorded before they recorded their own; None where it says none."""
    from railsusp.store import read_json

    try:
        got = read_json(out / "campaign" / "campaign.json").get("model_revision")
    except (RailsuspInputError, AttributeError):
        return None
    return got if isinstance(got, str) else None


#: the stages that simulate with the force laws (a network set is checked against them)
_SIMULATED = ("campaign", "surrogate", "field")


def _why_again(
    config: PipelineConfig,
    stage: str,
    prev: dict,
    taken: tuple[str, str | None],
    ran_stages: set[str],
    forced: set[str],
    revisions: tuple[str | None, str],
) -> str | None:
    """Why a stage with a record in ``pipeline.json`` runs again, in words, or None where
    the user knows (a first run, a restart they asked for) or a warning said it (a file of
    its gone or changed). ``taken``: the hashes its record is current with (this one's,
    the legacy one or None). The force laws' change is named (``revisions``: the run
    directory's campaign's, for a record that states none, and this railsusp's): an upgrade
    simulated a campaign of hours again with no word."""
    if not prev or stage in forced:
        return None
    read = [s for s in stage_inputs(config, stage) if s in ran_stages]
    if read:  # (and those marked it stale meanwhile)
        return f"it reads the outputs of {', '.join(read)}, made again now"
    state = prev.get("state")
    if state != "done":
        told = {"failed": "it failed", "running": "it was interrupted", "stale": "it was stale"}
        return f"{told.get(state, f'its state was {state!r}')} in the run before"
    if prev.get("hash") in set(taken) - {None}:
        return None  # its files: outputs_exist has warned
    before, now = prev.get("model_revision") or revisions[0], revisions[1]
    if stage in _SIMULATED and before is not None and before != now:
        return f"the force laws' revision changed ({before} -> {now})"
    if stage in METHOD_REVISIONS and prev.get("method_revision") != METHOD_REVISIONS[stage]:
        return (
            f"its settings changed, or railsusp computes it otherwise since (method revision "
            f"{METHOD_REVISIONS[stage]})"
        )
    return "its settings or the inputs it hashes changed"


def _resume(from_option: str, stage: str) -> str:
    """How to start again from ``stage``: ``--from estimate`` on the command line,
    ``start_from='estimate'`` from Python."""
    return f"{from_option}={stage!r}" if from_option.isidentifier() else f"{from_option} {stage}"


def _wagon_record(config: PipelineConfig) -> dict:
    """``pipeline.json``'s record of the run's wagon: its data as read (``wagon_data``) and
    its static wheel load (``static_wheel_load_N``, N)."""
    from railsusp.vehicle.setup import static_wheel_load
    from railsusp.vehicle.wagon import load_wagon

    wagon = load_wagon(config.wagon)
    return {
        "static_wheel_load_N": static_wheel_load(wagon),
        "wagon_data": wagon.model_dump(mode="json"),
    }


def _mark_later_stale(state: dict, dependents: Sequence[str]) -> None:
    """The ``dependents`` of a stage (:func:`~railsusp.pipeline_inputs.stage_dependents`)
    that pipeline.json says are done, marked ``stale`` when that stage starts to run: their
    outputs are of the run before (they run again after it), so :func:`railsusp.open_run`
    must not read them as this run's answer if the stage fails or is interrupted. Other
    stages' outputs stand (an estimate on a network set, while the campaign runs again)."""
    for later in dependents:
        entry = state["stages"].get(later)
        if isinstance(entry, dict) and entry.get("state") == "done":
            entry["state"] = "stale"
