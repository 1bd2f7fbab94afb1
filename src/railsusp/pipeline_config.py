"""The pipeline's configuration: the sections of a run's TOML as pydantic models, reading
and validating a file (:func:`load_config`), and the embedded demo (:func:`demo_config`).

Each section model types and range-checks its fields and refuses unknown keys;
:mod:`railsusp.config` adds the checks of the configuration as a whole. The stages that run
it are in :mod:`railsusp.pipeline`, which imports this module and re-exports
:class:`PipelineConfig`, :func:`load_config` and :func:`demo_config`; this module imports
nothing of the pipeline, so imports flow one way and a configuration can be read without
loading the stages.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
)

from railsusp.conditions import (
    RECORDING_MIN_RATE_HZ,
    WorkingCondition,
    get_condition,
    make_condition,
)
from railsusp.errors import ConditionError, RailsuspInputError
from railsusp.estimate.config import (
    CORRECTIONS_RANGE,
    NSGA_RANGES,
    REFINE_RANGES,
    SEEDS_RANGE,
    TRUST_BOX,
)
from railsusp.params import MAIN_SUSPENSION

_NSGA, _REF, _CORRECTIONS = NSGA_RANGES, REFINE_RANGES, CORRECTIONS_RANGE


def _within(default: Any, bounds: tuple[float, float], **field: Any) -> Any:
    """A field accepting ``bounds`` (low, high), both included: the range of the estimate's
    own setting (one source: :mod:`railsusp.estimate.config`). ``field``: pydantic
    :func:`~pydantic.Field`'s other keywords (a description)."""
    low, high = bounds
    return Field(default, ge=low, le=high, **field)


