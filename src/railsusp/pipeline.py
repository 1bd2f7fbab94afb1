"""The whole method in one run directory: campaign -> sensitivity -> surrogates -> field
recordings -> estimation -> validation -> report.

Each stage is skipped when its outputs exist and its inputs (its part of the configuration
and the hashes of the stages it reads) are unchanged; ``start_from`` forces a restart from a
stage. A failing stage leaves the previous stages' outputs intact; ``pipeline.json`` records
each stage's input hash, timing and state, and the error says how to resume.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
)

from railsusp.conditions import WorkingCondition, get_condition, make_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate.config import NSGA_RANGES, REFINE_RANGES, SEEDS_RANGE
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import content_hash, provenance, read_json, write_json

#: stage finishes with their elapsed time (info) and starts (debug), for the command line
log = logging.getLogger("railsusp.pipeline")

STAGES = ("campaign", "sensitivity", "surrogate", "field", "estimate", "validate", "report")


_NSGA, _REF = NSGA_RANGES, REFINE_RANGES


class _Cfg(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CampaignSection(_Cfg):
    samples: int = Field(64, ge=4, description="LHS samples")
    design: Literal["lhs", "lhs-optimised"] = "lhs"
    seed: int = Field(0, ge=0)
    batch_size: int = Field(32, ge=1)
    parameters: tuple[str, ...] = MAIN_SUSPENSION


class SensitivitySection(_Cfg):
    threshold: float = Field(0.05, gt=0.0, lt=1.0, description="ST threshold of the key rule")
    max_keys: int = Field(6, ge=1, le=10)
    statistics: tuple[str, ...] = ("mean", "p99")
    base_samples: int = Field(512, ge=64)


class SurrogateSection(_Cfg):
    """The surrogates and their training data.

    With ``samples > 0`` (the default) the surrogates train on a second campaign that samples
    only the key parameters (others nominal), as the estimator uses them; with ``samples = 0``
    they train on the sensitivity campaign, where the other parameters vary unseen and limit
    their accuracy (bench/README.md, surrogate.py).
    """

    model: Literal["cnn-gru", "cnn-gru-seq", "cnn-lstm", "cnn-bilstm", "bp", "gp-stats"] = Field(
        "bp", description="force model of the calibration (gp-stats: statistics GPs)"
    )
    samples: int = Field(
        128,
        ge=0,
        description="LHS samples of the key parameters for the surrogates' own campaign "
        "(0: train on the sensitivity campaign)",
    )
    seed: int = Field(1, ge=0, description="design seed of that campaign")
    epochs: int = Field(8, ge=1)
    fine_tune_epochs: int = Field(
        0, ge=0, description="then epochs at a tenth of the learning rate, from the best state"
    )
    batches_per_epoch: int = Field(60, ge=1)
    batch_size: int = Field(512, ge=8)
    device: str = "cpu"
    pretrained: str | None = Field(
        None,
        description="a network set trained on many tracks (a name shipped with railsusp, "
        "e.g. 'c80_k6', or a folder with networks.json) instead of training here; the "
        "training settings above are then not used",
    )

    @field_validator("samples")
    @classmethod
    def _samples(cls, v: int) -> int:
        if 0 < v < 8:
            raise ValueError(
                "0 (train on the sensitivity campaign) or at least 8 samples, to split "
                "them into train, validation and test runs"
            )
        return v


class FieldSection(_Cfg):
    """Measured recordings: a folder (``measured``), a long run cut into sections here
    (``recording``), or synthetic ones from ``truth``."""

    measured: str | None = Field(None, description="folder with index.json of recordings")
    recording: str | None = Field(
        None, description="long run (.mf4, .csv, .parquet) cut into sections by the field stage"
    )
    channel_map: str | None = Field(None, description="channel map TOML of the recording")
    line: str | None = Field(None, description="line description CSV to cut the recording by")
    sections: str | None = Field(None, description="section table CSV (start_m, end_m[, name])")
    speed_tolerance: float = Field(
        0.10, ge=0.0, le=1.0, description="largest (max - min) / mean speed in a section"
    )
    min_length_m: float = Field(150.0, ge=1.0, le=100_000.0, description="shortest section")
    max_duration_s: float = Field(120.0, ge=1.0, le=600.0, description="longer ones are split")
    rate_hz: float = Field(50.0, ge=10.0, le=5000.0, description="rate of the section records")
    truth: dict[str, float] = Field(
        default_factory=dict, description="hidden true parameters, display units"
    )
    seed: int = Field(7, ge=0, le=2**63 - 1)
    noise: float = Field(0.03, ge=0.0, le=0.5)
    with_track: bool = Field(
        False, description="synthetic recordings also carry their measured track geometry"
    )
    track_noise_mm: float = Field(0.0, ge=0.0, le=10.0, description="RMS error of that track")


class EstimateSection(_Cfg):
    # the ranges of the estimate's own settings (one source: railsusp.estimate.config)
    pop_size: int = Field(50, ge=_NSGA["pop_size"][0], le=_NSGA["pop_size"][1])
    n_gen: int = Field(100, ge=_NSGA["n_gen"][0], le=_NSGA["n_gen"][1])
    crossover_prob: float = Field(0.9, ge=0.0, le=1.0)
    mutation_prob: float = Field(0.05, ge=0.0, le=1.0)
    statistic: str = Field(
        "mean", description="mean, rms, p99, std, p99.85 (EN 14363) or a '+' combination"
    )
    per_condition: bool = Field(False, description="two objectives per condition")
    weighting: Literal["relative", "noise"] = Field(
        "relative", description="relative errors, or in units of the gp-stats predictive SD"
    )
    seeds: int = Field(1, ge=SEEDS_RANGE[0], le=SEEDS_RANGE[1])
    seed: int = Field(0, ge=_NSGA["seed"][0], le=_NSGA["seed"][1])
    refine: bool = Field(
        False,
        description="refine by output-error least squares with the simulator on the "
        "recordings' measured track (needs recordings with track geometry)",
    )
    refine_evaluations: int = Field(
        40, ge=_REF["max_evaluations"][0], le=_REF["max_evaluations"][1]
    )
    refine_screen: int = Field(
        64, ge=_REF["screen"][0], le=_REF["screen"][1], description="LHS points screened for starts"
    )
    refine_starts: int = Field(
        2, ge=_REF["starts"][0], le=_REF["starts"][1], description="best screened starts refined"
    )
    geometry_draws: int = Field(
        8,
        ge=_REF["geometry_draws"][0],
        le=_REF["geometry_draws"][1],
        description="draws of the recordings' stated track-geometry error propagated into "
        "the refined estimate's standard errors",
    )
    remove_geometry_bias: bool = Field(
        True,
        description="take the geometry-error bias that the draws estimate (first SIMEX "
        "step) off the refined estimate",
    )
    held_prior: dict[str, Any] = Field(
        default_factory=dict,
        description="{symbol: [low, high]} display units: the range each main-suspension "
        "parameter the refinement holds at nominal is known to lie in (docs/configuration.md)",
    )

    @field_validator("statistic")
    @classmethod
    def _statistic(cls, v: str) -> str:
        from railsusp.estimate import parse_statistics

        return "+".join(parse_statistics(v))


class PipelineConfig(_Cfg):
    """The whole configuration of a run (examples/quick.toml, examples/study.toml)."""

    name: str = "railsusp run"
    wagon: str | None = Field(None, description="wagon data TOML (default: C80/K6)")
    conditions: tuple[str | dict[str, Any], ...] = ("straight", "curve", "uphill")
    campaign: CampaignSection = CampaignSection()
    sensitivity: SensitivitySection = SensitivitySection()
    surrogate: SurrogateSection = SurrogateSection()
    field: FieldSection = FieldSection()
    estimate: EstimateSection = EstimateSection()
    scheduler: str | None = Field(None, description="Dask scheduler tcp://host:port")

    def run_source(self) -> Any:
        """The long run of ``[field] recording`` and how to cut it
        (:class:`~railsusp.measured.cut.RunSource`), or None."""
        from railsusp.pipeline_field import run_source

        return run_source(self.field)

    def working_conditions(self) -> list[WorkingCondition]:
        """The conditions of the run: those given, or with ``[field] recording`` the kept
        sections' conditions of the recording (:mod:`railsusp.measured.cut`)."""
        source = self.run_source()
        if source is not None:
            from railsusp.measured.cut import section_conditions

            return section_conditions(source)
        out = []
        for c in self.conditions:
            if isinstance(c, str):
                out.append(get_condition(c))
            else:
                fields = dict(c)
                base = fields.pop("base", None)
                start = get_condition(base).model_dump() if base else {}
                out.append(make_condition({**start, **fields}))
        return out


