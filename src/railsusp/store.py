"""The run directory: atomic writes of JSON and Parquet, reading input files, content hashes.

Every file railsusp writes goes through a temporary file in the same folder, is flushed to
disk (fsync) and renamed over its target, and the folder is fsynced after the rename: an
interrupted run, or a power loss, leaves either the old file or the new one, never half of
one. Artefacts made of several files are written into a temporary folder and renamed as one
(:func:`atomic_folder`). Input files are read by :func:`read_toml`, :func:`read_json` and
:func:`read_csv`, which turn every OS, decoding and syntax error into a one-line
:class:`RailsuspInputError`. Each result records what it was made from (:func:`content_hash`,
:func:`file_hash`); which code made it is :mod:`railsusp.provenance`'s record.

Whether what a file says is acceptable (strict validation against its model, an output path
that can be written) is :mod:`railsusp.input_checks`'s job, not this module's: the store
reads and writes bytes and hashes them; it judges no content.
"""

from __future__ import annotations

import errno
import fnmatch
import glob
import hashlib
import io
import json
import os
import re
import shutil
import tempfile
import tomllib
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from railsusp.errors import RailsuspInputError

#: what ``os.fsync`` of a folder (or ``os.open`` of one) raises where the file system or the
#: platform does not support it: ignored; anything else (EIO: the rename may not be on disk)
#: is an error, not a success reported (the disk audit)
_FSYNC_DIR_UNSUPPORTED = frozenset(
    {errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EBADF, errno.EISDIR}
)


def fsync_dir(path: str | Path) -> None:
    """Flush a folder's entries (a rename into it) to disk; a no-op where unsupported (a
    folder that cannot be opened for it, a file system whose folders take no fsync). Any
    other error (EIO, ENOSPC) is raised: it was swallowed, and a rename perhaps never on
    disk was reported as written (the disk audit)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError as exc:
        if exc.errno in _FSYNC_DIR_UNSUPPORTED | {errno.EACCES, errno.EPERM}:
            return
        raise
    try:
        os.fsync(fd)
    except OSError as exc:
        if exc.errno not in _FSYNC_DIR_UNSUPPORTED:
            raise
    finally:
        os.close(fd)


def fsync_file(path: str | Path) -> None:
    """Flush a written file's content to disk (before a rename makes it the file)."""
    with open(path, "rb+") as fh:
        os.fsync(fh.fileno())


