"""A network set carried over to a new force-law revision without training it again.

A network set answers only for the force laws it was trained on
(:func:`railsusp.surrogate.pretrained.check_network_set` refuses another
:data:`railsusp.vehicle.MODEL_REVISION`). When a revision changes the forces, the set is
either trained again (hours on two cores) or, where its networks are shown to serve the new
simulator as well as the old one, stamped with the new revision. The evidence is a
scoring of the unchanged networks on a fresh campaign of the new simulator
(``bench/rescore_networks.py``): its rows join the set's accuracy table, labelled with the
revision they were scored on, and the manifest says why the set was carried over.

What changes: the manifest's revision, its ``carried_over`` (now every condition: a network
trained on the former revision's laws is carried over too), wagon hash and reference
predictions (the networks
read the nominal wagon's response, which the new simulator gives), each bundle's stored
wagon (the wagon fields the revision added or switched, named by the caller; every other
field must be the one the network was trained on), its ``meta.model_revision`` (the
revision it serves; the one it was trained on stays in its ``meta.restamped`` record) and
the accuracy table's labels. The weights do not change; the manifest's ``reproduce``
commands, run today, would train on today's force laws.
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from railsusp.errors import RailsuspInputError
from railsusp.provenance import utc_now
from railsusp.store import atomic_folder, read_json, write_csv, write_json
from railsusp.surrogate.network_set import ACCURACY, MANIFEST, NetworkSet, read_network_set
from railsusp.surrogate.pretrained import make_references, wagon_hash


def _flat(wagon_fields: dict[str, Any]) -> dict[str, Any]:
    """``{"section.field": value}`` of a wagon's JSON dump."""
    return {
        f"{section}.{name}": value
        for section, fields in wagon_fields.items()
        if isinstance(fields, dict)
        for name, value in fields.items()
    }


def changed_wagon_fields(stored: dict[str, Any], wagon: Any) -> list[str]:
    """The wagon fields (``section.field``) in which the wagon a bundle stores and
    ``wagon`` differ, a field missing from the stored one included."""
    old, new = _flat(stored), _flat(wagon.model_dump(mode="json"))
    return sorted(k for k in old.keys() | new.keys() if old.get(k, ...) != new.get(k, ...))


def check_restampable(
    ns: NetworkSet, *, wagon: Any, fields: Sequence[str]
) -> dict[str, dict[str, Any]]:
    """Refuse, in one line, a network set that :func:`restamp_network_set` cannot carry
    over to today's revision with ``wagon``: one of today's revision already or of a newer
    one, or a bundle trained on a wagon that differs from ``wagon`` beyond ``fields``. Reads
    the manifest and the bundles' ``surrogate.json`` only, so that a caller checks it before
    the scoring campaign it would otherwise run first (bench/rescore_networks.py: hours, then
    the refusal). Returns each condition's ``surrogate.json`` document."""
    from railsusp.vehicle import MODEL_REVISION
    from railsusp.vehicle.revision import Standing, made_with, newer_remedy, standing

    if standing(ns.model_revision) is Standing.NEWER:  # not carried back to older force laws
        raise RailsuspInputError(
            f"network set {ns.name!r} ({ns.folder / MANIFEST}) was trained with "
            f"{made_with(ns.model_revision)}: {newer_remedy(ns.model_revision)}"
        )
    if ns.model_revision == MODEL_REVISION:
        raise RailsuspInputError(
            f"network set {ns.name!r} is of revision {MODEL_REVISION} already: nothing to stamp"
        )
    docs = {}
    for cond in ns.conditions:
        doc = read_json(ns.bundle(cond) / "surrogate.json")
        other = [f for f in changed_wagon_fields(doc["wagon"], wagon) if f not in fields]
        if other:
            raise RailsuspInputError(
                f"{ns.bundle(cond)}: trained on a wagon that differs in {', '.join(other)} "
                f"beyond the revision's fields ({', '.join(fields) or 'none'}); train it again"
            )
        docs[cond] = doc
    return docs


