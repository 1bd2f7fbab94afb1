"""The one-command pipeline: ``railsusp run CONFIG.toml`` and ``railsusp demo``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import pandas as pd
import typer
from rich.table import Table
from rich.text import Text

from railsusp.cli.common import (
    app,
    console,
    err_console,
    exit_code,
    fail,
    frame_table,
    show_progress,
)
from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_output_folder


def _run(
    config,
    out: Path,
    start_from: str | None,
    *,
    checked: bool = False,
    source: str = "configuration",
) -> list:
    """Run the pipeline with progress bars; returns its summary (:func:`_summary_parts`), read
    while the run directory's lock is still held: read after it, a second run finishing
    in between made one command's printout mix two runs' tables (the concurrency audit).
    ``source``: the configuration's file, named in its errors."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from railsusp.pipeline import STAGES, run_pipeline

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=err_console,
        disable=not show_progress(),
    ) as bar:
        stages = bar.add_task("stages", total=len(STAGES))
        runs = bar.add_task("campaign simulations", total=None, visible=False)

        def on_stage(stage: str, message: str) -> None:
            done = STAGES.index(stage) + (1 if message == "up to date" else 0)
            bar.update(stages, completed=done, description=f"stage {stage}: {message}")

        def on_runs(done: int, total: int) -> None:
            bar.update(runs, completed=done, total=total, visible=True)

        parts: list = []
        run_pipeline(
            config,
            out,
            start_from=start_from,
            progress=on_stage,
            run_progress=on_runs,
            checked=checked,
            finished=lambda _state: parts.extend(_summary_parts(out)),
            source=source,
        )
        bar.update(stages, completed=len(STAGES), description="stages: done")
    return parts


def _summary_parts(out: Path) -> list:
    """The tables and lines ``railsusp run`` prints of the run directory ``out``, read from
    it (under its lock: :func:`_run`), printed by :func:`_summary`."""
    import railsusp.summary as summary
    from railsusp.report_doc import fraction_errors_to_pct, header

    parts: list = []

    def show(csv: Path, title: str, cols: list[str] | None = None) -> None:
        """A run-directory table as the report shows it: readable headers, errors in %,
        numbers in the report's format (NSGA-II's 15031 kN/m on its bound read "1.5e+04"
        in {:.3g}), yes/no for the booleans (they read True/False) and each validation
        row's statistic labelled with what its kN columns hold (:func:`_labelled`)."""
        if not csv.exists():
            return
        df = _labelled(fraction_errors_to_pct(pd.read_csv(csv)))
        df = df[cols] if cols else df
        if "verdict" in df and "identifiable" in df:  # the recovery table's older column
            df = df.drop(columns="identifiable")
        df = df.apply(lambda col: col.map(_yes_no) if _has_bools(col) else col)
        parts.append(frame_table(df.rename(columns=header), title, fmt=summary.sig3))

    if (out / "estimate" / "validation" / "validation.csv").exists():  # the answer first
        est = summary.estimate_table(out).reset_index()
        cols = ["parameter", "unit", "nominal", "estimate", "low", "high", "change_pct"]
        answer = est[[*cols, "verdict", "note"]].rename(columns=header)
        parts.append(  # the report's number format: 29954 kN/m as 29954, not 3e+04
            frame_table(answer, "Answer (report.html, docs/api.md)", fmt=summary.sig3)
        )
        parts += [Text(line) for line in summary.agreement_lines(summary.force_agreement(out))]
    show(out / "estimate" / "estimate.csv", "Estimate (study Table 5 layout)")
    show(
        out / "estimate" / "validation" / "validation.csv",
        "Validation: force statistic before / after calibration (study Tables 8 and 9)",
        None,
    )
    if _has_aligned(out / "estimate" / "validation" / "validation.csv"):
        from railsusp.report_estimate import ALIGNED_NOTE

        parts.append(Text(ALIGNED_NOTE))
    show(out / "estimate" / "validation" / "recovery.csv", "Recovery of the hidden truth")
    timings = Table(title="Stage timings", title_justify="left")
    from railsusp.pipeline_state import read_run_state

    state = read_run_state(out, str(out))  # its structure checked: one line if damaged
    for c in ("stage", "seconds", "state"):
        timings.add_column(c)
    from railsusp.pipeline import STAGES

    for s in STAGES:
        v = state["stages"].get(s, {})
        timings.add_row(s, f"{v.get('seconds', 0.0):.1f}", v.get("state", ""))
    parts.append(timings)
    parts.append(Text(f"report: {out / 'report.html'} (Markdown twin: {out / 'report.md'})"))
    return parts


