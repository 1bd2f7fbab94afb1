"""What every command module shares: the Typer ``app`` they register on, the consoles,
the table helper and the one-line error exit. Kept apart from the package ``__init__`` so
that the command modules import this module, not the package that imports them."""

from __future__ import annotations

import sys

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
    err_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(2)
