"""Perturbed twins of a many-track campaign: every sample's own track run again with one key
parameter moved by a small step, the others as the sample has them.

A surrogate trained on forces alone can fit 95 % of a series and still move it by half of
what a parameter does (the gains of 0.4-0.8 of bench/README.md, "What limits the sequence
network's gains"): its loss never asks for the parameter derivative. A pair of runs on one
track that differ in one parameter gives that derivative as a finite difference the network
can be trained on (gradient-enhanced training, :mod:`railsusp.surrogate.pairs`).

Twin ``j`` (of ``per_sample``) of sample ``i`` moves key parameter
``parameters[(i * per_sample + j) % len(parameters)]`` (the campaign's sampled parameters, in
turn, so that every key gets as many pairs) by ``step`` of its Table 2 range, up or down at
random (seeded), down where up would leave the range. ``step`` = 0.05 is the refinement's and
the Jacobian check's finite-difference step (:mod:`railsusp.estimate.output_error`,
``bench/jacobian_check.py``). The twins are stored like the nominal twins
(``<run>/perturbed/<j>/batches/...``, atomically, batch by batch, so that a run resumes) with
the table of what was moved (``<run>/perturbed/perturbations.parquet``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.campaign.design import CampaignConfig, CampaignError, batch_paths
from railsusp.campaign.results import load_campaign
from railsusp.campaign.twins import check_twins_possible, simulate_twin_batches
from railsusp.params import bounds
from railsusp.store import read_json, read_parquet, write_json, write_parquet

#: sub-directory of a run directory holding its perturbed twins
PERTURBED_DIR = "perturbed"
#: the refinement's finite-difference step, fraction of each parameter's range
DEFAULT_STEP = 0.05


def perturbed_folder(run: str | Path, twin: int | None = None) -> Path:
    """Where the perturbed twins of run directory ``run`` are stored (twin ``twin``'s
    batches, when given)."""
    root = Path(run) / PERTURBED_DIR
    return root if twin is None else root / str(twin)


def _stamp(run: str | Path) -> Path:
    return perturbed_folder(run) / "twins.json"


def check_perturbation(step: float, per_sample: int) -> None:
    """Refuse, in one line, a step or twin count that makes no pair."""
    if not (isinstance(step, int | float) and 0.0 < step <= 0.5):
        raise CampaignError(f"step = {step!r}: accepted a fraction of the range in (0, 0.5]")
    if isinstance(per_sample, bool) or not isinstance(per_sample, int) or per_sample < 1:
        raise CampaignError(f"per_sample = {per_sample!r}: accepted an integer >= 1")


def perturbation_table(
    cfg: CampaignConfig, design: pd.DataFrame, step: float, per_sample: int
) -> pd.DataFrame:
    """What each twin moves: sample_id, twin, parameter, delta_unit (signed, fraction of the
    parameter's Table 2 range), one row per sample and twin. Reproducible from the campaign's
    seed; a move that would leave the range goes the other way."""
    check_perturbation(step, per_sample)
    keys = list(cfg.parameters)
    ids = design["sample_id"].to_numpy()
    rng = np.random.default_rng([cfg.seed, 0x7E57])
    sign = rng.choice([-1.0, 1.0], size=(len(ids), per_sample))
    which = (ids[:, None] * per_sample + np.arange(per_sample)[None, :]) % len(keys)
    lo, hi = bounds(keys)
    unit = (design[keys].to_numpy(float) - lo) / (hi - lo)
    at = np.take_along_axis(unit, which, axis=1)
    sign = np.where((at + sign * step > 1.0) | (at + sign * step < 0.0), -sign, sign)
    return pd.DataFrame(
        {
            "sample_id": np.repeat(ids, per_sample).astype(np.int64),
            "twin": np.tile(np.arange(per_sample, dtype=np.int64), len(ids)),
            "parameter": [keys[k] for k in which.ravel()],
            "delta_unit": (sign * step).ravel(),
        }
    )


def perturbed_parameters(
    cfg: CampaignConfig, design: pd.DataFrame, table: pd.DataFrame, twin: int
) -> np.ndarray:
    """(n_samples, simulated parameters) SI: the design with twin ``twin``'s moves applied
    (rows by sample_id)."""
    cols = list(cfg.simulated_parameters)
    x = design.set_index("sample_id").sort_index()[cols].to_numpy(float).copy()
    rows = table[table["twin"] == twin]
    lo, hi = bounds(cols)
    for name, grp in rows.groupby("parameter"):
        c = cols.index(str(name))
        ids = grp["sample_id"].to_numpy()
        x[ids, c] += grp["delta_unit"].to_numpy() * (hi[c] - lo[c])
    return x


def read_perturbations(run: str | Path) -> pd.DataFrame:
    """The stored table of :func:`perturbation_table` of a run's perturbed twins, its pages'
    checksums verified: a damaged table (a bit flipped in a page, which pandas read as other
    moves) is a one-line :class:`CampaignError` naming it and the remedy."""
    path = perturbed_folder(run) / "perturbations.parquet"
    if not path.exists():
        raise CampaignError(f"{run}: no perturbed twins (make them with run_perturbed_twins)")
    remedy = "run run_perturbed_twins again (it writes the table anew from the campaign's seed)"
    return read_parquet(path, remedy, error=CampaignError)


def perturbed_complete(run: str | Path, condition: str | None = None) -> bool:
    """Whether every twin of every batch (of ``condition`` only, when given) is stored, made
    for the campaign's present configuration."""
    cfg = load_campaign(run).config
    stamp = _stamp(run)
    have = read_json(stamp) if stamp.exists() else {}
    if have.get("config_hash") != cfg.hash():
        return False
    per_sample = int(have["per_sample"])
    return all(
        batch_paths(perturbed_folder(run, j), c.name, b)[0].exists()
        for j in range(per_sample)
        for c in cfg.conditions
        if condition is None or c.name == condition
        for b in range(cfg.n_batches)
    )


def run_perturbed_twins(
    run: str | Path,
    *,
    step: float = DEFAULT_STEP,
    per_sample: int = 1,
    progress: Callable[[int, int], None] | None = None,
    conditions: Sequence[str] | None = None,
) -> Path:
    """Simulate (or resume) ``per_sample`` perturbed twins of every sample of a many-track
    campaign (module docstring). Returns the twins' folder. ``progress(done, total)`` counts
    batches of each twin in turn; ``conditions`` (names) limits them to those conditions.
    Twins of another configuration, step or count already in the folder are refused."""
    check_perturbation(step, per_sample)
    camp = load_campaign(run)
    cfg = camp.config
    check_twins_possible(cfg, run)
    out, stamp = perturbed_folder(run), _stamp(run)
    want = {"config_hash": cfg.hash(), "step": float(step), "per_sample": per_sample}
    if stamp.exists():
        have = read_json(stamp)
        if any(have.get(k) != v for k, v in want.items()):
            raise CampaignError(
                f"{out} holds perturbed twins of another configuration, step or count "
                f"({', '.join(f'{k} {have.get(k)}' for k in want)}); delete that folder to "
                "make them again"
            )
    write_json(stamp, {"kind": "railsusp perturbed twins", **want})
    design = camp.design()
    table = perturbation_table(cfg, design, step, per_sample)
    write_parquet(out / "perturbations.parquet", table)
    for j in range(per_sample):
        simulate_twin_batches(
            run,
            perturbed_folder(run, j),
            perturbed_parameters(cfg, design, table, j),
            progress=progress,
            conditions=conditions,
        )
    return out
