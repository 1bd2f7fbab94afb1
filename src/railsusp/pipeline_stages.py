"""What each stage of the pipeline depends on and what it does: the part of the
configuration a stage hashes (:func:`stage_section`, with :func:`model_identity`, the wagon
data and force laws every simulated stage depends on) and the stage runners themselves
(:func:`stage_runners`: campaign, sensitivity, surrogate, field, estimate, validate,
report). :mod:`railsusp.pipeline` runs them in order, skipping the up-to-date ones.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from railsusp.estimate.config import BROYDEN_MIN_STEP
from railsusp.pipeline_config import PipelineConfig
from railsusp.pipeline_state import surrogate_campaign_dir

log = logging.getLogger("railsusp.pipeline")


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


def _tolerances_state(config: PipelineConfig) -> dict:
    """The wagon data's ``[tolerances]`` the report judges the estimate by, where they are
    not the defaults: the wagon's hash leaves them out (they are no model input), so an
    edited table left the report of the old ones up to date (the rerun audit of stop 65);
    with where they come from, which the report's sentence names. Empty for railsusp's
    defaults, so the report stage hashes as before."""
    from railsusp.summary import Tolerances, read_tolerances

    tol = read_tolerances(config.wagon).to_dict()  # as pipeline.json records them
    return {} if tol == Tolerances().to_dict() else {"tolerances": tol}


def stage_section(config: PipelineConfig, stage: str) -> Any:
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
        "report": {"name": config.name, **_tolerances_state(config)},
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


def stage_runners(
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
        run_campaign(
            cfg,
            dest,
            force=True,
            scheduler=config.scheduler,
            scheduler_setting="scheduler =",  # the configuration's, as the user wrote it
            progress=run_progress,
        )
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
        from railsusp.measured.recording import recordings_digest
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
                "measured_digest": recordings_digest(recs),  # validate's check
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
