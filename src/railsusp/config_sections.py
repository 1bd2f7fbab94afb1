"""The sections of a pipeline configuration's TOML, ``[campaign]``, ``[sensitivity]``,
``[surrogate]``, ``[field]`` and ``[estimate]``, as pydantic models: each types and
range-checks its fields and refuses unknown keys (:class:`StrictConfigModel`, their base and
:class:`~railsusp.pipeline_config.PipelineConfig`'s).

They are apart from :mod:`railsusp.pipeline_config`, which composes them into the whole
configuration and reads a file, because each section stands alone: it knows nothing of the
whole, of reading a file or of the stages, and takes its ranges from the settings it feeds
(:mod:`railsusp.estimate.config`). A stage's hash, which decides whether it runs again
(``pipeline.json``), takes the settings of its section: a change to a section's fields,
defaults or serialisation reruns users' stages.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from railsusp.conditions import RECORDING_MIN_RATE_HZ
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


class StrictConfigModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def not_empty(value: str | None, what: str = "a path") -> str | None:
    """A key naming a file, folder or network set given as an empty string (``wagon =
    ""``): refused, where it was read as the working folder (``measured = ""``) or failed
    far from the key ("wagon file . is a folder")."""
    if isinstance(value, str) and not value.strip():
        raise ValueError(f"empty: give {what}, or leave the key out")
    return value


class CampaignSection(StrictConfigModel):
    #: at least the sensitivity metamodel's sensitivity_metamodel.MIN_METAMODEL_RUNS (5): 4 were
    #: accepted, and the sensitivity stage then failed on every run
    samples: int = Field(64, ge=5, le=1_000_000, description="LHS samples")
    design: Literal["lhs", "lhs-optimised"] = "lhs"
    seed: int = Field(0, ge=0)
    batch_size: int = Field(32, ge=1, le=10_000)
    parameters: tuple[str, ...] = MAIN_SUSPENSION


class SensitivitySection(StrictConfigModel):
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


class SurrogateSection(StrictConfigModel):
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

    @field_validator("pretrained")
    @classmethod
    def _pretrained(cls, v: str | None) -> str | None:
        return not_empty(v, "a shipped network set's name or a folder with networks.json")

    @field_validator("samples")
    @classmethod
    def _samples(cls, v: int) -> int:
        if 0 < v < 8:
            raise ValueError(
                "0 (train on the sensitivity campaign) or at least 8 samples, to split "
                "them into train, validation and test runs"
            )
        return v


class FieldSection(StrictConfigModel):
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

    @field_validator("measured", "recording", "channel_map", "line", "sections")
    @classmethod
    def _paths(cls, v: str | None) -> str | None:
        return not_empty(v)


class EstimateSection(StrictConfigModel):
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
        "parameter the refinement holds is known to lie in; held at its centre "
        "(docs/configuration.md)",
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
