"""Commands that run the simulator: simulate, demo."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from railsusp._version import __version__
from railsusp.cli.common import (
    WagonOption,
    app,
    console,
    err_console,
    fail,
    option_names,
    show_progress,
)
from railsusp.cli.inputs import check_seed
from railsusp.condition_files import resolve_conditions
from railsusp.errors import RailsuspInputError, repeated_names
from railsusp.input_checks import check_figure_file, check_output_file
from railsusp.params import ParameterSet, parse_overrides
from railsusp.study import TABLE8_BEFORE


def _force_table(results: list, title: str, wheel: str = "auto", study: bool = True) -> Table:
    """Force statistics of the measured ``wheel`` (auto: the leading wheelset's, outer in
    curves) per condition beside the study's Table 8 where ``study`` (the study's wagon:
    its loaded C80's figures are no reference for another wagon)."""
    table = Table(title=title, title_justify="left")
    for col in (
        "condition",
        "wheel",
        "Y mean",
        "Y RMS",
        "Y p99",
        "Y max",
        "study Y",
        "Q mean",
        "Q p99",
        "Q max",
        "study Q",
        "Y/Q max",
        "dQ/Q max",
        "status",
    ):
        table.add_column(
            col, justify="left" if col in ("condition", "wheel", "status") else "right"
        )
    from railsusp.vehicle.simulation_result import WHEEL_NAMES

    for r in results:
        with warnings.catch_warnings():  # a failed set: its status column says so
            warnings.simplefilter("ignore", RuntimeWarning)
            s = r.statistics(wheel)
        study_wheel = r.measured_wheel(wheel) == r.measured_wheel()  # Table 8's wheel
        ref = TABLE8_BEFORE.get(r.condition.name) if study_wheel and study else None
        status = "ok" if r.ok[0] else r.failures()[0][1]
        table.add_row(
            r.condition.name,
            WHEEL_NAMES[r.measured_wheel(wheel)],
            *(number(s[k], 1) for k in ("Y_mean", "Y_rms", "Y_p99", "Y_max")),
            number(ref[0], 1) if ref else "-",
            *(number(s[k], 1) for k in ("Q_mean", "Q_p99", "Q_max")),
            number(ref[2], 1) if ref else "-",
            number(s["YQ_max"], 2),
            number(s["dQQ_max"], 2),
            status,
        )
    return table


def number(value: float, decimals: int) -> str:
    """A table cell: fixed decimals for ordinary magnitudes, scientific notation beyond 1e6
    (a diverged run's 1e300 kN is not printed as a 300-digit number), blank-free NaN."""
    v = float(value)
    if v != v:
        return "nan"
    if abs(v) >= 1e6:
        return f"{v:.3e}"
    return f"{v:.{decimals}f}"


@app.command()
def simulate(
    condition: Annotated[
        str,
        typer.Argument(
            help="standard condition names, comma-separated (straight,curve), or a TOML file"
        ),
    ],
    set_: Annotated[
        list[str] | None,
        typer.Option(
            "--set", help="parameter overrides, e.g. --set X13=16.1,X14=8.3 (display units)"
        ),
    ] = None,
    file: Annotated[
        Path | None,
        typer.Option("--file", help="TOML file with a \\[parameters] table (display units)"),
    ] = None,
    seed: Annotated[
        int | None, typer.Option(help="irregularity seed, 0 or more (default: condition's)")
    ] = None,
    wheel: Annotated[
        str,
        typer.Option(help="measured wheel: auto (leading wheelset, outer in curves) or w1L..w4R"),
    ] = "auto",
    wagon: WagonOption = None,
    out: Annotated[Path | None, typer.Option(help="write the force series to Parquet")] = None,
    plot: Annotated[Path | None, typer.Option(help="write a PNG of the force series")] = None,
) -> None:
    """Simulate one parameter set in one or more working conditions; print force statistics."""
    from railsusp.measured.field_folder import check_not_recordings
    from railsusp.vehicle.simulate import simulate as run_one
    from railsusp.vehicle.simulation_result import WHEEL_NAMES
    from railsusp.vehicle.wagon import load_wagon

    try:
        pset = ParameterSet.from_toml(file) if file else ParameterSet.nominal()
        if set_:
            pset = pset.replace(parse_overrides(set_), units="display")
        conds = resolve_conditions(condition)
        if seed is not None:
            check_seed(seed)
            try:
                conds = [c.with_changes(seed=seed) for c in conds]
            except RailsuspInputError as exc:  # too large: named as the option typed
                raise RailsuspInputError(option_names(str(exc), {"seed": "--seed"})) from None
        if out is not None:
            check_output_file(out, "--out")
            check_not_recordings(out)
            if out.suffix.lower() != ".parquet":  # the series are written as Parquet
                raise RailsuspInputError(f"--out {out}: accepted a .parquet file")
        if plot is not None:
            check_figure_file(plot, "--plot")
        twice = repeated_names([c.name for c in conds])  # "A" and "a": one file on Windows
        if twice and (out is not None or plot is not None):  # one file per condition name
            raise RailsuspInputError(
                f"conditions: {', '.join(twice)} named more than once, and --out and --plot "
                "write one file per condition name; accepted distinct names"
            )
        wagon_data = load_wagon(wagon)  # a packaged name or a file, one-line errors
        if wheel != "auto" and wheel not in WHEEL_NAMES:
            raise RailsuspInputError(
                f"--wheel {wheel!r} unknown; accepted auto or {', '.join(WHEEL_NAMES)}"
            )
        results = []
        with _progress() as bar:
            task = bar.add_task("simulating", total=len(conds))
            for c in conds:
                results.append(run_one(pset, c, wagon=wagon_data))
                bar.advance(task)
    except RailsuspInputError as exc:
        fail(str(exc))
    study = wagon_data == load_wagon()  # the study's figures are of the loaded C80
    console.print(_force_table(results, f"Wheel-rail forces (kN), {wagon_data.name}", wheel, study))
    for r in results:
        if not r.ok[0]:  # a run that stopped: no file of NaN series (said below)
            continue
        tag = f"-{r.condition.name}" if len(results) > 1 else ""
        if out is not None:
            path = out.with_name(f"{out.stem}{tag}{out.suffix}")
            console.print(f"wrote {r.to_parquet(path)}")
        if plot is not None:
            from railsusp.report import plot_forces

            path = plot.with_name(f"{plot.stem}{tag}{plot.suffix}")
            console.print(f"wrote {plot_forces(r, path, wheel=wheel)}")
    failed = [r for r in results if not r.ok[0]]
    if failed:
        err_console.print(
            f"{len(failed)} of {len(results)} runs failed: "
            + ", ".join(f"{r.condition.name} ({r.failures()[0][1]})" for r in failed)
            + ("; no file written for them" if out is not None or plot is not None else ""),
            style="bold red",
            markup=False,
            highlight=False,
        )
        raise typer.Exit(1)


def _progress():
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=err_console,
        transient=True,
        disable=not show_progress(),
    )


@app.command()
def version() -> None:
    """Print the railsusp version (as ``railsusp --version`` does)."""
    console.print(f"railsusp {__version__}")
