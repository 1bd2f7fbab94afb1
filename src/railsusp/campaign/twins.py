"""Nominal twins of a many-track campaign: every sample's own track run again with every
parameter at its nominal value.

A surrogate that reads the nominal wagon's forces on the same track as an input
(:attr:`railsusp.surrogate.features.FeatureSpec.nominal_response`,
:mod:`railsusp.surrogate.nominal`) only has to learn what the parameters change, not the
whole response to the track.
The twins are stored beside the campaign (``<run>/nominal/batches/...``,
the campaign's batch layout), batch by batch and atomically, so that a run resumes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from railsusp.campaign.batch_files import write_batch
from railsusp.campaign.batch_simulation import simulate_task
from railsusp.campaign.config_changes import config_changes
from railsusp.campaign.design import CampaignConfig, CampaignError, batch_paths, track_seeds
from railsusp.campaign.results import load_campaign
from railsusp.interrupts import stop_if_interrupted
from railsusp.params import ParameterSet
from railsusp.store import read_json, write_json

#: sub-directory of a run directory holding its nominal twins
NOMINAL_DIR = "nominal"


def nominal_folder(run: str | Path) -> Path:
    """Where the nominal twins of run directory ``run`` are stored."""
    return Path(run) / NOMINAL_DIR


def _stamp(run: str | Path) -> Path:
    """The file naming the configuration the twins were made for."""
    return nominal_folder(run) / "twins.json"


def twins_complete(run: str | Path, condition: str | None = None) -> bool:
    """Whether every batch of the campaign (of ``condition`` only, when given) has its
    nominal twin, made for the campaign's present configuration."""
    cfg = load_campaign(run).config
    out = nominal_folder(run)
    stamp = _stamp(run)
    if not stamp.exists() or read_json(stamp).get("config_hash") != cfg.hash():
        return False
    return all(
        batch_paths(out, c.name, b)[0].exists()
        for c in cfg.conditions
        if condition is None or c.name == condition
        for b in range(cfg.n_batches)
    )


def check_twins_possible(cfg: CampaignConfig, run: str | Path) -> None:
    """Refuse, in one line, a campaign on one common track: its twins would all be the same
    run (one nominal simulation serves every sample)."""
    if not cfg.independent_seeds:
        raise CampaignError(
            f"{run}: nominal twins need a campaign with a track per sample "
            "(independent_seeds); on a common track one nominal run serves every sample"
        )


def run_nominal_twins(
    run: str | Path,
    *,
    progress: Callable[[int, int], None] | None = None,
    max_batches: int | None = None,
    conditions: Sequence[str] | None = None,
) -> Path:
    """Simulate (or resume) the nominal twin of every sample of a many-track campaign: its
    condition, track seed, FRA class, radius and cant, every parameter nominal. Returns the
    twins' folder. ``progress(done, total)`` counts batches; ``max_batches`` stops after
    that many new ones; ``conditions`` (names) limits them to those conditions."""
    if max_batches is not None and max_batches < 0:
        raise CampaignError(f"max_batches = {max_batches}: accepted an integer >= 0")
    camp = load_campaign(run)
    cfg = camp.config
    check_twins_possible(cfg, run)
    out = nominal_folder(run)
    stamp = _stamp(run)
    held = read_json(stamp) if stamp.exists() else {}
    if stamp.exists() and held.get("config_hash") != cfg.hash():
        # (a stamp written before it held the configuration names no difference)
        changes = config_changes(held.get("config"), cfg)
        raise CampaignError(
            f"{out} holds the nominal twins of another configuration ("
            + (f"{changes}; " if changes else "")
            + f"hash {held.get('config_hash')}, the campaign's {cfg.hash()}); delete that "
            "folder to make them again"
        )
    write_json(
        stamp,
        {
            "kind": "railsusp nominal twins",
            "config_hash": cfg.hash(),
            "config": cfg.model_dump(mode="json"),  # what a refusal says differs
        },
    )
    x0 = ParameterSet.nominal().to_array(cfg.simulated_parameters)
    x_all = np.tile(x0, (len(camp.design()), 1))
    simulate_twin_batches(
        run, out, x_all, progress=progress, max_batches=max_batches, conditions=conditions
    )
    return out


def simulate_twin_batches(
    run: str | Path,
    out: Path,
    x_all: np.ndarray,
    *,
    progress: Callable[[int, int], None] | None = None,
    max_batches: int | None = None,
    conditions: Sequence[str] | None = None,
) -> None:
    """Simulate (or resume) every sample of campaign ``run`` again on its own track (its
    condition, seed, FRA class, radius and cant) with parameters ``x_all`` (n_samples,
    simulated parameters, SI; row i for sample i), batch by batch into ``out`` in the
    campaign's batch layout. Arguments as :func:`run_nominal_twins`."""
    if max_batches is not None and max_batches < 0:
        raise CampaignError(f"max_batches = {max_batches}: accepted an integer >= 0")
    camp = load_campaign(run)
    cfg = camp.config
    ids_all = camp.design()["sample_id"].to_numpy()
    cfg_json = cfg.model_dump_json()
    todo = [
        (ci, b)
        for ci, c in enumerate(cfg.conditions)
        if conditions is None or c.name in conditions
        for b in range(cfg.n_batches)
        if not batch_paths(out, c.name, b)[0].exists()
    ]
    n_conds = sum(conditions is None or c.name in conditions for c in cfg.conditions)
    total = n_conds * cfg.n_batches
    done = total - len(todo)
    if progress:
        progress(done, total)
    for ci, b in todo[:max_batches] if max_batches is not None else todo:
        cond = cfg.conditions[ci]
        ids = ids_all[b * cfg.batch_size : (b + 1) * cfg.batch_size]
        seeds = track_seeds(cfg, cond)
        res = simulate_task(cfg_json, ci, ids, x_all[ids], seeds[ids])
        write_batch(out, b, res, cond.n_steps)
        done += 1
        if progress:
            progress(done, total)
        stop_if_interrupted()  # a swallowed Ctrl-C: stop here, with this batch stored
