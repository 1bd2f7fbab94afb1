"""Whether the files of a run directory read: a file damaged after it was written (a copy cut
short, a full disk, a hand edit) is found when a run resumes, not when a later stage trips
over it.

railsusp writes every file atomically, so a kill never leaves one half-written; these checks
are about what happens to a run directory afterwards. Each kind of file has a check that costs
little more than opening it: a Parquet footer, a JSON document, a CSV whose last line is whole,
a zip archive's directory and checksums (PyTorch's ``.pt`` and NumPy's ``.npz`` are zips).
Other files (figures, HTML, Markdown) are not checked: nothing in railsusp reads them back.
What a finished stage wrote is also recorded by size and SHA-256 (:func:`file_sizes`,
:func:`file_hashes`) and compared later (:func:`changed_files`): an edit that keeps a file
readable, and its size, is found by its hash alone.
"""

from __future__ import annotations

import csv
import re
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, BinaryIO

from railsusp.errors import RailsuspInputError
from railsusp.store import file_hash, file_hash_cached, parquet_readable, read_json

#: suffixes whose files are zip archives: PyTorch's ``torch.save`` and NumPy's ``savez``
ZIP_SUFFIXES = (".pt", ".npz")
#: bytes read from a CSV file's start and end to find its header and last line
_TAIL_BYTES = 65536
#: the line ends a CSV file may use (Windows, Unix, and old Mac Excel's bare CR)
_LINE_END = re.compile(rb"\r\n|\r|\n")


def _cells(line: bytes) -> int:
    """The cells of one CSV line, quoted commas counted as text (the ``csv`` module); a line
    the ``csv`` module cannot parse (a stray quote, a cell beyond its field size limit) is
    counted by its commas."""
    text = line.decode("utf-8-sig", errors="replace")
    try:
        return max((len(row) for row in csv.reader([text])), default=0)
    except csv.Error:
        return text.count(",") + 1


def _tail(f: BinaryIO) -> bytes:
    """The last :data:`_TAIL_BYTES` of an open file."""
    f.seek(max(0, f.seek(0, 2) - _TAIL_BYTES))
    return f.read()


def _last_line_short(tail: bytes, n_columns: int) -> bool:
    """Whether a file ending in ``tail`` ends inside a line of fewer than ``n_columns``
    cells (no line end after it)."""
    if not tail or tail.endswith((b"\n", b"\r")):
        return False
    return _cells(_LINE_END.split(tail)[-1]) < n_columns


def csv_last_line_cut(path: str | Path, n_columns: int) -> bool:
    """Whether a CSV file ends inside a line that has fewer cells than its header's
    ``n_columns``: the mark of a truncated copy (a hand-written file may lack the last line
    end, never a cell)."""
    with Path(path).open("rb") as f:
        return _last_line_short(_tail(f), n_columns)


def _csv_readable(path: Path) -> bool:
    """A header line, no NUL byte at either end (a text table has none; a file zeroed by a
    crash is nothing but), and no last line cut short."""
    with path.open("rb") as f:
        head = f.read(_TAIL_BYTES)
        tail = _tail(f)
    header = _LINE_END.split(head, maxsplit=1)[0]
    if not header.strip() or b"\x00" in head or b"\x00" in tail:
        return False
    return not _last_line_short(tail, _cells(header))


def zip_readable(path: Path) -> bool:
    """The zip's central directory reads and every member's CRC checks (a compressed
    member that does not inflate counts as damaged, whatever zlib raises)."""
    try:
        with zipfile.ZipFile(path) as z:
            return z.testzip() is None
    except Exception:  # BadZipFile, EOFError, zlib.error, NotImplementedError, ...
        return False


class TorchFileCutShort(RailsuspInputError):
    """A ``torch.save`` file cut short or damaged (:func:`torch_file_cut_short`): nothing in
    it to trust, so a caller that can make it again catches this and does."""


