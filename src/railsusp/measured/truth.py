"""The hidden truth of synthetic recordings (``truth.json``): read, and told to belong to the
recordings it is scored against.

``synth-field`` writes beside its recordings the parameters it simulated them with, and the
SHA-256 of each recording's table as written (``recording_files``) and a digest of the
recordings as read (``recordings_digest``). ``validate --truth``
scores the estimate's parameter recovery against such a file. Before stop 74 it took the
truth of any folder without a word (the QA of stop 73): an estimate of one synthetic field
scored against another field's truth gave recovery errors of a wagon it never measured. The
truth is checked by the recordings' contents, not their place: a blind test keeps its truth
away from its recordings on purpose, and the sections cut from a synthetic run
(``sections --write``, whose index records the SHA-256 of the run it cut, ``source_sha256``)
belong to the truth of that run.
"""

from __future__ import annotations

from pathlib import Path

from railsusp.errors import RailsuspInputError
from railsusp.measured.field_folder import index_document
from railsusp.measured.reader import read_index
from railsusp.measured.recording import Recording, same_recordings
from railsusp.params import ParameterSet
from railsusp.store import file_hash, file_hash_cached, read_json

#: what a truth file is, for the errors of :func:`read_truth`
TRUTH_FILE = "a truth.json as railsusp synth-field writes it ({'parameters_display': {...}})"

#: the key of ``truth.json`` holding each recording table's SHA-256, by file name
RECORDING_FILES = "recording_files"

#: the key of ``truth.json`` holding the digest of the recordings as read
#: (:func:`~railsusp.measured.recording.recordings_digest`): a copy whose bytes differ but
#: whose recordings read the same (line endings changed by git, a re-encoded file) is still
#: theirs (the review of stop 74), their track-geometry files too since digest version 2
RECORDINGS_DIGEST = "recordings_digest"


def read_truth(path: str | Path, where: str = "truth") -> ParameterSet:
    """The hidden true parameters of synthetic recordings (``truth.json``, display units),
    checked: a file that is not one (a recording's sidecar, an empty object) is a one-line
    error naming ``where`` and the file, not a KeyError."""
    doc = _truth_doc(path, where)
    try:
        return ParameterSet(doc["parameters_display"], units="display")
    except RailsuspInputError as exc:
        raise RailsuspInputError(f"{where} {path}: {exc}") from None


def _truth_doc(path: str | Path, where: str) -> dict:
    """``truth.json`` as a JSON object holding a ``parameters_display`` table, else the
    one-line error of :func:`read_truth`."""
    try:
        doc = read_json(path)
    except RailsuspInputError as exc:
        raise RailsuspInputError(f"{where} {exc}; accepted {TRUTH_FILE}") from None
    values = doc.get("parameters_display") if isinstance(doc, dict) else None
    if not isinstance(values, dict):
        raise RailsuspInputError(
            f"{where} {path}: no 'parameters_display' table; accepted {TRUTH_FILE}"
        )
    return doc


def recording_files(folder: str | Path, names: list[str]) -> dict[str, str]:
    """The SHA-256 of each recording table ``names`` in ``folder``, as ``synth-field``
    records them in ``truth.json`` (:data:`RECORDING_FILES`)."""
    return {name: file_hash(Path(folder) / name) for name in names}


def check_truth_of(
    path: str | Path,
    folder: str | Path,
    where: str = "--truth",
    recordings: list[Recording] | None = None,
) -> None:
    """Refuse, in one line naming ``where``, a truth file written with other recordings than
    those of the field folder ``folder``: every recording table there must be one the truth
    lists by its SHA-256, or the folder must hold the sections of a run it lists (its index's
    ``source_sha256``, each table a section its ``sections.csv`` lists as kept and, where
    the index records them, with the SHA-256 it was written with), or ``recordings`` (the
    folder's, as read) must read as those the truth (or the sections' index) was written
    with (its ``recordings_digest``). A truth file without
    ``recording_files`` (written before stop 74, or by hand, as the shipped example's states
    its run) is taken as it is: nothing to tell."""
    doc = _truth_doc(path, where)
    known = doc.get(RECORDING_FILES)
    if known is None:
        return
    if not isinstance(known, dict) or not all(isinstance(v, str) for v in known.values()):
        raise RailsuspInputError(
            f"{where} {path}: '{RECORDING_FILES}' is not a table of file names to SHA-256 "
            f"hashes; accepted {TRUTH_FILE}"
        )
    hashes = {v.lower() for v in known.values()}
    tables = read_index(folder)
    index = index_document(Path(folder)) or {}
    source = index.get("source_sha256")
    if isinstance(source, str) and source.lower() in hashes:  # the sections of its run:
        foreign = _foreign_sections(Path(folder), tables, index)
        digest = index.get(RECORDINGS_DIGEST)  # the sections' own, as sections --write read
    else:
        foreign = [p.name for p in tables if _hash(p) not in hashes]
        digest = doc.get(RECORDINGS_DIGEST)
    if not foreign:
        return
    if recordings is not None and isinstance(digest, str):
        if same_recordings(recordings, digest):
            return  # the same recordings in other bytes
    raise RailsuspInputError(
        f"{where} {path}: the truth of other recordings than {folder}'s ({', '.join(foreign)} "
        f"{'is' if len(foreign) == 1 else 'are'} none of the tables it was written with, by "
        "their SHA-256, nor read as the same recordings): its recovery would score the "
        "estimate against a wagon these recordings never measured; accepted the truth.json "
        "that synth-field wrote with these recordings, or with the run their sections were "
        "cut from"
    )


def _hash(path: Path) -> str | None:
    """A table's SHA-256, or None where it cannot be read (the reader says why)."""
    try:
        return file_hash_cached(path)
    except OSError:
        return None


def _kept_sections(folder: Path) -> set[str]:
    """The names of the sections a sections folder's ``sections.csv`` lists as kept (those
    ``sections --write`` wrote); empty where it does not read."""
    import csv

    try:
        with open(folder / "sections.csv", newline="", encoding="utf-8-sig") as fh:
            return {r["section"] for r in csv.DictReader(fh) if r.get("kept") == "yes"}
    except (OSError, UnicodeDecodeError, KeyError, csv.Error):
        return set()


def _foreign_sections(folder: Path, tables: list[Path], index: dict) -> list[str]:
    """The tables of a sections folder cut from the truth's run that are none of its
    sections: not a section its ``sections.csv`` lists as kept (a recording added to the
    index), or, where the index records each section's SHA-256 as ``sections --write``
    wrote it (``recording_files``, since stop 76), a table whose bytes are no longer those
    (an edited section; a copy in other bytes is told by the index's digest instead)."""
    cut = _kept_sections(folder)
    written = index.get(RECORDING_FILES)
    by_content = isinstance(written, dict)  # (an index written before stop 76: by name only)

    def rewritten(p: Path) -> bool:
        sha = written.get(p.name)
        return not isinstance(sha, str) or sha.lower() != _hash(p)

    return [p.name for p in tables if p.stem not in cut or (by_content and rewritten(p))]
