"""The code stamp of an estimator folder: what its ``settings.json`` records of the force
laws (:data:`railsusp.vehicle.MODEL_REVISION`) and of the summary statistics' definitions
(:data:`railsusp.estimate.summaries.STATISTICS_VERSION`) that its cached simulations were
made with, and the check that refuses a folder made with others.

Why a module of its own: both estimators (the amortised flows and the synthetic likelihood)
write the stamp when they train and check it when they read a folder again; it is neither
the simulation of the training cases nor the reading of a recording.
"""

from __future__ import annotations

from pathlib import Path

from railsusp.errors import RailsuspInputError


def check_model_revision(stamp: dict, path: Path) -> None:
    """Refuse, in one line, an estimator folder whose ``settings.json`` (``stamp``) was
    simulated with other force laws than :data:`railsusp.vehicle.MODEL_REVISION` (or before
    the revision was recorded there, stop 60), or summarised with other statistics'
    definitions than :data:`railsusp.estimate.summaries.STATISTICS_VERSION` (recorded since
    stop 62): its cached simulations and what was trained on them describe another model,
    and mixing them with new ones would pass unseen."""
    from railsusp.vehicle.revision import mismatch

    again = f"train again with another --out (or delete {path.parent})"
    revision = stamp.get("model_revision")
    said = mismatch(revision, again)
    if said is not None:
        raise RailsuspInputError(f"{path}: its simulations were made with {said}")
    got, now = stamp.get("statistics_version"), estimator_stamp()["statistics_version"]
    if got != now:
        was = f"version {got}" if got else "a version before 2026-11-30.2 (none recorded)"
        raise RailsuspInputError(
            f"{path}: its summary statistics are of the definitions of {was}, this railsusp "
            f"computes version {now}: {again}"
        )


def estimator_stamp() -> dict[str, str]:
    """What an estimator folder's ``settings.json`` records of the code that made its cached
    simulations and statistics (:func:`check_model_revision` checks it)."""
    from railsusp.estimate.summaries import STATISTICS_VERSION
    from railsusp.vehicle import MODEL_REVISION

    return {"model_revision": MODEL_REVISION, "statistics_version": STATISTICS_VERSION}
