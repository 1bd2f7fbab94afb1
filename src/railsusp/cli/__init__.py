"""The ``railsusp`` command line: thin wrappers over the library, rich tables for output.

Bad input (unknown parameter, out-of-range value, bad condition) prints one line on stderr
and exits with status 2, never a traceback. Commands live in the submodules by topic.
"""

from __future__ import annotations

import sys

import typer
from rich.console import Console
from rich.table import Table

from railsusp.errors import RailsuspInputError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="railsusp: suspension parameter estimation for heavy-haul freight wagons.",
)
# Wide tables when piped (CI logs, files); the terminal's width otherwise.
console = Console(width=None if sys.stdout.isatty() else 150)
err_console = Console(stderr=True, width=None if sys.stderr.isatty() else 150)


def frame_table(df, title: str, fmt: str = "{:.4g}") -> Table:
    """A pandas DataFrame as a rich table: numbers right-aligned, NaN/None blank; text
    columns (names of conditions, models) keep their width when the terminal is narrow."""
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
                else fmt.format(v)
                if isinstance(v, float)
                else str(v)
                for v in row
            )
        )
    return table


def fail(message: str) -> None:
    """Print a one-line error and exit with status 2."""
    err_console.print(f"[bold red]error:[/] {message}", highlight=False, soft_wrap=True)
    raise typer.Exit(2)


# the command modules register themselves on ``app``, in this order in the help
# isort: off
from railsusp.cli import inputs  # noqa: E402
from railsusp.cli import simulation  # noqa: E402
from railsusp.cli import analysis  # noqa: E402
from railsusp.cli import surrogates  # noqa: E402
from railsusp.cli import field  # noqa: E402
from railsusp.cli import recordings  # noqa: E402
from railsusp.cli import pipeline  # noqa: E402

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
    "pipeline",
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
