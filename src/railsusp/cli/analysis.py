"""The ``railsusp sensitivity`` command: Sobol indices (S1, ST with bootstrap intervals)
and the key parameters of a stored campaign, printed as tables and set against the study's.

The command that makes the campaign (``railsusp campaign``) is :mod:`railsusp.cli.campaigns`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from railsusp.cli.common import app, console, err_console, fail, hold_folders
from railsusp.errors import RailsuspInputError

#: the analysis's settings -> the options of ``sensitivity``, for its error messages
_SENSITIVITY_OPTIONS = {
    "threshold": "--threshold",
    "max_keys": "--max-keys",
    "min_cv": "--min-cv",
    "base_samples": "--base-samples",
    "seed": "--seed",
    "statistics": "--statistics",
    "key_statistics": "--key-statistics",
    "compare": "--compare",
}


@app.command()
def sensitivity(
    run: Annotated[Path, typer.Argument(help="campaign run directory")],
    statistics: Annotated[
        str,
        typer.Option(
            help="feature statistics to analyse, each printed (the key statistics are analysed too)"
        ),
    ] = "mean,p99",
    threshold: Annotated[float, typer.Option(help="ST threshold of the key rule")] = 0.05,
    key_statistics: Annotated[str, typer.Option(help="statistics the key rule uses")] = (
        "mean,p99"
    ),
    max_keys: Annotated[int, typer.Option(help="at most this many key parameters")] = 6,
    min_cv: Annotated[
        float,
        typer.Option(help="ignore features varying less than this (coefficient of variation)"),
    ] = 0.005,
    base_samples: Annotated[
        int | None,
        typer.Option(
            help="Saltelli N on the metamodel (default 2048; an LHS campaign's: a Saltelli "
            "campaign is analysed directly)"
        ),
    ] = None,
    compare: Annotated[
        Path | None,
        typer.Option(
            help="a second run directory (e.g. a Saltelli campaign) to set against this one"
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="bootstrap / metamodel seed")] = 0,
) -> None:
    """Sobol indices (S1, ST with bootstrap intervals) and the key parameters of a campaign."""
    from railsusp.campaign import STATISTICS
    from railsusp.sensitivity import analyse

    stats = tuple(s.strip() for s in statistics.split(",") if s.strip())
    key_stats = tuple(s.strip() for s in key_statistics.split(",") if s.strip())
    if not stats:  # refused as an empty --key-statistics is (not analysed as the key ones)
        fail(f"--statistics (none): accepted one or more of {', '.join(STATISTICS)}")
    stats = (*stats, *(k for k in key_stats if k not in stats))
    try:
        # the campaign for the analysis's duration: a campaign --force replaced it under
        # the analysis, which then wrote the old campaign's indices beside the new one
        hold_folders(
            writes=[("", run)], reads=[("--compare", compare)] if compare is not None else []
        )
        with err_console.status("Sobol analysis"):
            s = analyse(
                run,
                statistics=stats,
                threshold=threshold,
                key_statistics=key_stats,
                max_keys=max_keys,
                min_cv=min_cv,
                base_samples=base_samples,
                seed=seed,
                compare=compare,
            )
    except RailsuspInputError as exc:
        fail(str(exc), options=_SENSITIVITY_OPTIONS)
    except ValueError as exc:  # most name the run already
        text = str(exc)
        fail(text if text.startswith(str(Path(run))) else f"{run}: {text}")
    idx = s["indices"]
    keys = s["key_parameters"]["keys"]
    kp = s["key_parameters"]
    ignored = set(kp["ignored_features"]) | set(kp.get("unfitted_features", ()))
    unfit = "" if kp.get("min_r2") is None else f" or metamodel R2 < {kp['min_r2']:g}"
    for st in stats:  # every statistic analysed; the key rule's said in the title
        sel = idx[idx.statistic == st]
        role = "a key statistic" if st in key_stats else "not in the key rule"
        table = Table(
            title=f"Total Sobol indices ST ± 95 % ({s['method']}, statistic '{st}', {role}; "
            f"dim: feature ignored, CV < {min_cv:.1%}{unfit})",
            title_justify="left",
        )
        table.add_column("parameter")
        cols = sel[["condition", "quantity", "cv"]].drop_duplicates().to_numpy().tolist()
        for cond, q, cv in cols:
            table.add_column(f"{cond} {q}\nCV {cv:.1%}", justify="right")
        for p in sel.parameter.unique():
            cells = []
            for cond, q, _ in cols:
                r = sel[(sel.parameter == p) & (sel.condition == cond) & (sel.quantity == q)]
                r = r.iloc[0]
                cell = f"{r.ST:.3f} ± {r.ST_conf:.3f}"
                cells.append(f"[dim]{cell}[/]" if f"{cond} {q} {st}" in ignored else cell)
            table.add_row(f"[bold]{p}[/]" if p in keys else p, *cells)
        console.print(table)
    console.print(f"key parameters: [bold]{', '.join(keys)}[/]  ({s['key_parameters']['rule']})")
    cmp = s["comparison"]
    console.print("study: lateral X14, X15, X16, X18; vertical X13, X15, X17. Ours vs study:")
    for r in cmp.itertuples():
        study = (
            "/".join(
                n for n, f in (("lateral", r.study_lateral), ("vertical", r.study_vertical)) if f
            )
            or "-"
        )
        console.print(
            f"  {r.parameter:>4} rank {r.our_rank:>2}  max ST {r.our_max_ST:.3f} "
            f"({r.where})  ours key: {'yes' if r.ours_key else 'no '}  study: {study}",
            highlight=False,
        )
    unfitted = set(kp.get("unfitted_features", ()))
    for f in s["metamodel_r2"]:
        if not f["r2_holdout"] >= 0.8:  # NaN (a constant feature, not scored) too
            name = f"{f['condition']} {f['quantity']} {f['statistic']}"
            left = " (left out of the key rule)" if name in unfitted else ""
            console.print(f"[yellow]metamodel {name}: held-out R2 {f['r2_holdout']:.2f}{left}[/]")
    if "agreement" in s:
        console.print("agreement with the compared run (max |dST|, Spearman of ST):")
        for a in s["agreement"]:
            console.print(
                f"  {a['condition']} {a['quantity']} {a['statistic']}: "
                f"{a['max_abs_dST']:.3f}, {a['spearman_ST']:.2f}",
                highlight=False,
            )
    console.print(f"wrote {run / 'sensitivity'}")
