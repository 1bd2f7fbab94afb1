"""The ``railsusp campaign`` command: sample the suspension parameters and simulate every
sample in every condition into a run directory (a track family and the parameters not sampled
read from its options, the key parameters from an earlier sensitivity analysis), with a
progress bar and the count of failed simulations.

Apart from :mod:`railsusp.cli.analysis` (``railsusp sensitivity``, which analyses a stored
campaign): this command makes one, and neither calls the other (``--keys-from`` reads the
analysis's ``key_parameters.json``)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated

import typer

from railsusp.cli.common import (
    WagonOption,
    app,
    console,
    err_console,
    fail,
    hold_folders,
    show_progress,
)
from railsusp.cli.inputs import check_seed, condition_options
from railsusp.errors import RailsuspInputError


@app.command()
def campaign(
    out: Annotated[Path, typer.Option(help="run directory")],
    samples: Annotated[int, typer.Option(help="LHS samples, or Saltelli base N")] = 1000,
    conditions: Annotated[
        str,
        typer.Option(
            help="names, a TOML file, or a field folder (its recordings' conditions, on their "
            "measured track geometry when they carry one)"
        ),
    ] = "straight,curve,uphill",
    duration: Annotated[
        float | None,
        typer.Option(
            help="seconds per run, same sampling interval (default: the conditions'); long "
            "runs give statistics averaged over 20 s segments, for long recordings"
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="design seed, 0 or more")] = 0,
    design: Annotated[str, typer.Option(help="lhs, lhs-optimised or sobol (Saltelli)")] = "lhs",
    second_order: Annotated[bool, typer.Option(help="Saltelli with second order")] = False,
    parameters: Annotated[
        str | None,
        typer.Option(help="sampled subset, others nominal (default: X11..X20, all ten)"),
    ] = None,
    keys_from: Annotated[
        Path | None,
        typer.Option(
            help="sample only the key parameters of this run's sensitivity analysis, others "
            "nominal: the training campaign of the surrogates (replaces --parameters)"
        ),
    ] = None,
    batch_size: Annotated[int, typer.Option(help="sets per batch (one stored file)")] = 32,
    independent_seeds: Annotated[
        bool,
        typer.Option(
            help="a different track realisation per sample (default: common random numbers)"
        ),
    ] = False,
    irregularity_classes: Annotated[
        str | None,
        typer.Option(
            help="LO:HI: each sample's FRA class drawn from LO..HI (a track family; "
            "implies --independent-seeds)"
        ),
    ] = None,
    radius: Annotated[
        str | None,
        typer.Option(help="LO:HI m: each sample's curve radius, in every curve condition"),
    ] = None,
    cant: Annotated[
        str | None,
        typer.Option(help="LO:HI mm: each sample's cant, in every curve condition"),
    ] = None,
    vary_others: Annotated[
        bool,
        typer.Option(
            help="vary the main-suspension parameters not sampled over their Table 2 ranges "
            "(or --prior) instead of holding them nominal; not surrogate inputs"
        ),
    ] = False,
    prior: Annotated[
        str | None,
        typer.Option(
            help="SYM=LO:HI,... (display units): narrower ranges of parameters not sampled; "
            "they are varied over these (implies --vary-others for them)"
        ),
    ] = None,
    wheel: Annotated[str, typer.Option(help="measured wheel: auto or w1L..w4R")] = "auto",
    wagon: WagonOption = None,
    workers: Annotated[int | None, typer.Option(help="run on a local Dask cluster")] = None,
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler tcp://host:port")] = None,
    force: Annotated[bool, typer.Option(help="discard results of another configuration")] = False,
    max_batches: Annotated[
        int | None, typer.Option(help="stop after this many new batches")
    ] = None,
) -> None:
    """Sample the suspension parameters and simulate every sample in every condition.

    A training campaign for surrogates that must work on any track: ``--independent-seeds``
    (each sample its own irregularity realisation), optionally a track family
    (``--irregularity-classes``, ``--radius``, ``--cant``), and ``--vary-others`` /
    ``--prior`` so that the parameters not estimated vary instead of sitting at nominal."""
    from railsusp.campaign import run_campaign
    from railsusp.input_checks import check_output_folder
    from railsusp.measured import conditions_from
    from railsusp.vehicle.wagon import load_wagon

    try:
        if workers is not None and workers < 1:
            raise RailsuspInputError(f"--workers = {workers}: accepted an integer >= 1")
        if max_batches is not None and max_batches < 0:
            raise RailsuspInputError(f"--max-batches = {max_batches}: accepted an integer >= 0")
        if second_order and design != "sobol":  # stored, unused, yet in the run's hash
            raise RailsuspInputError(
                f"--second-order: accepted only with --design sobol (a Saltelli design), "
                f"not {design}"
            )
        check_seed(seed)
        check_output_folder(out)
        # the folder for the command's duration (run_campaign's own lock is lent to it),
        # and the run whose key parameters are read, as no process rewrites them meanwhile
        hold_folders(
            creates=[("--out", out)],
            reads=[("--keys-from", keys_from)] if keys_from is not None else [],
        )
        if Path(conditions).is_dir():  # a field folder's conditions and their track files:
            # read shared, not beside a writer of the folder (a mixed read, the audit)
            hold_folders(reads=[("--conditions", Path(conditions))])
        from railsusp.params import MAIN_SUSPENSION

        sampled = _parameters(parameters) if parameters is not None else tuple(MAIN_SUSPENSION)
        if keys_from is not None:
            sampled = _sensitivity_keys(keys_from, parameters)
            console.print(f"sampling the key parameters of {keys_from}: {', '.join(sampled)}")
        wagon_data = load_wagon(wagon)  # simulated, and the recordings' wheel load
        conds = conditions_from(conditions, wagon=wagon_data)
        if duration is not None:
            conds = [_with_duration(c, duration) for c in conds]
        family, others = _variation(irregularity_classes, radius, cant, vary_others, prior, sampled)
        if family is not None and not independent_seeds:
            independent_seeds = True
            console.print("a track family: each sample on its own track (--independent-seeds)")
        cfg = _config(
            conds,
            {"samples": samples, "batch_size": batch_size, "design": design}
            | ({"parameters": parameters} if parameters is not None else {}),
            parameters=sampled,
            second_order=second_order,
            seed=seed,
            independent_seeds=independent_seeds,
            wheel=wheel,
            track_family=family,
            other_parameters=others,
            wagon=wagon_data,
        )
        if scheduler is not None and workers is None:  # (with both: run_campaign refuses)
            _check_scheduler(scheduler)
    except RailsuspInputError as exc:
        fail(str(exc))
    total = cfg.n_runs * len(cfg.conditions)
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
        disable=not show_progress(),
    ) as bar:
        task = bar.add_task("runs", total=total, rate="")
        t0 = [None, 0]

        def progress(done: int, tot: int) -> None:
            import time as _time

            now = _time.perf_counter()
            if t0[0] is None:  # the folder accepted (its first call): now said, not before
                _announce(cfg, out)
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
            error = None
        except RailsuspInputError as exc:
            error = str(exc)
            bar.update(task, visible=False)  # the error is the last line, not the bar
    if error is not None:
        fail(error)
    _say_stored(out, max_batches)
    _report_failures(out, total)


def _announce(cfg, out: Path) -> None:
    """What the campaign simulates, and where: said once ``run_campaign`` has accepted the
    folder (its first progress call, before any simulation), not before a refusal."""
    if cfg.design == "sobol":
        k = cfg.n_runs // cfg.samples
        label = "N(2D+2)" if cfg.second_order else "N(D+2)"
        console.print(
            f"Saltelli design: {label} = {cfg.samples} x {k} = {cfg.n_runs} "
            f"simulations per condition",
            highlight=False,
        )
    total, sets, n = cfg.n_runs * len(cfg.conditions), cfg.n_runs, len(cfg.conditions)
    console.print(f"{total} simulations ({sets} sets x {n} conditions) into {out}", highlight=False)


def _check_scheduler(address: str) -> None:
    """Refuse, before the campaign is announced or its folder prepared, a ``--scheduler``
    that is no address or where no Dask scheduler answers (one line, as ``run_campaign``
    says it when it connects: it connects again, to the scheduler now known to answer)."""
    from railsusp.campaign.dask_cluster import check_scheduler_address, connect_scheduler

    check_scheduler_address(address, "--scheduler")
    connect_scheduler(address, "--scheduler").close()


def _parameters(typed: str) -> tuple[str, ...]:
    """``--parameters`` as the symbols typed, each a known parameter; an unknown one is
    refused naming the option."""
    from railsusp.params import spec

    names = tuple(p.strip() for p in typed.split(",") if p.strip())
    for name in names:
        try:
            spec(name)
        except RailsuspInputError as exc:
            raise RailsuspInputError(f"--parameters {typed}: {exc}") from None
    return names


def _with_duration(condition, duration: float):
    """``condition`` recording ``duration`` s, its refusal naming ``--duration`` (the option
    typed), not the condition's field."""
    try:
        return condition.with_duration(duration)
    except RailsuspInputError as exc:
        message = condition_options(str(exc), {"duration_s": "--duration"}, condition.name)
        raise RailsuspInputError(message) from None