def load_config(path: str | Path) -> PipelineConfig:
    """Read and validate a pipeline TOML; errors name the field (one line)."""
    from railsusp.config import check_config, read_config, validation_message

    path = Path(path)
    try:
        cfg = PipelineConfig(**read_config(path, PipelineConfig))
    except ValidationError as exc:
        raise RailsuspInputError(validation_message(path, exc)) from None
    cfg = _beside(cfg, path.parent)
    check_config(cfg, str(path))
    return cfg


#: ``[field]`` files of a long run, named relative to the configuration file's folder
RUN_FILES = ("recording", "channel_map", "line", "sections")


def _beside(cfg: PipelineConfig, folder: Path) -> PipelineConfig:
    """``cfg`` with the long run's relative file names resolved against ``folder`` (the
    configuration file's), so that a configuration travels with its recording."""
    update = {
        k: str(folder / v)
        for k in RUN_FILES
        if (v := getattr(cfg.field, k)) is not None and not Path(v).is_absolute()
    }
    if not update:
        return cfg
    return cfg.model_copy(update={"field": cfg.field.model_copy(update=update)})


class StageError(RailsuspInputError):
    """A stage failed; earlier stages' outputs are intact."""


#: the hidden truth of the demo: a degraded wagon (display units)
DEMO_TRUTH = {
    "X11": 1.3,
    "X13": 16.1,
    "X14": 8.3,
    "X15": 164.0,
    "X16": 1.7,
    "X17": 1.91,
    "X18": 51.3,
}


