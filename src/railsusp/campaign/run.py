"""Running a campaign: simulate batches of samples (locally or on Dask), reduce them to
features, write each finished batch atomically, resume from what is stored. A measured
track file is read here, once, and its contents go with each batch (:func:`simulate_task`),
so that a cluster's workers simulate the track whose hash ``campaign.json`` records."""

from __future__ import annotations

import hashlib
import logging
import shutil
import tempfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsusp.campaign.batch_files import batch_count, batch_done, foreign_batches, write_batch
from railsusp.campaign.dask_cluster import check_scheduler_address, executor_record, run_on_dask
from railsusp.campaign.design import (
    CHANNELS,
    STATISTICS,
    CampaignConfig,
    CampaignError,
    batch_paths,
    make_design,
    read_meta,
    track_seeds,
    track_table,
)
from railsusp.campaign.results import RESUME, stored_config
from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_output_folder
from railsusp.numbers import is_whole
from railsusp.run_lock import run_lock
from railsusp.store import (
    parquet_readable,
    provenance,
    read_json,
    read_parquet,
    remove_stale_temporaries,
    utc_now,
    write_json,
    write_parquet,
)
from railsusp.variation import (
    layout_groups,
)
from railsusp.vehicle import MODEL_REVISION
from railsusp.vehicle.simulate import simulate_requests
from railsusp.vehicle.simulation_result import WHEEL_NAMES
from railsusp.vehicle.track_geometry import geometry_digests

log = logging.getLogger("railsusp.campaign")


def simulate_task(
    config_json: str,
    condition_index: int,
    sample_ids: np.ndarray,
    x: np.ndarray,
    seeds: np.ndarray | None,
    track_files: Mapping[str, bytes] | None = None,
) -> dict[str, Any]:
    """Simulate one batch (runs on a Dask worker or locally); returns series and features.

    ``track_files``: the contents of the condition's measured track file, by the name the
    condition gives it (:func:`run_campaign` reads it on the client): the batch simulates
    those bytes and never opens the user's file, which a worker would look for on its own
    disk and relative to its own working folder (another track, or none: the Dask audit).
    Without them a named file is read here.

    With a track family, each layout (FRA class, radius and cant) is a request of its own
    and every sample runs on its own seed; the requests share the integrator's parallel calls
    (:func:`~railsusp.vehicle.simulate.simulate_requests`), so a curve batch whose samples
    each have their own radius and cant keeps every core busy."""
    config = CampaignConfig.model_validate_json(config_json)
    named = config.conditions[condition_index]
    with _local_track(named, track_files) as (cond, local_names):
        try:
            return _simulate_batch(config, named, cond, sample_ids, x, seeds)
        except RailsuspInputError as exc:  # a bad file: named as the user named it
            text = str(exc)
            for local in sorted(local_names, key=len, reverse=True):
                text = text.replace(local, local_names[local])
            exc.args = (text, *exc.args[1:])
            raise


@contextmanager
def _local_track(
    cond: WorkingCondition, track_files: Mapping[str, bytes] | None
) -> Iterator[tuple[WorkingCondition, dict[str, str]]]:
    """``cond`` as this machine simulates it: with its measured track file's contents in
    ``track_files``, a copy of them in a temporary folder (removed after) is the file it
    reads, parsed by the same reader as the original (so the results are bitwise the
    same); also the copy's paths -> the name the user gave, for messages."""
    name = cond.track_geometry
    if name is None or track_files is None or name not in track_files:
        yield cond, {}
        return
    with tempfile.TemporaryDirectory(prefix="railsusp-track-") as tmp:
        local = Path(tmp) / Path(name).name  # the same suffix, which chooses the reader
        local.write_bytes(track_files[name])
        names = {str(local): name, str(local.resolve()): name}
        yield cond.with_changes(track_geometry=str(local)), names


