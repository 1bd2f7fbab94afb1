"""Exceptions raised on bad user input.

Every message names the offending field, the value given and what is accepted, so that the
command line can print it as one line (exit status 2) without a traceback.
"""

from __future__ import annotations

import difflib


class RailsuspInputError(ValueError):
    """Bad user input: a parameter, condition or file that cannot be accepted."""


class ParameterError(RailsuspInputError):
    """A suspension or vehicle parameter is unknown, non-finite or out of its range."""


class ConditionError(RailsuspInputError):
    """A working-condition field is missing, non-finite or out of its range."""


def did_you_mean(name: str, options: list[str]) -> str:
    """' (did you mean 'X'?)' for the closest of ``options`` to a misspelt ``name``, or ''."""
    same_case = [o for o in options if o.lower() == name.lower()]
    m = same_case or difflib.get_close_matches(name, options, n=1, cutoff=0.6)
    return f" (did you mean {m[0]!r}?)" if m else ""
