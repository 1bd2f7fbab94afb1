"""What every command module shares: the Typer ``app`` they register on, the consoles,
the table helper and the one-line error exit. Kept apart from the package ``__init__`` so
that the command modules import this module, not the package that imports them."""

from __future__ import annotations

import errno
import logging
import re
import sys
import warnings
from collections.abc import Callable, Mapping, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from railsusp.errors import OutputStreamError
from railsusp.interrupts import catch_interrupts

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="railsusp: suspension parameter estimation for heavy-haul freight wagons.",
)


class _StreamConsole(Console):
    """A rich Console whose failed writes raise :class:`OutputStreamError` naming its
    stream (a broken pipe is still rich's: the reader went away, a quiet exit 1)."""

    def _check_buffer(self) -> None:
        try:
            super()._check_buffer()
        except OutputStreamError:
            raise
        except OSError as exc:
            raise OutputStreamError("stderr" if self.stderr else "stdout", exc) from exc


def _is_terminal(stream: object) -> bool:
    """Whether ``stream`` is a terminal; a closed one (``>&-``: Python's ``sys.stdout`` is
    None) is not, and what it prints is dropped, as Python's ``print`` drops it."""
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty()) if isatty is not None else False
    except (OSError, ValueError):  # a stream closed under it
        return False


# Wide tables when piped (CI logs, files); the terminal's width otherwise. What goes to
# stderr is messages, each one line however long (soft wrap: the terminal folds it, a log
# or a grep sees one line): the interrupt line and others broke at 80 or 150 columns (the
# QA of stop 74).
console = _StreamConsole(width=None if _is_terminal(sys.stdout) else 150)
err_console = _StreamConsole(
    stderr=True, soft_wrap=True, width=None if _is_terminal(sys.stderr) else 150
)


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
    # each Ctrl-C recorded, so that one Python swallowed still stops a run at its next
    # stage; the previous handler back when the command ends (a test runner's process)
    _command_context().call_on_close(catch_interrupts())
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
    seen = exc
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO):
            return 1
        seen = seen.__cause__ or seen.__context__
    return 2


def _command_context():
    """The click context of the command running: typer's own click since typer 0.20
    (``typer._click``), click itself before (as ``railsusp.cli._click_exceptions``)."""
    try:
        from typer._click.globals import get_current_context
    except ImportError:  # pragma: no cover - older typer
        from click import get_current_context
    return get_current_context()


def given_options(*names: str) -> list[str]:
    """The options among ``names`` (parameter names) typed on the command line, as typed
    (``--epochs``, ``--no-record-correction``), read from click's parameter source: typer
    passes a default and a typed value alike, so comparing a value with its default would
    not tell a default typed again from an option left out."""
    ctx = _command_context()
    given = []
    for name in names:
        source = ctx.get_parameter_source(name)
        if source is None or source.name in ("DEFAULT", "DEFAULT_MAP"):
            continue
        option = "--" + name.replace("_", "-")
        if ctx.params.get(name) is False:  # a flag typed as its --no- form
            option = "--no-" + name.replace("_", "-")
        given.append(option)
    return given


def _command_words() -> str:
    """The command running as typed, ``railsusp posterior train`` (the program's own name
    left out: a test runner calls it otherwise)."""
    ctx, words = _command_context(), []
    while ctx is not None and ctx.parent is not None:
        words.append(ctx.info_name or "")
        ctx = ctx.parent
    return " ".join(["railsusp", *reversed(words)])


def _remove_if_bare(folder: Path, made: list[Path]) -> None:
    """Remove the folders a refused or failed command made for its lock alone (``made``,
    deepest first), where nothing but the lock file is in ``folder``: a refusal leaves no
    empty output folder behind. Called while the lock is still held."""
    from railsusp.run_lock import LOCK_NAME

    try:
        if [p.name for p in folder.iterdir()] != [LOCK_NAME]:
            return
        (folder / LOCK_NAME).unlink()
        for d in made:
            d.rmdir()
    except OSError:
        return


