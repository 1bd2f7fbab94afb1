"""The run directory's files: JSON, Parquet, CSV and TOML written atomically and read back,
and content hashes.

Every file railsusp writes goes through :mod:`railsusp.atomic_files` (a temporary file in the
same folder, flushed to disk and renamed over its target; a folder of several files renamed
as one): an interrupted run, or a power loss, leaves either the old file or the new one,
never half of one. That module holds the writes to disk, this one the formats: input files
are read by :func:`read_toml`, :func:`read_json` and :func:`read_csv`, which turn every OS,
decoding and syntax error into a one-line :class:`RailsuspInputError`. Each result records
what it was made from (:func:`content_hash`, :func:`file_hash`); which code made it is
:mod:`railsusp.provenance`'s record.

Whether what a file says is acceptable (strict validation against its model, an output path
that can be written) is :mod:`railsusp.input_checks`'s job, not this module's: the store
reads and writes bytes and hashes them; it judges no content.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import tomllib
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

# the atomic writes are railsusp.atomic_files'; these names are imported from here too (a
# test that replaces one, e.g. to fill the disk, patches railsusp.atomic_files: the writers
# there call each other, and a name replaced here reaches only this module's callers)
from railsusp.atomic_files import atomic_folder as atomic_folder
from railsusp.atomic_files import atomic_write_bytes as atomic_write_bytes
from railsusp.atomic_files import atomic_write_text as atomic_write_text
from railsusp.atomic_files import put_back_aside as put_back_aside
from railsusp.atomic_files import remove_stale_temporaries as remove_stale_temporaries
from railsusp.atomic_files import replacing_file
from railsusp.errors import RailsuspInputError


def atomic_write_figure(fig: Any, path: str | Path, **savefig: Any) -> Path:
    """Write a matplotlib figure to ``path`` atomically, in the format of its suffix
    (``savefig``'s keywords passed on); the figure is left open."""
    path = Path(path)
    buffer = io.BytesIO()
    fig.savefig(buffer, format=path.suffix.lstrip(".").lower() or "png", **savefig)
    return atomic_write_bytes(path, buffer.getvalue())


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
    with replacing_file(path) as tmp:
        pq.write_table(
            table,
            tmp,
            row_group_size=row_group_size or max(1, table.num_rows),
            write_page_checksum=True,
        )
    return path