def demo_config() -> PipelineConfig:
    """The embedded default (identical to examples/quick.toml, checked by a test)."""
    return PipelineConfig(
        name="quick demo: C80/K6, synthetic field data of a degraded wagon",
        # the study's CNN-GRU trained on many tracks, shipped: nothing trained in the demo
        surrogate=SurrogateSection(model="cnn-gru-seq", pretrained="c80_k6"),
        field=FieldSection(truth=DEMO_TRUTH, with_track=True),
        estimate=EstimateSection(refine=True),
    )


def run_pipeline(
    config: PipelineConfig,
    out: str | Path,
    *,
    start_from: str | None = None,
    progress: Callable[[str, str], None] | None = None,
    run_progress: Callable[[int, int], None] | None = None,
) -> dict:
    """Run the stages in order, skipping the up-to-date ones; returns ``pipeline.json``.

    ``progress(stage, message)`` reports stage starts; ``run_progress(done, total)`` the
    campaign's simulations.
    """
    from railsusp.config import check_config
    from railsusp.store import check_output_folder

    out = check_output_folder(out)
    if start_from is not None and start_from not in STAGES:
        raise RailsuspInputError(f"--from {start_from!r}: accepted {', '.join(STAGES)}")
    check_config(config)  # every combination, before any stage runs
    out.mkdir(parents=True, exist_ok=True)
    state_path = out / "pipeline.json"
    state = read_json(state_path) if state_path.exists() else {"stages": {}}
    state["config"] = config.model_dump(mode="json")
    forced = STAGES.index(start_from) if start_from else len(STAGES)
    upstream: dict[str, str] = {}
    runners = _stage_runners(config, out, run_progress)
    for i, stage in enumerate(STAGES):
        section = _section(config, stage)
        h = content_hash({"section": section, "upstream": upstream, "stage": stage})
        prev = state["stages"].get(stage, {})
        up_to_date = (
            prev.get("hash") == h
            and prev.get("state") == "done"
            and i < forced
            and _outputs_exist(config, out, stage)
        )
        if up_to_date:
            log.debug("stage %s: up to date", stage)
            if progress:
                progress(stage, "up to date")
        else:
            log.debug("stage %s: running", stage)
            if progress:
                progress(stage, "running")
            t0 = time.perf_counter()
            state["stages"][stage] = {"hash": h, "state": "running"}
            write_json(state_path, state)
            try:
                info = runners[stage]() or {}
            except Exception as exc:
                log.info("stage %s: failed after %.1f s", stage, time.perf_counter() - t0)
                state["stages"][stage] = {"hash": h, "state": "failed", "error": str(exc)}
                write_json(state_path, state)
                raise StageError(
                    f"stage {stage!r} failed: {exc}. Earlier stages are kept; fix the cause "
                    f"and run the same command again (or --from {stage})"
                ) from exc
            state["stages"][stage] = {
                "hash": h,
                "state": "done",
                "info": info,
                "seconds": time.perf_counter() - t0,
                "finished": provenance()["utc"],
            }
            write_json(state_path, state)
            log.info("stage %s: done in %.1f s", stage, state["stages"][stage]["seconds"])
            forced = min(forced, i + 1)  # everything downstream reruns
        upstream[stage] = h
    state["provenance"] = provenance()
    write_json(state_path, state)
    return state


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


