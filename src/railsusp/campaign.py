"""Simulation campaigns: sample the suspension parameters, simulate every sample in every
condition, store force series and scalar features in a run directory.

Verbs (SALib style): :func:`make_design` samples (Latin hypercube from ``scipy.stats.qmc``,
optionally optimised, or a Saltelli/Sobol design from SALib for direct Sobol analysis);
:func:`run_campaign` evaluates batches of samples with the batched simulator, locally (all
cores, through the simulator's threads) or on a Dask cluster, and writes each finished batch
atomically; :func:`load_campaign` reads a run directory back.

Run directory::

    campaign.json                    configuration, its hash, provenance, layout
    design.parquet                   sample_id, the sampled parameters and the varied
                                     non-key parameters (SI)
    tracks.parquet                   per condition and sample: irregularity seed, FRA class,
                                     curve radius and cant (railsusp.variation)
    batches/<condition>/batch-NNNNN.features.parquet   tidy features of the batch
    batches/<condition>/batch-NNNNN.parquet            force series of the batch (float32)
    features.parquet                 all tidy features, written when the campaign completes

A batch counts as done when its series file exists (it is written last, atomically and
fsynced, after its features file), so a campaign killed at any moment, or a power loss,
resumes with the same command, recomputing nothing already stored and never counting a
half-written batch as done. Results do not depend on where a batch ran: each sample is
integrated on its own. Samples whose simulation failed (derailment, divergence) keep their
rows with a non-zero ``status`` and NaN features; :func:`failed_runs` counts them.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Sequence
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
from railsusp.errors import RailsuspInputError
from railsusp.params import MAIN_SUSPENSION, bounds, spec
from railsusp.store import (
    check_output_folder,
    content_hash,
    provenance,
    read_json,
    write_json,
    write_parquet,
)
from railsusp.variation import (
    TrackFamily,
    check_other_parameters,
    layout_groups,
    sample_others,
    sample_tracks,
)
from railsusp.vehicle.simulate import WHEEL_NAMES, SolverSettings, simulate_batch
from railsusp.vehicle.wagon import WagonData, load_wagon

CHANNELS = (
    tuple(f"Y_{w}" for w in WHEEL_NAMES)
    + tuple(f"Q_{w}" for w in WHEEL_NAMES)
    + ("car_acc_y", "car_acc_z")
)
STATISTICS = ("mean", "rms", "p99", "max")


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
        if len(set(names)) != len(names):
            raise ValueError(f"condition names repeat: {names}")
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
        return content_hash(self.model_dump(mode="json"))

    def settings(self) -> SolverSettings:
        return SolverSettings(**self.solver)


def make_config(conditions: Sequence[WorkingCondition], samples: int, **kw: Any) -> CampaignConfig:
    """A validated campaign configuration; errors name the field (one line)."""
    from pydantic import ValidationError

    wagon = kw.pop("wagon", None) or load_wagon()
    try:
        return CampaignConfig(conditions=tuple(conditions), samples=samples, wagon=wagon, **kw)
    except ValidationError as exc:
        msgs = [
            f"{'.'.join(str(p) for p in e['loc']) or 'campaign'}: "
            f"{e['msg'].removeprefix('Value error, ')}"
            for e in exc.errors()
        ]
        raise CampaignError("campaign configuration: " + "; ".join(msgs)) from None


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


# ------------------------------------------------------------------------------- worker
def simulate_task(
    config_json: str,
    condition_index: int,
    sample_ids: np.ndarray,
    x: np.ndarray,
    seeds: np.ndarray | None,
) -> dict[str, Any]:
    """Simulate one batch (runs on a Dask worker or locally); returns series and features.

    With a track family, samples that share FRA class, radius and cant are simulated
    together (one batched call per layout), each on its own seed."""
    config = CampaignConfig.model_validate_json(config_json)
    cond = config.conditions[condition_index]
    if config.track_family is None:
        groups = [(cond, np.arange(len(sample_ids)))]
    else:
        tracks = track_table(config, cond).set_index("sample_id").loc[sample_ids]
        groups = layout_groups(cond, tracks.reset_index())
    series = np.zeros((len(sample_ids), len(CHANNELS), cond.n_steps), dtype=np.float32)
    status = np.zeros(len(sample_ids), dtype=np.int64)
    features = []
    for gcond, idx in groups:
        r = simulate_batch(
            x[idx],
            gcond,
            symbols=config.simulated_parameters,
            seeds=None if seeds is None else [int(s) for s in seeds[idx]],
            wagon=config.wagon,
            settings=config.settings(),
        )
        series[idx] = np.concatenate([r.Y, r.Q, r.car_acc_y[:, None], r.car_acc_z[:, None]], axis=1)
        status[idx] = r.status
        features.append(features_table(r, sample_ids[idx], config.wheel, cond.name))
    feats = pd.concat(features, ignore_index=True)
    if len(groups) > 1:  # the order of one batched call: quantity, statistic, sample
        order = {int(s): i for i, s in enumerate(sample_ids)}
        feats = (
            feats.assign(_q=feats.quantity.map({"Y": 0, "Q": 1, "YQ": 2, "dQQ": 3}))
            .assign(_s=feats.statistic.map({s: i for i, s in enumerate(STATISTICS)}))
            .assign(_i=feats.sample_id.map(order))
            .sort_values(["_q", "_s", "_i"], kind="stable")
            .drop(columns=["_q", "_s", "_i"])
            .reset_index(drop=True)
        )
    return {
        "condition": cond.name,
        "sample_ids": sample_ids,
        "series": series,
        "status": status,
        "features": feats,
    }


def features_table(
    result, sample_ids: np.ndarray, wheel: str = "auto", condition: str | None = None
) -> pd.DataFrame:
    """Tidy scalar features of the measured wheel (forces in kN): one row per sample,
    quantity (Y, Q, YQ, dQQ) and statistic (mean, rms, p99, max). ``condition``: the name
    stored (default: the result's)."""
    s = result.statistics(wheel, set_index=None)
    rows = []
    for q in ("Y", "Q"):
        for st in STATISTICS:
            rows.append((q, st, s[f"{q}_{st}"]))
    rows.append(("YQ", "max", s["YQ_max"]))
    rows.append(("dQQ", "max", s["dQQ_max"]))
    frames = [
        pd.DataFrame(
            {
                "sample_id": sample_ids,
                "condition": result.condition.name if condition is None else condition,
                "wheel": WHEEL_NAMES[result.measured_wheel(wheel)],
                "quantity": q,
                "statistic": st,
                "value": np.asarray(v, float),
                "status": result.status.astype(np.int64),
            }
        )
        for q, st, v in rows
    ]
    return pd.concat(frames, ignore_index=True)


# ------------------------------------------------------------------------------- store
def _batch_paths(out: Path, condition: str, b: int) -> tuple[Path, Path]:
    folder = out / "batches" / condition
    return folder / f"batch-{b:05d}.parquet", folder / f"batch-{b:05d}.features.parquet"


def _write_batch(out: Path, b: int, res: dict[str, Any], n_t: int) -> None:
    series_path, feat_path = _batch_paths(out, res["condition"], b)
    write_parquet(feat_path, res["features"])
    s = res["series"]  # (n, channels, n_t)
    n = s.shape[0]
    df = pd.DataFrame(
        {
            "sample_id": np.repeat(res["sample_ids"], n_t),
            "step": np.tile(np.arange(n_t, dtype=np.int32), n),
        }
    )
    for c, name in enumerate(CHANNELS):
        df[name] = s[:, c, :].reshape(-1)
    write_parquet(
        series_path, df, metadata={"railsusp.status": ",".join(str(int(v)) for v in res["status"])}
    )  # series last: marks the batch done


def _prepare(config: CampaignConfig, out: Path, force: bool) -> pd.DataFrame:
    """Create or re-open a run directory; refuse a different configuration unless forced."""
    check_output_folder(out)
    meta_path = out / "campaign.json"
    if meta_path.exists():
        try:
            meta = _read_meta(meta_path)
        except RailsuspInputError as exc:
            if not force:
                raise CampaignError(
                    f"{exc}; use --force to discard that run directory's results"
                ) from None
            meta = {}  # corrupt: discarded below like another configuration
        if meta.get("config_hash") != config.hash():
            if not force:
                raise CampaignError(
                    f"{out} holds a campaign with another configuration (hash "
                    f"{meta.get('config_hash')}, now {config.hash()}); use a new --out, or "
                    f"--force to discard the old results"
                )
            for sub in (
                "batches",
                "features.parquet",
                "design.parquet",
                "tracks.parquet",
                "sensitivity",
                "splits",
            ):
                p = out / sub
                if p.is_dir():
                    shutil.rmtree(p)
                elif p.exists():
                    p.unlink()
        elif (out / "design.parquet").exists():
            return pd.read_parquet(out / "design.parquet")
    design = make_design(config)
    write_parquet(out / "design.parquet", design)
    write_parquet(
        out / "tracks.parquet",
        pd.concat(
            [track_table(config, c).assign(condition=c.name) for c in config.conditions],
            ignore_index=True,
        ),
    )
    write_json(
        meta_path,
        {
            "kind": "railsusp campaign",
            "config_hash": config.hash(),
            "config": config.model_dump(mode="json"),
            "n_runs": config.n_runs,
            "n_batches": config.n_batches,
            "channels": list(CHANNELS),
            "created": provenance(),
        },
    )
    return design


def run_campaign(
    config: CampaignConfig,
    out: str | Path,
    *,
    force: bool = False,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    max_batches: int | None = None,
) -> Path:
    """Run (or resume) a campaign into ``out``; returns the run directory.

    ``scheduler`` (``tcp://host:port``) or ``workers`` (a local Dask cluster of that many
    processes) send batches to Dask; otherwise batches run here, one after another, each on
    all cores. ``progress(done_runs, total_runs)`` reports finished simulations (samples x
    conditions). ``max_batches`` stops after that many new batches (partial runs, tests).
    """
    out = Path(out)
    if workers is not None and workers < 1:
        raise CampaignError(f"--workers = {workers}: accepted an integer >= 1")
    if max_batches is not None and max_batches < 0:
        raise CampaignError(f"--max-batches = {max_batches}: accepted an integer >= 0")
    design = _prepare(config, out, force)
    x_all = design[list(config.simulated_parameters)].to_numpy()
    ids_all = design["sample_id"].to_numpy()
    n_t = {c.name: c.n_steps for c in config.conditions}
    todo: list[tuple[int, int]] = []
    done_runs = 0
    for ci, cond in enumerate(config.conditions):
        for b in range(config.n_batches):
            if _batch_paths(out, cond.name, b)[0].exists():
                done_runs += len(ids_all[b * config.batch_size : (b + 1) * config.batch_size])
            else:
                todo.append((ci, b))
    total = config.n_runs * len(config.conditions)
    if progress:
        progress(done_runs, total)
    if max_batches is not None:
        todo = todo[:max_batches]
    cfg_json = config.model_dump_json()
    seeds = {ci: track_seeds(config, c) for ci, c in enumerate(config.conditions)}

    def args(ci: int, b: int):
        sl = slice(b * config.batch_size, (b + 1) * config.batch_size)
        s = seeds[ci]
        return cfg_json, ci, ids_all[sl], x_all[sl], None if s is None else s[sl]

    def finish(b: int, res: dict[str, Any]) -> None:
        nonlocal done_runs
        _write_batch(out, b, res, n_t[res["condition"]])
        done_runs += len(res["sample_ids"])
        if progress:
            progress(done_runs, total)

    if scheduler is None and workers is None:
        for ci, b in todo:
            finish(b, simulate_task(*args(ci, b)))
    else:
        _run_dask(todo, args, finish, scheduler, workers)
    if all(
        _batch_paths(out, c.name, b)[0].exists()
        for c in config.conditions
        for b in range(config.n_batches)
    ):
        feats = pd.concat(
            [
                pd.read_parquet(_batch_paths(out, c.name, b)[1])
                for c in config.conditions
                for b in range(config.n_batches)
            ],
            ignore_index=True,
        )
        write_parquet(out / "features.parquet", feats)
        meta = read_json(out / "campaign.json")
        meta["completed"] = provenance()
        write_json(out / "campaign.json", meta)
    return out


def _run_dask(todo, args, finish, scheduler: str | None, workers: int | None) -> None:
    """Submit batches to a Dask cluster and store them as they complete."""
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers or 1, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        futures = {}
        for ci, b in todo:
            fut = client.submit(simulate_task, *args(ci, b), pure=False)
            futures[fut] = b
        for fut in as_completed(futures):
            finish(futures[fut], fut.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# ------------------------------------------------------------------------------- reading
class Campaign:
    """A campaign run directory opened for reading."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        meta_path = self.path / "campaign.json"
        if not meta_path.exists():
            raise CampaignError(f"{self.path} is not a campaign run directory (no campaign.json)")
        self.meta = _read_meta(meta_path)
        try:
            self.config = CampaignConfig.model_validate(self.meta["config"])
        except (KeyError, TypeError, ValueError) as exc:
            first = str(exc).strip().splitlines()[0]
            raise CampaignError(
                f"{meta_path} is corrupt: its configuration does not validate ({first})"
            ) from None

    @property
    def complete(self) -> bool:
        return "completed" in self.meta

    def design(self) -> pd.DataFrame:
        return pd.read_parquet(self.path / "design.parquet")

    def tracks(self, condition: str) -> pd.DataFrame:
        """The track of every sample of one condition (seed, FRA class, radius, cant),
        recomputed from the configuration (``tracks.parquet`` holds the same)."""
        cond = next((c for c in self.config.conditions if c.name == condition), None)
        if cond is None:
            raise CampaignError(f"no condition {condition!r} in {self.path}")
        return track_table(self.config, cond)

    def features(self) -> pd.DataFrame:
        """All tidy features (complete or not: read from the finished batches)."""
        p = self.path / "features.parquet"
        if p.exists():
            return pd.read_parquet(p)
        files = sorted((self.path / "batches").glob("*/batch-*.features.parquet"))
        done = [f for f in files if f.with_name(f.name.replace(".features", "")).exists()]
        if not done:
            raise CampaignError(f"{self.path}: no finished batch yet")
        return pd.concat([pd.read_parquet(f) for f in done], ignore_index=True)

    def feature_matrix(
        self, condition: str, quantity: str, statistic: str, features: pd.DataFrame | None = None
    ) -> pd.Series:
        """One feature for all samples (index sample_id); NaN for failed samples.
        ``features``: the table of :meth:`features` when already read (many lookups)."""
        f = self.features() if features is None else features
        sel = f[(f.condition == condition) & (f.quantity == quantity) & (f.statistic == statistic)]
        if sel.empty:
            raise CampaignError(f"no feature {quantity}/{statistic} in condition {condition!r}")
        return sel.set_index("sample_id")["value"].sort_index()

    def series(self, condition: str) -> tuple[np.ndarray, np.ndarray]:
        """(sample_ids, series (n, channels, n_t)) of one condition from the finished batches."""
        folder = self.path / "batches" / condition
        files = sorted(f for f in folder.glob("batch-*.parquet") if ".features" not in f.name)
        if not files:
            raise CampaignError(f"{self.path}: no series for condition {condition!r}")
        df = pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
        ids = np.unique(df["sample_id"].to_numpy())
        n_t = int(df["step"].max()) + 1
        arr = df[list(CHANNELS)].to_numpy().reshape(len(ids), n_t, len(CHANNELS))
        return ids, arr.transpose(0, 2, 1)


def _read_meta(meta_path: Path) -> dict[str, Any]:
    """``campaign.json``, or a one-line error when it is unreadable or not a JSON object."""
    meta = read_json(meta_path)
    if not isinstance(meta, dict):
        raise CampaignError(f"{meta_path} is corrupt: a JSON object was expected")
    return meta


def require_complete(campaign: Campaign) -> Campaign:
    """``campaign`` if every batch of it is stored; a one-line error saying how to finish it
    otherwise (a surrogate trained on part of a campaign would silently see fewer runs)."""
    if not campaign.complete:
        cfg = campaign.config
        done = sum(
            _batch_paths(campaign.path, c.name, b)[0].exists()
            for c in cfg.conditions
            for b in range(cfg.n_batches)
        )
        raise CampaignError(
            f"{campaign.path}: the campaign is incomplete ({done} of "
            f"{cfg.n_batches * len(cfg.conditions)} batches); run the same `railsusp "
            f"campaign` command again to finish it"
        )
    return campaign


def failed_runs(path: str | Path) -> pd.DataFrame:
    """The failed simulations (derailed, diverged) of a run directory's finished batches:
    one row per condition and sample, with its status code."""
    feats = Campaign(path).features()
    failed = feats[feats["status"] != 0]
    return (
        failed[["condition", "sample_id", "status"]]
        .drop_duplicates()
        .sort_values(["condition", "sample_id"])
        .reset_index(drop=True)
    )


def load_campaign(path: str | Path) -> Campaign:
    """Open a campaign run directory."""
    return Campaign(path)
