"""Checking user input and phrasing what is wrong with it as one line.

A configuration, condition or wagon file is validated by its pydantic model in strict mode
(:func:`validate_document`), and pydantic's errors are turned into the project's one-line
input errors: what a field needs and what it was given (:func:`type_error_text`), the range
a value must lie in or the keys a section accepts (:func:`error_detail`). Output paths given
on the command line or to the API are refused before any work is done when they cannot be
written (:func:`check_output_folder`, :func:`check_output_file`, :func:`check_figure_file`),
or said to be when the system refuses to make them (:func:`unmade_folder`).

Kept apart from :mod:`railsusp.store`, which persists the run directory: this module
decides whether input is acceptable and says why not; it writes nothing (but the file
:func:`check_output_file` makes and removes at once to try a folder), and imports no
railsusp module but :mod:`railsusp.errors`.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import re
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path, PurePath
from typing import Any

import numpy as np

from railsusp.errors import RailsuspInputError

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


def check_replaced_folder(
    path: str | Path, option: str, command: str, own: tuple[str, ...] = ()
) -> Path:
    """Refuse, before any work, an output folder that ``command`` writes as one artefact
    (:func:`~railsusp.atomic_files.atomic_folder`: the folder renamed aside and a new one
    put in its place) where that would lose what it holds (the QA of stop 73):

    - the folder the command runs in, or one above it: ``--out .`` failed after the whole
      run ("'.' has an empty name", the result lost), and ``--out "$PWD"`` renamed the
      shell's folder away;
    - with ``own`` (the files that mark a folder the command may write into, ``estimate.json``
      for estimate; for validate also the estimate's folder): an existing folder that holds
      other files and none of ``own``, a user's folder or a whole run directory, whose files
      of the command's output names were replaced or dropped without a word (the others are
      carried into the new folder).

    Also refuses what :func:`check_output_folder` does."""
    path = check_output_folder(path, option)
    full, here = path.resolve(), Path.cwd().resolve()
    if full == here or full in here.parents:
        where = "the folder you are in" if full == here else "a folder above the one you are in"
        raise RailsuspInputError(
            f"{option} {path} is {where}: {command} replaces its output folder whole (the "
            "old one renamed aside, the new one put in its place): accepted a folder below it"
        )
    if full.exists() and not os.access(full.parent, os.W_OK | os.X_OK):  # the swap's place
        raise RailsuspInputError(  # (a link's folder: beside it, where the link points)
            f"{option} {path}: {command} replaces the folder whole, its new version made "
            f"beside it in {full.parent}, which cannot be written (the run failed there after "
            "all its work): accepted a folder in a writable folder"
        )
    if own and full.is_dir() and not any((full / name).exists() for name in own):
        held = sorted(e.name for e in full.iterdir() if not e.name.startswith("."))  # a lock
        if held:
            raise RailsuspInputError(
                f"{option} {path} holds {', '.join(held[:3])}{' and more' if held[3:] else ''}"
                f" and no {' or '.join(own)}: {command} would replace the folder with its own "
                f"output: accepted a new or empty folder, or one {command} wrote"
            )
    return path


def unmade_folder(
    exc: OSError, path: str | Path, option: str = "--out"
) -> RailsuspInputError | None:
    """``exc``, the system's refusal to make the output folder ``path`` or a folder above it
    (a folder under ``/proc``, which :func:`check_output_folder` cannot tell from a
    writable one: "/proc/foo: No such file or directory"), as a one-line error naming the
    option; None where ``exc`` is about another file."""
    if not exc.filename:
        return None
    failed = Path(os.fsdecode(exc.filename)).absolute()
    wanted = Path(path).absolute()
    if failed != wanted and failed not in wanted.parents:
        return None
    return RailsuspInputError(
        f"{option} {path}: the folder {failed} cannot be made "
        f"({exc.strerror or type(exc).__name__}); accepted a folder that can be made and "
        "written"
    )


def check_output_file(path: str | Path, option: str = "--out") -> Path:
    """Refuse an output file that is a folder or lies in a folder that cannot be written.
    An existing folder is tried with a file made and removed at once: under ``/proc``
    ``os.access`` tells root it may write, and ``sections --plot /proc/x.png`` failed only
    after the long run had been read and cut (stop 78's hunt)."""
    path = Path(path)
    if path.is_dir():
        raise RailsuspInputError(f"{option} {path} is a folder, not a file")
    if path.parent.exists() and not path.parent.is_dir():
        raise RailsuspInputError(f"{option} {path}: {path.parent} is a file, not a folder")
    check_output_folder(path.parent, option)
    if path.parent.is_dir():
        try:
            fd, probe = tempfile.mkstemp(prefix=".railsusp-probe-", dir=path.parent)
        except OSError as exc:
            raise RailsuspInputError(
                f"{option} {path}: no file can be written in {path.parent} "
                f"({exc.strerror or type(exc).__name__}); accepted a file in a writable folder"
            ) from None
        os.close(fd)
        os.unlink(probe)
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
