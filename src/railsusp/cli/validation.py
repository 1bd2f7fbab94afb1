"""The ``validate`` command: the wagon simulated again with nominal and estimated
parameters beside the recordings (Tables 8/9 of the study) and, with a truth, the recovery."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from railsusp.cli.common import WagonOption, app, console, fail, hold_folders
from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_replaced_folder


@app.command()
def validate(
    estimate_dir: Annotated[Path, typer.Argument(help="folder written by railsusp estimate")],
    measured: Annotated[
        Path | None, typer.Option(help="recordings folder (default: the one the estimate used)")
    ] = None,
    truth: Annotated[
        Path | None,
        typer.Option(help="truth.json of synthetic recordings, to score parameter recovery"),
    ] = None,
    sensitivity: Annotated[
        Path | None,
        typer.Option(help="RUN/sensitivity of the campaign, to flag parameters with low Sobol ST"),
    ] = None,
    out: Annotated[Path | None, typer.Option(help="default: ESTIMATE_DIR/validation")] = None,
    wagon: WagonOption = None,
) -> None:
    """Re-simulate with nominal and estimated parameters; Tables 8/9 and recovery scores."""
    from railsusp.key_parameters import check_sensitivity_output
    from railsusp.measured.field_folder import check_not_recordings
    from railsusp.validate import validate as run_validate

    try:
        # the output folder, before the simulations, not after them: --out, or by default
        # ESTIMATE_DIR/validation (unchecked, a folder there that could not be replaced or
        # an estimate's folder that could not be written failed after the simulations)
        if out is not None:
            check_not_recordings(out)
            own = ("validation.json", "estimate.json")  # validate --out EST: beside it
            check_replaced_folder(out, "--out", "validate", own=own)
        else:
            check_replaced_folder(
                estimate_dir / "validation", "--out (default)", "validate", own=("validation.json",)
            )
        if truth is not None:  # before the simulations, not after them
            from railsusp.measured import read_truth

            if not truth.is_file():
                raise RailsuspInputError(f"--truth {truth}: no such file; accepted a truth.json")
            read_truth(truth, "--truth")
        readable = (sensitivity / "key_parameters.json", sensitivity) if sensitivity else ()
        if sensitivity is not None and not any(p.is_file() for p in readable):
            raise RailsuspInputError(
                f"--sensitivity {sensitivity}: no Sobol indices there; accepted a campaign's "
                "RUN/sensitivity folder, its key_parameters.json or indices.parquet"
            )
    except (RailsuspInputError, ValueError, FileNotFoundError, KeyError) as exc:
        fail(f"{estimate_dir}: {exc}")
    try:
        # the estimate (or --out) for the command's duration, and what it reads shared: the
        # recordings' folder (a synth-field rewrote it under a running validation: the
        # concurrency audit) and the campaign whose sensitivity is read; then that analysis
        # checked to be of that campaign
        hold_folders(
            creates=[("--out", out)] if out is not None else [],
            writes=[("", estimate_dir)] if out is None else [],
            reads=([("", estimate_dir)] if out is not None else [])
            + ([("--measured", measured)] if measured is not None else [])
            + [("--sensitivity", c) for c in [_campaign_of(sensitivity)] if c is not None],
        )
        if measured is None:  # the estimate's own, read under its lock: the one validated
            hold_folders(reads=[("", f) for f in [_measured_of(estimate_dir)] if f is not None])
        if sensitivity is not None:
            check_sensitivity_output(sensitivity)
    except RailsuspInputError as exc:
        fail(str(exc))
    try:
        with console.status("re-simulating the measured conditions"):
            res = run_validate(
                estimate_dir, measured=measured, truth=truth, sensitivity=sensitivity, wagon=wagon
            )
        res.save(out or estimate_dir / "validation")  # a link: written where it points
    except (RailsuspInputError, ValueError, FileNotFoundError, KeyError) as exc:
        fail(f"{estimate_dir}: {exc}")
    f = res.forces
    has_truth = "truth_kN" in f
    table = Table(
        title="Simulated vs measured force statistic, before (Table 8) and after "
        "(Table 9) calibration",
        title_justify="left",
    )
    from railsusp.report_estimate import ALIGNED_NOTE, statistic_label

    cols = ["condition", "statistic", "measured", "before", "error", "after", "error"]
    if has_truth:
        cols += ["truth sim.", "noise floor"]
    for c in cols:
        table.add_column(c, justify="left" if c in ("condition", "statistic") else "right")
    for r in f.itertuples(index=False):
        cells = [  # what the kN columns hold, as the report and `railsusp run` say it: a
            # mean of |Y| was "Y mean" (the QA of stop 73: check-recording's signed mean
            # of Y differs)
            r.condition,
            f"{r.force} aligned*"
            if r.statistic == "aligned"
            else statistic_label(str(r.statistic), str(r.force)),
            f"{r.measured_kN:.2f}",
            f"{r.before_kN:.2f}",
            f"{100 * r.before_error:.2f} %",
            f"{r.after_kN:.2f}",
            f"{100 * r.after_error:.2f} %",
        ]
        if has_truth:
            cells += [f"{r.truth_kN:.2f}", f"{100 * r.truth_error:.2f} %"]
        table.add_row(*cells)
    console.print(table)
    if (f.statistic == "aligned").any():
        console.print(ALIGNED_NOTE, highlight=False, markup=False)
    for line in res.failures:
        console.print(f"[yellow]simulation stopped, its rows are NaN: {line}[/yellow]")
    if res.recovery is not None:
        rec = Table(title="Parameter recovery against the hidden truth", title_justify="left")
        for c in (
            "parameter",
            "unit",
            "truth",
            "estimate",
            "error % value",
            "error % range",
            "verdict",
            "why not identified",
        ):
            rec.add_column(c)
        for r in res.recovery.itertuples(index=False):
            rec.add_row(
                r.parameter,
                r.unit,
                f"{r.truth:.4g}",
                f"{r.estimate:.4g}",
                f"{r.error_pct_of_value:.1f}",
                f"{r.error_pct_of_range:.1f}",
                r.verdict,  # the summary card's three (it said "identified: no" for each)
                r.why_not,
            )
        console.print(rec)
    console.print(f"wrote {out or estimate_dir / 'validation'}")


def _measured_of(estimate_dir: Path) -> Path | None:
    """The recordings' folder ``estimate_dir/estimate.json`` records (``measured``), which
    ``validate`` reads without ``--measured``; None where the file or the field does not
    read (the validation itself then says why, in one line)."""
    from railsusp.store import read_json

    try:
        doc = read_json(estimate_dir / "estimate.json")
    except RailsuspInputError:
        return None
    folder = doc.get("measured") if isinstance(doc, dict) else None
    if not isinstance(folder, str) or not folder or "\0" in folder:  # no path the OS takes
        return None
    from railsusp.validation_inputs import measured_of

    return measured_of(doc, estimate_dir)


def _campaign_of(sensitivity: Path | None) -> Path | None:
    """The campaign folder of ``--sensitivity`` (``RUN/sensitivity``, or a file in it), or
    None where it is not beside a campaign's ``campaign.json``."""
    if sensitivity is None:
        return None
    folder = sensitivity if sensitivity.is_dir() else sensitivity.parent
    campaign = folder.absolute().parent
    return campaign if (campaign / "campaign.json").is_file() else None
