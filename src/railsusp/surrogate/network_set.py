"""What a network set is on disk, and where one lies (issue 19, item 5).

A network set (:mod:`railsusp.surrogate.pretrained`) is a folder: one bundle per working
condition (:data:`BUNDLE_FILES`), its accuracy table (:data:`ACCURACY`) and a manifest
(:data:`MANIFEST`). This module holds those file names, the manifest read as a
:class:`NetworkSet`, and the finding of a set by name (one shipped with railsusp) or by
folder. It is apart from :mod:`railsusp.surrogate.pretrained`, which checks a set against a
run, predicts its references, installs it into a run and writes new ones, because reading a
manifest or finding a set loads no network.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from railsusp.errors import RailsuspInputError
from railsusp.store import read_json

#: the manifest of a network set
MANIFEST = "networks.json"
FORMAT = "railsusp-networks/1"
#: the set's accuracy table (Table 7 layout) on its campaign's held-out runs
ACCURACY = "compare.csv"
#: the files of one condition's bundle that a set carries (no training checkpoint)
BUNDLE_FILES = ("surrogate.json", "model.pt")


def packaged_root() -> Path:
    """The folder of the network sets shipped inside the package."""
    return Path(str(resources.files("railsusp") / "data" / "networks"))


def packaged_sets() -> list[str]:
    """Names of the network sets shipped with railsusp."""
    root = packaged_root()
    if not root.is_dir():
        return []
    return sorted(p.name for p in root.iterdir() if (p / MANIFEST).is_file())


def resolve_network_set(source: str | Path, field: str = "surrogate.pretrained") -> Path:
    """The folder of a network set: a name of :func:`packaged_sets` or a folder holding a
    :data:`MANIFEST`. ``field`` names the setting in the one-line error."""
    names = packaged_sets()
    if str(source) in names:
        return packaged_root() / str(source)
    folder = Path(source)
    if (folder / MANIFEST).is_file():
        return folder
    shipped = ", ".join(names) or "none"
    raise RailsuspInputError(
        f"{field} = {str(source)!r}: neither a network set shipped with railsusp ({shipped}) "
        f"nor a folder holding {MANIFEST}"
    )


@dataclass(frozen=True)
class NetworkSet:
    """A network set's manifest (:data:`MANIFEST`) and where it lies."""

    folder: Path
    name: str
    kind: str
    model_revision: str
    wagon_hash: str
    parameters: tuple[str, ...]
    conditions: tuple[str, ...]
    #: the commands that trained the set, in order (campaign, twins, training, copy here)
    reproduce: tuple[str, ...]
    #: per condition: the seed, the parameter sets (SI) and the statistics of their predicted
    #: series that :func:`~railsusp.surrogate.pretrained.check_references` recomputes
    references: dict[str, dict[str, Any]]
    description: str = ""

    def bundle(self, condition: str) -> Path:
        return self.folder / condition

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "name": self.name,
            "description": self.description,
            "kind": self.kind,
            "model_revision": self.model_revision,
            "wagon_hash": self.wagon_hash,
            "parameters": list(self.parameters),
            "conditions": list(self.conditions),
            "reproduce": list(self.reproduce),
            "references": self.references,
        }


def read_network_set(folder: str | Path) -> NetworkSet:
    """The manifest of the network set in ``folder``; a one-line error if it is missing,
    of another format, or names a condition whose bundle is not there."""
    folder = Path(folder)
    path = folder / MANIFEST
    try:
        doc = read_json(path)
    except (OSError, ValueError) as exc:
        raise RailsuspInputError(f"{path}: not a readable network manifest ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise RailsuspInputError(f"{path}: format {got!r}, accepted {FORMAT!r}")
    try:
        ns = NetworkSet(
            folder=folder,
            name=str(doc["name"]),
            description=str(doc.get("description", "")),
            kind=str(doc["kind"]),
            model_revision=str(doc["model_revision"]),
            wagon_hash=str(doc["wagon_hash"]),
            parameters=tuple(doc["parameters"]),
            conditions=tuple(doc["conditions"]),
            reproduce=tuple(doc["reproduce"]),
            references=dict(doc["references"]),
        )
    except (KeyError, TypeError) as exc:
        raise RailsuspInputError(f"{path}: manifest field {exc} missing or malformed") from None
    for cond in ns.conditions:
        missing = [f for f in BUNDLE_FILES if not (ns.bundle(cond) / f).is_file()]
        if missing:
            raise RailsuspInputError(
                f"{path}: condition {cond!r} lacks {', '.join(missing)} in {ns.bundle(cond)}"
            )
    return ns
