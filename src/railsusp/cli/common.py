"""What every command module shares: the Typer ``app`` they register on, the consoles,
the table helper and the one-line error exit. Kept apart from the package ``__init__`` so
that the command modules import this module, not the package that imports them."""

from __future__ import annotations

import logging
import re
import sys
import warnings
from collections.abc import Callable, Mapping
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="railsusp: suspension parameter estimation for heavy-haul freight wagons.",
)
# Wide tables when piped (CI logs, files); the terminal's width otherwise.
console = Console(width=None if sys.stdout.isatty() else 150)
err_console = Console(stderr=True, width=None if sys.stderr.isatty() else 150)


#: ``--wagon`` of the commands that simulate a wagon: a wagon file or a packaged name
WagonOption = Annotated[
    str | None,
    typer.Option(help="wagon data TOML, or a packaged name: loaded (default), tare"),
]


#: "quiet", "normal" or "verbose": set by the global options, read by the commands
verbosity = "normal"
_said: set[str] = set()


def is_quiet() -> bool:
    """True under the global ``--quiet`` option."""
    return verbosity == "quiet"


def show_progress() -> bool:
    """Whether progress bars are drawn: on a terminal and not under ``--quiet``. Written to a
    file or a pipe, rich prints each bar's last state when it stops, which put a line such
    as "stages 0/7" before the one-line error that stopped it."""
    return not is_quiet() and err_console.is_terminal


def _say_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Python's warnings as one readable line each, once per message."""
    text = " ".join(str(message).split())
    if text in _said:
        return
    _said.add(text)
    kind = "" if category in (UserWarning, RuntimeWarning) else f" ({category.__name__})"
    err_console.print(f"warning: {text}{kind}", markup=False, highlight=False, soft_wrap=True)


class _ConsoleLog(logging.Handler):
    """The library's log (stage starts and finishes) as plain lines on stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        err_console.print(record.getMessage(), markup=False, highlight=False, soft_wrap=True)


_handler = _ConsoleLog()


def _version(value: bool) -> None:
    if value:
        from railsusp._version import __version__

        console.print(f"railsusp {__version__}", markup=False, highlight=False)
        raise typer.Exit()


@app.callback()
def _global(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="print the version and exit"
        ),
    ] = False,
    quiet: Annotated[
        bool,
        typer.Option("--quiet", "-q", help="no progress: the results, errors and warnings only"),
    ] = False,
    verbose: Annotated[
        bool,
        typer.Option("--verbose", "-v", help="also when each stage starts, each training epoch"),
    ] = False,
) -> None:
    """railsusp: suspension parameter estimation for heavy-haul freight wagons."""
    global verbosity
    if quiet and verbose:
        fail("--quiet and --verbose: accepted one of them, not both")
    verbosity = "quiet" if quiet else "verbose" if verbose else "normal"
    warnings.showwarning = _say_warning
    warnings.simplefilter("default")
    logger = logging.getLogger("railsusp")
    if _handler not in logger.handlers:
        logger.addHandler(_handler)
    logger.setLevel(logging.WARNING if quiet else logging.DEBUG if verbose else logging.INFO)
    logger.propagate = False


def frame_table(df, title: str, fmt: str | Callable[[float], str] = "{:.4g}") -> Table:
    """A pandas DataFrame as a rich table: numbers right-aligned, NaN/None blank; text
    columns (names of conditions, models) keep their width when the terminal is narrow.
    ``fmt``: a format string for the floats, or a function (the report's ``sig3``)."""
    if isinstance(fmt, str):
        fmt = fmt.format
    table = Table(title=title, title_justify="left")
    for col in df.columns:
        text = df[col].dtype == object
        width = max((len(str(v)) for v in df[col]), default=0) if text else None
        table.add_column(str(col), justify="right", min_width=width, no_wrap=text)
    for row in df.itertuples(index=False):
        table.add_row(
            *(
                ""
                if v is None or (isinstance(v, float) and v != v)
                else fmt(v)
                if isinstance(v, float)
                else str(v)
                for v in row
            )
        )
    return table


def fail(message: str, code: int = 2, options: Mapping[str, str] | None = None) -> None:
    """Print a one-line error and exit with status ``code`` (2: bad input); ``options``
    (setting -> option) names the options the user typed in place of the settings the
    library's checks name (:func:`option_names`)."""
    if options:
        message = option_names(message, options)
    err_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code)


def option_names(message: str, options: Mapping[str, str]) -> str:
    """``message`` with each setting of ``options`` that it names as ``setting = value``
    (anywhere) or ``setting value`` (at its start) given as the command-line option
    (``speed_tolerance = 1.5: accepted 0 to 1`` -> ``--speed-tolerance 1.5: ...``)."""
    for setting, option in options.items():
        name = re.escape(setting)
        message = re.sub(rf"(?<![\w-]){name} = ", f"{option} ", message)
        message = re.sub(rf"^{name} ", f"{option} ", message)
    return message


def exit_code(exc: BaseException) -> int:
    """2 for bad input; 1 where what failed underneath was the machine (a full disk, a
    quota, an I/O error: a stage's error wraps it), as for an OSError the command meets
    itself (:func:`railsusp.cli.main`)."""
    import errno

    seen = exc
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO):
            return 1
        seen = seen.__cause__ or seen.__context__
    return 2
