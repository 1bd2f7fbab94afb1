"""The force laws a run directory was made with, as its own records state them
(:data:`REVISION_RECORDS`), and the line :func:`railsusp.open_run` warns with where they are
not this railsusp's (the upgrade audit of stop 66: runs of older force laws were read as
current). Reads the run directory only; :mod:`railsusp.api` presents it.
"""

from __future__ import annotations

from pathlib import Path

from railsusp.errors import RailsuspInputError
from railsusp.store import read_json

#: the files of a run directory that record the force-law revision
#: (:data:`railsusp.vehicle.MODEL_REVISION`) their stage simulated or was made with, in the
#: order :attr:`railsusp.api.RunResult.model_revision` reads them: the sensitivity
#: campaign, the surrogates' own campaign, a shipped network set's manifest, the estimate;
#: each read only where it is the run's own (:func:`own_records`)
REVISION_RECORDS = (
    "campaign/campaign.json",
    "surrogate-campaign/campaign.json",
    "surrogate-pretrained/surrogates/networks.json",
    "estimate/estimate.json",
)


def revision_records(path: Path) -> dict[str, str | None]:
    """Each file of :data:`REVISION_RECORDS` that is the run directory ``path``'s own
    (:func:`own_records`) and in it, by its path in it, with the force-law revision it records
    (None: none). A file that does not read is left out: the table that needs it
    refuses it (:meth:`railsusp.api.RunResult._need`)."""
    out: dict[str, str | None] = {}
    for rel in own_records(path):
        p = path / rel
        if not p.is_file():
            continue
        try:
            doc = read_json(p)
        except RailsuspInputError:
            continue
        if isinstance(doc, dict):
            got = doc.get("model_revision")
            out[rel] = None if got is None else str(got)
    return out


def own_records(path: Path) -> list[str]:
    """The files of :data:`REVISION_RECORDS` that are the run's own, in that order: its
    campaign's and its estimate's, and of the surrogate folders
    (``surrogate-campaign``, ``surrogate-pretrained``) those that a stage's record in
    ``pipeline.json`` lists among its files, or, while the surrogate stage records none
    (not finished, or made before files were recorded), the one its recorded
    configuration takes (every one, where none is recorded). A surrogate route the
    configuration no longer takes leaves its folder behind (a ``surrogate-campaign/``
    of older force laws, kept after a switch to a network set or to ``samples = 0``),
    and its record warned of a run whose stages are all current (the review of stop
    66)."""
    from railsusp.surrogate.pretrained import surrogates_run

    try:
        state = read_json(path / "pipeline.json")
    except RailsuspInputError:
        state = {}
    state = state if isinstance(state, dict) else {}
    stages = state.get("stages") if isinstance(state.get("stages"), dict) else {}
    listed = [
        e["files"]
        for e in stages.values()
        if isinstance(e, dict) and isinstance(e.get("files"), dict)
    ]
    surrogate = stages.get("surrogate")
    route: tuple[str, ...] = ()
    if not (isinstance(surrogate, dict) and isinstance(surrogate.get("files"), dict)):
        config = state.get("config")
        s = config.get("surrogate") if isinstance(config, dict) else None
        if isinstance(s, dict):
            base = surrogates_run(s.get("pretrained"), s.get("samples", 0))
            route = (f"{base}/campaign.json", f"{base}/surrogates/networks.json")
        else:  # no configuration recorded: every route's
            route = REVISION_RECORDS
    return [
        rel
        for rel in REVISION_RECORDS
        if not rel.startswith("surrogate-")  # the run's own folders, whatever its route
        or rel in route
        or any(rel in files for files in listed)
    ]


def outdated_model(path: Path) -> str:
    """Why the run's tables are of other force laws than this railsusp simulates, in one
    line naming both revisions (:func:`railsusp.vehicle.revision.made_with`) and what
    ``railsusp run`` does with the folder; '' where they are of these (or no stage has
    recorded any yet). A record of another revision decides; records that all state none
    are of a run made before revisions were recorded (an ``estimate.json`` stating none
    beside a campaign of this revision was written before estimates recorded it: no sign
    of another model)."""
    from railsusp.vehicle.revision import Standing, made_with, standing

    records = revision_records(path)
    other = [
        (rel, r) for rel, r in records.items() if standing(r) not in (Standing.THIS, Standing.NONE)
    ]
    if other:
        rel, revision = other[0]
        made = f"{made_with(revision)} ({rel})"
    elif records and all(r is None for r in records.values()):
        revision = None
        made = f"{made_with(None)}, none recorded in {', '.join(records)}"
    else:
        return ""
    if standing(revision) is Standing.NEWER:
        what = "open it with the newer railsusp that made it (railsusp run refuses it)"
    else:
        what = f"railsusp run CONFIG --out {path} would simulate every stage again"
    return (
        f"{path}: made with {made}: its tables are read as that run wrote them, of that "
        f"model; {what}"
    )