def hold_folders(
    *,
    creates: Sequence[tuple[str, Path]] = (),
    writes: Sequence[tuple[str, Path]] = (),
    reads: Sequence[tuple[str, Path]] = (),
    near: Sequence[tuple[str, Path]] = (),
) -> None:
    """Lock, until the command ends, the folders it works in (:func:`railsusp.run_lock
    .run_lock`), each given as (option, folder) for the refusal's wording:

    * ``creates``: output folders it writes, made where missing (and removed again when the
      command leaves nothing in them but the lock: a refused command leaves no folder);
    * ``writes``: existing folders it writes into (one that does not exist is not locked:
      the command refuses it itself);
    * ``reads``: folders whose results it reads, locked shared (readers run together, not
      beside a writer); skipped where missing or not writable (nothing writes there);
    * and the ``railsusp run`` directory any of these, or of ``near``, lies in, shared:
      ``railsusp run`` holds it exclusively while its stages work in its folders.

    Writers' locks are exclusive and lent to the library code the command runs (a campaign
    locks its own folder). A folder named twice is locked once, exclusively if written.
    Refused: :class:`~railsusp.errors.RailsuspInputError`, one line naming the holder. The
    locks go when the command's click context closes (its end, whatever the exit). Once
    they are held, the report of a run directory whose stages' recorded outputs the command
    is about to write gets a stale banner (:func:`~railsusp.cli.report_marks.
    mark_run_reports`), taken off again at that close where the command changed none of
    them."""
    from railsusp.cli.report_marks import mark_run_reports, unmark_unwritten
    from railsusp.input_checks import unmade_folder
    from railsusp.run_lock import enclosing_runs, hold_shared, run_lock

    plan: dict[Path, dict] = {}

    def add(option: str, folder: Path, mode: str, named: Path | None = None) -> None:
        key = folder.resolve()  # a folder and a link to it are one folder, locked once
        have = plan.get(key)
        if have is None:
            plan[key] = {"option": option, "folder": folder, "mode": mode, "named": named}
        elif mode != "read" and have["mode"] == "read":
            have.update(option=option, folder=folder, mode=mode, named=None)
        elif mode == "create":
            have["mode"] = "create"

    for option, folder in creates:
        add(option, Path(folder), "create")
    for option, folder in writes:
        add(option, Path(folder), "write")
    for option, folder in reads:
        add(option, Path(folder), "read")
    for option, folder in [*creates, *writes, *reads, *near]:
        for run in enclosing_runs(Path(folder)):
            add(option, run, "read", named=Path(folder))
    stack = _command_context().with_resource(ExitStack())
    # the run directories first: a command refused beside a working `railsusp run` makes
    # no folder inside it on the way
    for item in sorted(plan.values(), key=lambda item: item["named"] is None):
        folder, option = item["folder"], item["option"]
        if item["mode"] == "create":
            made = []
            probe = folder.absolute()
            while not probe.exists():
                made.append(probe)
                probe = probe.parent
            try:
                folder.mkdir(parents=True, exist_ok=True)
            except OSError as exc:  # /proc/foo: the system's "No such file or directory"
                raise unmade_folder(exc, folder, option) or exc from None
            stack.enter_context(run_lock(folder, option, lend=True))
            if made:
                stack.callback(_remove_if_bare, folder, made)
        elif item["mode"] == "write":
            if folder.is_dir():
                stack.enter_context(run_lock(folder, option, lend=True))
        elif folder.is_dir():  # (a read-only one read without it: nothing writes there)
            hold_shared(stack, folder, option, item["named"])
    # every lock held (a refused command marks nothing): the reports of the run directories
    # whose stages' outputs the command is about to write no longer stand as their answer;
    # put back when it ends having changed none of them (refused by its own checks)
    marked = mark_run_reports(
        [
            (item["folder"], item["mode"] == "create")
            for item in plan.values()
            if item["mode"] in ("create", "write")
        ],
        _command_words(),
        enclosing_runs,
    )
    if marked:  # entered last, so called first: while the locks are still held
        stack.callback(unmark_unwritten, marked)
