"""The ``railsusp`` command line: thin wrappers over the library, rich tables for output.

Bad input (unknown parameter, out-of-range value, bad condition) prints one line on stderr
and exits with status 2, never a traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from railsusp import __version__
from railsusp.conditions import (
    STANDARD_CONDITIONS,
    WorkingCondition,
    make_condition,
    resolve_conditions,
)
from railsusp.errors import RailsuspInputError
from railsusp.params import CATALOGUE, ParameterSet, parse_overrides
from railsusp.study import TABLE8_BEFORE
from railsusp.vehicle.track import COMPONENTS, band_rms, irregularities_for, synthesise

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="railsusp: suspension parameter estimation for heavy-haul freight wagons.",
)
# Wide tables when piped (CI logs, files); the terminal's width otherwise.
console = Console(width=None if sys.stdout.isatty() else 150)
err_console = Console(stderr=True, width=None if sys.stderr.isatty() else 150)


def _fail(message: str) -> None:
    err_console.print(f"[bold red]error:[/] {message}", highlight=False, soft_wrap=True)
    raise typer.Exit(2)


def parameter_table(pset: ParameterSet, title: str = "Parameter catalogue (C80 / K6)") -> Table:
    """Catalogue rows: symbol, description, unit, nominal, range, current value."""
    table = Table(title=title, title_justify="left")
    for col in ("symbol", "description", "unit", "nominal", "range", "value"):
        table.add_column(col, justify="right" if col in ("nominal", "value") else "left")
    for s in CATALOGUE:
        rng = (
            "fixed"
            if s.bounds_display is None
            else (f"{s.bounds_display[0]:g} .. {s.bounds_display[1]:g}")
        )
        value = pset.display(s.symbol)
        shown = f"{value:g}" if value == s.nominal_display else f"[bold yellow]{value:g}[/]"
        unit = s.display_unit + (f" (study: {s.table_unit})" if s.table_unit else "")
        table.add_row(s.symbol, s.description, unit, f"{s.nominal_display:g}", rng, shown)
    return table


def condition_table(conditions: list[WorkingCondition]) -> Table:
    """One row per working condition, in engineering units."""
    table = Table(title="Working conditions", title_justify="left")
    for col in (
        "name",
        "speed km/h",
        "radius m",
        "cant mm",
        "deficiency mm",
        "spirals m",
        "grade ‰",
        "coupler kN",
        "track",
        "record",
    ):
        table.add_column(col)
    for c in conditions:
        curve = c.curve_radius_m is not None
        table.add_row(
            c.name,
            f"{c.speed_kmh:g}",
            f"{c.curve_radius_m:g} {c.curve_direction}" if curve else "tangent",
            f"{c.cant_mm:g}" if curve else "-",
            f"{c.cant_deficiency_mm:.1f}" if curve else "-",
            f"{c.entry_spiral_m:g}/{c.exit_spiral_m:g}" if curve else "-",
            f"{c.grade_permille:+g}",
            f"{c.coupler_force_kN:g}",
            "perfect"
            if c.irregularity_class is None
            else f"class {c.irregularity_class}, seed {c.seed}",
            f"{c.duration_s:g} s / {c.n_steps}",
        )
    return table


def track_summary_table(conditions: list[WorkingCondition]) -> Table:
    """RMS of the synthesised irregularities over each section vs the PSD band integral."""
    table = Table(title="Synthesised track input (RMS over the section, mm)", title_justify="left")
    table.add_column("condition")
    table.add_column("length m", justify="right")
    for comp in COMPONENTS:
        table.add_column(f"{comp} (PSD)", justify="right")
    for c in conditions:
        irr = irregularities_for(c)
        if irr is None:
            table.add_row(c.name, f"{c.section_length_m:.0f}", *["0 (0)"] * len(COMPONENTS))
            continue
        cells = []
        for comp in COMPONENTS:
            rms = float(np.std(irr.component(comp)[0])) * 1e3
            ref = band_rms(comp, irr.track_class, irr.wavelength_min, irr.wavelength_max) * 1e3
            cells.append(f"{rms:.2f} ({ref:.2f})")
        table.add_row(c.name, f"{c.section_length_m:.0f}", *cells)
    return table


@app.command()
def params(
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="override, e.g. --set X13=16.1,X14=8.3 (display units)"),
    ] = None,
    file: Annotated[
        Path | None,
        typer.Option("--file", help="TOML file with a [parameters] table (display units)"),
    ] = None,
) -> None:
    """Print the parameter catalogue (Tables 1 and 2 of the study), with any overrides."""
    try:
        pset = ParameterSet.from_toml(file) if file else ParameterSet.nominal()
        if set_:
            pset = pset.replace(parse_overrides(set_), units="display")
    except RailsuspInputError as exc:
        _fail(str(exc))
    console.print(parameter_table(pset))


@app.command()
def conditions(
    which: Annotated[
        str, typer.Argument(help="comma-separated standard names or a TOML file")
    ] = ",".join(STANDARD_CONDITIONS),
) -> None:
    """Print the working conditions (Table 6 of the study, with our documented choices)."""
    try:
        conds = resolve_conditions(which)
    except RailsuspInputError as exc:
        _fail(str(exc))
    console.print(condition_table(conds))
    for c in conds:
        console.print(f"  [bold]{c.name}[/]: {c.describe()}", highlight=False)


@app.command()
def track(
    track_class: Annotated[int, typer.Option("--class", help="FRA track class 1..6")] = 5,
    length: Annotated[float, typer.Option(help="section length, m")] = 2000.0,
    seed: Annotated[int, typer.Option(help="random seed")] = 0,
    wavelength_min: Annotated[float, typer.Option(help="shortest wavelength, m")] = 1.0,
    wavelength_max: Annotated[float, typer.Option(help="longest wavelength, m")] = 120.0,
    plot: Annotated[Path | None, typer.Option(help="write a PNG of traces and PSDs")] = None,
) -> None:
    """Synthesise FRA-class irregularities and compare their RMS and PSD with the spectrum."""
    try:
        if length <= 0 or length > 1e6:
            raise RailsuspInputError(f"--length = {length:g} m outside (0, 1e6] m")
        make_condition(
            {
                "name": "track",
                "irregularity_class": track_class,
                "wavelength_min_m": wavelength_min,
                "wavelength_max_m": wavelength_max,
                "seed": seed,
            }
        )
        irr = synthesise(
            length, track_class, seed, wavelength_min=wavelength_min, wavelength_max=wavelength_max
        )
    except RailsuspInputError as exc:
        _fail(str(exc))
    table = Table(title=f"FRA class {track_class}, {length:g} m, seed {seed}", title_justify="left")
    for col in ("component", "RMS mm", "expected mm", "max |x| mm"):
        table.add_column(col, justify="right")
    for comp in COMPONENTS:
        x = irr.component(comp)[0]
        ref = band_rms(comp, track_class, wavelength_min, wavelength_max)
        table.add_row(
            comp, f"{np.std(x) * 1e3:.2f}", f"{ref * 1e3:.2f}", f"{np.abs(x).max() * 1e3:.2f}"
        )
    console.print(table)
    if plot is not None:
        from railsusp.report import plot_track_irregularities

        out = plot_track_irregularities(irr, plot)
        console.print(f"wrote {out}")


def _force_table(results: list, title: str) -> Table:
    """Measured-wheel force statistics per condition beside the study's Table 8."""
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
    from railsusp.vehicle.simulate import WHEEL_NAMES

    for r in results:
        s = r.statistics()
        ref = TABLE8_BEFORE.get(r.condition.name)
        status = "ok" if r.ok[0] else r.failures()[0][1]
        table.add_row(
            r.condition.name,
            WHEEL_NAMES[r.measured_wheel()],
            *(f"{s[k][0]:.1f}" for k in ("Y_mean", "Y_rms", "Y_p99", "Y_max")),
            f"{ref[0]:.1f}" if ref else "-",
            *(f"{s[k][0]:.1f}" for k in ("Q_mean", "Q_p99", "Q_max")),
            f"{ref[2]:.1f}" if ref else "-",
            f"{s['YQ_max'][0]:.2f}",
            f"{s['dQQ_max'][0]:.2f}",
            status,
        )
    return table