def _process_umask() -> int:
    """The process's umask (read by setting it and back; done once, at import)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: the umask the outputs' modes follow: a temporary file is created 0600 (a folder 0700),
#: and renamed into place it would stay so; a file written in place would be 0666 & ~umask
_UMASK = _process_umask()


def plain_mode(path: str | Path) -> None:
    """Give a temporary file (created 0600) the mode a plainly written one gets, before it
    is renamed into place."""
    os.chmod(path, 0o666 & ~_UMASK)


def _naming(exc: OSError, target: Path, folder: Path | None = None) -> OSError:
    """``exc`` as it is to be shown, its errno kept (the exit status depends on it): the user
    was told "No space left on device" and not where, or was shown a hidden temporary (the
    disk audit). For a file ``target`` (``folder`` None): an error naming no file
    (pyarrow's "[errno 28] No space left on device", a bare write error) or naming one of
    its temporaries (``.NAME.XXXXXXXX.tmp``) names ``target``. For a folder ``target``
    written in the temporary ``folder`` (:func:`atomic_folder`): an error naming a file
    inside ``folder``, or ``folder``, names the same file inside ``target``. Any other error
    is returned as it is."""
    named = exc.filename
    if isinstance(named, (str, bytes, os.PathLike)):
        named = os.path.abspath(os.fsdecode(named))
    else:  # none, or a file descriptor
        named = None
    where: Path | None = None
    if folder is None:
        found = None if named is None else _TEMPORARY.match(os.path.basename(named))
        if named is None or (
            found is not None
            and found["target"] == target.name
            and os.path.dirname(named) == os.path.abspath(target.parent)
        ):
            where = target
    elif named is not None:
        hidden = os.path.abspath(folder)
        if named == hidden:
            where = target
        elif named.startswith(hidden + os.sep):
            where = target / os.path.relpath(named, hidden)
    if where is None:
        return exc
    reason = exc.strerror or (os.strerror(exc.errno) if exc.errno else str(exc))
    return OSError(exc.errno, reason, str(where))


@contextmanager
def _replacing(path: Path) -> Iterator[str]:
    """The one way a file is written: yields a temporary file beside ``path`` (``.NAME.*.tmp``)
    to write and close; then its content is flushed to disk, it gets the mode a plainly
    written file gets (0666 less the umask, not the temporary file's 0600), is renamed over
    ``path`` and the rename is flushed too. On an error the temporary file is removed and
    ``path`` is untouched; an OSError naming no file or the temporary names ``path``
    (:func:`_naming`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        os.close(fd)
        try:
            yield tmp
            fsync_file(tmp)
            plain_mode(tmp)
            os.replace(tmp, path)
            fsync_dir(path.parent)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except OSError as exc:
        shown = _naming(exc, path)
        if shown is exc:
            raise
        raise shown from exc


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + rename), with the mode a
    plainly written file gets (0666 less the umask), not the temporary file's 0600."""
    path = Path(path)
    with _replacing(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
    return path


#: the name of a temporary file :func:`_replacing` makes: ``.NAME.`` + mkstemp's eight
#: random characters + ``.tmp`` (a user's ``.notes.tmp`` is no railsusp temporary)
_TEMPORARY = re.compile(r"^\.(?P<target>.+)\.[a-z0-9_]{8}\.tmp$")


def remove_stale_temporaries(folder: str | Path, targets: Sequence[str] | None = None) -> int:
    """Remove the temporaries of :func:`_replacing` (``.NAME.XXXXXXXX.tmp``) that a process
    killed while writing left directly in ``folder``; the number removed. ``targets``: only
    those of files of these names (default: of any name). Subfolders are not entered, and
    other hidden files are left alone: only for a folder whose lock the caller holds
    (:func:`railsusp.run_lock.run_lock`) and whose files no other process writes, since
    another writer's temporary would be live (a training checkpoint being saved under a
    campaign's ``surrogates/``, which the campaign's whole-tree sweep deleted: the
    run-directory store audit). A kill during a write left them for good (the
    interrupt/resume audit of stop 60)."""
    removed = 0
    folder = Path(folder)
    if not folder.is_dir():
        return 0
    for tmp in folder.iterdir():
        found = _TEMPORARY.match(tmp.name)
        if found is None or (targets is not None and found["target"] not in targets):
            continue
        if tmp.is_file() and not tmp.is_symlink():
            tmp.unlink(missing_ok=True)
            removed += 1
    return removed


def atomic_write_figure(fig: Any, path: str | Path, **savefig: Any) -> Path:
    """Write a matplotlib figure to ``path`` atomically, in the format of its suffix
    (``savefig``'s keywords passed on); the figure is left open."""
    path = Path(path)
    buffer = io.BytesIO()
    fig.savefig(buffer, format=path.suffix.lstrip(".").lower() or "png", **savefig)
    return atomic_write_bytes(path, buffer.getvalue())


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def write_csv(path: str | Path, df: pd.DataFrame, **kw: Any) -> Path:
    """Write a DataFrame as CSV atomically (``kw`` go to :meth:`DataFrame.to_csv`)."""
    kw.setdefault("index", False)
    return atomic_write_text(path, df.to_csv(**kw))


def parquet_readable(path: str | Path, pages: bool = False) -> bool:
    """Whether ``path`` is a Parquet file whose footer reads: a file cut short (a copy
    interrupted, a full disk) or missing is not (our writes are atomic, so a kill never
    leaves one). ``pages``: also read every page and check the checksums railsusp writes
    (:func:`write_parquet`), so that a bit flipped inside a data page, which leaves the
    footer intact, is found too; this reads the whole file (a file written without
    checksums, before they were written, is read whole and has nothing more to check)."""
    try:
        pf = pq.ParquetFile(path, page_checksum_verification=True)  # reads the footer
        for group in range(pf.num_row_groups if pages else 0):  # one at a time in memory
            pf.read_row_group(group)
    except (OSError, ValueError, pa.ArrowException):  # missing; not Parquet, cut short, a
        return False  # page whose checksum does not match or that does not decode
    return True


def read_parquet(
    path: str | Path,
    remedy: str = "",
    error: type[RailsuspInputError] = RailsuspInputError,
    **kw: Any,
) -> pd.DataFrame:
    """A Parquet table of a run directory, its pages' checksums verified (where it has them:
    :func:`write_parquet` writes them; older files read as before). A file that is missing,
    cut short or damaged (a flipped bit in a data page) is a one-line input error naming it,
    ``remedy`` appended (how to make it again), never pyarrow's traceback nor, silently,
    changed numbers; ``error``: the error's class (a subclass of the input error). ``kw``
    go to :func:`pandas.read_parquet` (``columns``)."""
    path = Path(path)
    try:
        return pd.read_parquet(path, page_checksum_verification=True, **kw)
    except FileNotFoundError:
        raise error(f"{path} does not exist{remedy and '; ' + remedy}") from None
    except (OSError, ValueError, pa.ArrowException) as exc:  # not Parquet, a bad checksum
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise error(f"{path} is damaged ({first}){remedy and '; ' + remedy}") from None


def read_csv(path: str | Path) -> pd.DataFrame:
    """A table of a run directory; an empty or unparsable file (a hand-edited run) is a
    one-line input error naming it, not pandas' traceback."""
    path = Path(path)
    try:
        return pd.read_csv(path)
    except FileNotFoundError:
        raise RailsuspInputError(f"{path} does not exist") from None
    except (pd.errors.EmptyDataError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise RailsuspInputError(f"{path}: not a readable table ({first})") from None


@contextmanager
def atomic_folder(path: str | Path, keep: bool = True, drop: Sequence[str] = ()) -> Iterator[Path]:
    """Write a multi-file artefact as one: yields a temporary sibling folder to write into;
    on success it replaces ``path``, on an error it is removed and ``path`` is untouched.

    ``keep``: other entries of an existing ``path`` (a training checkpoint, figures) are
    carried into the new folder (hard links where possible), except those whose names match
    a glob pattern of ``drop`` (what the old artefact wrote and this one replaces or no
    longer has: an old estimate's validation, a removed condition's recording). The swap is
    two renames (the old folder aside, the new one in); a crash between them leaves the old
    folder beside ``path`` as ``.NAME.old-*`` and no ``path``: the next save puts it back
    first (it held finished work: a trained network and its checkpoint), then carries on. A
    process killed while writing leaves ``.NAME.new-*``: the next save removes it. The
    folder gets the mode a plainly made one gets (0777 less the umask), not the temporary
    folder's 0700.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    name = glob.escape(path.name)  # ``est[1]``, ``run*``: a pattern only of this name's
    aside = sorted(path.parent.glob(f".{name}.old-*"), key=lambda p: p.stat().st_mtime)
    if aside and not path.exists():  # a crash between the two renames: the old one back
        os.rename(aside.pop(), path)
    for pattern in (f".{name}.old-*", f".{name}.new-*"):
        for stale in path.parent.glob(pattern):
            shutil.rmtree(stale, ignore_errors=True)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.new-"))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_UMASK)
        for f in tmp.rglob("*"):
            if f.is_file():
                fsync_file(f)
        if keep and path.is_dir():
            for entry in path.iterdir():
                target = tmp / entry.name
                if target.exists() or any(fnmatch.fnmatchcase(entry.name, d) for d in drop):
                    continue
                if entry.is_dir():
                    shutil.copytree(entry, target, copy_function=_link_or_copy)
                else:
                    _link_or_copy(entry, target)
        fsync_dir(tmp)
        if path.exists():
            old = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.old-"))
            os.rmdir(old)
            os.rename(path, old)
            os.rename(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(tmp, path)
        fsync_dir(path.parent)
    except OSError as exc:  # a file of the hidden folder named as the one it was to become
        shown = _naming(exc, path, folder=tmp)
        if shown is exc:
            raise
        raise shown from exc
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _link_or_copy(src: str | Path, dst: str | Path) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def read_toml(path: str | Path, what: str = "file") -> dict[str, Any]:
    """Read a TOML file; any OS, decoding or syntax error is a one-line input error naming
    the file (``what`` says what it is: "configuration", "condition file", ...)."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8-sig")  # a byte-order mark (Notepad) is no error
    except IsADirectoryError:
        raise RailsuspInputError(f"{what} {path} is a folder, not a TOML file") from None
    except FileNotFoundError:
        raise RailsuspInputError(f"{what} {path} does not exist") from None
    except OSError as exc:
        raise RailsuspInputError(f"{what} {path} cannot be read ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise RailsuspInputError(
            f"{what} {path} is not UTF-8 text (byte {exc.start}): not a TOML file"
        ) from None
    except ValueError as exc:  # a path with a NUL character
        raise RailsuspInputError(f"{what} {str(path)!r} is not a usable path ({exc})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RailsuspInputError(f"{what} {path}: not valid TOML ({exc})") from None


def _default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot serialise {type(obj).__name__} to JSON")


def canonical_json(obj: Any) -> str:
    """JSON with sorted keys and no whitespace variation: the basis of content hashes."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_default)


def content_hash(obj: Any) -> str:
    """SHA-256 of the canonical JSON of ``obj`` (hex, 16 characters)."""
    return hashlib.sha256(canonical_json(obj).encode()).hexdigest()[:16]


def file_hash(path: str | Path) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def file_hash_cached(path: str | Path) -> str:
    """:func:`file_hash`, read once per version of the file (kept by absolute path, inode,
    modification and change times and size: a file replaced by an atomic write is a new
    inode, whatever its time and size, and one rewritten in place with its modification
    time set back, as ``cp -p`` does, has a new change time, which no user tool sets): for
    hashes asked for again and again, a surrogate's track inputs every generation, a
    campaign's geometry files every batch, a run's recorded outputs every time the API
    reads one."""
    p = os.path.abspath(path)
    st = os.stat(p)
    return _file_hash_of(p, st.st_ino, st.st_mtime_ns, st.st_ctime_ns, st.st_size)


@lru_cache(maxsize=1024)
def _file_hash_of(path: str, _inode: int, _mtime_ns: int, _ctime_ns: int, _size: int) -> str:
    return file_hash(path)


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON, atomically."""
    text = json.dumps(obj, indent=2, sort_keys=True, default=_default) + "\n"
    return atomic_write_bytes(path, text.encode())


def read_json(path: str | Path) -> Any:
    """Read a JSON file; an unreadable, non-UTF-8 or malformed file is a one-line input
    error naming the file."""
    path = Path(path)
    try:
        return json.loads(path.read_bytes().decode("utf-8-sig"))  # a BOM (Windows) allowed
    except FileNotFoundError:
        raise RailsuspInputError(f"{path} does not exist") from None
    except OSError as exc:
        raise RailsuspInputError(f"{path} cannot be read ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise RailsuspInputError(f"{path} is not UTF-8 text (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise RailsuspInputError(f"{path} is corrupt: not valid JSON ({exc})") from None
    except RecursionError:
        raise RailsuspInputError(f"{path} is corrupt: nested deeper than JSON data is") from None


def write_parquet(
    path: str | Path,
    df: pd.DataFrame,
    metadata: dict[str, str] | None = None,
    row_group_size: int | None = None,
) -> Path:
    """Write a DataFrame to Parquet atomically, with optional key/value metadata and a CRC
    checksum in every page header: a bit flipped in a data page leaves the footer intact and
    the file its size, and only the checksums (verified by :func:`read_parquet` and
    ``parquet_readable(pages=True)``) tell it from the numbers written."""
    path = Path(path)
    table = pa.Table.from_pandas(df, preserve_index=False)
    if metadata:
        meta = dict(table.schema.metadata or {})
        meta.update({k.encode(): v.encode() for k, v in metadata.items()})
        table = table.replace_schema_metadata(meta)
    with _replacing(path) as tmp:
        pq.write_table(
            table,
            tmp,
            row_group_size=row_group_size or max(1, table.num_rows),
            write_page_checksum=True,
        )
    return path
