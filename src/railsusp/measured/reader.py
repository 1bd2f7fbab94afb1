"""The field folder: recordings in the documented format (one working condition each),
listed in ``index.json``, each a table and a JSON sidecar
(:mod:`railsusp.measured.recording_reader`). This module reads the folder as a whole: its
index (every listed path inside the folder, none twice), all its recordings read again
when a writer replaces the folder during the read, one condition name per recording, and
the conditions a campaign takes from a folder.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError, repeated
from railsusp.measured.recording import FORMAT, Recording
from railsusp.measured.recording_reader import read_recording
from railsusp.measured.sidecar import inside
from railsusp.vehicle.wagon import WagonData


def read_index(folder: str | Path) -> list[Path]:
    """The recordings a field folder's ``index.json`` lists, each inside the folder."""
    folder = Path(folder)
    index = folder / "index.json"
    if not index.is_file():
        raise RailsuspInputError(f"{folder}: no index.json listing the recordings")
    try:
        doc = json.loads(index.read_text("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RailsuspInputError(f"{index}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("recordings"), list):
        raise RailsuspInputError(
            f'{index}: a JSON object with a "recordings" list of file names is needed'
        )
    if not doc["recordings"]:
        raise RailsuspInputError(f"{index}: the recordings list is empty")
    if "format" in doc and doc["format"] != FORMAT:
        raise RailsuspInputError(f"{index}: format {doc['format']!r}; accepted {FORMAT!r}")
    names = doc["recordings"]
    twice = repeated(names)
    if twice:  # the same recording counted twice would weigh it double in the estimate
        raise RailsuspInputError(
            f"{index} recordings: {', '.join(twice)} listed more than once; accepted each once"
        )
    return [inside(folder, n, f"{index} recordings") for n in names]


#: how many times :func:`read_field` reads a folder replaced while it read it
SWAP_RETRIES = 3


def _folder_identity(folder: str | Path) -> tuple[int, int] | None:
    """The folder's device and inode (a folder swapped in by an atomic rename is another
    inode); None while it is missing (between the swap's two renames)."""
    try:
        st = os.stat(folder)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def read_field(
    folder: str | Path,
    *,
    wheel_load_N: float | None = None,
    wagon: str | Path | WagonData | None = None,
) -> list[Recording]:
    """All recordings listed in a field folder's ``index.json`` (never ``truth.json``),
    read as recordings of ``wagon`` (default: the packaged loaded C80): their wheel loads
    checked against its static wheel load (or ``wheel_load_N``; a tare C80's 24.5 kN was
    refused against the loaded one's) and their measured track's lead-in against its axle
    spread (:func:`read_recording`). Two recordings of one condition name are refused: the
    estimate, the validation and ``align-track`` tell recordings apart by it (two
    ``straight`` files got each other's track offset and one validation figure).

    A folder replaced while it is read (a writer's atomic swap: ``synth-field``, ``sections
    --write``) is read again, up to :data:`SWAP_RETRIES` times: a read across the swap
    returned recordings of two generations under one ``index.json``, with no error (the
    concurrency audit of stop 66; the command-line readers hold the folder's lock, a
    library call does not)."""
    for _ in range(SWAP_RETRIES):
        before = _folder_identity(folder)
        try:
            paths = read_index(folder)
            recordings = [read_recording(p, wheel_load_N=wheel_load_N, wagon=wagon) for p in paths]
        except (OSError, RailsuspInputError):
            if _folder_identity(folder) == before:
                raise  # the folder as it is (or missing throughout): said as always
            continue
        if _folder_identity(folder) == before:
            break
    else:
        raise RailsuspInputError(
            f"{folder}: replaced {SWAP_RETRIES} times while it was read (a writer such as "
            "synth-field or sections --write works in it); read it again once it is done"
        )
    seen: dict[str, Path] = {}
    for path, rec in zip(paths, recordings, strict=True):
        name = rec.condition.name
        if name in seen:
            raise RailsuspInputError(
                f"{Path(folder) / 'index.json'}: {seen[name].name} and {path.name} are both "
                f"recordings of condition {name!r}; accepted one condition name per recording "
                "(give each its own: condition_name in the sidecar, or the condition's name)"
            )
        seen[name] = path
    return recordings


def conditions_from(
    spec: str, *, wagon: str | Path | WagonData | None = None
) -> list[WorkingCondition]:
    """Conditions named by ``spec``: standard names or a TOML file (as
    :func:`~railsusp.condition_files.resolve_conditions`), or a field folder (``index.json``), whose
    recordings' conditions are taken with their measured track geometry, so that a campaign
    can run on the track the recordings were made on; read as recordings of ``wagon``
    (:func:`read_field`; the wagon the campaign simulates)."""
    from railsusp.condition_files import resolve_conditions

    folder = Path(spec)
    if folder.is_dir():
        if not (folder / "index.json").is_file():
            raise RailsuspInputError(f"conditions {spec!r}: a folder without index.json")
        return [rec.condition for rec in read_field(folder, wagon=wagon)]
    return resolve_conditions(spec)
