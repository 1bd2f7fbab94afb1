"""How a stored result's force-law revision stands to this railsusp's.

Every simulated result (a campaign, the surrogates and network sets trained on one, an
estimate, a posterior estimator's cached simulations, a run directory) records the
revision of the force laws it was made with (:data:`railsusp.vehicle.MODEL_REVISION`,
recorded since 2026-11-30). Before one is used with today's model, its revision is one of
four: **this** railsusp's; **none** recorded (made before revisions were recorded, so with
older force laws than any revision); **older**; or **newer** (a newer railsusp's result,
which this one must neither discard as outdated nor read as its own). A revision that is not
of the form ``YYYY-MM-DD.N`` (edited by hand) is **other**: neither older nor newer.

Each check states the standing in the words of :func:`made_with` and differs from the
others only in its remedy, so that a user meets one phrasing whichever file is refused.
"""

from __future__ import annotations

import re
from enum import Enum

import railsusp.vehicle

#: the day revisions began to be recorded: a result recording none was made before it
FIRST_RECORDED = "2026-11-30"

#: a force-law revision: a date and that day's number
_REVISION = re.compile(r"(\d{4}-\d{2}-\d{2})(?:\.(\d+))?")


class Standing(Enum):
    """A recorded revision against this railsusp's (module docstring)."""

    THIS = "this"
    NONE = "none"
    OLDER = "older"
    NEWER = "newer"
    OTHER = "other"


def _key(text: object) -> tuple[str, int] | None:
    """(day, number) of a revision; None for anything else. Compared as such: as strings
    ``2026-11-30.10`` would sort before ``2026-11-30.9``."""
    found = _REVISION.fullmatch(text) if isinstance(text, str) else None
    return None if found is None else (found[1], int(found[2] or 0))


def this_revision() -> str:
    """This railsusp's force-law revision (:data:`railsusp.vehicle.MODEL_REVISION`), read
    when called: what a result made now is stamped with and compared against, so that
    the stamp and the comparison never disagree (a name imported once kept the revision
    of the import, the wording of :func:`made_with` the one of the call)."""
    return railsusp.vehicle.MODEL_REVISION


def standing(recorded: object, ours: str | None = None) -> Standing:
    """How the revision ``recorded`` (None: none recorded) stands to ``ours`` (default:
    this railsusp's, read when called)."""
    ours = this_revision() if ours is None else ours
    if recorded is None:
        return Standing.NONE
    if str(recorded) == ours:
        return Standing.THIS
    got, now = _key(recorded), _key(ours)
    if got is None or now is None:
        return Standing.OTHER
    return Standing.NEWER if got > now else Standing.OLDER


def revision_newer(recorded: object, than: str | None = None) -> bool:
    """Whether ``recorded`` is a later revision than ``than`` (default: this railsusp's):
    a result of a newer railsusp, which this one must not discard as outdated."""
    return standing(recorded, than) is Standing.NEWER


def made_with(recorded: object) -> str:
    """The revision ``recorded`` in the words every check uses, to follow "made with" or
    "simulated with": "force-law revision 2026-11-24.2, older than this railsusp's
    2026-11-30.2", "... newer than ...", "force-law revision '7', not this railsusp's ...",
    "..., this railsusp's", or for None "force laws older than any recorded force-law
    revision (it records none: ...)"."""
    ours = railsusp.vehicle.MODEL_REVISION
    s = standing(recorded)
    if s is Standing.NONE:
        return (
            f"force laws older than any recorded force-law revision (it records none: made before "
            f"revisions were recorded, on {FIRST_RECORDED}; this railsusp's is {ours})"
        )
    if s is Standing.THIS:
        return f"force-law revision {recorded}, this railsusp's"
    if s is Standing.OTHER:
        return f"force-law revision {recorded!r}, not this railsusp's {ours}"
    return f"force-law revision {recorded}, {s.value} than this railsusp's {ours}"


def newer_remedy(recorded: object) -> str:
    """What to do with a newer railsusp's result: use it there."""
    return f"use it with the railsusp that made it (force-law revision {recorded} or later)"


def mismatch(recorded: object, remedy: str) -> str | None:
    """None where ``recorded`` is this railsusp's revision; otherwise its standing in the
    words of :func:`made_with` and what to do: :func:`newer_remedy` for a newer railsusp's
    result (never made again here as outdated), ``remedy`` for any other."""
    s = standing(recorded)
    if s is Standing.THIS:
        return None
    return f"{made_with(recorded)}: {newer_remedy(recorded) if s is Standing.NEWER else remedy}"
