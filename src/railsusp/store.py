"""The run directory: atomic writes of JSON and Parquet, content hashes, provenance.

Every file railsusp writes goes through a temporary file in the same folder, is flushed to
disk (fsync) and renamed over its target, and the folder is fsynced after the rename: an
interrupted run, or a power loss, leaves either the old file or the new one, never half of
one. Artefacts made of several files are written into a temporary folder and renamed as one
(:func:`atomic_folder`). Input files are read by :func:`read_toml` and :func:`read_json`,
which turn every OS, decoding and syntax error into a one-line :class:`RailsuspInputError`.
"""

from __future__ import annotations

import datetime as _dt
import fnmatch
import hashlib
import io
import json
import os
import platform
import re
import shutil
import socket
import subprocess
import tempfile
import tomllib
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path, PurePath
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from railsusp.errors import RailsuspInputError


def fsync_dir(path: str | Path) -> None:
    """Flush a folder's entries (a rename into it) to disk; a no-op where unsupported."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
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


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + rename), with the mode a
    plainly written file gets (0666 less the umask), not the temporary file's 0600."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        plain_mode(tmp)
        os.replace(tmp, path)
        fsync_dir(path.parent)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def remove_stale_temporaries(folder: str | Path) -> int:
    """Remove the temporaries (``.NAME.*.tmp``) that a process killed while writing left
    under ``folder``; the number removed. Only for a folder whose lock the caller holds
    (:func:`railsusp.run_lock.run_lock`): another writer's temporary would be live. A kill
    during a write left them for good (the interrupt/resume audit of stop 60)."""
    removed = 0
    for tmp in Path(folder).rglob(".*.tmp"):
        if tmp.is_file():
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


def parquet_readable(path: str | Path) -> bool:
    """Whether ``path`` is a Parquet file whose footer reads: a file cut short (a copy
    interrupted, a full disk) or missing is not (our writes are atomic, so a kill never
    leaves one)."""
    try:
        pq.ParquetFile(path).metadata  # noqa: B018  (reads and checks the footer)
    except (OSError, ValueError):  # missing; ArrowInvalid (not Parquet, cut short)
        return False
    return True


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
    aside = sorted(path.parent.glob(f".{path.name}.old-*"), key=lambda p: p.stat().st_mtime)
    if aside and not path.exists():  # a crash between the two renames: the old one back
        os.rename(aside.pop(), path)
    for pattern in (f".{path.name}.old-*", f".{path.name}.new-*"):
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


#: pydantic's strict-mode type errors, as what the field needs
_NEEDED = {
    "int_type": "a whole number",
    "float_type": "a number",
    "bool_type": "true or false",
    "string_type": "a string",
    "tuple_type": "a list",
    "list_type": "a list",
    "dict_type": "a table",
    "model_type": "a table",
}


#: a TOML date or time, as :func:`validate_document` writes it (``1979-05-27``, ``07:32:00``)
_ISO_DATE = re.compile(r"^(\d{4}-\d{2}-\d{2}|\d{2}:\d{2}:\d{2})")


def validate_document(model: Any, doc: Any) -> Any:
    """``doc``, read from a TOML or JSON file, validated by the pydantic ``model`` in strict
    mode, so that a value of the wrong type is refused rather than converted: a number
    written as a string (``speed_kmh = "80"``), a boolean given as a number
    (``with_track = 1``) or as a string (``refine = "false"``), a float where a count is
    meant (``n_gen = 2.0``). An integer still stands for a float (``mass = 91600``).

    The document goes through JSON because strict validation of JSON input takes a file's
    arrays for tuples and its strings for paths, as a file can only write them; TOML dates
    become strings (refused wherever a number is needed)."""
    return model.model_validate_json(json.dumps(doc, default=_plain), strict=True)


def _plain(value: Any) -> Any:
    """A value JSON cannot write, as a file would hold it: a NumPy scalar or array as its
    Python number(s), any mapping as a table, a pydantic model as its fields, a path, date
    or time (TOML's) as its text. Anything else is refused (TypeError naming its type)
    rather than validated as its printed text: a Decimal read as the string "16.1" would be
    refused with advice about quotes that a script cannot follow."""
    from pydantic import BaseModel

    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    if isinstance(value, Mapping):
        return dict(value)
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json")
    if isinstance(value, PurePath | _dt.date | _dt.time):  # a datetime is a date
        return str(value)
    raise TypeError(
        f"a {type(value).__name__} ({value!r:.40}) where a number, a string, a boolean, a list "
        "or a table goes"
    )


def json_numbers(doc: Any) -> Any:
    """``doc`` (read from JSON) with its whole-number floats as integers: JSON has one number
    type, so ``"n_steps": 1000.0`` (as MATLAB or pandas write it) is the whole number 1000 for
    :func:`validate_document`; floats stay floats where a real number is meant."""
    if isinstance(doc, dict):
        return {k: json_numbers(v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [json_numbers(v) for v in doc]
    if isinstance(doc, float) and doc.is_integer():
        return int(doc)
    return doc


def type_error_text(err: Any) -> str | None:
    """For a strict-mode type error of :func:`validate_document` (one of pydantic's
    ``ValidationError.errors()``), what the field needs and what it was given, e.g.
    ``a whole number is needed, not a string (write it without quotes)``; else None."""
    needed = _NEEDED.get(err.get("type", ""))
    if needed is None:
        return None
    value = err.get("input")
    if isinstance(value, str) and _ISO_DATE.match(value):
        return f"{needed} is needed, not a date or time"
    if isinstance(value, str):
        quotes = "" if needed in ("a string", "a list", "a table") else " (write it without quotes)"
        return f"{needed} is needed, not a string{quotes}"
    got = {
        bool: "a boolean",
        int: "an integer",
        float: "a float",
        list: "a list",
        dict: "a table",
        type(None): "null",
    }
    return f"{needed} is needed, not {got.get(type(value), type(value).__name__)}"


#: pydantic's error types of a value outside a field's bounds
BOUND_ERRORS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")


def field_at(model: Any, loc: Sequence[Any]) -> tuple[Any, Any]:
    """(the model class holding the last key of ``loc``, its pydantic ``FieldInfo`` or None
    where the key is not a field) for a location of ``model``'s nested sections (an error's
    ``loc``); (None, None) where the path leaves the models."""
    holder = model
    for i, key in enumerate(loc):
        fields = getattr(holder, "model_fields", None)
        if not isinstance(fields, dict):
            return None, None
        info = fields.get(str(key))
        if i == len(loc) - 1 or info is None:
            return (holder, info) if i == len(loc) - 1 else (None, None)
        holder = info.annotation
    return None, None


def bound_text(x: float) -> str:
    """A range bound as written: a whole number in full (a seed's 9223372036854775807, not
    9.22337e+18), others as %g."""
    return str(x) if isinstance(x, int) else f"{x:g}"


def bounds_text(info: Any) -> str:
    """A field's bounds as an interval, "[4, 1e+06]" or "(0, 5] m" (its ``unit`` from
    ``json_schema_extra``); "" without bounds."""
    lo = hi = None
    left, right = "[", "]"
    for m in getattr(info, "metadata", ()):
        for name, bracket in (("gt", "("), ("ge", "[")):
            if getattr(m, name, None) is not None:
                lo, left = getattr(m, name), bracket
        for name, bracket in (("lt", ")"), ("le", "]")):
            if getattr(m, name, None) is not None:
                hi, right = getattr(m, name), bracket
    if lo is None and hi is None:
        return ""
    extra = getattr(info, "json_schema_extra", None)
    unit = extra.get("unit", "") if isinstance(extra, dict) else ""
    low = "-inf" if lo is None else bound_text(lo)
    high = "inf" if hi is None else bound_text(hi)
    return f"{left}{low}, {high}{right} {unit}".rstrip()


def error_detail(model: Any, err: Any) -> str | None:
    """What a pydantic error of ``model`` misses in its own message: the accepted range of a
    value outside a field's bounds ("accepted [4, 1000000]"), or the keys a section accepts
    for an unknown one; None otherwise."""
    holder, info = field_at(model, err.get("loc", ()))
    if err.get("type") in BOUND_ERRORS and info is not None:
        text = bounds_text(info)
        return f"accepted {text}" if text else None
    if err.get("type") == "extra_forbidden" and holder is not None and info is None:
        return f"accepted keys: {', '.join(holder.model_fields)}"
    return None


def check_output_folder(path: str | Path, option: str = "--out") -> Path:
    """Refuse an output folder that is an existing file or cannot be created or written,
    before any work is done (one-line error). Creates nothing."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise RailsuspInputError(f"{option} {path} is an existing file, not a folder")
    if path.is_symlink() and not path.exists():
        raise RailsuspInputError(
            f"{option} {path} is a link to {os.readlink(path)}, which does not exist"
        )
    probe = path.absolute()
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise RailsuspInputError(f"{option} {path}: {probe} is a file, not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise RailsuspInputError(f"{option} {path}: the folder {probe} is not writable")
    return path


def check_output_file(path: str | Path, option: str = "--out") -> Path:
    """Refuse an output file that is a folder or lies in a folder that cannot be written."""
    path = Path(path)
    if path.is_dir():
        raise RailsuspInputError(f"{option} {path} is a folder, not a file")
    if path.parent.exists() and not path.parent.is_dir():
        raise RailsuspInputError(f"{option} {path}: {path.parent} is a file, not a folder")
    check_output_folder(path.parent, option)
    return path


#: the figure formats the command line's ``--plot`` writes (matplotlib's, by suffix)
FIGURE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def check_figure_file(path: str | Path, option: str = "--plot") -> Path:
    """Refuse a figure file as :func:`check_output_file` does, and one whose suffix names no
    format in :data:`FIGURE_SUFFIXES`, before any work is done."""
    path = check_output_file(path, option)
    if path.suffix.lower() not in FIGURE_SUFFIXES:
        raise RailsuspInputError(
            f"{option} {path}: format {path.suffix or '(no suffix)'} unknown; accepted "
            f"{', '.join(FIGURE_SUFFIXES)}"
        )
    return path


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
    """:func:`file_hash`, read once per version of the file (kept by absolute path,
    modification time and size): for hashes asked for again and again, a surrogate's
    track inputs every generation, a campaign's geometry files every batch."""
    p = os.path.abspath(path)
    st = os.stat(p)
    return _file_hash_of(p, st.st_mtime_ns, st.st_size)


@lru_cache(maxsize=1024)
def _file_hash_of(path: str, _mtime_ns: int, _size: int) -> str:
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
    """Write a DataFrame to Parquet atomically, with optional key/value metadata."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    if metadata:
        meta = dict(table.schema.metadata or {})
        meta.update({k.encode(): v.encode() for k, v in metadata.items()})
        table = table.replace_schema_metadata(meta)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        pq.write_table(table, tmp, row_group_size=row_group_size or max(1, table.num_rows))
        fsync_file(tmp)
        plain_mode(tmp)
        os.replace(tmp, path)
        fsync_dir(path.parent)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def _git(*args: str) -> str | None:
    """A git command's output in the railsusp source tree; None where it is no checkout."""
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(["git", *args], cwd=here, capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout if out.returncode == 0 else None


def git_sha() -> str | None:
    """The git commit of the railsusp source tree, if it is a checkout."""
    out = _git("rev-parse", "HEAD")
    return (out or "").strip() or None


def git_dirty() -> bool | None:
    """Whether the railsusp source tree has uncommitted changes to tracked files (its
    results then come from code no commit holds); None where it is no checkout."""
    out = _git("status", "--porcelain", "--untracked-files=no", "--", ".")
    return None if out is None else bool(out.strip())


#: the libraries whose versions a result records (read from their metadata: importing
#: torch to ask its version would cost a second)
RECORDED_LIBRARIES = (
    "numpy", "scipy", "numba", "pandas", "torch", "pymoo", "SALib", "asammdf", "sbi",
)  # fmt: skip


def library_versions() -> dict[str, str]:
    """Installed versions of :data:`RECORDED_LIBRARIES` (those installed)."""
    from importlib import metadata

    out = {}
    for name in RECORDED_LIBRARIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


def code_identity() -> dict[str, Any]:
    """Which railsusp made a result: its version, git commit and whether the tree was
    modified (each pipeline stage records it: stages of one run may come from two)."""
    from railsusp._version import __version__

    return {"railsusp": __version__, "git_sha": git_sha(), "git_dirty": git_dirty()}


def utc_now() -> str:
    """The UTC time to the second, ISO 8601: when a file or a stage was made."""
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def provenance(identity: dict[str, Any] | None = None) -> dict[str, Any]:
    """Who and what produced a file: railsusp's version, git commit and whether its tree was
    modified (``identity``, default :func:`code_identity`), the libraries' versions, host,
    UTC time."""
    return {
        **(code_identity() if identity is None else identity),
        "python": platform.python_version(),
        **library_versions(),
        "host": socket.gethostname(),
        "platform": platform.platform(),
        "utc": utc_now(),
    }
