"""The ``railsusp`` command line: thin wrappers over the library, rich tables for output.

Bad input (unknown parameter, out-of-range value, bad condition) prints one line on stderr
and exits with status 2, never a traceback. Commands live in the submodules by topic.
Global options: ``--version``, ``--quiet`` (no progress: the results, errors and warnings only) and
``--verbose`` (also the library's debug log: when each stage starts); a Python warning is
said once, as one line (``warning: ...``), not with its source line.
"""

from __future__ import annotations

import sys

from railsusp.cli.common import (
    OutputStreamError,
    app,
    console,
    err_console,
    fail,
    frame_table,
)
from railsusp.errors import RailsuspInputError

# the command modules register themselves on ``app``, in this order in the help
# isort: off
from railsusp.cli import inputs
from railsusp.cli import simulation
from railsusp.cli import modes
from railsusp.cli import campaigns
from railsusp.cli import analysis
from railsusp.cli import surrogates
from railsusp.cli import field
from railsusp.cli import estimation
from railsusp.cli import validation
from railsusp.cli import recordings
from railsusp.cli import pipeline
from railsusp.cli import posterior

# isort: on

#: one example per command, shown at the end of its --help
EXAMPLES = {
    "params": "railsusp params --set X13=16.1,X14=8.3",
    "conditions": "railsusp conditions my-conditions.toml",
    "track": "railsusp track --class 5 --plot track.png",
    "simulate": "railsusp simulate curve --set X13=16.1 --out f.parquet --plot f.png",
    "version": "railsusp version",
    "modes": "railsusp modes --speed 60 --decay",
    "campaign": "railsusp campaign --samples 256 --conditions straight,curve,uphill "
    "--out runs/lhs\n\n"
    "Many tracks: railsusp campaign --samples 512 --keys-from runs/lhs --independent-seeds "
    "--irregularity-classes 4:6 --radius 250:400 --cant 0:100 --vary-others --out runs/tracks",
    "sensitivity": "railsusp sensitivity runs/lhs",
    "train": "railsusp train runs/keys --model cnn-gru",
    "compare": "railsusp compare runs/keys",
    "synth-field": "railsusp synth-field --truth X13=16.1,X14=8.3 --with-track --out field/",
    "align-track": "railsusp align-track field/ --write",
    "estimate": "railsusp estimate --measured field/ --simulator --parameters X13,X14 --out est/",
    "validate": "railsusp validate est/ --truth field/truth.json",
    "check-recording": "railsusp check-recording field/curve.csv",
    "sections": "railsusp sections run.mf4 --map map.toml --write field/",
    "example-recording": "railsusp example-recording --out example/",
    "run": "railsusp run quick --out runs/quick",
    "demo": "railsusp demo",
}


def command_name(info) -> str:
    """The name a registered command is called by (Typer's rule: the function's name with
    dashes, unless given)."""
    return info.name or info.callback.__name__.replace("_", "-")


for _info in app.registered_commands:
    _example = EXAMPLES.get(command_name(_info))
    if _example and not _info.epilog:
        _info.epilog = f"Example: {_example}"

__all__ = [
    "analysis",
    "app",
    "campaigns",
    "console",
    "err_console",
    "estimation",
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
    "validation",
]


#: the line a Ctrl-C ends a command with
INTERRUPTED = (
    "interrupted: what was finished is kept (every file is saved whole); run the same "
    "command again to resume"
)


def main() -> None:
    """Console-script entry point. Click runs outside its standalone mode so that what it
    would print as a boxed usage error (an unknown option, ``--class 5.5``) or a traceback
    (an operating-system error: disk full, a folder not writable) is one line here, and the
    exit status is the command's."""
    import errno

    import typer
    from rich.markup import escape

    clicks = _click_exceptions()
    try:
        code = app(standalone_mode=False)
    except clicks.NoArgsIsHelpError as exc:  # a bare group: its help, as typer shows it
        exc.show()
        sys.exit(exc.exit_code)
    except clicks.ClickException as exc:  # a usage error: one line, not click's box
        ctx = getattr(exc, "ctx", None)
        where = f" (see {ctx.command_path} --help)" if ctx is not None else ""
        err_console.print(f"error: {escape(exc.format_message())}{where}", highlight=False)
        sys.exit(exc.exit_code)
    except typer.Abort:  # end of input at a prompt
        err_console.print("aborted")
        sys.exit(1)
    except RailsuspInputError as exc:  # pragma: no cover - commands catch their own
        err_console.print(f"error: {escape(str(exc))}", highlight=False)
        sys.exit(2)
    except OutputStreamError as exc:  # the printout refused (> /dev/full), not the files
        _stream_failed(exc)
    except OSError as exc:  # what the machine refused: one line, not a traceback
        where = f"{exc.filename}: " if exc.filename else ""
        # a full disk or quota: the remedy too (what is written is written atomically, what
        # is stored is kept, so the same command resumes: the disk audit of stop 65)
        remedy = (
            "; free space and run the same command again"
            if exc.errno in (errno.ENOSPC, errno.EDQUOT)
            else ""
        )
        err_console.print(
            f"error: {escape(where + (exc.strerror or str(exc)) + remedy)}", highlight=False
        )
        sys.exit(1 if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO) else 2)
    except SystemExit as exc:  # a command that exits itself: as Python would
        if exc.code == 130 and not getattr(exc, "said", False):  # (estimate says its own)
            err_console.print(INTERRUPTED)
        raise
    if code == 130:  # typer turns a Ctrl-C into a silent exit 130
        err_console.print(INTERRUPTED)
    sys.exit(code if isinstance(code, int) else 0)


def _stream_failed(exc: OutputStreamError) -> None:
    """Exit 1 on a write to stdout or stderr that the system refused: one line saying that
    the stream, not the disk of the run's files, failed (a full ``> /dev/full`` said "free
    space and run the same command again"), on stderr where that is not the one failing.
    The stream is pointed at the null device so that Python's last flush at exit does not
    fail again with a traceback-like "Exception ignored" message."""
    import errno
    import os
    import stat

    stream = getattr(sys, exc.stream, None)
    try:  # a file on a disk, which may be the run's (not a device such as /dev/full)
        on_disk = stat.S_ISREG(os.fstat(stream.fileno()).st_mode)
    except (AttributeError, OSError, ValueError):
        on_disk = False
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())
    except (AttributeError, OSError, ValueError):  # no descriptor (a test runner's buffer)
        pass
    try:
        full = on_disk and exc.errno in (errno.ENOSPC, errno.EDQUOT)
        err_console.print(
            f"error: {exc.stream}: {exc.strerror or exc}: the printed output could not be "
            "written (the files the command wrote are whole and kept"
            + (
                "; if they share that disk, free space and run the same command again)"
                if full
                else ")"
            ),
            markup=False,
            highlight=False,
        )
    except OSError:  # stderr refused too: the exit status alone says it
        pass
    sys.exit(1)


def _click_exceptions():
    """The exception module of the click that typer runs: its own copy since typer 0.20
    (``typer._click``), click itself before."""
    try:
        from typer._click import exceptions
    except ImportError:  # pragma: no cover - older typer
        from click import exceptions
    return exceptions
