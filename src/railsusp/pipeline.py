"""The whole method in one run directory: campaign -> sensitivity -> surrogates -> field
recordings -> estimation -> validation -> report.

Each stage is skipped when its outputs exist and its inputs (its part of the configuration
and the hashes of the stages it reads) are unchanged; ``start_from`` forces a restart from a
stage. A failing stage leaves the previous stages' outputs intact; ``pipeline.json`` records
each stage's input hash, timing and state, and its files' sizes and SHA-256 (a file changed
since makes the stage run again), and the error says how to resume.

The configuration, its models and its reading, is :mod:`railsusp.pipeline_config`; what
each stage hashes and does is :mod:`railsusp.pipeline_stages`; this module runs the stages
in order and keeps ``pipeline.json``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from railsusp.errors import RailsuspInputError
from railsusp.integrity import file_hashes, file_mtimes, file_sizes

# the configuration's public names, imported from here by users, tests, benches and docs
from railsusp.pipeline_config import PipelineConfig as PipelineConfig  # re-export
from railsusp.pipeline_config import demo_config as demo_config  # re-export
from railsusp.pipeline_config import load_config as load_config  # re-export
from railsusp.pipeline_stages import stage_runners, stage_section
from railsusp.pipeline_state import (
    PIPELINE_FORMAT,
    blame,
    outputs_exist,
    run_state,
    stage_files,
)
from railsusp.pipeline_state import STAGES as STAGES  # re-export
from railsusp.run_lock import run_lock
from railsusp.store import code_identity, content_hash, provenance, utc_now, write_json
from railsusp.summary import read_tolerances

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
) -> dict:
    """Run the stages in order, skipping the up-to-date ones; returns ``pipeline.json``.

    ``progress(stage, message)`` reports stage starts; ``run_progress(done, total)`` the
    campaign's simulations. ``out`` is a new or empty folder, or a run directory to resume:
    a folder holding other files is refused (the stages would write over them). ``options``
    name ``out`` and ``start_from`` in the errors (the command line's, or the API's).
    ``checked``: ``config`` has been through :func:`~railsusp.config.check_config` already
    (:func:`~railsusp.pipeline_config.load_config` does it), so it is not checked again: a
    measured folder's recordings are read in full by that check.
    """
    from railsusp.config import check_config, check_cuda
    from railsusp.input_checks import check_output_folder

    out_option, from_option = options
    out = check_output_folder(out, out_option)
    if start_from is not None and start_from not in STAGES:
        raise RailsuspInputError(f"{from_option} {start_from!r}: accepted {', '.join(STAGES)}")
    state = run_state(out, out_option)
    if not checked:
        check_config(config)  # every combination, before any stage runs
    check_cuda(config, "configuration", surrogate_done=_surrogate_kept(config, state, start_from))
    out.mkdir(parents=True, exist_ok=True)
    with run_lock(out, out_option):  # one run at a time in a folder
        # read again under the lock: another run may have ended meanwhile
        return _run_stages(
            config,
            out,
            run_state(out, out_option),
            start_from,
            progress,
            run_progress,
            from_option,
        )


def stage_hashes(config: PipelineConfig, stages: Sequence[str] = STAGES) -> dict[str, str]:
    """The hash that decides whether each of ``stages`` (the first ones of :data:`STAGES`,
    in order) runs again: its section's (:func:`~railsusp.pipeline_stages.stage_section`)
    with the hashes of every stage before it, so that a changed stage reruns all after it."""
    upstream: dict[str, str] = {}
    for stage in stages:
        upstream[stage] = content_hash(
            {"section": stage_section(config, stage), "upstream": dict(upstream), "stage": stage}
        )
    return upstream


def _surrogate_kept(config: PipelineConfig, state: dict, start_from: str | None) -> bool:
    """Whether the surrogate stage will be skipped as up to date: done, and neither it nor a
    stage before it changed, nor a restart from one of them. Done alone passed a run whose
    changed campaign then simulated again before its training failed on a missing CUDA
    device (the rerun audit of stop 65)."""
    forced = STAGES.index(start_from) if start_from else len(STAGES)
    upto = STAGES[: STAGES.index("surrogate") + 1]
    return all(
        state["stages"].get(stage, {}).get("hash") == h
        and state["stages"][stage].get("state") == "done"
        and i < forced
        for i, (stage, h) in enumerate(stage_hashes(config, upto).items())
    )


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
    from railsusp.report_html import mark_report_stale

    state_path = out / "pipeline.json"
    state["format"] = PIPELINE_FORMAT  # what this railsusp writes (run_state refuses newer)
    state["config"] = config.model_dump(mode="json")
    # the verdicts' tolerances as the run read them: open_run judges with these, not with
    # whatever wagon file a relative path names from its own working folder
    state["tolerances"] = read_tolerances(config.wagon).to_dict()
    # and the wagon its recordings are read as, for the same reason: its data (axle spread)
    # and its static wheel load (runs of stop 59 recorded this alone; summary reads both)
    state.update(_wagon_record(config))
    forced = STAGES.index(start_from) if start_from else len(STAGES)
    hashes = stage_hashes(config)
    runners = stage_runners(config, out, run_progress)
    ran = False
    for i, stage in enumerate(STAGES):
        h = hashes[stage]
        prev = state["stages"].get(stage, {})
        up_to_date = (
            prev.get("hash") == h
            and prev.get("state") == "done"
            and i < forced
            and outputs_exist(
                config, out, stage, prev.get("files"), prev.get("sha256"), prev.get("mtime_ns")
            )
        )
        if up_to_date:
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
            log.debug("stage %s: running", stage)
            if progress:
                progress(stage, "running")
            t0 = time.perf_counter()
            state["stages"][stage] = {"hash": h, "state": "running"}
            _mark_later_stale(state, stage)
            # the report, rebuilt last, must not stand as this run's answer meanwhile (a
            # failed or interrupted run left it so): a stale banner until it is remade
            mark_report_stale(out, stage)
            write_json(state_path, state)
            try:
                info = runners[stage]() or {}
            except Exception as exc:
                log.info("stage %s: failed after %.1f s", stage, time.perf_counter() - t0)
                state["stages"][stage] = {"hash": h, "state": "failed", "error": str(exc)}
                write_json(state_path, state)
                raise StageError(
                    f"stage {stage!r} failed: {exc}. Earlier stages are kept; fix the cause "
                    f"and run the same command again (or {_resume(from_option, stage)})"
                    + blame(config, out, stage, str(exc))
                ) from exc
            files = stage_files(config, out, stage)
            state["stages"][stage] = {
                "hash": h,
                "state": "done",
                "info": info,
                "seconds": time.perf_counter() - t0,
                "finished": utc_now(),
                "made_by": made_by,  # stages of one run may come from two commits
                "files": file_sizes(files, out),
                # and their contents: an edit that keeps a file's size is found too
                "sha256": file_hashes(files, out),
                "mtime_ns": file_mtimes(files, out),  # unchanged by stat: not hashed again
            }
            write_json(state_path, state)
            log.info("stage %s: done in %.1f s", stage, state["stages"][stage]["seconds"])
            forced = min(forced, i + 1)  # everything downstream reruns
        if stage == "field":  # written or up to date: later stages need only its conditions
            release_cut()
    if ran:
        state["provenance"]["finished"] = utc_now()
    write_json(state_path, state)
    return state


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


def _mark_later_stale(state: dict, stage: str) -> None:
    """The stages after ``stage`` that pipeline.json says are done, marked ``stale`` when
    ``stage`` starts to run: their outputs are of the run before (every later stage runs
    again after it), so :func:`railsusp.open_run` must not read them as this run's answer if
    ``stage`` fails or is interrupted."""
    for later in STAGES[STAGES.index(stage) + 1 :]:
        entry = state["stages"].get(later)
        if isinstance(entry, dict) and entry.get("state") == "done":
            entry["state"] = "stale"