def _labelled(df: pd.DataFrame) -> pd.DataFrame:
    """A validation table's ``statistic`` saying what the row's kN columns hold, as the
    report labels it (``mean of |Y|``, ``mean of Q``); a time-aligned row's ``aligned*``,
    told by :data:`~railsusp.report_estimate.ALIGNED_NOTE` under the table (the report's
    label, a sentence, wrapped over six lines in the terminal's column). Other tables as
    they are."""
    if not {"statistic", "force"} <= set(df.columns):
        return df
    from railsusp.report_estimate import statistic_label

    df = df.copy()
    df["statistic"] = [
        "aligned*" if s == "aligned" else statistic_label(str(s), str(f))
        for s, f in zip(df.statistic, df.force, strict=True)
    ]
    return df


def _has_aligned(csv: Path) -> bool:
    """Whether the validation table ``csv`` has time-aligned rows."""
    if not csv.exists():
        return False
    df = pd.read_csv(csv)
    return "statistic" in df.columns and bool((df.statistic == "aligned").any())


def _summary(out: Path, parts: list | None = None) -> None:
    """The run directory's summary on stdout (text as it is: no markup read): ``parts``,
    read by :func:`_summary_parts` under the run's lock, or read now where None."""
    for part in _summary_parts(out) if parts is None else parts:
        console.print(part)


def _has_bools(col: pd.Series) -> bool:
    """Whether a table's column holds booleans (a bool column, or one with blanks)."""
    return col.dtype == bool or any(isinstance(v, bool | np.bool_) for v in col)


def _yes_no(v: object) -> object:
    """A boolean as the report's table cell words, yes or no; anything else as it is."""
    return ("yes" if v else "no") if isinstance(v, bool | np.bool_) else v


@app.command()
def run(
    config: Annotated[
        Path,
        typer.Argument(
            help="pipeline TOML, or a packaged example's name: quick, pretrained, study, tiny "
            "(the repository's examples/)"
        ),
    ],
    out: Annotated[Path | None, typer.Option(help="run directory (default: runs/<stem>)")] = None,
    start_from: Annotated[
        str | None, typer.Option("--from", help="force a restart from this stage")
    ] = None,
) -> None:
    """The whole method: campaign, sensitivity, surrogates, field data, estimation,
    validation, report; up-to-date stages are skipped."""
    from railsusp.pipeline_config import config_path, load_config

    try:
        cfg = load_config(config)
        target = check_output_folder(out or Path("runs") / config.stem)
        parts = _run(cfg, target, start_from, checked=True, source=str(config_path(config)))
    except RailsuspInputError as exc:
        fail(str(exc), exit_code(exc))
    _summary(target, parts)


@app.command()
def demo(
    out: Annotated[Path, typer.Option(help="run directory")] = Path("runs/demo"),
) -> None:
    """The main job on the embedded default (examples/quick.toml): a degraded C80 wagon's
    synthetic recordings, calibrated end to end, with an HTML report (a few minutes)."""
    from railsusp.pipeline_config import demo_config

    console.rule("railsusp demo: C80 wagon on K6 bogies, hidden degraded parameters")
    try:
        parts = _run(demo_config(), check_output_folder(out), None)
    except RailsuspInputError as exc:
        fail(str(exc), exit_code(exc))
    _summary(out, parts)
