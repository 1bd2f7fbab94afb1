"""What each stage of the pipeline does: the stage runners (:func:`stage_runners`:
campaign, sensitivity, surrogate, field, estimate, validate, report). What each depends on
is :mod:`railsusp.pipeline_inputs`; :mod:`railsusp.pipeline` runs them in order, skipping
the up-to-date ones.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from railsusp.pipeline_config import PipelineConfig
from railsusp.pipeline_inputs import lhs_campaign
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


def stage_runners(
    config: PipelineConfig, out: Path, run_progress: Callable[[int, int], None] | None = None
) -> dict[str, Callable[[], dict]]:
    camp_dir = out / "campaign"
    sur_dir = surrogate_campaign_dir(config, out)

    def run_lhs(dest: Path, samples: int, seed: int, parameters: tuple[str, ...]) -> int:
        """An LHS campaign of ``parameters`` (others nominal) in every condition; its runs."""
        from railsusp.campaign import run_campaign

        cfg = lhs_campaign(config, samples, seed, parameters)
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
                # and relative to the estimate's folder: the run's own recordings wherever
                # the run directory is moved (validation_inputs.measured_of)
                "measured_in_run": "../field",
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
            truth_option="truth file",  # (it named --truth, which no one typed)
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