def torch_file_cut_short(path: Path) -> bool:
    """A file too short to be a zip's first header (``torch.save``'s format), one that
    starts with zeros (what a crash can leave of a file being written), or a zip whose
    directory or checksums do not read: a copy interrupted or a full disk, nothing in it to
    trust. A file of another format is not "cut short": :func:`read_torch_file` refuses it
    otherwise."""
    with Path(path).open("rb") as f:
        head = f.read(4)
    if len(head) < 4 or head == b"\0\0\0\0":  # empty, or the zeros a crash leaves
        return True
    return head == b"PK\x03\x04" and not zip_readable(path)


def read_torch_file(path: Path, what: str, remedy: str, map_location: str = "cpu") -> Any:
    """What ``torch.save`` wrote to ``path``, read with ``weights_only=True`` (tensors,
    numbers, strings and containers: no code runs). Anything else (a file cut short, a
    pickle that would run code, another format) is refused with one line naming ``what``
    and the ``remedy``, never trusted and never a traceback. A file cut short raises
    :class:`TorchFileCutShort`, which callers that can make the file again catch."""
    import torch

    if torch_file_cut_short(path):
        raise TorchFileCutShort(
            f"{what} {path} is cut short or damaged (its zip does not read); {remedy}"
        )
    try:
        return torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # torch raises UnpicklingError, RuntimeError, EOFError, ...
        raise RailsuspInputError(
            f"{what} {path} refused: not a plain PyTorch state ({_torch_reason(exc)}); {remedy}"
        ) from None


class NpzDamaged(RailsuspInputError):
    """A NumPy archive that does not read (:func:`read_npz`); ``reason``: what NumPy found,
    in a few words, for a caller that says it in words of its own."""

    def __init__(self, message: str, reason: str) -> None:
        super().__init__(message)
        self.reason = reason


def read_npz(path: Path, what: str, remedy: str) -> dict[str, Any]:
    """Every array of the NumPy archive ``path`` (``np.savez``), read whole, pickles refused.
    A file cut short, emptied or of another kind is refused with one line naming ``what``
    and the ``remedy`` (NumPy raised ``BadZipFile``, or ``EOFError``, which the command
    line took for an interrupted prompt and answered "Aborted."). The file is opened here
    and closed whatever NumPy finds: given the path, ``np.load`` left it open where the
    archive was damaged (a ResourceWarning "unclosed file" with the refusal)."""
    import numpy as np

    try:
        with open(path, "rb") as fh:
            z = np.load(fh, allow_pickle=False)
            if not isinstance(z, np.lib.npyio.NpzFile):  # one array (np.save), not an archive
                raise ValueError("one array, not an archive of np.savez")
            with z:
                return {name: z[name] for name in z.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if path.is_file() and path.stat().st_size == 0:
            reason = "an empty file"
        raise NpzDamaged(f"{what} {path} is damaged ({reason}); {remedy}", reason) from None


#: terminal colour codes, which torch puts in some of its messages
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _torch_reason(exc: Exception) -> str:
    """What ``torch.load`` found wrong, in a few words: the global it would not load (a
    pickle of code or of objects that are not tensors), else the first sentence of its
    message; never its advice to load the file unsafely."""
    text = _ANSI.sub("", str(exc))
    found = re.search(r"GLOBAL ([\w.]+)", text)
    if found:
        return f"it holds objects that are not tensors: {found.group(1).rstrip('.')}"
    first = text.strip().splitlines()[0] if text.strip() else ""
    first = first.split(" In PyTorch 2.6")[0].strip()
    if len(first) < 12:  # a bare key or number: what torch.load tripped over, not why
        return f"no file torch.save writes: {type(exc).__name__} {first}".strip()
    return first


def file_readable(path: str | Path) -> bool:
    """Whether ``path`` exists and reads as its suffix says (see the module's docstring);
    a file of another suffix only has to exist."""
    path = Path(path)
    if not path.is_file():
        return False
    suffix = path.suffix.lower()
    try:
        if suffix == ".parquet":
            return parquet_readable(path)
        if suffix == ".json":
            read_json(path)  # a BOM allowed; nesting deeper than Python's is damage
        elif suffix == ".csv":
            return _csv_readable(path)
        elif suffix in ZIP_SUFFIXES:
            return zip_readable(path)
    except (OSError, RailsuspInputError):
        return False
    return True


def files_under(
    root: str | Path, *, skip_folders: Iterable[str] = (), skip_names: Iterable[str] = ()
) -> list[Path]:
    """The files under ``root``, in path order.

    ``skip_folders``: names of ``root``'s subfolders that belong to something else (another
    pipeline stage's output inside this one's folder); ``skip_names``: file names left out
    (a training checkpoint, which is only a resume point and is trained past when it does
    not read). Hidden files (the temporary of an atomic write in progress) are left out."""
    root = Path(root)
    if not root.is_dir():
        return []
    skip_folders, skip_names = set(skip_folders), set(skip_names)
    found = []
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root).parts
        if rel[0] in skip_folders or any(p.startswith(".") for p in rel):
            continue
        if path.name not in skip_names and path.is_file():
            found.append(path)
    return found


