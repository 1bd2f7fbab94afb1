"""Which field folders a command may replace: never measured recordings.

``synth-field --out`` and ``sections --write`` write a whole field folder at once
(:func:`~railsusp.store.atomic_folder`). Into an existing folder that would replace what it
holds, so each writer accepts only a folder it could write again itself: a new or empty
one, or one it wrote before (``synth-field``: an index with its ``seed`` beside
``truth.json``; ``sections``: an index naming the long run it was cut from, ``source``,
beside the cut's ``sections.csv``, and only a cut of the same run: a user's index may hold
a ``source`` of its own, docs/data-format.md). The same run is told by the file's
contents, its size and SHA-256 in the index (``source_bytes``, ``source_sha256``), not its
name: a run moved or renamed is the same run, another run of the same file name
(``day1/run.mf4``, ``day2/run.mf4``) is not (before stop 63 the name alone was compared,
and the second day's sections silently replaced the first's). An index written before
holds only the name, and is compared by it.
Anything else, a folder of measured recordings above all, is refused before any work: the
project's rule that bad input loses no data (before stop 57, ``synth-field`` replaced a
folder of section recordings with synthetic ones and exited 0). The commands that write
results (``estimate``, ``validate``, ``simulate``) never write into a field folder or over a
recording's table (:func:`check_not_recordings`).
"""

from __future__ import annotations

import glob
import json
from pathlib import Path
from typing import Literal

from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_replaced_folder
from railsusp.measured.recording import FORMAT
from railsusp.run_lock import LOCK_NAME
from railsusp.store import file_hash_cached

#: what wrote a field folder, by the marks it leaves (:func:`folder_kind`)
Kind = Literal["new", "empty", "synthetic", "sections", "other"]

_WRITERS = {"synthetic": "synth-field", "sections": "sections --write"}


def folder_kind(path: str | Path) -> Kind:
    """What ``path`` holds: nothing yet, an empty folder, a synthetic field (``synth-field``),
    the sections of a long run (``sections --write``), or anything else (measured
    recordings, other files, an index that cannot be read). railsusp's lock file
    (:data:`~railsusp.run_lock.LOCK_NAME`, left in every folder a command locked) is not
    counted: a folder holding only it is empty (it was "other", so a folder made for the
    writer's lock refused the writer)."""
    path = Path(path)
    if not path.exists():
        return "new"
    if path.is_dir() and all(p.name == LOCK_NAME for p in path.iterdir()):
        return "empty"  # railsusp's lock file alone: the folder a writer made for its lock
    index = index_document(path)
    if index is None:
        return "other"
    if "seed" in index and (path / "truth.json").is_file():
        return "synthetic"
    if "source" in index and (path / "sections.csv").is_file():
        if not (path / "truth.json").exists():
            return "sections"
    return "other"


def index_document(path: Path) -> dict | None:
    """The folder's ``index.json`` as a JSON object, or None where it is missing, unreadable
    or not an object."""
    try:
        index = json.loads((path / "index.json").read_text("utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return index if isinstance(index, dict) else None


def source_fingerprint(path: str | Path) -> dict[str, int | str]:
    """The long run's file as a sections folder's ``index.json`` records it: its name
    (``source``, for the reader), size in bytes and SHA-256 (``source_bytes``,
    ``source_sha256``: what tells the same run from another, wherever the file lies). A run
    that is no file (made in memory) has its name only, and is compared by it."""
    path = Path(path)
    if not path.is_file():
        return {"source": path.name}
    return {
        "source": path.name,
        "source_bytes": path.stat().st_size,
        "source_sha256": file_hash_cached(path),
    }


def _same_source(index: dict, fingerprint: dict[str, int | str]) -> bool:
    """Whether a sections folder's ``index`` was cut from the run of ``fingerprint``: its
    size and SHA-256 where the index holds them, else (an index written before stop 63)
    its file name."""
    if "source_sha256" in index or "source_bytes" in index:
        return (  # a run that is no file has no size or hash: not the same
            index.get("source_bytes") == fingerprint.get("source_bytes")
            and str(index.get("source_sha256", "")).lower() == fingerprint.get("source_sha256")
        )
    return str(index["source"]) == fingerprint["source"]


def _fingerprint_text(fingerprint: dict) -> str:
    """A run's size and the start of its SHA-256, to tell two files of one name apart."""
    sha = str(fingerprint.get("source_sha256", ""))[:12]
    return f"{fingerprint.get('source_bytes')} bytes, SHA-256 {sha}..."


def check_field_output(
    path: str | Path,
    writer: Literal["synthetic", "sections"],
    option: str,
    source: str | Path | None = None,
) -> Path:
    """Refuse (one line, before any work) an output folder that ``writer`` would replace
    but did not write: see the module's docstring; for ``sections``, ``source`` is the long
    run being cut (its file: compared by contents with the run the folder was cut from, or
    by name where the folder's index holds no fingerprint). Also refuses what
    :func:`~railsusp.input_checks.check_output_folder` does (a file, an unwritable folder)."""
    path = check_replaced_folder(path, option, _WRITERS[writer])
    kind = folder_kind(path)
    if kind in ("new", "empty") or (kind == writer == "synthetic"):
        return path
    if kind == writer == "sections":  # the long run it was cut from: its index's source
        index: dict = index_document(path)  # type: ignore[assignment]
        if source is None:
            return path
        try:
            now = source_fingerprint(source)
        except OSError as exc:
            raise RailsuspInputError(f"{source}: cannot be read ({exc.strerror})") from None
        if _same_source(index, now):
            return path
        before, name = str(index["source"]), str(now["source"])
        if before == name and "source_sha256" in index:  # same name, other contents
            before += f", {_fingerprint_text(index)}"
            name += f", {_fingerprint_text(now)}"
        raise RailsuspInputError(
            f"{option} {path} holds the sections of another run ({before}); sections --write "
            f"would replace them with those of {name}: accepted a new or empty folder, or "
            "one holding this run's sections (the same file contents, wherever it lies)"
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


def earlier_sections(path: str | Path) -> list[str]:
    """What an earlier ``sections --write`` wrote into ``path`` and a new cut replaces or
    no longer has: each recording its index lists and the recording's sidecar, as glob
    patterns of exact names for :func:`~railsusp.store.atomic_folder`'s ``drop``. A
    cut with fewer or other sections (another ``--min-length``) left the earlier cut's
    recordings beside the new index (the audit of stop 63); a file of the user's in the
    folder (notes, a track file) is still carried over. Nothing for a folder that is not a
    sections folder (new, empty)."""
    path = Path(path)
    if folder_kind(path) != "sections":
        return []
    listed = (index_document(path) or {}).get("recordings")
    names: list[str] = []
    for n in listed if isinstance(listed, list) else []:
        if isinstance(n, str) and n and Path(n).name == n:  # a file of the folder itself
            names += [n, f"{Path(n).stem}.json"]
    return [glob.escape(n) for n in names]


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
