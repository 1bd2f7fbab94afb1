"""Exceptions raised on bad user input.

Every message names the offending field, the value given and what is accepted, so that the
command line can print it as one line (exit status 2) without a traceback.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Sequence


class RailsuspInputError(ValueError):
    """Bad user input: a parameter, condition or file that cannot be accepted."""


class OutputStreamError(OSError):
    """A write to the command's standard output or error that the system refused (``>
    /dev/full``, a full disk under a redirected stream): the stream named, so that the
    one-line error says that the printout was lost, not the run's files
    (:func:`railsusp.cli.main`)."""

    def __init__(self, stream: str, cause: OSError) -> None:
        super().__init__(cause.errno, cause.strerror or str(cause))
        self.stream = stream


class ParameterError(RailsuspInputError):
    """A suspension or vehicle parameter is unknown, non-finite or out of its range."""


class ConditionError(RailsuspInputError):
    """A working-condition field is missing, non-finite or out of its range."""


def did_you_mean(name: str, options: list[str]) -> str:
    """' (did you mean 'X'?)' for the closest of ``options`` to a misspelt ``name``, or ''.
    An option that is ``name`` with a unit after it (``t [s]``, ``v (km/h)``: a table's
    header, which names its channel whole) is the closest: the bare name suggested nothing
    (the docs audit of stop 65)."""
    same_case = [o for o in options if o.lower() == name.lower()]
    with_unit = [
        o for o in options if re.sub(r"\s*[\[(][^\])]*[\])]\s*$", "", o).lower() == name.lower()
    ]
    m = same_case or with_unit or difflib.get_close_matches(name, options, n=1, cutoff=0.6)
    return f" (did you mean {m[0]!r}?)" if m else ""


def cut_repr(value: object, width: int = 60) -> str:
    """``repr(value)`` cut to ``width`` characters for a one-line message: a recording's
    cell of 200 000 characters was quoted whole in its refusal."""
    text = repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def first_listed(items: Sequence[object], shown: int) -> str:
    """The first ``shown`` of ``items`` for a message, comma-separated, and how many more
    (``"a, b, c and 4 more"``): a long list in one line."""
    more = f" and {len(items) - shown} more" if len(items) > shown else ""
    return ", ".join(str(i) for i in items[:shown]) + more


def repeated(items: Sequence[object]) -> list[str]:
    """The items that ``items`` holds more than once, as sorted text for a message
    (``"X13, X14"``): a name given twice would overwrite or weigh double."""
    return sorted({str(x) for x in items if items.count(x) > 1})


def repeated_names(names: Sequence[str]) -> list[str]:
    """The names of ``names`` that another one equals when case is ignored, as given
    (``["A", "a"]``): condition names become file and folder names, which are one on a
    case-blind disk (Windows, macOS)."""
    folded = [n.casefold() for n in names]
    return sorted({n for n, f in zip(names, folded, strict=True) if folded.count(f) > 1})
