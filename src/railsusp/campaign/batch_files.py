"""A campaign's batch files: written atomically (the series last: its file marks the batch
done), stamped with the configuration and the force-law revision that simulated them, and
told apart from other campaigns' on resume (:func:`batch_done`, :func:`foreign_batches`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from railsusp.campaign.design import CHANNELS, batch_paths
from railsusp.store import parquet_readable, write_parquet
from railsusp.vehicle.revision import this_revision

#: the Parquet metadata key of a batch file that names the campaign configuration (its
#: :meth:`~railsusp.campaign.design.CampaignConfig.hash`) that simulated it
STAMP_KEY = "railsusp.config_hash"
#: and with the force laws' revision that simulated them (:data:`railsusp.vehicle.
#: MODEL_REVISION`; since stop 60): a batch of other force laws is never this campaign's
REVISION_KEY = "railsusp.model_revision"
#: and with the configuration's batch size (since stop 69): with ``campaign.json`` lost, a
#: campaign of one batch per condition says its batch size only here (its samples fit any
#: larger one); the stamp's hash, which holds the batch size, vouches for it
BATCH_SIZE_KEY = "railsusp.batch_size"


def write_batch(
    out: Path,
    b: int,
    res: dict[str, Any],
    n_t: int,
    config_hash: str | None = None,
    batch_size: int | None = None,
) -> None:
    """Store batch ``b`` of a :func:`simulate_task` result under ``out/batches``: features,
    then the series (atomically, last: its file marks the batch done). ``config_hash``
    stamps both files with the configuration that simulated them, so that a campaign whose
    ``campaign.json`` was lost or damaged keeps the batches that are its own;
    ``batch_size``, with the batch size that configuration grouped its samples by."""
    series_path, feat_path = batch_paths(out, res["condition"], b)
    stamp = {REVISION_KEY: this_revision()}
    if config_hash is not None:
        stamp[STAMP_KEY] = config_hash
    if batch_size is not None:
        stamp[BATCH_SIZE_KEY] = str(int(batch_size))
    write_parquet(feat_path, res["features"], metadata=stamp)
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
    status = {"railsusp.status": ",".join(str(int(v)) for v in res["status"])}
    write_parquet(series_path, df, metadata={**status, **stamp})  # last: marks the batch done


def batch_done(out: Path, condition: str, b: int, config_hash: str, pages: bool = True) -> bool:
    """Both files of a batch present, each with an intact Parquet footer and this
    configuration's stamp (or none: written before batches were stamped): a file cut short
    is simulated again rather than taken as finished work, and so is a batch of another
    configuration copied in (its forces were taken with this design's parameters).

    ``pages``: each file is also read whole, its pages' checksums verified
    (:func:`~railsusp.store.parquet_readable`): a bit flipped inside a data page leaves the
    footer and the stamp as they were, and such a batch was taken in on resume with its
    numbers changed (the run-directory store audit). Without, the footers and stamps
    alone: the cheap check of whether every batch is stored (:func:`~railsusp.campaign.
    results.incomplete`); the readers verify the checksums of what they read."""
    for path in batch_paths(out, condition, b):
        meta = _batch_metadata(path)
        if meta is None or meta.get(STAMP_KEY.encode(), config_hash.encode()) != (
            config_hash.encode()
        ):
            return False
        if _other_force_laws(meta):
            return False
        if pages and not parquet_readable(path, pages=True):
            return False
    return True


def _other_force_laws(meta: dict[bytes, bytes]) -> bool:
    """Whether a batch file's metadata says it was simulated with another force-law revision
    (a batch written before batches were stamped with it says nothing: False)."""
    revision = meta.get(REVISION_KEY.encode())
    return revision is not None and revision != this_revision().encode()


def _batch_metadata(path: Path) -> dict[bytes, bytes] | None:
    """A batch file's Parquet key/value metadata, or None where its footer does not read."""
    try:
        return pq.ParquetFile(path).schema_arrow.metadata or {}
    except (OSError, ValueError):
        return None


def batch_stamp(path: Path) -> str | None:
    """The configuration hash a batch file was stamped with; None for a file that does not
    read or that carries none (written before batches were stamped)."""
    stamp = (_batch_metadata(path) or {}).get(STAMP_KEY.encode())
    return None if stamp is None else stamp.decode()


def stamped_batch_size(path: Path) -> int | None:
    """The batch size a batch file was stamped with; None for a file that does not read or
    that carries none (written before stop 69) or not a positive whole number."""
    size = (_batch_metadata(path) or {}).get(BATCH_SIZE_KEY.encode())
    try:
        value = int(size.decode()) if size is not None else None
    except (UnicodeDecodeError, ValueError):
        return None
    return value if value is not None and value > 0 else None


def foreign_batches(out: Path, config_hash: str) -> tuple[list[list[Path]], int]:
    """The batches under ``out`` not stamped with ``config_hash`` (another configuration's,
    or unstamped: a file of theirs that reads carries another stamp or none), as their
    files, and the number of this configuration's that are whole (both files read); a file
    that does not read decides nothing (its batch is simulated again, :func:`batch_done`)."""
    batches: dict[Path, list[Path]] = {}  # by the series file's path
    for f in sorted((out / "batches").glob("*/batch-*.parquet")):
        batches.setdefault(f.with_name(f.name.replace(".features", "")), []).append(f)
    foreign, own = [], 0
    for files in batches.values():
        metas = [m for m in map(_batch_metadata, files) if m is not None]
        if any(
            m.get(STAMP_KEY.encode()) != config_hash.encode() or _other_force_laws(m) for m in metas
        ):
            foreign.append(files)
        elif len(metas) == 2:
            own += 1
    return foreign, own


def batch_count(n: int) -> str:
    return f"{n} batch" if n == 1 else f"{n} batches"
