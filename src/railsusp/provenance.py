"""Provenance: which railsusp, and which libraries, made a result, on which host and when.

Every result a run directory holds records where it came from: railsusp's version, its git
commit and whether the source tree was modified (:func:`code_identity`), the versions of the
libraries that shape the numbers (:data:`RECORDED_LIBRARIES`), the host and the UTC time
(:func:`provenance`, :func:`utc_now`). Two results that differ can then be traced to the code
that made them. Writing the files that hold these records is :mod:`railsusp.store`'s job.
"""

from __future__ import annotations

import datetime as _dt
import platform
import socket
import subprocess
from functools import lru_cache
from pathlib import Path
from typing import Any


@lru_cache(maxsize=4)
def _is_checkout(here: str) -> bool:
    """Whether the package folder ``here`` is ``src/railsusp`` of a git checkout's top level
    (asked git once per folder: :func:`_git` runs for every provenance record)."""
    try:
        top = subprocess.run(
            ["git", "rev-parse", "--show-toplevel"],
            cwd=here, capture_output=True, text=True, timeout=5,
        )  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return False
    return top.returncode == 0 and (
        (Path(top.stdout.strip()) / "src" / "railsusp").resolve() == Path(here)
    )


def _git(*args: str) -> str | None:
    """A git command's output in the railsusp source tree; None where it is no checkout of
    railsusp: an installed package inside a repository of the user's (a project's
    ``.venv``) is no checkout, though git finds the repository around it (its commit was
    recorded as railsusp's, "clean": the packaging audit of stop 65). A checkout holds this
    package at ``src/railsusp`` of its top level (:func:`_is_checkout`)."""
    here = Path(__file__).resolve().parent
    if not _is_checkout(str(here)):
        return None
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
#: torch to ask its version would cost a second): scikit-learn's Gaussian-process metamodel
#: computes the Sobol indices of an LHS campaign, matplotlib draws every figure
RECORDED_LIBRARIES = (
    "numpy", "scipy", "numba", "pandas", "torch", "pymoo", "SALib", "scikit-learn",
    "matplotlib", "asammdf", "sbi",
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
