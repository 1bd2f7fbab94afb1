"""Commands for measured recordings: synthesise field data, check a recording."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table

from railsusp.cli import app, console, fail
from railsusp.conditions import resolve_conditions
from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet, parse_overrides


@app.command("synth-field")
def synth_field(
    out: Annotated[Path, typer.Option(help="field folder to write")],
    truth: Annotated[str, typer.Option(help="hidden true parameters, e.g. X13=16.1,X14=8.3")] = "",
    conditions: Annotated[str, typer.Option(help="names or a TOML file")] = (
        "straight,curve,uphill"
    ),
    seed: Annotated[int, typer.Option(help="noise seed")] = 7,
    noise: Annotated[float, typer.Option(help="white noise, fraction of the channel RMS")] = 0.03,
    fmt: Annotated[str, typer.Option("--format", help="csv or parquet")] = "csv",
) -> None:
    """Synthetic instrumented-wheelset recordings of hidden true parameters (truth.json)."""
    from railsusp.measured import synthesise_field

    try:
        if not 0.0 <= noise <= 0.5:
            raise RailsuspInputError(f"--noise {noise:g} outside the accepted range [0, 0.5]")
        if fmt not in ("csv", "parquet"):
            raise RailsuspInputError(f"--format {fmt!r}: accepted csv or parquet")
        pset = ParameterSet(parse_overrides(truth) if truth else {}, units="display")
        conds = resolve_conditions(conditions)
        with console.status("simulating the hidden truth"):
            synthesise_field(pset, conds, out, seed=seed, noise=noise, fmt=fmt)
    except RailsuspInputError as exc:
        fail(str(exc))
    console.print(
        f"wrote {len(conds)} recording(s) to {out} (index.json); the truth is in "
        f"{out / 'truth.json'}, which the estimator never reads"
    )


@app.command("check-recording")
def check_recording(
    path: Annotated[Path, typer.Argument(help="recording table (.csv / .parquet) or stem")],
    min_rate: Annotated[float, typer.Option(help="lowest usable sampling rate, Hz")] = 50.0,
) -> None:
    """Validate a measured recording and summarise it (every problem is listed at once)."""
    from railsusp.measured import RecordingError, read_recording

    try:
        rec = read_recording(path, min_rate_hz=min_rate)
    except RecordingError as exc:
        for p in exc.problems:
            console.print(f"  - {p}", highlight=False)
        fail(f"{exc.path}: {len(exc.problems)} problem(s), listed above")
    except RailsuspInputError as exc:
        fail(str(exc))
    table = Table(
        title=f"{path}: {rec.condition.name}, {rec.sampling_rate:.1f} Hz, "
        f"{rec.time[-1] - rec.time[0]:.1f} s",
        title_justify="left",
    )
    for col in ("wheel", "Y mean kN", "Y max kN", "Q mean kN", "Q max kN"):
        table.add_column(col, justify="right")
    for w in rec.wheels:
        table.add_row(
            w,
            f"{np.mean(np.abs(rec.Y[w])):.2f}",
            f"{np.max(np.abs(rec.Y[w])):.2f}",
            f"{np.mean(rec.Q[w]):.2f}",
            f"{np.max(rec.Q[w]):.2f}",
        )
    console.print(table)
