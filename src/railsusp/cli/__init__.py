"""The ``railsusp`` command line: thin wrappers over the library, rich tables for output.

Bad input (unknown parameter, out-of-range value, bad condition) prints one line on stderr
and exits with status 2, never a traceback. Commands live in the submodules by topic.
Global options: ``--version``, ``--quiet`` (errors and warnings only, no progress) and
``--verbose`` (also the library's debug log: when each stage starts); a Python warning is
said once, as one line (``warning: ...``), not with its source line.
"""

from __future__ import annotations

import sys

from railsusp.cli.common import app, console, err_console, fail, frame_table
from railsusp.errors import RailsuspInputError

# the command modules register themselves on ``app``, in this order in the help
# isort: off
from railsusp.cli import inputs
from railsusp.cli import simulation
from railsusp.cli import modes
from railsusp.cli import analysis
from railsusp.cli import surrogates
from railsusp.cli import field
from railsusp.cli import recordings
from railsusp.cli import pipeline
from railsusp.cli import posterior

# isort: on

__all__ = [
    "analysis",
    "app",
    "console",
    "err_console",
    "fail",
    "field",
    "frame_table",
    "inputs",
    "main",
    "modes",
    "pipeline",
    "posterior",
    "recordings",
    "simulation",
    "surrogates",
]


def main() -> None:
    """Console-script entry point."""
    try:
        app()
    except RailsuspInputError as exc:  # pragma: no cover - commands catch their own
        err_console.print(f"error: {exc}")
        sys.exit(2)
