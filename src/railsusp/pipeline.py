"""The whole method in one run directory: campaign -> sensitivity -> surrogates -> field
recordings -> estimation -> validation -> report.

Each stage is skipped when its outputs exist and its inputs (its part of the configuration
and the hashes of the stages it reads) are unchanged; ``start_from`` forces a restart from a
stage. A failing stage leaves the previous stages' outputs intact; ``pipeline.json`` records
each stage's input hash, timing and state, and the error says how to resume.

The configuration, its models and its reading, is :mod:`railsusp.pipeline_config`; this
module runs the stages.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from railsusp.errors import RailsuspInputError
from railsusp.estimate.config import BROYDEN_MIN_STEP
from railsusp.integrity import file_sizes

# the configuration's public names, imported from here by users, tests, benches and docs
from railsusp.pipeline_config import PipelineConfig as PipelineConfig  # re-export
from railsusp.pipeline_config import demo_config as demo_config  # re-export
from railsusp.pipeline_config import load_config as load_config  # re-export
from railsusp.pipeline_state import STAGES as STAGES  # re-export
from railsusp.pipeline_state import (
    blame,
    outputs_exist,
    run_state,
    stage_files,
    surrogate_campaign_dir,
)
from railsusp.run_lock import run_lock
from railsusp.store import code_identity, content_hash, provenance, utc_now, write_json
from railsusp.summary import read_tolerances

#: stage finishes with their elapsed time (info) and starts (debug), for the command line
log = logging.getLogger("railsusp.pipeline")


class StageError(RailsuspInputError):
    """A stage failed; earlier stages' outputs are intact."""