def _simulate_batch(
    config: CampaignConfig,
    named: WorkingCondition,
    cond: WorkingCondition,
    sample_ids: np.ndarray,
    x: np.ndarray,
    seeds: np.ndarray | None,
) -> dict[str, Any]:
    """:func:`simulate_task` of condition ``named`` (the configuration's), simulated as
    ``cond`` (the same, its track file where this machine holds it)."""
    if config.track_family is None:
        groups = [(cond, np.arange(len(sample_ids)))]
    else:
        tracks = track_table(config, named).set_index("sample_id").loc[sample_ids]
        groups = layout_groups(cond, tracks.reset_index())
    series = np.zeros((len(sample_ids), len(CHANNELS), cond.n_steps), dtype=np.float32)
    status = np.zeros(len(sample_ids), dtype=np.int64)
    features = []
    results = simulate_requests(  # every layout in as few parallel calls as they allow
        [
            (x[idx], gcond, None if seeds is None else [int(s) for s in seeds[idx]])
            for gcond, idx in groups
        ],
        symbols=config.simulated_parameters,
        wagon=config.wagon,
        settings=config.settings(),
    )
    for (_, idx), r in zip(groups, results, strict=True):
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
        "model_revision": MODEL_REVISION,  # the force laws the worker simulated with
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


def _keep_own_batches(out: Path, config: CampaignConfig, problem: str, force: bool) -> None:
    """A campaign folder whose ``campaign.json`` is gone or damaged (``problem``): its
    batches stamped with this configuration are kept and the files made from the design
    written again (design, tracks, features); what was made from its batches (their
    sensitivity, splits and twins) stays where every batch is this configuration's.
    Other batches are another configuration's, or unknown, and are discarded with
    ``force`` only."""
    foreign, own = foreign_batches(out, config.hash())
    if foreign and not force:
        n = len(foreign)
        raise CampaignError(
            f"{problem}, and {n} of its batches {'is' if n == 1 else 'are'} not "
            "stamped as this configuration's (another campaign's or other force laws', or "
            "written before batches were stamped); use a new --out, or --force to discard them"
            + (f" ({batch_count(own)} of this configuration would be kept)" if own else "")
        )
    made = [n for n in ("features.parquet", *_FROM_BATCHES) if (out / n).exists()]
    if not own and made and not force:  # made from batches no longer there: whose?
        raise CampaignError(
            f"{problem}, and it holds {', '.join(made)} but no batch of this configuration "
            "(another campaign's results); use a new --out, or --force to discard them"
        )
    for files in foreign:
        for f in files:
            f.unlink()
    if foreign or not own:  # what was made from other batches, or from unknown ones, goes
        _remove(out, _FROM_BATCHES)
    _remove(out, _FROM_DESIGN)
    if own:
        log.warning("%s: kept %s stamped as this configuration's", problem, batch_count(own))


#: what a campaign folder holds that follows from its design alone (written again from it)
_FROM_DESIGN = ("features.parquet", "design.parquet", "tracks.parquet")
#: what other work made from its batches
_FROM_BATCHES = (
    "sensitivity",
    "splits",
    "nominal",  # the nominal twins (railsusp.campaign.twins) of the old design
    "perturbed",  # and its perturbed twins (railsusp.campaign.perturbed)
    "surrogates",  # the networks trained on its batches (railsusp train)
)


def _remove(out: Path, names: tuple[str, ...]) -> None:
    """Remove these files or folders of ``out`` where they exist."""
    for name in names:
        p = out / name
        if p.is_dir():
            shutil.rmtree(p)
        elif p.exists():
            p.unlink()


def _discard(out: Path) -> None:
    """Remove the results of a campaign of another configuration."""
    _remove(out, ("batches", *_FROM_DESIGN, *_FROM_BATCHES))


def _geometry_files(config: CampaignConfig) -> dict:
    """``campaign.json``'s record of the measured track files' contents (none without)."""
    files = geometry_digests(config.conditions)
    return {"track_geometry_files": files} if files else {}


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


