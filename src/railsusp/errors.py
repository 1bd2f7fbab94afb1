"""Exceptions raised on bad user input.

Every message names the offending field, the value given and what is accepted, so that the
command line can print it as one line (exit status 2) without a traceback.
"""

from __future__ import annotations


class RailsuspInputError(ValueError):
    """Bad user input: a parameter, condition or file that cannot be accepted."""


class ParameterError(RailsuspInputError):
    """A suspension or vehicle parameter is unknown, non-finite or out of its range."""


class ConditionError(RailsuspInputError):
    """A working-condition field is missing, non-finite or out of its range."""