@app.command()
def simulate(
    condition: Annotated[str, typer.Argument(help="standard condition name or a TOML file")],
    set_: Annotated[
        list[str] | None,
        typer.Option(
            "--set", help="parameter overrides, e.g. --set X13=16.1,X14=8.3 (display units)"
        ),
    ] = None,
    file: Annotated[
        Path | None,
        typer.Option("--file", help="TOML file with a [parameters] table (display units)"),
    ] = None,
    seed: Annotated[
        int | None, typer.Option(help="irregularity seed (default: condition's)")
    ] = None,
    wheel: Annotated[
        str,
        typer.Option(help="measured wheel: auto (leading wheelset, outer in curves) or w1L..w4R"),
    ] = "auto",
    wagon: Annotated[Path | None, typer.Option(help="wagon data TOML (default C80/K6)")] = None,
    out: Annotated[Path | None, typer.Option(help="write the force series to Parquet")] = None,
    plot: Annotated[Path | None, typer.Option(help="write a PNG of the force series")] = None,
) -> None:
    """Simulate one parameter set in one or more working conditions; print force statistics."""
    from railsusp.vehicle.simulate import WHEEL_NAMES
    from railsusp.vehicle.simulate import simulate as run_one
    from railsusp.vehicle.wagon import load_wagon

    try:
        pset = ParameterSet.from_toml(file) if file else ParameterSet.nominal()
        if set_:
            pset = pset.replace(parse_overrides(set_), units="display")
        conds = resolve_conditions(condition)
        if seed is not None:
            conds = [c.with_changes(seed=seed) for c in conds]
        wagon_data = load_wagon(wagon)
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
        _fail(str(exc))
    console.print(_force_table(results, f"Wheel-rail forces (kN), {wagon_data.name}"))
    for r in results:
        tag = f"-{r.condition.name}" if len(results) > 1 else ""
        if out is not None:
            path = out.with_name(f"{out.stem}{tag}{out.suffix}")
            console.print(f"wrote {r.to_parquet(path)}")
        if plot is not None:
            from railsusp.report import plot_forces

            path = plot.with_name(f"{plot.stem}{tag}{plot.suffix}")
            console.print(f"wrote {plot_forces(r, path, wheel=wheel)}")


