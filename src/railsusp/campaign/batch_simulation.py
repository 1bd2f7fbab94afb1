"""Simulating one batch of a campaign: the samples of one condition through the batched
simulator, reduced to the tidy scalar features (Y, Q, Y/Q, dQ/Q) stored beside the force
series. This is the work a Dask worker (or the local loop of
:func:`~railsusp.campaign.run.run_campaign`) does: it reads nothing of the run directory,
so a cluster's workers need only the arguments sent with the batch, the measured track
file's contents included."""

from __future__ import annotations

import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsusp.campaign.design import CHANNELS, STATISTICS, CampaignConfig, track_table
from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.variation import layout_groups
from railsusp.vehicle.revision import this_revision
from railsusp.vehicle.simulate import simulate_requests
from railsusp.vehicle.simulation_result import WHEEL_NAMES


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
    condition gives it (:func:`~railsusp.campaign.run.run_campaign` reads it on the
    client): the batch simulates those bytes and never opens the user's file, which a worker
    would look for on its own disk and relative to its own working folder (another track, or
    none: the Dask audit).
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
        "model_revision": this_revision(),  # the force laws the worker simulated with
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