def _drop_other_conditions(surrogates: Path, conditions: list) -> None:
    """Remove the surrogates of conditions the configuration no longer has from a run's
    ``surrogates/<model>/`` folders before they are trained again. The estimate loads every
    bundle of its model's folder: one left from a renamed condition, on other key
    parameters, stopped every later run in the same folder ("surrogate short uses ('X13',
    'X14'), the calibration ('X14',)"), even with ``--from campaign``."""
    import shutil

    names = {c.name for c in conditions}
    for model in surrogates.iterdir() if surrogates.is_dir() else []:
        for sub in model.iterdir() if model.is_dir() else []:
            if sub.is_dir() and sub.name not in names and not sub.name.startswith("."):
                log.info("surrogates: %s of a condition no longer configured, removed", sub)
                shutil.rmtree(sub)


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
    done = state["stages"].get("surrogate", {}).get("state") == "done" and start_from not in (
        "campaign",
        "sensitivity",
        "surrogate",
    )
    check_cuda(config, "configuration", surrogate_done=done)
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

    state_path = out / "pipeline.json"
    state["config"] = config.model_dump(mode="json")
    # the verdicts' tolerances as the run read them: open_run judges with these, not with
    # whatever wagon file a relative path names from its own working folder
    state["tolerances"] = read_tolerances(config.wagon).to_dict()
    # and the wagon its recordings are read as, for the same reason: its data (axle spread)
    # and its static wheel load (runs of stop 59 recorded this alone; summary reads both)
    state.update(_wagon_record(config))
    forced = STAGES.index(start_from) if start_from else len(STAGES)
    upstream: dict[str, str] = {}
    runners = _stage_runners(config, out, run_progress)
    ran = False
    for i, stage in enumerate(STAGES):
        section = _section(config, stage)
        h = content_hash({"section": section, "upstream": upstream, "stage": stage})
        prev = state["stages"].get(stage, {})
        up_to_date = (
            prev.get("hash") == h
            and prev.get("state") == "done"
            and i < forced
            and outputs_exist(config, out, stage, prev.get("files"))
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
            state["stages"][stage] = {
                "hash": h,
                "state": "done",
                "info": info,
                "seconds": time.perf_counter() - t0,
                "finished": utc_now(),
                "made_by": made_by,  # stages of one run may come from two commits
                "files": file_sizes(stage_files(config, out, stage), out),
            }
            write_json(state_path, state)
            log.info("stage %s: done in %.1f s", stage, state["stages"][stage]["seconds"])
            forced = min(forced, i + 1)  # everything downstream reruns
        upstream[stage] = h
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


def model_identity(config: PipelineConfig) -> dict[str, str]:
    """What the simulated stages' results depend on beyond the configuration: the wagon's
    data as read (a wagon file edited in place, or the embedded data of another railsusp)
    and the force laws' revision (:data:`railsusp.vehicle.MODEL_REVISION`). In the stage
    hashes, so that a run directory made with another model is simulated again instead of
    being reused (the demo's did, and its estimate stage then failed reading surrogates
    saved with an older wagon description)."""
    from railsusp.surrogate.pretrained import wagon_hash
    from railsusp.vehicle import MODEL_REVISION
    from railsusp.vehicle.wagon import load_wagon

    return {"wagon_data": wagon_hash(load_wagon(config.wagon)), "model_revision": MODEL_REVISION}


def _measured_state(config: PipelineConfig) -> dict:
    """What the field stage's copy of a ``[field] measured`` folder depends on beyond its
    path: every file's path in it, size and modification time (as a long run's
    ``[field] recording`` counts its files). Without them a folder whose recordings were
    replaced kept the old copy, and the estimate on it, up to date. Empty (so the stage
    hashes as before) without a measured folder."""
    if config.field.measured is None:
        return {}
    folder = Path(config.field.measured)
    files = []
    for p in sorted(folder.rglob("*")) if folder.is_dir() else []:
        if p.is_file() and not any(part.startswith(".") for part in p.relative_to(folder).parts):
            st = p.stat()
            files.append((p.relative_to(folder).as_posix(), st.st_size, st.st_mtime_ns))
    return {"measured_files": files}


def _section(config: PipelineConfig, stage: str) -> Any:
    """The inputs of ``stage`` whose hash decides whether it runs again. The conditions are
    those the run simulates, resolved (a packaged condition's values, a ``base``'s, the
    recording's cut), with the contents of their measured track-geometry files: before
    stop 60 they were hashed as written, so a packaged condition changed by an upgrade, or
    a geometry file edited in place, left every stage up to date on the old results."""
    from railsusp.vehicle.track_geometry import geometry_digests

    conditions = config.working_conditions()
    base = {
        "wagon": config.wagon,
        "conditions": [c.model_dump(mode="json") for c in conditions],
        "model": model_identity(config),
    }
    files = geometry_digests(conditions)
    if files:
        base["track_geometry_files"] = files
    source = config.run_source()
    if source is not None:  # the conditions, and the field, come from the recording's cut
        base["recording"] = repr(source.state())
    sections = {
        "campaign": {**base, **config.campaign.model_dump()},
        "sensitivity": config.sensitivity.model_dump(),
        "surrogate": _surrogate_section(config),
        "field": {**base, **config.field.model_dump(), **_measured_state(config)},
        "estimate": _estimate_section(config),
        "validate": {},
        "report": {"name": config.name},
    }
    return sections[stage]


def _estimate_section(config: PipelineConfig) -> dict:
    """The estimate stage's inputs: its settings (without a held_prior, and with
    channel_gains and expected_draws off, the section hashes as before those existed, so
    runs stay up to date; ``expected_generations`` counts only with expected draws, and
    then always: before 2026-11-29 expected draws meant NSGA-II's generations, now a polish
    after them, so such a run estimates again);
    on time-aligned forces also the route of NSGA-II's estimate, which since 2026-11-28
    takes the geometry error's bias off its choice where the recordings state their
    accuracy, so that such a run estimates again; with ``correction_slopes`` the trust
    region's check (since 2026-11-29 the simulator checks each first-order step's point, and
    the box resizes), so that such a run estimates again; with Broyden's update also its
    step floor (since stop 53 no update across a step under it), for the same reason."""
    e = config.estimate
    optional = (
        "held_prior",
        "channel_gains",
        "expected_draws",
        "simulator_corrections",
        "correction_slopes",
    )
    unset = {k for k in optional if not getattr(e, k)}
    if e.slope_update == "simulated":  # as before the setting existed
        unset.add("slope_update")
    if not e.expected_draws:
        unset.add("expected_generations")
    if not e.preview_generations:  # as before the setting existed
        unset |= {"preview_generations", "preview_s"}
    section = e.model_dump(exclude=unset or None)
    if e.statistic == "aligned":
        section["nsga_geometry"] = (
            "expected-forces polish" if e.expected_draws else "first SIMEX step"
        )
    if e.correction_slopes:
        section["correction_steps"] = "checked by the simulator's cost (trust region)"
        if e.slope_update == "broyden":  # the floor came after Broyden's update: estimate again
            section["broyden_min_step"] = BROYDEN_MIN_STEP
    return section


def _surrogate_section(config: PipelineConfig) -> dict:
    """The surrogate stage's inputs: its settings (without ``pretrained`` when unset, so a
    run made before the option existed stays up to date); with a network set only what
    is used, the model and the set (its manifest and the bytes of its networks), so that
    another set under the same name copies again and training settings change nothing."""
    s = config.surrogate
    if s.pretrained is None:
        return s.model_dump(exclude={"pretrained"})
    from railsusp.surrogate.pretrained import read_network_set, resolve_network_set, set_hash

    ns = read_network_set(resolve_network_set(s.pretrained))
    return {"model": s.model, "pretrained": s.pretrained, "network_set": set_hash(ns)}


def _stage_runners(
    config: PipelineConfig, out: Path, run_progress: Callable[[int, int], None] | None = None
) -> dict[str, Callable[[], dict]]:
    camp_dir = out / "campaign"
    sur_dir = surrogate_campaign_dir(config, out)

    def run_lhs(dest: Path, samples: int, seed: int, parameters: tuple[str, ...]) -> int:
        """An LHS campaign of ``parameters`` (others nominal) in every condition; its runs."""
        from railsusp.campaign import make_config, run_campaign
        from railsusp.vehicle.wagon import load_wagon

        c = config.campaign
        cfg = make_config(
            config.working_conditions(),
            samples,
            design=c.design,
            seed=seed,
            batch_size=c.batch_size,
            parameters=parameters,
            wagon=load_wagon(config.wagon),
        )
        run_campaign(cfg, dest, force=True, scheduler=config.scheduler, progress=run_progress)
        return cfg.n_runs * len(cfg.conditions)

    def campaign() -> dict:
        c = config.campaign
        return {"runs": run_lhs(camp_dir, c.samples, c.seed, c.parameters)}

    def sensitivity() -> dict:
        from railsusp.sensitivity import analyse

        s = config.sensitivity
        res = analyse(
            camp_dir,
            statistics=s.statistics,
            threshold=s.threshold,
            key_statistics=s.statistics,
            max_keys=s.max_keys,
            base_samples=s.base_samples,
        )
        return {"keys": res["key_parameters"]["keys"]}

    def surrogate() -> dict:
        from railsusp.surrogate import TrainConfig
        from railsusp.surrogate.compare import compare
        from railsusp.surrogate.statistics import train_statistics_surrogate

        s = config.surrogate
        if s.pretrained is not None:  # trained on many tracks elsewhere: checked, copied
            from railsusp.surrogate.pretrained import (
                check_references,
                install_network_set,
                read_network_set,
                resolve_network_set,
            )

            ns = read_network_set(resolve_network_set(s.pretrained))
            check_references(ns, [c.name for c in config.working_conditions()])
            install_network_set(ns, sur_dir / "surrogates")
            return {"pretrained": ns.name, "parameters": list(ns.parameters), "models": [ns.kind]}
        info: dict = {}
        if s.samples:
            from railsusp.surrogate import key_parameters

            keys = key_parameters(camp_dir)
            info["runs"] = run_lhs(sur_dir, s.samples, s.seed, keys)
            info["parameters"] = list(keys)
        tcfg = TrainConfig(
            epochs=s.epochs,
            fine_tune_epochs=s.fine_tune_epochs,
            batches_per_epoch=s.batches_per_epoch,
            batch_size=s.batch_size,
            device=s.device,
        )
        window_model = "bp" if s.model == "gp-stats" else s.model
        _drop_other_conditions(sur_dir / "surrogates", config.working_conditions())
        tab = compare(sur_dir, models=(window_model, "rbf", "gp-stats"), train=tcfg)
        for cond in config.working_conditions():
            train_statistics_surrogate(sur_dir, cond.name)
        return {**info, "models": sorted(set(tab.model))}

    def field() -> dict:
        from railsusp.pipeline_field import field_stage

        return field_stage(config, out)

    def estimate() -> dict:
        from railsusp.estimate import NSGAConfig, SimulatorForces, open_force_model
        from railsusp.estimate.config import HeldPrior
        from railsusp.estimate.route import EstimateRoute
        from railsusp.measured import read_field
        from railsusp.surrogate import key_parameters, not_estimated
        from railsusp.vehicle.wagon import load_wagon, wagon_reference

        e = config.estimate
        # a network set's inputs are its own key parameters, whatever the sensitivity found
        params = None if config.surrogate.pretrained else key_parameters(camp_dir)
        model, params = open_force_model(sur_dir / "surrogates" / config.surrogate.model, params)
        cfg = NSGAConfig(
            pop_size=e.pop_size,
            n_gen=e.n_gen,
            crossover_prob=e.crossover_prob,
            mutation_prob=e.mutation_prob,
            seed=e.seed,
            statistic=e.statistic,
            per_condition=e.per_condition,
            weighting=e.weighting,
            channel_gains=e.channel_gains,
            expected_draws=e.expected_draws,
            expected_generations=e.expected_generations,
            preview_generations=e.preview_generations,
            preview_s=e.preview_s,
        )
        route = EstimateRoute(
            nsga=cfg,
            seeds=e.seeds,
            geometry_draws=e.geometry_draws,
            remove_geometry_bias=e.remove_geometry_bias,
            simulator_corrections=e.simulator_corrections,
            correction_slopes=e.correction_slopes,
            slope_update=e.slope_update,
            refine=e.refine,
            refine_evaluations=e.refine_evaluations,
            refine_screen=e.refine_screen,
            refine_starts=e.refine_starts,
            held_prior=HeldPrior.from_display(e.held_prior) if e.refine else None,
            refine_setting="estimate.refine",
            corrections_setting="estimate.simulator_corrections",
        )
        wagon = load_wagon(config.wagon)
        recs = read_field(out / "field", wagon=wagon)
        # the simulator of the run's wagon for the corrections and the refinement (they
        # simulated the packaged C80 whatever the configuration's wagon)
        res = route.run(model, recs, params, simulator=SimulatorForces(params, wagon=wagon))
        res.save(
            out / "estimate",
            extra={
                "measured": str((out / "field").resolve()),
                "model": config.surrogate.model,
                "wagon": wagon_reference(config.wagon),  # validate's default
                "not_estimated": not_estimated(
                    sur_dir / "surrogates" / config.surrogate.model, params
                ),
            },
        )
        return {"estimate": res.estimate}

    def validate() -> dict:
        from railsusp.validate import validate as run_validate

        truth = out / "field" / "truth.json"
        res = run_validate(
            out / "estimate",
            truth=truth if truth.exists() else None,
            sensitivity=camp_dir / "sensitivity",
            wagon=config.wagon,
        )
        res.save(out / "estimate" / "validation")
        return {"scored": res.recovery is not None}

    def report() -> dict:
        from railsusp.report_html import build_report

        paths = build_report(out)
        return {"files": [str(p.name) for p in paths]}

    return {
        "campaign": campaign,
        "sensitivity": sensitivity,
        "surrogate": surrogate,
        "field": field,
        "estimate": estimate,
        "validate": validate,
        "report": report,
    }