class _Cfg(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CampaignSection(_Cfg):
    #: at least the sensitivity metamodel's sensitivity_metamodel.MIN_METAMODEL_RUNS (5): 4 were
    #: accepted, and the sensitivity stage then failed on every run
    samples: int = Field(64, ge=5, le=1_000_000, description="LHS samples")
    design: Literal["lhs", "lhs-optimised"] = "lhs"
    seed: int = Field(0, ge=0)
    batch_size: int = Field(32, ge=1, le=10_000)
    parameters: tuple[str, ...] = MAIN_SUSPENSION


class SensitivitySection(_Cfg):
    threshold: float = Field(0.05, gt=0.0, lt=1.0, description="ST threshold of the key rule")
    max_keys: int = Field(6, ge=1, le=10)
    statistics: tuple[str, ...] = ("mean", "p99")
    base_samples: int = Field(512, ge=64, le=65_536)  # railsusp.sensitivity.BASE_SAMPLES

    @field_validator("base_samples")
    @classmethod
    def _power_of_two(cls, v: int) -> int:
        """Saltelli's N on Sobol' points: a power of 2, or the points lose their balance
        (scipy warned at the sensitivity stage without naming the setting)."""
        if v & (v - 1):
            low = 1 << (v.bit_length() - 1)
            raise ValueError(
                f"{v} is not a power of 2; accepted a power of 2 from 64 to 65536 (near it: "
                f"{low} or {2 * low})"
            )
        return v


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
        le=1_000_000,
        description="LHS samples of the key parameters for the surrogates' own campaign "
        "(0: train on the sensitivity campaign)",
    )
    seed: int = Field(1, ge=0, description="design seed of that campaign")
    epochs: int = Field(8, ge=1, le=10_000)
    fine_tune_epochs: int = Field(
        0,
        ge=0,
        le=10_000,
        description="then epochs at a tenth of the learning rate, from the best state",
    )
    batches_per_epoch: int = Field(60, ge=1, le=100_000)
    batch_size: int = Field(512, ge=1, le=65_536)  # as TrainConfig and `train --batch-size`
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
    sections: str | None = Field(
        None,
        description="section table CSV (start_m, end_m[, name]; optionally each row's track: "
        "radius_m, direction, cant_mm, grade_permille)",
    )
    speed_tolerance: float = Field(
        0.10, ge=0.0, le=1.0, description="largest (max - min) / mean speed in a section"
    )
    min_length_m: float = Field(150.0, ge=1.0, le=100_000.0, description="shortest section")
    max_duration_s: float = Field(120.0, ge=1.0, le=600.0, description="longer ones are split")
    rate_hz: float = Field(
        RECORDING_MIN_RATE_HZ,
        ge=RECORDING_MIN_RATE_HZ,  # the field stage reads the sections at this rate or more
        le=5000.0,
        description="rate of the section records",
    )
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
    pop_size: int = _within(50, _NSGA["pop_size"])
    n_gen: int = _within(100, _NSGA["n_gen"])
    crossover_prob: float = Field(0.9, ge=0.0, le=1.0)
    mutation_prob: float = Field(0.05, ge=0.0, le=1.0)
    statistic: str = Field(
        "mean",
        description="mean, rms, p99, std, p99.85 (EN 14363) or a '+' combination; aligned: "
        "the time-aligned forces on the recordings' measured track",
    )
    per_condition: bool = Field(False, description="two objectives per condition")
    channel_gains: bool = Field(
        False,
        description="the time-aligned comparison profiles each force channel's gain "
        "(calibration factor, within 1 ± 0.1) out of the misfit",
    )
    expected_draws: int = _within(
        0,
        _NSGA["expected_draws"],
        description="with 'aligned', on recordings whose geometry states its accuracy: "
        "polish NSGA-II's choice by the surrogate's least squares on its mean over this many "
        "draws of the true track geometry given the measured one, instead of the first SIMEX "
        "step; the simulator refinement compares such means too (0: neither)",
    )
    simulator_corrections: int = _within(
        0,
        _CORRECTIONS,
        description="with 'aligned' alone: correct the surrogate's level error at NSGA-II's "
        "estimate by this many simulations of it, repeating the surrogate's least squares "
        "with each (output space mapping; 0: the surrogate alone)",
    )
    correction_slopes: bool = Field(
        False,
        description="each simulator correction also simulates the estimate stepped in every "
        "key and matches the simulator's slopes there (first order), its least squares "
        f"within a trust box ({100 * TRUST_BOX:g} % of each range at first), each proposed "
        "point checked by the simulator's cost there; k + 1 simulations per recording and "
        "step instead of one",
    )
    slope_update: Literal["simulated", "broyden"] = Field(
        "simulated",
        description="with correction_slopes: the slopes at each later point of the "
        "corrections simulated again ('simulated', k more simulations per recording and "
        "step) or carried by Broyden's update from the simulated level's change along each "
        "step ('broyden', none; not across a step under 1 % of range)",
    )
    expected_generations: bool = Field(
        False,
        description="NSGA-II's generations compare the expected forces too (expected_draws "
        "times the predictions; with 'aligned' alone or with 'mean')",
    )
    preview_generations: int = _within(
        0,
        _NSGA["preview_generations"],
        description="the first this many generations (below n_gen) compare each recording's "
        "first preview_s seconds only; the rest start from their Pareto set on the whole "
        "records (0: none)",
    )
    preview_s: float = _within(
        20.0,
        _NSGA["preview_s"],
        description="seconds of each recording the preview generations compare",
    )
    weighting: Literal["relative", "noise"] = Field(
        "relative", description="relative errors, or in units of the gp-stats predictive SD"
    )
    seeds: int = _within(1, SEEDS_RANGE)
    seed: int = _within(0, _NSGA["seed"])
    refine: bool = Field(
        False,
        description="refine by output-error least squares with the simulator on the "
        "recordings' measured track (needs recordings with track geometry)",
    )
    refine_evaluations: int = _within(40, _REF["max_evaluations"])
    refine_screen: int = _within(64, _REF["screen"], description="LHS points screened for starts")
    refine_starts: int = _within(2, _REF["starts"], description="best screened starts refined")
    geometry_draws: int = _within(
        8,
        _REF["geometry_draws"],
        description="draws of the recordings' stated track-geometry error propagated into "
        "NSGA-II's time-aligned estimate and the refined estimate's standard errors (not "
        "used with expected_draws)",
    )
    remove_geometry_bias: bool = Field(
        True,
        description="take the geometry-error bias that the draws estimate (first SIMEX "
        "step) off NSGA-II's time-aligned estimate and off the refined estimate (not used "
        "with expected_draws)",
    )
    held_prior: dict[str, Any] = Field(
        default_factory=dict,
        description="{symbol: [low, high]} display units: the range each main-suspension "
        "parameter the refinement holds at nominal is known to lie in (docs/configuration.md)",
    )

    @field_validator("held_prior")
    @classmethod
    def _prior_numbers(cls, v: dict[str, Any]) -> dict[str, Any]:
        """``{X19 = ["20000", "40000"]}`` is a slip, not a range (the rest of the range
        checks are :class:`~railsusp.estimate.config.HeldPrior`'s)."""
        for sym, pair in v.items():
            if isinstance(pair, list) and any(isinstance(x, str) for x in pair):
                raise ValueError(
                    f"{sym} = {pair!r}: numbers are needed, not strings (write them without quotes)"
                )
        return v

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

    @field_validator("name")
    @classmethod
    def _one_line_name(cls, v: str) -> str:
        """The report's title: one line of printable text (an empty name titled the report
        with nothing, a newline split every line that names the run)."""
        if not v.strip() or not v.isprintable() or len(v) > 200:
            raise ValueError(f"{v!r}: accepted one line of printable text, 1 to 200 characters")
        return v

    @field_validator("wagon", mode="before")
    @classmethod
    def _wagon_path(cls, v: Any) -> Any:
        """A ``Path`` stands for the file's string (as in ``railsusp.run``'s dicts)."""
        return os.fspath(v) if isinstance(v, os.PathLike) else v

    @field_validator("conditions", mode="before")
    @classmethod
    def _condition_objects(cls, v: Any) -> Any:
        """A :class:`~railsusp.conditions.WorkingCondition` stands for its fields (what
        ``railsusp.get_condition`` returns, accepted by ``railsusp.run``'s dicts; the
        constructor refused it with pydantic's seven-line error)."""
        if isinstance(v, list | tuple):
            return tuple(
                c.model_dump(mode="json", exclude_none=True)
                if isinstance(c, WorkingCondition)
                else c
                for c in v
            )
        return v

    def run_source(self) -> Any:
        """The long run of ``[field] recording`` and how to cut it
        (:class:`~railsusp.measured.cut.RunSource`), or None."""
        from railsusp.pipeline_field import run_source

        return run_source(self.field, self.wagon)

    def working_conditions(self) -> list[WorkingCondition]:
        """The conditions of the run: those given, or with ``[field] recording`` the kept
        sections' conditions of the recording (:mod:`railsusp.measured.cut`); their values
        validated strictly (:func:`railsusp.conditions.make_condition`)."""
        source = self.run_source()
        if source is not None:
            from railsusp.measured.cut import section_conditions

            return section_conditions(source)
        out = []
        for c in self.conditions:
            if isinstance(c, str):
                try:
                    out.append(get_condition(c))
                except ConditionError as exc:  # a file's name: its tables go in the list
                    raise ConditionError(
                        f'{exc}, or a table such as {{base = "curve", name = "tight", '
                        "curve_radius_m = 250} (docs/conditions.md)"
                    ) from None
            else:
                fields = dict(c)
                base = fields.pop("base", None)
                start = get_condition(base).model_dump() if base else {}
                out.append(make_condition({**start, **fields}))
        return out