def restamp_network_set(
    folder: str | Path,
    *,
    wagon: Any,
    fields: Sequence[str],
    accuracy: pd.DataFrame,
    note: str,
) -> NetworkSet:
    """Stamp the network set in ``folder`` with today's force-law revision and ``wagon``.

    ``fields``: the wagon fields the new revision added or switched; a bundle trained on a
    wagon that differs from ``wagon`` in any other field is refused (one line).
    ``accuracy``: the set's networks scored on a campaign of today's simulator (rows of
    the accuracy table's layout, Y and Q of every condition), appended to ``compare.csv``
    with their ``model`` labelled by today's revision, the rows already there by the set's
    former one. ``note``: why the set serves the new revision, kept in the manifest
    (``model_revision_note``, the earlier notes in ``model_revision_history``) and in each
    bundle's ``meta.restamped``."""
    from railsusp.vehicle import MODEL_REVISION

    folder = Path(folder)
    ns = read_network_set(folder)
    docs = check_restampable(ns, wagon=wagon, fields=fields)
    if not note.strip():
        raise RailsuspInputError("note: say why the set serves the new revision")
    scored = {
        (c, t)
        for c, t in zip(accuracy.get("condition", ()), accuracy.get("target", ()), strict=True)
    }
    missing = sorted(c for c in ns.conditions if not {(c, "Y"), (c, "Q")} <= scored)
    if missing:
        raise RailsuspInputError(
            f"accuracy: no Y and Q rows of condition(s) {', '.join(missing)} scored on "
            f"revision {MODEL_REVISION}; score every condition of the set first"
        )
    manifest = read_json(folder / MANIFEST)
    stamp = {
        "from": ns.model_revision,
        "to": MODEL_REVISION,
        "wagon_fields": list(fields),
        "note": note,
        "date": utc_now(),
    }
    rows = accuracy.copy()
    rows["model"] = [f"{m} (revision {MODEL_REVISION})" for m in rows["model"]]
    before = pd.read_csv(folder / ACCURACY)
    # the rows of the training campaign say the force laws they were scored on
    before["model"] = [
        f"{m} (revision {ns.model_revision})" if m == ns.kind else m for m in before["model"]
    ]
    table = pd.concat([before, rows], ignore_index=True)
    with atomic_folder(folder, keep=False) as tmp:
        shutil.copytree(folder, tmp, dirs_exist_ok=True)
        for cond, doc in docs.items():
            doc["wagon"] = wagon.model_dump(mode="json")
            meta = doc.setdefault("meta", {})
            # the bundle now serves today's force laws (estimate.forces.check_force_laws and
            # write_network_set read this); the revision it was trained on stays in the stamp
            # (a bundle carried over before was trained on its first stamp's, not on the
            # revision it served since; stamps before they recorded it: that one's "from")
            earlier = meta.get("restamped") or []
            trained = (
                (earlier[0].get("trained") or earlier[0].get("from"))
                if earlier
                else meta.get("model_revision")
            )
            meta["restamped"] = [*meta.get("restamped", []), {**stamp, "trained": trained}]
            meta["model_revision"] = MODEL_REVISION
            write_json(tmp / cond / "surrogate.json", doc)
        write_csv(tmp / ACCURACY, table)
        history = list(manifest.get("model_revision_history", []))
        if manifest.get("model_revision_note"):
            history.append({"revision": ns.model_revision, "note": manifest["model_revision_note"]})
        out = {
            **manifest,
            "model_revision": MODEL_REVISION,
            "model_revision_note": note,
            "model_revision_history": history,
            # every network of the set is now carried over, one trained on the laws of the
            # set's former revision too (the report would call it trained on today's)
            "carried_over": list(ns.conditions),
            "wagon_hash": wagon_hash(wagon),
            "references": make_references(tmp, ns.conditions, ns.parameters),
        }
        write_json(tmp / MANIFEST, out)
    return read_network_set(folder)


__all__ = ["changed_wagon_fields", "check_restampable", "restamp_network_set"]
