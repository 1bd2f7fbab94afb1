"""The ``railsusp`` console script's entry point (pyproject ``[project.scripts]``).

Loading the command line imports typer, rich and every command module, about half a second
in which Python's own SIGINT handling printed a Ctrl-C as a KeyboardInterrupt traceback of
the import (the command line's handler, :func:`railsusp.interrupts.catch_interrupts`, is
installed by the command once loaded). Here a Ctrl-C while it loads ends the command with
one line on stderr and status 130, as one while it runs does. ``import railsusp``, which
comes before this module, loads the standard library only (its public names load on first
use; NumPy and pydantic took 0.2 s of it before stop 76). Standard library only.
"""

from __future__ import annotations

import sys

#: said on a Ctrl-C before the command line was loaded: no command had started
INTERRUPTED_LOADING = "interrupted while loading the command line: nothing was started"


def main() -> None:
    """Load the command line and run it (:func:`railsusp.cli.main`)."""
    try:
        from railsusp.cli import main as run_command
    except KeyboardInterrupt:
        print(INTERRUPTED_LOADING, file=sys.stderr)
        raise SystemExit(130) from None
    run_command()
