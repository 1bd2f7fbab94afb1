"""Running a campaign: simulate batches of samples (locally or on Dask), reduce them to
features, write each finished batch atomically, resume from what is stored. A measured
track file is read here, once, and its contents go with each batch (:func:`simulate_task`),
so that a cluster's workers simulate the track whose hash ``campaign.json`` records.

This module is the batch loop on the client; what one batch does (on a worker or here) is
:mod:`railsusp.campaign.batch_simulation`, and what the run directory may be resumed from is
decided before the loop by :mod:`railsusp.campaign.run_directory`."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd

from railsusp.campaign.batch_files import batch_done, write_batch
from railsusp.campaign.batch_simulation import features_table as features_table  # public here too
from railsusp.campaign.batch_simulation import simulate_task
from railsusp.campaign.dask_cluster import check_scheduler_address, executor_record, run_on_dask
from railsusp.campaign.design import CampaignConfig, CampaignError, batch_paths, track_seeds
from railsusp.campaign.results import RESUME
from railsusp.campaign.run_directory import (
    in_stored_batches,
    prepare_run_directory,
    remove_campaign_temporaries,
)
from railsusp.input_checks import check_output_folder
from railsusp.interrupts import stop_if_interrupted
from railsusp.numbers import is_whole
from railsusp.provenance import provenance, utc_now
from railsusp.run_lock import run_lock
from railsusp.store import read_json, read_parquet, write_json, write_parquet
from railsusp.vehicle.revision import this_revision


def _track_contents(config: CampaignConfig, out: Path) -> dict[str, bytes]:
    """The contents of the measured track files the conditions name (by name as given),
    read here once for every batch of this run, wherever it is simulated; refused (one
    line) where they are not the contents whose hash ``campaign.json`` records (the file
    edited or gone since the campaign was prepared): the hash stays that of the track
    simulated."""
    recorded = read_json(out / "campaign.json").get("track_geometry_files", {})
    contents: dict[str, bytes] = {}
    for cond in config.conditions:
        name = cond.track_geometry
        if name is None or name in contents:
            continue
        try:
            data = Path(name).read_bytes()
        except OSError as exc:
            raise CampaignError(
                f"condition {cond.name!r}: track_geometry {name} cannot be read "
                f"({exc.strerror or exc}); accepted a track geometry file (relative to the "
                "working folder, docs/data-format.md)"
            ) from None
        if hashlib.sha256(data).hexdigest() != recorded.get(name):
            raise CampaignError(
                f"condition {cond.name!r}: track_geometry {name} changed while the campaign "
                f"started (its contents are not those {out / 'campaign.json'} records); run "
                "the same command again"
            )
        contents[name] = data
    return contents


def _record_run(out: Path, scheduler: str | None, workers: int | None, batches: int) -> None:
    """Add to ``campaign.json``'s ``runs`` how this run (or resume) simulates: serially, on
    local processes (how many) or a scheduler (its address), with the Dask versions where
    used, when its first batch was stored and how many it was to run (``batches``): its
    ``created`` and ``completed`` said nothing of it (the Dask audit)."""
    meta_path = out / "campaign.json"
    meta = read_json(meta_path)
    runs = meta.get("runs")
    entry = {
        "utc": utc_now(),
        **executor_record(scheduler, workers),
        "batches_to_run": batches,
    }
    write_json(meta_path, {**meta, "runs": [*(runs if isinstance(runs, list) else []), entry]})


def run_campaign(
    config: CampaignConfig,
    out: str | Path,
    *,
    force: bool = False,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    max_batches: int | None = None,
    scheduler_setting: str = "--scheduler",
) -> Path:
    """Run (or resume) a campaign into ``out``; returns the run directory.

    ``scheduler`` (``tcp://host:port``) or ``workers`` (a local Dask cluster of that many
    processes) send batches to Dask; otherwise batches run here, one after another, each on
    all cores. ``progress(done_runs, total_runs)`` reports finished simulations (samples x
    conditions). ``max_batches`` stops after that many new batches (partial runs, tests).
    ``scheduler_setting``: where the user gave ``scheduler`` (``--scheduler``, or
    ``scheduler =`` in a pipeline configuration), named when it is refused or does not
    answer. Measured track files are read here and their contents sent with each batch: a
    cluster's workers need no access to them. How each run went (serial, local processes,
    a scheduler) is listed under ``runs`` in ``campaign.json``. The cluster failing on the
    way is a :class:`~railsusp.campaign.dask_cluster.ClusterError` (an OSError: the
    machines', not bad input; the batches stored are kept).
    """
    out = Path(out)
    # (type slips were TypeErrors from deep in Dask or a slice, after the folder was made;
    # max_batches = True ran one batch)
    if workers is not None and not (is_whole(workers) and workers >= 1):
        raise CampaignError(
            f"--workers = {workers!r}: accepted an integer >= 1 (the processes of a local Dask "
            "cluster), or None (no Dask)"
        )
    if max_batches is not None and not (is_whole(max_batches) and max_batches >= 0):
        raise CampaignError(
            f"--max-batches = {max_batches!r}: accepted an integer >= 0 (new batches to run), "
            "or None (all)"
        )
    if scheduler is not None and not isinstance(scheduler, str):
        raise CampaignError(
            f"{scheduler_setting} {scheduler!r}: accepted an address tcp://host:port (a string), "
            "or None (no scheduler)"
        )
    if scheduler is not None and workers is not None:  # the workers were ignored
        raise CampaignError(
            f"--workers {workers} with {scheduler_setting} {scheduler}: accepted one of them "
            "(the scheduler's cluster has its own workers; --workers starts a local one)"
        )
    if scheduler is not None:
        check_scheduler_address(scheduler, scheduler_setting)
    check_output_folder(out)
    out.mkdir(parents=True, exist_ok=True)
    # one process at a time: two on one folder simulated the same batches twice, and one
    # with --force or another configuration deleted what the other was writing
    with run_lock(out, "--out"):
        remove_campaign_temporaries(out)
        return _run_locked(
            config, out, force, scheduler, workers, progress, max_batches, scheduler_setting
        )


def _run_locked(
    config: CampaignConfig,
    out: Path,
    force: bool,
    scheduler: str | None,
    workers: int | None,
    progress: Callable[[int, int], None] | None,
    max_batches: int | None,
    scheduler_setting: str = "--scheduler",
) -> Path:
    """:func:`run_campaign` in its folder, holding the folder's lock. A campaign stored in
    other batches than ``config.batch_size`` says, and otherwise the same, is resumed in
    them (:func:`~railsusp.campaign.run_directory.in_stored_batches`), with or without
    ``force``: the batch size groups the same simulations."""
    config = in_stored_batches(config, out)
    design = prepare_run_directory(config, out, force)
    x_all = design[list(config.simulated_parameters)].to_numpy()
    ids_all = design["sample_id"].to_numpy()
    n_t = {c.name: c.n_steps for c in config.conditions}
    todo: list[tuple[int, int]] = []
    # the batches stored whole (every page's checksum verified: read once per run) and those
    # written by this run, by condition name and batch: the campaign is complete when it
    # holds all (the folder's lock keeps them as they are meanwhile)
    stored: set[tuple[str, int]] = set()
    done_runs = 0
    for ci, cond in enumerate(config.conditions):
        for b in range(config.n_batches):
            if batch_done(out, cond.name, b, config.hash()):
                done_runs += len(ids_all[b * config.batch_size : (b + 1) * config.batch_size])
                stored.add((cond.name, b))
            else:
                todo.append((ci, b))
    total = config.n_runs * len(config.conditions)
    if progress:
        progress(done_runs, total)
    if max_batches is not None:
        todo = todo[:max_batches]
    cfg_json = config.model_dump_json()
    seeds = {ci: track_seeds(config, c) for ci, c in enumerate(config.conditions)}
    tracks = _track_contents(config, out) if todo else {}
    recorded = False  # how this run simulates: with its first batch stored

    def args(ci: int, b: int):
        sl = slice(b * config.batch_size, (b + 1) * config.batch_size)
        s = seeds[ci]
        name = config.conditions[ci].track_geometry
        batch = (cfg_json, ci, ids_all[sl], x_all[sl], None if s is None else s[sl])
        # the batch's track file alone, where it has one: without, the arguments are those
        # a worker of an older railsusp takes, which then says its model revision differs
        return (*batch, {name: tracks[name]}) if name in tracks else batch

    def finish(b: int, res: dict[str, Any]) -> None:
        nonlocal done_runs, recorded
        worker = res.get("model_revision")
        if worker != this_revision():  # a cluster node of another railsusp: never stamped ours
            raise CampaignError(
                f"batch {b} of {res['condition']!r} was simulated with force laws of revision "
                f"{worker} where this railsusp has {this_revision()}: install the same railsusp "
                "on every worker of the cluster (the batches stored so far are kept)"
            )
        if not recorded:  # (a resume may run otherwise than the start did)
            _record_run(out, scheduler, workers, len(todo))
            recorded = True
        write_batch(out, b, res, n_t[res["condition"]], config.hash(), config.batch_size)
        stored.add((res["condition"], b))
        done_runs += len(res["sample_ids"])
        if progress:
            progress(done_runs, total)
        stop_if_interrupted()  # a swallowed Ctrl-C: stop here, with this batch stored

    if scheduler is None and workers is None:
        for ci, b in todo:
            finish(b, simulate_task(*args(ci, b)))
    else:
        run_on_dask(simulate_task, todo, args, finish, scheduler, workers, scheduler_setting)
    if all((c.name, b) in stored for c in config.conditions for b in range(config.n_batches)):
        feats = pd.concat(
            [
                read_parquet(batch_paths(out, c.name, b)[1], RESUME)
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
