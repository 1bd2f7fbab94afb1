"""Campaign configuration and sampling design: what a campaign runs (validated, hashed into
the run directory) and the parameter samples and per-sample tracks it runs them on."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    ValidationInfo,
    field_validator,
    model_serializer,
)
from scipy.stats import qmc

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError, repeated_names
from railsusp.input_checks import BOUND_ERRORS, error_detail
from railsusp.params import MAIN_SUSPENSION, bounds, spec
from railsusp.store import (
    content_hash,
    read_json,
)
from railsusp.variation import (
    TrackFamily,
    check_other_parameters,
    sample_others,
    sample_tracks,
)
from railsusp.vehicle.simulate import SolverSettings
from railsusp.vehicle.simulation_result import WHEEL_NAMES
from railsusp.vehicle.wagon import WagonData, load_wagon

CHANNELS = (
    tuple(f"Y_{w}" for w in WHEEL_NAMES)
    + tuple(f"Q_{w}" for w in WHEEL_NAMES)
    + ("car_acc_y", "car_acc_z")
)
STATISTICS = ("mean", "rms", "p99", "max")

#: base samples N of a Saltelli (``sobol``) design at the least, a power of two: below it
#: SALib's estimators are noise (ST = 19.8 +- 54 at N = 2, 1.46 at N = 8: the campaign audit
#: of stop 59); the direct Sobol analysis refuses fewer (railsusp.sensitivity_indices), so a
#: campaign is refused them before its runs are spent
MIN_SALTELLI_BASE = 16


class CampaignError(RailsuspInputError):
    """A campaign cannot start or resume as asked."""


class CampaignConfig(BaseModel):
    """Everything that determines a campaign's results (its hash names the run)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    parameters: tuple[str, ...] = Field(MAIN_SUSPENSION, min_length=1)
    samples: int = Field(ge=2, le=1_000_000, description="LHS samples, or Saltelli base N")
    design: Literal["lhs", "lhs-optimised", "sobol"] = "lhs"
    second_order: bool = False
    seed: int = Field(0, ge=0)
    conditions: tuple[WorkingCondition, ...] = Field(min_length=1)
    independent_seeds: bool = False
    batch_size: int = Field(32, ge=1, le=10_000)
    wheel: str = "auto"
    wagon: WagonData
    solver: dict[str, float | str] = Field(
        default_factory=lambda: asdict(SolverSettings()), validate_default=True
    )
    #: per-sample FRA class / curve radius / cant within a family (needs independent_seeds)
    track_family: TrackFamily | None = None
    #: parameters not estimated, varied over these SI ranges (not held at nominal)
    other_parameters: dict[str, tuple[float, float]] = Field(default_factory=dict)

    @model_serializer(mode="wrap")
    def _without_unset_variation(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """Leave ``track_family`` and ``other_parameters`` out when unset, so that the
        content hashes of run directories made before they existed stay as they were."""
        data = handler(self)
        if data.get("track_family", "") is None:
            del data["track_family"]
        if data.get("other_parameters", None) == {}:
            del data["other_parameters"]
        return data

    @field_validator("other_parameters")
    @classmethod
    def _known_others(
        cls, v: dict[str, tuple[float, float]], info: ValidationInfo
    ) -> dict[str, tuple[float, float]]:
        return check_other_parameters(v, info.data.get("parameters", ()))

    @field_validator("parameters")
    @classmethod
    def _known_sampled(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        syms = tuple(spec(s).symbol for s in v)
        for s in syms:
            if not spec(s).is_sampled:
                raise ValueError(f"{s} is a fixed parameter; sampled ones are X11..X20")
        if len(set(syms)) != len(syms):
            raise ValueError(f"parameters repeat: {syms}")
        return syms

    def model_post_init(self, _ctx: Any) -> None:
        if self.design == "sobol" and self.samples & (self.samples - 1):
            raise ValueError(f"a Sobol/Saltelli design needs N a power of two, got {self.samples}")
        names = [c.name for c in self.conditions]
        twice = repeated_names(names)  # one batch folder each, even on a case-blind disk
        if twice:
            raise ValueError(f"condition names repeat ({', '.join(twice)}, case ignored): {names}")
        if self.wheel != "auto" and self.wheel not in WHEEL_NAMES:
            raise ValueError(f"wheel {self.wheel!r}: accepted auto or {', '.join(WHEEL_NAMES)}")
        fam = self.track_family
        if fam is not None:
            if not self.independent_seeds:
                raise ValueError(
                    "track_family needs independent_seeds (each sample its own realisation)"
                )
            if fam.varies_layout and all(c.curve_radius_m is None for c in self.conditions):
                raise ValueError(
                    "track_family: curve_radius_m / cant_mm need a curve condition "
                    f"(conditions: {', '.join(names)})"
                )

    @property
    def simulated_parameters(self) -> tuple[str, ...]:
        """The design's parameter columns: the sampled (key) ones, then the varied others."""
        return (*self.parameters, *self.other_parameters)

    @property
    def n_runs(self) -> int:
        """Number of parameter sets (rows of the design)."""
        d = len(self.parameters)
        if self.design == "sobol":
            return self.samples * (2 * d + 2 if self.second_order else d + 2)
        return self.samples

    @property
    def n_batches(self) -> int:
        return -(-self.n_runs // self.batch_size)

    def hash(self) -> str:
        """The configuration's content hash, with the wagon's profile files' contents."""
        return content_hash(self.wagon.with_profile_digests(self.model_dump(mode="json")))

    def settings(self) -> SolverSettings:
        return SolverSettings(**self.solver)


def saltelli_base_too_small(samples: int) -> bool:
    """Whether ``samples`` base samples N are too few for a Saltelli design's Sobol indices
    (N < :data:`MIN_SALTELLI_BASE`). The one rule behind both refusals, each in its own
    words: of a campaign when it is made (:func:`saltelli_issue`, through
    :func:`make_config`) and of a stored one by its direct analysis
    (``railsusp.sensitivity_indices.sobol_direct``, which imports this module)."""
    return samples < MIN_SALTELLI_BASE


def saltelli_issue(config: CampaignConfig) -> str | None:
    """Why a Saltelli (``sobol``) design cannot give Sobol indices (one line naming the
    settings), or None (also for any other design).

    SALib's estimators take each block of rows A, AB_1 .. AB_D, B (and BA_i with second
    order) to differ only in the column swapped: a track realisation, FRA class, radius or
    cant, or values of the non-key parameters drawn per row (``independent_seeds``,
    ``track_family``, ``other_parameters``) differ between every row of a block, and their
    variance is added to every total index (inert parameters then pass the key threshold).
    Fewer than :data:`MIN_SALTELLI_BASE` base samples give indices that are noise."""
    if config.design != "sobol":
        return None
    varied = [
        name
        for name, on in (
            ("independent_seeds", config.independent_seeds),
            ("track_family", config.track_family is not None),
            ("other_parameters", bool(config.other_parameters)),
        )
        if on
    ]
    if varied:
        return (
            f"design sobol with {', '.join(varied)}: accepted only without them (per-row "
            "tracks or non-key values break the Saltelli blocks, whose rows may differ only "
            "in the swapped column, and add their variance to every total index), or design "
            "lhs / lhs-optimised with them"
        )
    if saltelli_base_too_small(config.samples):
        return (
            f"samples {config.samples}: a Saltelli design (design sobol) needs N >= "
            f"{MIN_SALTELLI_BASE} base samples, a power of two, for its Sobol indices (at "
            "N = 2 total indices of 10 to 20 came out, and were taken as key)"
        )
    return None


def make_config(conditions: Sequence[WorkingCondition], samples: int, **kw: Any) -> CampaignConfig:
    """A validated campaign configuration; errors name the field (one line). A Saltelli
    design that its Sobol analysis would refuse (:func:`saltelli_issue`) is refused here,
    before its runs are spent (a stored campaign still loads: the analysis refuses it), and
    so is ``second_order`` with a design other than ``sobol`` (nothing would use it, yet it
    changes the configuration's hash; a stored one still loads)."""
    from pydantic import ValidationError

    wagon = kw.pop("wagon", None) or load_wagon()
    try:
        config = CampaignConfig(conditions=tuple(conditions), samples=samples, wagon=wagon, **kw)
    except ValidationError as exc:
        msgs = [_setting_error(e) for e in exc.errors()]
        raise CampaignError("campaign configuration: " + "; ".join(msgs)) from None
    issue = saltelli_issue(config)
    if issue:
        raise CampaignError(f"campaign configuration: {issue}")
    if config.second_order and config.design != "sobol":  # stored, unused, in the hash
        raise CampaignError(
            f"campaign configuration: second_order: accepted only with design sobol (a "
            f"Saltelli design), not {config.design}"
        )
    return config


def _setting_error(err: Any) -> str:
    """One of pydantic's errors of :class:`CampaignConfig` as ``setting: what is accepted``:
    a value outside a setting's bounds with the range (``samples = 0: accepted [2, 1000000]``,
    not pydantic's one bound, "Input should be greater than or equal to 2"), no parameter
    with the parameters that can be sampled (not "Tuple should have at least 1 item after
    validation, not 0"), others as pydantic says them."""
    where = ".".join(str(p) for p in err["loc"]) or "campaign"
    if err["type"] in BOUND_ERRORS:
        detail = error_detail(CampaignConfig, err)
        if detail:
            return f"{where} = {err.get('input')!r}: {detail}"
    if err["type"] == "too_short" and tuple(err["loc"]) == ("parameters",):
        sampled = f"{MAIN_SUSPENSION[0]}..{MAIN_SUSPENSION[-1]}"
        return f"{where}: none given; accepted one or more of {sampled}"
    return f"{where}: {err['msg'].removeprefix('Value error, ')}"


# ------------------------------------------------------------------------------- design
def salib_problem(parameters: Sequence[str]) -> dict[str, Any]:
    """SALib problem description over the given parameters (SI bounds)."""
    lo, hi = bounds(parameters)
    return {
        "num_vars": len(parameters),
        "names": list(parameters),
        "bounds": [[float(a), float(b)] for a, b in zip(lo, hi, strict=True)],
    }


def make_design(config: CampaignConfig) -> pd.DataFrame:
    """The design: one row per parameter set, columns sample_id and the parameters (SI).

    ``lhs``: Latin hypercube (scipy.stats.qmc.LatinHypercube, seeded); ``lhs-optimised``: the
    same with random-CD optimisation of its centred discrepancy; ``sobol``: SALib's Saltelli
    scheme on a scrambled Sobol sequence, N (D + 2) rows (N (2D + 2) with second order).
    """
    params = list(config.parameters)
    lo, hi = bounds(params)
    if config.design == "sobol":
        from SALib.sample import sobol as sobol_sample

        x = sobol_sample.sample(
            salib_problem(params),
            config.samples,
            calc_second_order=config.second_order,
            seed=config.seed,
        )
    else:
        opt = "random-cd" if config.design == "lhs-optimised" else None
        unit = qmc.LatinHypercube(
            d=len(params), optimization=opt, rng=np.random.default_rng(config.seed)
        ).random(config.samples)
        x = lo + (hi - lo) * unit
    df = pd.DataFrame(x, columns=params)
    df.insert(0, "sample_id", np.arange(len(df), dtype=np.int64))
    others = sample_others(config.other_parameters, len(df), config.seed)
    for col in others.columns:
        df[col] = others[col].to_numpy()
    return df


def track_seeds(config: CampaignConfig, condition: WorkingCondition) -> np.ndarray | None:
    """Irregularity seed per sample: None (common random numbers: the condition's seed for
    all) unless ``independent_seeds``, then distinct seeds derived from the campaign seed."""
    if not config.independent_seeds:
        return None
    ss = np.random.SeedSequence([config.seed, condition.seed])
    return np.random.default_rng(ss).integers(0, 2**31 - 1, size=config.n_runs)


def track_table(config: CampaignConfig, condition: WorkingCondition) -> pd.DataFrame:
    """The track of every sample of one condition (:func:`railsusp.variation.sample_tracks`):
    sample_id, seed, irregularity_class, curve_radius_m, cant_mm."""
    return sample_tracks(
        config.track_family,
        condition,
        track_seeds(config, condition),
        config.n_runs,
        config.seed,
    )


# ---- the run directory
def batch_paths(out: Path, condition: str, b: int) -> tuple[Path, Path]:
    """Series and features files of batch ``b`` of ``condition`` in run directory ``out``."""
    folder = out / "batches" / condition
    return folder / f"batch-{b:05d}.parquet", folder / f"batch-{b:05d}.features.parquet"


def read_meta(meta_path: Path) -> dict[str, Any]:
    """``campaign.json``, or a one-line error when it is unreadable or not a JSON object."""
    meta = read_json(meta_path)
    if not isinstance(meta, dict):
        raise CampaignError(f"{meta_path} is corrupt: a JSON object was expected")
    return meta