def _progress():
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=err_console,
        transient=True,
    )


@app.command()
def campaign(
    out: Annotated[Path, typer.Option(help="run directory")],
    samples: Annotated[int, typer.Option(help="LHS samples, or Saltelli base N")] = 1000,
    conditions: Annotated[str, typer.Option(help="names or a TOML file")] = (
        "straight,curve,uphill"
    ),
    seed: Annotated[int, typer.Option(help="design seed")] = 0,
    design: Annotated[str, typer.Option(help="lhs, lhs-optimised or sobol (Saltelli)")] = "lhs",
    second_order: Annotated[bool, typer.Option(help="Saltelli with second order")] = False,
    parameters: Annotated[str, typer.Option(help="sampled subset, others nominal")] = (
        "X11,X12,X13,X14,X15,X16,X17,X18,X19,X20"
    ),
    batch_size: Annotated[int, typer.Option(help="sets per batch (one stored file)")] = 32,
    independent_seeds: Annotated[
        bool,
        typer.Option(
            help="a different track realisation per sample (default: common random numbers)"
        ),
    ] = False,
    wheel: Annotated[str, typer.Option(help="measured wheel: auto or w1L..w4R")] = "auto",
    workers: Annotated[int | None, typer.Option(help="run on a local Dask cluster")] = None,
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler tcp://host:port")] = None,
    force: Annotated[bool, typer.Option(help="discard results of another configuration")] = False,
    max_batches: Annotated[
        int | None, typer.Option(help="stop after this many new batches")
    ] = None,
) -> None:
    """Sample the suspension parameters and simulate every sample in every condition."""
    from railsusp.campaign import make_config, run_campaign

    try:
        conds = resolve_conditions(conditions)
        cfg = make_config(
            conds,
            samples,
            parameters=tuple(p for p in parameters.split(",") if p.strip()),
            design=design,
            second_order=second_order,
            seed=seed,
            batch_size=batch_size,
            independent_seeds=independent_seeds,
            wheel=wheel,
        )
    except RailsuspInputError as exc:
        _fail(str(exc))
    d = len(cfg.parameters)
    if cfg.design == "sobol":
        k = 2 * d + 2 if cfg.second_order else d + 2
        label = "N(2D+2)" if cfg.second_order else "N(D+2)"
        console.print(
            f"Saltelli design: {label} = {cfg.samples} x {k} = {cfg.n_runs} "
            f"simulations per condition",
            highlight=False,
        )
    total = cfg.n_runs * len(cfg.conditions)
    console.print(
        f"{total} simulations ({cfg.n_runs} sets x {len(cfg.conditions)} conditions) into {out}",
        highlight=False,
    )
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    with Progress(
        TextColumn("campaign"),
        BarColumn(),
        MofNCompleteColumn(),
        TaskProgressColumn(),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=err_console,
    ) as bar:
        task = bar.add_task("runs", total=total, rate="")
        t0 = [None, 0]

        def progress(done: int, tot: int) -> None:
            import time as _time

            now = _time.perf_counter()
            if t0[0] is None:
                t0[0], t0[1] = now, done
            elapsed = now - t0[0]
            rate = (done - t0[1]) / elapsed if elapsed > 0 else 0.0
            bar.update(task, completed=done, rate=f"{rate:.1f} runs/s")

        try:
            run_campaign(
                cfg,
                out,
                force=force,
                scheduler=scheduler,
                workers=workers,
                progress=progress,
                max_batches=max_batches,
            )
        except RailsuspInputError as exc:
            _fail(str(exc))
    console.print(f"campaign stored in {out}")