#: campaign settings -> the options that set them, for make_config's refusals
_CONFIG_OPTIONS = {
    "samples": "--samples",
    "batch_size": "--batch-size",
    "design": "--design",
    "parameters": "--parameters",
}


def _config(conds: list, typed: dict, **kwargs):
    """:func:`railsusp.campaign.make_config` of ``conds`` and ``kwargs``, its refusals of the
    settings in ``typed`` (setting -> the option's value as typed: samples, batch_size and
    design, passed on; parameters where ``--parameters`` was given) naming the options
    (``campaign configuration: samples = 0: accepted [2, 1000000]`` -> ``--samples 0:
    accepted [2, 1000000]``)."""
    from railsusp.campaign import make_config

    try:
        return make_config(conds, **{k: v for k, v in typed.items() if k != "parameters"}, **kwargs)
    except RailsuspInputError as exc:
        text = str(exc)
        for setting, value in typed.items():
            named = f"{_CONFIG_OPTIONS[setting]} {value if value != '' else repr(value)}: "
            text = re.sub(
                rf"(?:^campaign configuration: |(?<=; )){setting}(?: = [^:;]*)?: ",
                lambda _m, named=named: named,
                text,
            )
        raise RailsuspInputError(text) from None


def _say_stored(out: Path, max_batches: int | None) -> None:
    """Where the campaign is, and, when --max-batches stopped it early, that it is not
    whole and how to finish it (the counts below are then of the batches that ran)."""
    from railsusp.campaign import incomplete, load_campaign

    missing = incomplete(load_campaign(out), "run the same command without --max-batches")
    if max_batches is not None and missing:  # the same command would stop early again
        console.print(
            f"stopped by --max-batches {max_batches}: {missing}", highlight=False, soft_wrap=True
        )
    else:
        console.print(f"campaign stored in {out}")