def _section(config: PipelineConfig, stage: str) -> Any:
    base = {
        "wagon": config.wagon,
        "conditions": list(config.conditions),
        "model": model_identity(config),
    }
    source = config.run_source()
    if source is not None:  # the conditions, and the field, come from the recording's cut
        base["conditions"] = [c.model_dump(mode="json") for c in config.working_conditions()]
        base["recording"] = repr(source.state())
    sections = {
        "campaign": {**base, **config.campaign.model_dump()},
        "sensitivity": config.sensitivity.model_dump(),
        "surrogate": _surrogate_section(config),
        "field": {**base, **config.field.model_dump()},
        # without a held_prior the section hashes as before it existed (runs stay up to date)
        "estimate": config.estimate.model_dump(
            exclude=None if config.estimate.held_prior else {"held_prior"}
        ),
        "validate": {},
        "report": {"name": config.name},
    }
    return sections[stage]


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


_OUTPUTS = {
    "campaign": "campaign/features.parquet",
    "sensitivity": "campaign/sensitivity/key_parameters.json",
    "surrogate": "surrogates/compare.csv",  # under surrogate_campaign_dir
    "field": "field/index.json",
    "estimate": "estimate/estimate.json",
    "validate": "estimate/validation/validation.json",
    "report": "report.html",
}


def surrogate_campaign_dir(config: PipelineConfig, out: str | Path) -> Path:
    """The run directory whose ``surrogates/`` the estimation uses."""
    from railsusp.surrogate.pretrained import surrogates_run

    s = config.surrogate
    return Path(out) / surrogates_run(s.pretrained, s.samples)


def _outputs_exist(config: PipelineConfig, out: Path, stage: str) -> bool:
    base = surrogate_campaign_dir(config, out) if stage == "surrogate" else out
    return (base / _OUTPUTS[stage]).exists()


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
        tab = compare(sur_dir, models=(window_model, "rbf", "gp-stats"), train=tcfg)
        for cond in config.working_conditions():
            train_statistics_surrogate(sur_dir, cond.name)
        return {**info, "models": sorted(set(tab.model))}

    def field() -> dict:
        from railsusp.pipeline_field import field_stage

        return field_stage(config, out)

    def estimate() -> dict:
        from railsusp.estimate import (
            NSGAConfig,
            check_refinable,
            estimate_with_seeds,
            open_force_model,
            refine_estimate,
        )
        from railsusp.estimate.config import HeldPrior
        from railsusp.measured import read_field
        from railsusp.surrogate import key_parameters, not_estimated

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
        )
        recs = read_field(out / "field")
        if e.refine:  # before NSGA-II runs
            check_refinable(recs, "estimate.refine")
        res = estimate_with_seeds(model, recs, params, cfg, e.seeds)
        if e.refine:
            refine_estimate(
                res,
                recs,
                max_evaluations=e.refine_evaluations,
                screen=e.refine_screen,
                starts=e.refine_starts,
                seed=e.seed,
                geometry_draws=e.geometry_draws,
                remove_geometry_bias=e.remove_geometry_bias,
            )
            res.held_prior = HeldPrior.from_display(e.held_prior)
        res.save(
            out / "estimate",
            extra={
                "measured": str((out / "field").resolve()),
                "model": config.surrogate.model,
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