@app.command()
def sensitivity(
    run: Annotated[Path, typer.Argument(help="campaign run directory")],
    statistics: Annotated[str, typer.Option(help="feature statistics to analyse")] = "mean,p99",
    threshold: Annotated[float, typer.Option(help="ST threshold of the key rule")] = 0.05,
    key_statistics: Annotated[str, typer.Option(help="statistics the key rule uses")] = (
        "mean,p99"
    ),
    max_keys: Annotated[int, typer.Option(help="at most this many key parameters")] = 6,
    min_cv: Annotated[
        float,
        typer.Option(help="ignore features varying less than this (coefficient of variation)"),
    ] = 0.005,
    base_samples: Annotated[int, typer.Option(help="Saltelli N on the metamodel")] = 2048,
    compare: Annotated[
        Path | None,
        typer.Option(
            help="a second run directory (e.g. a Saltelli campaign) to set against this one"
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="bootstrap / metamodel seed")] = 0,
) -> None:
    """Sobol indices (S1, ST with bootstrap intervals) and the key parameters of a campaign."""
    from railsusp.sensitivity import analyse

    stats = tuple(s.strip() for s in statistics.split(",") if s.strip())
    key_stats = tuple(s.strip() for s in key_statistics.split(",") if s.strip())
    stats = (*stats, *(k for k in key_stats if k not in stats))
    try:
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
        _fail(str(exc))
    except ValueError as exc:
        _fail(f"{run}: {exc}")
    idx = s["indices"]
    keys = s["key_parameters"]["keys"]
    ignored = set(s["key_parameters"]["ignored_features"])
    for st in key_stats:
        sel = idx[idx.statistic == st]
        table = Table(
            title=f"Total Sobol indices ST ± 95 % ({s['method']}, statistic '{st}'; "
            f"dim: feature ignored, CV < {min_cv:.1%})",
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
    for f in s["metamodel_r2"]:
        if f["r2_holdout"] < 0.8:
            console.print(
                f"[yellow]metamodel {f['condition']} {f['quantity']} "
                f"{f['statistic']}: held-out R2 {f['r2_holdout']:.2f}[/]"
            )
    if "agreement" in s:
        console.print("agreement with the compared run (max |dST|, Spearman of ST):")
        for a in s["agreement"]:
            console.print(
                f"  {a['condition']} {a['quantity']} {a['statistic']}: "
                f"{a['max_abs_dST']:.3f}, {a['spearman_ST']:.2f}",
                highlight=False,
            )
    console.print(f"wrote {run / 'sensitivity'}")


def _epoch_reporter(bar, task):
    """A training progress callback bound to one progress-bar task."""

    def report(epoch: int, train_loss: float, val_loss: float) -> None:
        bar.update(task, completed=epoch, loss=f"train {train_loss:.4f} val {val_loss:.4f}")

    return report


def _train_config(epochs, batches_per_epoch, batch_size, device, seed):
    from railsusp.surrogate import TrainConfig

    return TrainConfig(
        epochs=epochs,
        batches_per_epoch=batches_per_epoch,
        batch_size=batch_size,
        device=device,
        seed=seed,
    )


@app.command()
def train(
    run: Annotated[Path, typer.Argument(help="campaign run directory")],
    model: Annotated[str, typer.Option(help="cnn-gru, cnn-lstm, cnn-bilstm or bp")] = "cnn-gru",
    conditions: Annotated[str | None, typer.Option(help="default: all of the campaign")] = None,
    epochs: Annotated[int, typer.Option(help="maximum epochs (early stopping)")] = 40,
    batches_per_epoch: Annotated[int, typer.Option(help="mini-batches per epoch")] = 200,
    batch_size: Annotated[int, typer.Option(help="windows per mini-batch")] = 512,
    window: Annotated[int, typer.Option(help="window length, steps")] = 20,
    device: Annotated[str, typer.Option(help="cpu, cuda or auto")] = "cpu",
    seed: Annotated[int, typer.Option(help="training seed")] = 0,
) -> None:
    """Train a window surrogate per condition (RUN/surrogates/<model>/<condition>/); print its
    accuracy on the held-out test samples. Re-running resumes from the last checkpoint."""
    from railsusp.campaign import load_campaign
    from railsusp.surrogate import KINDS, train_surrogate
    from railsusp.surrogate.data import load_series
    from railsusp.surrogate.evaluate import evaluate

    try:
        if model not in KINDS:
            raise RailsuspInputError(f"--model {model!r}: accepted {', '.join(KINDS)}")
        camp = load_campaign(run)
        conds = (
            [c.strip() for c in conditions.split(",")]
            if conditions
            else [c.name for c in camp.config.conditions]
        )
        tcfg = _train_config(epochs, batches_per_epoch, batch_size, device, seed)
    except (RailsuspInputError, ValueError) as exc:
        _fail(str(exc))
    table = Table(title=f"{model}: accuracy on held-out simulations", title_justify="left")
    for col in (
        "condition",
        "force",
        "simulated kN",
        "predicted kN",
        "rel. error of mean",
        "NRMSE",
        "R2",
        "test runs",
    ):
        table.add_column(col, justify="left" if col in ("condition", "force") else "right")
    for cond in conds:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

        with Progress(
            TextColumn(f"{cond} {model}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[loss]}"),
            console=err_console,
        ) as bar:
            task = bar.add_task("train", total=epochs, loss="")
            try:
                sur = train_surrogate(
                    run,
                    cond,
                    kind=model,
                    window=window,
                    train=tcfg,
                    progress=_epoch_reporter(bar, task),
                )
            except (RailsuspInputError, ValueError) as exc:
                _fail(str(exc))
        data = load_series(camp, cond, sur.spec)
        test = data.subset(np.flatnonzero(np.isin(data.sample_ids, sur.meta["test_ids"])))
        for r in evaluate(sur, test):
            table.add_row(
                cond,
                r["target"],
                f"{r['simulated_mean_kN']:.2f}",
                f"{r['predicted_mean_kN']:.2f}",
                f"{100 * r['relative_error_of_mean']:.2f} %",
                f"{r['nrmse']:.3f}",
                f"{r['r2']:.3f}",
                str(r["n_samples"]),
            )
    console.print(table)
    console.print(f"saved under {run / 'surrogates' / model}")


@app.command()
def compare(
    run: Annotated[Path, typer.Argument(help="campaign run directory")],
    models: Annotated[str, typer.Option(help="models to compare")] = (
        "cnn-gru,cnn-lstm,cnn-bilstm,bp,rbf,gp-stats"
    ),
    conditions: Annotated[str | None, typer.Option(help="default: all of the campaign")] = None,
    epochs: Annotated[int, typer.Option(help="maximum epochs (early stopping)")] = 40,
    batches_per_epoch: Annotated[int, typer.Option(help="mini-batches per epoch")] = 200,
    batch_size: Annotated[int, typer.Option(help="windows per mini-batch")] = 512,
    device: Annotated[str, typer.Option(help="cpu, cuda or auto")] = "cpu",
    seed: Annotated[int, typer.Option(help="training seed")] = 0,
) -> None:
    """Train all surrogates on the same split and print the study's Table 7 layout."""
    from railsusp.surrogate.compare import ALL_MODELS, table7
    from railsusp.surrogate.compare import compare as run_compare

    names = [m.strip() for m in models.split(",") if m.strip()]
    bad = [m for m in names if m not in ALL_MODELS]
    if bad:
        _fail(f"--models {', '.join(bad)}: accepted {', '.join(ALL_MODELS)}")
    try:
        with err_console.status("training surrogates") as status:
            tab = run_compare(
                run,
                models=names,
                conditions=([c.strip() for c in conditions.split(",")] if conditions else None),
                train=_train_config(epochs, batches_per_epoch, batch_size, device, seed),
                progress=lambda msg: status.update(f"training {msg}"),
            )
    except (RailsuspInputError, ValueError) as exc:
        _fail(str(exc))
    t7 = table7(tab)
    table = Table(
        title="Surrogates on held-out simulations (study Table 7 layout, mean force "
        "of the measured wheel; |Y| for lateral)",
        title_justify="left",
    )
    for col in t7.columns:
        table.add_column(col, justify="left" if col in ("condition", "model") else "right")
    for r in t7.itertuples(index=False):
        table.add_row(*(f"{v:.3f}" if isinstance(v, float) else str(v) for v in r))
    console.print(table)
    console.print(f"wrote {run / 'surrogates' / 'compare.csv'} and overlay figures")


@app.command()
def demo() -> None:
    """The main job on the embedded default: catalogue, conditions, track input and the
    nominal wagon's wheel-rail forces in the three conditions."""
    from railsusp.vehicle.simulate import simulate as run_one

    conds = list(STANDARD_CONDITIONS.values())
    console.rule(f"railsusp {__version__}: C80 wagon on K6 bogies")
    console.print(parameter_table(ParameterSet.nominal()))
    console.print(condition_table(conds))
    console.print(track_summary_table(conds))
    results = []
    with _progress() as bar:
        task = bar.add_task("simulating the nominal wagon", total=len(conds))
        for c in conds:
            results.append(run_one(None, c))
            bar.advance(task)
    console.print(
        _force_table(
            results,
            "Nominal wagon: wheel-rail forces of the measured "
            "wheel (kN) beside the study's Table 8 (simulated)",
        )
    )
    console.print(
        "[dim]Next stages (campaign, sensitivity, surrogate, estimation, validation) are "
        "not built yet: see the open issues.[/]"
    )


@app.command()
def version() -> None:
    """Print the railsusp version."""
    console.print(__version__)


def main() -> None:
    """Console-script entry point."""
    try:
        app()
    except RailsuspInputError as exc:  # pragma: no cover - commands catch their own
        err_console.print(f"error: {exc}")
        sys.exit(2)


if __name__ == "__main__":
    main()