def _prepare(config: CampaignConfig, out: Path, force: bool) -> pd.DataFrame:
    """Create or re-open a run directory; refuse a different configuration unless forced."""
    check_output_folder(out)
    meta_path = out / "campaign.json"
    if meta_path.exists():
        try:
            meta = read_meta(meta_path)
            stored_config(meta, meta_path)  # valid, and the one its batches are stamped with
        except RailsuspInputError as exc:  # damaged: the batches' stamps say whose they are
            _keep_own_batches(out, config, str(exc), force)
        else:
            revision = meta.get("model_revision", MODEL_REVISION)  # unstated: older files
            if "model_revision" not in meta:
                log.warning(
                    "%s states no force-law revision (made before 2026-11-30): its batches "
                    "may be of other force laws; where its conditions run below 58 km/h or "
                    "with lead-ins under 40 m, start it again in a new --out",
                    meta_path,
                )
            if revision != MODEL_REVISION and not force:  # its batches: other force laws
                raise CampaignError(
                    f"{out} holds a campaign simulated with force-law revision {revision}; "
                    f"railsusp now simulates {MODEL_REVISION}: use a new --out, or --force to "
                    "discard the old results (resumed, its batches would mix the two)"
                )
            # the measured track files' contents (none recorded before stop 60: taken as now)
            files = geometry_digests(config.conditions)
            was = meta.get("track_geometry_files", files)
            edited = sorted(k for k in files if was.get(k) != files[k])
            if edited and meta.get("config_hash") == config.hash() and not force:
                raise CampaignError(
                    f"{out} holds a campaign simulated on other contents of its track geometry "
                    f"file(s) {', '.join(edited)} (edited since); use a new --out, or --force "
                    "to discard the old results"
                )
            if meta.get("config_hash") != config.hash() or revision != MODEL_REVISION or edited:
                if not force:
                    raise CampaignError(
                        f"{out} holds a campaign with another configuration (hash "
                        f"{meta.get('config_hash')}, now {config.hash()}); use a new --out, "
                        f"or --force to discard the old results"
                    )
                _discard(out)
            elif parquet_readable(out / "design.parquet", pages=True):
                stored = read_parquet(out / "design.parquet")
                if stored.equals(make_design(config)):  # it follows from the configuration
                    if files and "track_geometry_files" not in meta:  # made before stop 60:
                        # recorded now, so that a later edit is seen (the review of stop 60)
                        write_json(meta_path, {**meta, "track_geometry_files": files})
                    return stored
                if not force:  # its batches were simulated on one of the two: which?
                    raise CampaignError(
                        f"{out / 'design.parquet'} is not this configuration's design "
                        "(edited by hand, or made by another SciPy or SALib), so its batches "
                        "cannot be paired with their parameters; use a new --out, or --force "
                        "to start the campaign again"
                    )
                _discard(out)
            # (a design that is gone or does not read is made again below: it follows from
            # the configuration, as the batches that campaign.json vouches for do)
    elif any((out / sub).exists() for sub in ("batches", "features.parquet")):
        # results without the configuration that made them: only batches stamped with this
        # configuration are taken in (others would pair forces of one design with another's
        # parameters)
        _keep_own_batches(out, config, f"{out} holds campaign results but no campaign.json", force)
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
            "model_revision": MODEL_REVISION,
            "config": config.model_dump(mode="json"),
            **_geometry_files(config),
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
        _remove_stale_temporaries(out)
        return _run_locked(
            config, out, force, scheduler, workers, progress, max_batches, scheduler_setting
        )


def _remove_stale_temporaries(out: Path) -> None:
    """The temporaries a campaign killed while writing left (:func:`~railsusp.store.
    remove_stale_temporaries`): of its own files at the top of ``out`` and of its batches in
    ``out/batches/<condition>/``, the folders the campaign's lock keeps to it. The rest of
    the folder is other work's (a network training under ``surrogates/`` saves its
    checkpoint through a temporary of its own), and is not entered."""
    remove_stale_temporaries(out, targets=("campaign.json", *_FROM_DESIGN))
    batches = out / "batches"
    for folder in sorted(batches.iterdir()) if batches.is_dir() else []:
        if folder.is_dir() and not folder.is_symlink():
            remove_stale_temporaries(folder)


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
    """:func:`run_campaign` in its folder, holding the folder's lock."""
    design = _prepare(config, out, force)
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
        if worker != MODEL_REVISION:  # a cluster node of another railsusp: never stamped ours
            raise CampaignError(
                f"batch {b} of {res['condition']!r} was simulated with force laws of revision "
                f"{worker} where this railsusp has {MODEL_REVISION}: install the same railsusp "
                "on every worker of the cluster (the batches stored so far are kept)"
            )
        if not recorded:  # (a resume may run otherwise than the start did)
            _record_run(out, scheduler, workers, len(todo))
            recorded = True
        write_batch(out, b, res, n_t[res["condition"]], config.hash())
        stored.add((res["condition"], b))
        done_runs += len(res["sample_ids"])
        if progress:
            progress(done_runs, total)

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