def _variation(
    classes: str | None,
    radius: str | None,
    cant: str | None,
    vary_others: bool,
    prior: str | None,
    sampled: tuple[str, ...],
) -> tuple[dict | None, dict]:
    """The campaign's track family and varied non-key parameters from the options."""
    from railsusp.params import spec
    from railsusp.variation import full_ranges, parse_priors, parse_range

    family = {}
    if classes is not None:
        lo, hi = parse_range(classes, "--irregularity-classes")
        if lo != int(lo) or hi != int(hi):
            raise RailsuspInputError(f"--irregularity-classes {classes!r}: accepted integers")
        family["irregularity_classes"] = (int(lo), int(hi))
    if radius is not None:
        family["curve_radius_m"] = parse_range(radius, "--radius")
    if cant is not None:
        family["cant_mm"] = parse_range(cant, "--cant")
    priors = parse_priors(prior) if prior else {}
    sampled_syms = {spec(p).symbol for p in sampled}
    inside = sorted(sampled_syms & set(priors))
    if inside:
        raise RailsuspInputError(
            f"--prior {', '.join(inside)}: sampled already (a prior is for parameters not sampled)"
        )
    others = full_ranges(sampled_syms, priors) if vary_others else priors
    return (family or None), others


def _report_failures(out: Path, total: int) -> None:
    """Print how many simulations failed; exit with status 1 when any did."""
    from railsusp.campaign import Campaign, failed_of

    try:
        feats = Campaign(out).features()  # of the batches that ran
        failed = failed_of(feats)
        total = min(total, feats.groupby(["condition", "sample_id"]).ngroups)
    except RailsuspInputError:  # no finished batch yet (--max-batches 0)
        return
    if failed.empty:
        console.print(f"0 of {total} simulations failed", highlight=False)
        return
    by_cond = failed.groupby("condition").size()
    err_console.print(
        f"{len(failed)} of {total} simulations failed (derailed or diverged; NaN features): "
        + ", ".join(f"{c} {n}" for c, n in by_cond.items()),
        style="bold red",
        markup=False,
        highlight=False,
    )
    raise typer.Exit(1)


def _sensitivity_keys(run: Path, parameters: str | None) -> tuple[str, ...]:
    """The key parameters chosen by ``railsusp sensitivity`` in ``run`` (for --keys-from);
    an analysis made from another campaign than the one in ``run`` is refused, and so is a
    ``--parameters`` given too (``parameters`` None where it was not: its default typed out
    is given as well)."""
    from railsusp.key_parameters import read_key_parameters

    if parameters is not None:
        raise RailsuspInputError("--keys-from and --parameters: give one of them, not both")
    path = run / "sensitivity" / "key_parameters.json"
    if not path.exists():
        raise RailsuspInputError(
            f"--keys-from {run}: no sensitivity analysis there ({path} is missing); "
            f"run `railsusp sensitivity {run}` first"
        )
    keys = tuple(read_key_parameters(run)["key_parameters"]["keys"])
    if not keys:
        raise RailsuspInputError(f"--keys-from {run}: its sensitivity analysis found no key")
    return keys
