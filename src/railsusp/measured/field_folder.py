"""Which field folders a command may replace: never measured recordings.

``synth-field --out`` and ``sections --write`` write a whole field folder at once
(:func:`~railsusp.store.atomic_folder`). Into an existing folder that would replace what it
holds, so each writer accepts only a folder it could write again itself: a new or empty
one, or one it wrote before (``synth-field``: an index with its ``seed`` beside
``truth.json``; ``sections``: an index naming the long run it was cut from, ``source``,
beside the cut's ``sections.csv``, and only a cut of the same run: a user's index may hold
a ``source`` of its own, docs/data-format.md).
Anything else, a folder of measured recordings above all, is refused before any work: the
project's rule that bad input loses no data (before stop 57, ``synth-field`` replaced a
folder of section recordings with synthetic ones and exited 0). The commands that write
results (``estimate``, ``validate``, ``simulate``) never write into a field folder or over a
recording's table (:func:`check_not_recordings`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_output_folder
from railsusp.measured.recording import FORMAT

#: what wrote a field folder, by the marks it leaves (:func:`folder_kind`)
Kind = Literal["new", "empty", "synthetic", "sections", "other"]

_WRITERS = {"synthetic": "synth-field", "sections": "sections --write"}


def folder_kind(path: str | Path) -> Kind:
    """What ``path`` holds: nothing yet, an empty folder, a synthetic field (``synth-field``),
    the sections of a long run (``sections --write``), or anything else (measured
    recordings, other files, an index that cannot be read)."""
    path = Path(path)
    if not path.exists():
        return "new"
    if path.is_dir() and not any(path.iterdir()):
        return "empty"
    index = _index(path)
    if index is None:
        return "other"
    if "seed" in index and (path / "truth.json").is_file():
        return "synthetic"
    if "source" in index and (path / "sections.csv").is_file():
        if not (path / "truth.json").exists():
            return "sections"
    return "other"


def _index(path: Path) -> dict | None:
    """The folder's ``index.json`` as a JSON object, or None where it is missing, unreadable
    or not an object."""
    try:
        index = json.loads((path / "index.json").read_text("utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return index if isinstance(index, dict) else None


def check_field_output(
    path: str | Path,
    writer: Literal["synthetic", "sections"],
    option: str,
    source: str | None = None,
) -> Path:
    """Refuse (one line, before any work) an output folder that ``writer`` would replace
    but did not write: see the module's docstring; for ``sections``, ``source`` is the file
    name of the long run being cut. Also refuses what
    :func:`~railsusp.input_checks.check_output_folder` does (a file, an unwritable folder)."""
    path = check_output_folder(path, option)
    kind = folder_kind(path)
    if kind in ("new", "empty") or (kind == writer == "synthetic"):
        return path
    if kind == writer == "sections":  # the long run it was cut from: its index's source
        before = str(_index(path)["source"])  # type: ignore[index]
        if source is None or before == source:
            return path
        raise RailsuspInputError(
            f"{option} {path} holds the sections of another run ({before}); sections --write "
            f"would replace them with those of {source}: accepted a new or empty folder, or "
            "one holding this run's sections"
        )
    held = (
        f"a field folder written by {_WRITERS[kind]}"
        if kind in _WRITERS
        else "files of another kind (measured recordings, another command's output)"
    )
    raise RailsuspInputError(
        f"{option} {path} holds {held}; {_WRITERS[writer]} would replace them: accepted a "
        f"new or empty folder, or one {_WRITERS[writer]} wrote"
    )


def check_not_recordings(path: str | Path, option: str = "--out") -> None:
    """Refuse, in one line, an output that would write over measured data: a field folder
    (``index.json`` listing recordings) as an output folder, or a recording's table (a
    ``.parquet``/``.csv`` with a railsusp recording sidecar) as an output file. An estimate
    written into its recordings' folder replaced a recording named ``estimate`` with the
    results (the command-line audit of stop 60)."""
    path = Path(path)
    if path.is_dir() and (path / "index.json").is_file():
        raise RailsuspInputError(
            f"{option} {path} is a field folder of recordings (index.json): results are not "
            "written among them; accepted another folder"
        )
    sidecar = path.with_suffix(".json")
    if sidecar.is_file() and path.suffix.lower() in (".parquet", ".csv"):  # or beside one
        try:
            doc = json.loads(sidecar.read_text("utf-8-sig"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            return
        if isinstance(doc, dict) and doc.get("format") == FORMAT:
            raise RailsuspInputError(
                f"{option} {path} is a recording (its sidecar {sidecar.name} says so): not "
                "written over; accepted another file"
            )