def file_sizes(paths: Iterable[Path], base: str | Path) -> dict[str, int]:
    """Each file's size in bytes, keyed by its path relative to ``base`` (POSIX form): what a
    run records of a finished stage's files, so that one cut short afterwards is found
    whatever its format (a CSV cut inside its last number still has all its cells)."""
    return {p.relative_to(base).as_posix(): p.stat().st_size for p in paths}


def file_hashes(paths: Iterable[Path], base: str | Path) -> dict[str, str]:
    """Each file's SHA-256 (hex), keyed as :func:`file_sizes` keys it: recorded beside the
    sizes, so that an edit that keeps a file's size (``15.917`` made ``25.917`` in an
    estimate.json, a bit flipped in a Parquet page) is found too; the summary and the API
    showed such an edit as the run's answer while its report showed the number it wrote.
    Hashing costs a read of each file, little beside what the stages cost to make them."""
    return {p.relative_to(base).as_posix(): file_hash(p) for p in paths}


def file_mtimes(paths: Iterable[Path], base: str | Path) -> dict[str, int]:
    """Each file's modification time (ns), keyed as :func:`file_sizes` keys it: a file whose
    size and modification time are as recorded is taken as unchanged without hashing it (as
    make and git's index do), so that resuming a run reads no gigabytes of campaign; any
    write, an edit that keeps the size included, moves the time and has it hashed."""
    return {p.relative_to(base).as_posix(): p.stat().st_mtime_ns for p in paths}


def changed_files(
    sizes: Mapping[str, int],
    base: str | Path,
    hashes: Mapping[str, str] | None = None,
    mtimes: Mapping[str, int] | None = None,
) -> list[Path]:
    """The files of a :func:`file_sizes` record that are gone or have another size now, or,
    where ``hashes`` (a :func:`file_hashes` record) holds theirs, another SHA-256; a file
    whose size and modification time are those of ``mtimes`` (:func:`file_mtimes`) is not
    hashed. A file the hashes do not name (a run made before they were recorded: ``hashes``
    None) is compared by its size alone, as such runs were: they stay up to date, and an
    edit that keeps a size goes unseen in them until a stage runs again and records its
    hashes."""
    base = Path(base)
    hashes = hashes if isinstance(hashes, Mapping) else {}
    mtimes = mtimes if isinstance(mtimes, Mapping) else {}
    changed = []
    for rel, size in (sizes if isinstance(sizes, Mapping) else {}).items():
        path = base / rel
        try:
            st = path.stat()
            if st.st_size != size:
                changed.append(path)
            elif rel in hashes and mtimes.get(rel) != st.st_mtime_ns:
                if file_hash_cached(path) != hashes[rel]:
                    changed.append(path)
        except OSError:
            changed.append(path)
    return changed


def unreadable_files(paths: Iterable[Path]) -> list[Path]:
    """The files among ``paths`` that do not read (:func:`file_readable`)."""
    return [p for p in paths if not file_readable(p)]