#: the configurations shipped in the package (``data/examples/``, the repository's
#: ``examples/``), which :func:`load_config` takes by name (``railsusp run quick``): an
#: installed railsusp had none of the files its help and docs name
EXAMPLE_CONFIGS = ("quick", "pretrained", "study", "tiny")


def config_path(path: str | Path) -> Path:
    """The configuration file ``path`` names: itself, or the packaged example of that name
    (:data:`EXAMPLE_CONFIGS`) where it is one and no file of the name is there."""
    from importlib import resources

    if str(path) in EXAMPLE_CONFIGS and not Path(path).exists():
        return Path(str(resources.files("railsusp").joinpath(f"data/examples/{path}.toml")))
    return Path(path)


def load_config(path: str | Path) -> PipelineConfig:
    """Read and validate a pipeline TOML, or the packaged example ``path`` names
    (:func:`config_path`); errors name the field (one line)."""
    from railsusp.config import check_config, read_config, validation_message
    from railsusp.input_checks import validate_document

    path = config_path(path)
    if not path.exists():
        raise RailsuspInputError(
            f"configuration {path} does not exist; accepted a pipeline TOML file or a "
            f"packaged example's name ({', '.join(EXAMPLE_CONFIGS)}: `railsusp run quick`)"
        )
    try:
        cfg = validate_document(PipelineConfig, read_config(path))
    except ValidationError as exc:
        raise RailsuspInputError(validation_message(path, exc, PipelineConfig)) from None
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
