"""The checks of an ``estimate.json`` before it is validated: its fields of the kinds
validate reads (one line naming the field where a hand edit broke one) and the force laws
it was made with (validate re-simulates with this railsusp's, so an estimate of other
force laws would compare another model). Kept apart from the validation run
(:mod:`railsusp.validate`): they read the file alone and decide whether anything is
simulated at all.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_whole


def check_estimate_fields(est: dict, path: Path, need_measured: bool = True) -> None:
    """Refuse, in one line naming ``path`` and the field, an ``estimate.json`` whose fields
    validate reads are not of their kind (a hand-edited ``"measured": 123`` or ``"config":
    "x"`` gave a TypeError's traceback)."""
    kinds: list[tuple[str, Any, str]] = [
        ("parameters", list, "a list of parameter symbols"),
        ("estimate_display", dict, "an object of values by symbol"),
        ("config", dict, "an object of the estimate's settings"),
    ]
    if need_measured:
        kinds.append(("measured", str, "the recordings' folder as a string"))
    for key, kind, accepted in kinds:
        value = est.get(key)
        if not isinstance(value, kind) or (key == "measured" and not value):
            raise RailsuspInputError(
                f"{path}: field {key!r} is {value!r}; accepted {accepted} (the estimate.json "
                "of a folder written by railsusp estimate)"
            )
    if not all(isinstance(p, str) for p in est["parameters"]):
        raise RailsuspInputError(
            f"{path}: field 'parameters' is {est['parameters']!r}; accepted a list of parameter "
            "symbols"
        )
    from railsusp.estimate.config import held_at_of

    held_at_of(est, str(path))  # the "after" set holds the parameters not estimated there
    config = est["config"]
    if not isinstance(config.get("statistic"), str):
        raise RailsuspInputError(
            f"{path}: field 'config.statistic' is {config.get('statistic')!r}; accepted a "
            "statistic such as 'mean' or 'aligned'"
        )
    for key in ("expected_draws", "seed"):
        value = config.get(key, 0)
        if not is_whole(value):
            raise RailsuspInputError(
                f"{path}: field 'config.{key}' is {value!r}; accepted an integer"
            )
    for key, kinds_ in (("wagon", (str, type(None))), ("wagon_data", (dict, type(None)))):
        if not isinstance(est.get(key), kinds_):
            raise RailsuspInputError(
                f"{path}: field {key!r} is {est.get(key)!r}; accepted "
                + ("a wagon name or file" if key == "wagon" else "an object of wagon data")
            )


def measured_of(est: dict, estimate_dir: str | Path) -> Path:
    """The recordings' folder of ``estimate.json``: a run directory's own (``measured_in_run``,
    ``../field`` against the estimate's folder, by name: ``RUN/estimate`` a link gives the
    run's ``field``, not one beside the link's target) where it holds recordings, else the
    folder it recorded (``measured``; a relative one against the estimate's folder). A run
    directory moved or copied elsewhere so validates its own recordings: the absolute path
    alone made a moved run's validation read a folder no longer there (stop 79's paths
    hunt), while an estimate folder copied out of its run still finds the run's. The
    recordings' digest checks either (:func:`railsusp.validate.validate`)."""
    here = Path(estimate_dir).absolute()
    own = est.get("measured_in_run")
    if isinstance(own, str) and own and "\0" not in own:
        folder = Path(os.path.normpath(here / own))
        if (folder / "index.json").is_file():
            return folder
    folder = Path(est["measured"])
    return folder if folder.is_absolute() else Path(os.path.normpath(here / folder))


def check_estimate_revision(est: dict, path: Path) -> None:
    """Refuse, in one line naming ``path``, both revisions and the remedy, an estimate made
    with other force laws than this railsusp simulates (its ``model_revision``, recorded
    since the upgrade audit): validate re-simulates it with this railsusp's, so its "before"
    and "after" would move with the model alone (a run of 2026-11-24.2: the nominal lateral
    mean 4.90 -> 6.18 kN) and be read as the estimate's doing. An estimate that records no
    revision (written before) cannot be told: warned of, and validated as before."""
    from railsusp.vehicle import MODEL_REVISION
    from railsusp.vehicle.revision import Standing, made_with, newer_remedy, standing

    revision = est.get("model_revision")
    s = standing(revision)
    if s is Standing.NONE:  # not older force laws: estimates record it since 2026-11-30.2
        warnings.warn(
            f"{path} records no force-law revision (written before estimates recorded it): "
            f"validate cannot tell whether it was made with the force laws it re-simulates "
            f"(revision {MODEL_REVISION}); estimate again to be sure",
            stacklevel=3,
        )
    elif s is not Standing.THIS:
        remedy = (
            newer_remedy(revision)
            if s is Standing.NEWER
            else "estimate again (`railsusp run` on its run directory, or `railsusp "
            "estimate`) and validate that"
        )
        raise RailsuspInputError(
            f"{path}: made with {made_with(revision)}, so the validation would compare "
            f"another model: {remedy}"
        )
