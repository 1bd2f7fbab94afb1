"""Commands of the simulation-based posterior: ``railsusp posterior train`` and
``railsusp posterior estimate`` (docs/posterior.md).

The commands and the options they take are here; the checks of options that need more than
a type are in :mod:`railsusp.cli.posterior_options`, and what train and join print of the
estimator's coverage checks in :mod:`railsusp.cli.posterior_tables`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from railsusp.cli.common import (
    WagonOption,
    app,
    console,
    err_console,
    fail,
    frame_table,
    hold_folders,
    is_quiet,
)
from railsusp.cli.posterior_options import (
    check_long_record_option,
    check_result_file,
    parse_counts,
    parse_product_cases,
    read_for_estimator,
    refuse_synthetic_only,
)
from railsusp.cli.posterior_tables import print_calibration_table, print_checks, print_verdict
from railsusp.errors import RailsuspInputError

posterior_app = typer.Typer(
    no_args_is_help=True,
    help="Parameters with 90 % intervals on unknown track: simulation-based posterior.",
)
app.add_typer(posterior_app, name="posterior")

#: settings field -> command-line option, for the error messages
_OPTIONS = {"section_s": "--section", "n_train": "--simulations", "n_check": "--check",
            "noise": "--noise", "parameters": "--parameters",
            "n_calibration": "--calibration", "ensemble": "--ensemble",
            "product_sections": "--product-sections", "n_product": "--product-cases",
            "product_cases": "--product-cases", "statistics": "--statistics",
            "projection_rank": "--projection-rank",
            "statistics_emulator_cases": "--statistics-emulator-cases",
            "condition_offset": "--condition-offset", "sum_y": "--sum-y",
            "samples": "--samples", "seed": "--seed", "wagon": "--wagon"}  # fmt: skip


@posterior_app.command(
    "train",
    epilog="Example: railsusp posterior train --out runs/post --conditions straight,curve "
    "--simulations 2000",
)
def train_command(
    out: Annotated[Path, typer.Option(help="run directory (the estimator goes to posterior/)")],
    conditions: Annotated[str, typer.Option(help="names or a TOML file")] = "straight,curve",
    parameters: Annotated[
        str, typer.Option(help="estimated parameters, a subset of X11-X20 (comma-separated)")
    ] = "X11,X12,X13,X14,X15,X16,X17,X18,X19,X20",
    section: Annotated[float, typer.Option(help="training section per condition, s")] = 20.0,
    simulations: Annotated[int, typer.Option(help="training simulations (cases)")] = 2000,
    check: Annotated[int, typer.Option(help="untouched held-out simulations for the check")] = 200,
    calibration: Annotated[
        int, typer.Option(help="held-out simulations fitting the spread correction (0: none)")
    ] = 200,
    ensemble: Annotated[int, typer.Option(help="flows in the ensemble")] = 1,
    product_sections: Annotated[
        str,
        typer.Option(
            help="numbers of sections at which the fused posterior is corrected and "
            "checked, comma-separated (empty: records of several sections are not "
            "calibrated)"
        ),
    ] = "",
    product_cases: Annotated[
        str,
        typer.Option(
            help="held-out cases per set (calibration, test) of several sections: one count "
            "for every entry of --product-sections, or one per entry, comma-separated"
        ),
    ] = "100",
    noise: Annotated[float, typer.Option(help="instrument noise, fraction of RMS")] = 0.03,
    lead_in: Annotated[
        float | None, typer.Option(help="lead-in before each section, m (default: the condition's)")
    ] = None,
    sum_y: Annotated[
        bool,
        typer.Option(
            help="also the wheelset's track-shifting force Y - Y_partner (both wheels "
            "recorded; EN 14363 sum Y)"
        ),
    ] = False,
    statistics: Annotated[
        str,
        typer.Option(
            help="families of statistics, comma-separated or 'all' (the first four): en14363 "
            "(always), third-octave, wheelset, coherence, cross-spectra (the last three need "
            "both wheels of the instrumented wheelset recorded)"
        ),
    ] = "en14363",
    projection_rank: Annotated[
        int,
        typer.Option(
            help="combinations of the statistics the synthetic likelihood reads beyond the "
            "EN 14363 summary (with --long-record synthetic-likelihood)"
        ),
    ] = 15,  # DEFAULT_PROJECTION_RANK (a test holds them equal)
    statistics_emulator_cases: Annotated[
        int,
        typer.Option(
            help="0: the synthetic likelihood's emulator of all statistics learns from every "
            "simulation; N: from the first N only (it chooses the combinations), and an "
            "emulator of the combinations alone from all of them (tens of thousands of "
            "simulations: docs/posterior.md; with --long-record synthetic-likelihood)"
        ),
    ] = 0,
    condition_offset: Annotated[
        int,
        typer.Option(
            help="for an estimator of further conditions of the same wagon: the number of "
            "conditions of the estimators before it (their tracks and noise are not reused), "
            "joined to them by railsusp posterior join"
        ),
    ] = 0,
    seed: Annotated[int, typer.Option(help="seed of every draw")] = 0,
    wagon: WagonOption = None,
    samples: Annotated[
        int,
        typer.Option(
            help="posterior draws per recording and per held-out case of the checks (100 to "
            "100000; more draws, steadier interval ends, a longer check)"  # POSTERIOR_COUNTS
        ),
    ] = 1000,
    long_record: Annotated[
        str,
        typer.Option(
            help="also fit and check the posterior of long records: 'synthetic-likelihood' "
            "(the mean of the sections' statistics); 'fusion' (default): only the flows"
        ),
    ] = "fusion",
) -> None:
    """Train the posterior estimator on simulations from the prior (cached: a re-run
    resumes) and check its calibration on held-out simulations."""
    from railsusp.condition_files import resolve_conditions
    from railsusp.estimate import posterior
    from railsusp.estimate.posterior_settings import PosteriorSettings
    from railsusp.input_checks import check_output_folder

    try:
        check_output_folder(out)
        from railsusp.measured.field_folder import check_not_recordings

        check_not_recordings(out)  # a field folder's recordings are no estimator's folder
        check_long_record_option(long_record)
        if (
            parse_product_cases(product_cases) != {"n_product": 100}
            and not product_sections.strip()
        ):
            raise RailsuspInputError(  # ignored before, silently
                f"--product-cases {product_cases}: counts the cases of --product-sections, "
                "which is not given; accepted with --product-sections"
            )
        conds = resolve_conditions(conditions)
        if lead_in is not None:
            if not 0.0 <= lead_in <= 5000.0:
                raise RailsuspInputError(f"--lead-in {lead_in:g} m: accepted 0 to 5000 m")
            conds = [c.with_changes(lead_in_m=lead_in) for c in conds]
        settings = PosteriorSettings(
            tuple(conds),
            parameters=tuple(p for p in parameters.split(",") if p.strip()),
            section_s=section,
            n_train=simulations,
            n_check=check,
            n_calibration=calibration,
            ensemble=ensemble,
            product_sections=parse_counts(product_sections),
            **parse_product_cases(product_cases),
            noise=noise,
            sum_y=sum_y,
            statistics=tuple(statistics.split(",")),
            projection_rank=projection_rank,
            statistics_emulator_cases=statistics_emulator_cases,
            condition_offset=condition_offset,
            seed=seed,
            samples=samples,
            wagon=wagon,
        )
        if long_record != "synthetic-likelihood":
            refuse_synthetic_only(projection_rank, statistics_emulator_cases)
        hold_folders(creates=[("--out", out)])  # the run directory for the training's duration
        # temporaries a killed training left of its files and cached chunks, under the
        # lock: kept for good before (the QA of stop 74)
        from railsusp.store import remove_stale_temporaries

        for part in ("", "simulations", "synthetic"):  # the synthetic likelihood's too
            remove_stale_temporaries(out / "posterior" / part)
        if is_quiet():
            est = posterior.train(settings, out)
        else:
            with console.status("simulating and training"):
                est = posterior.train(settings, out)
        synthetic = None
        if long_record == "synthetic-likelihood":
            from railsusp.estimate import posterior_synthetic_run

            synthetic = posterior_synthetic_run.train(settings, out)
    except RailsuspInputError as exc:
        # the options the user typed, not the fields (the lead-in: where --lead-in set it)
        typed = {"lead_in_m": "--lead-in"} if lead_in is not None else {}
        fail(str(exc), options={**_OPTIONS, **typed})
    if not is_quiet():
        print_calibration_table(est)
    if synthetic is not None:
        print_checks(synthetic.checks, "synthetic likelihood, ")
    print_verdict(est, out / "posterior", synthetic.checks if synthetic is not None else [])


@posterior_app.command(
    "estimate",
    epilog="Example: railsusp posterior estimate --measured field/ --estimator runs/post",
)
def estimate_command(
    measured: Annotated[Path, typer.Option(help="field folder (index.json) of recordings")],
    estimator: Annotated[Path, typer.Option(help="run directory of a trained estimator")],
    out: Annotated[Path | None, typer.Option(help="JSON file for the result")] = None,
    seed: Annotated[int, typer.Option(help="seed of the posterior draws")] = 0,
    long_record: Annotated[
        str,
        typer.Option(
            help="how several sections combine: 'fusion' (the flows' posteriors fused, "
            "default) or 'synthetic-likelihood' (the mean of their statistics; fitted by "
            "train --long-record synthetic-likelihood)"
        ),
    ] = "fusion",
) -> None:
    """Posterior median and 90 % interval of each parameter for a field folder."""
    from railsusp.estimate import posterior
    from railsusp.estimate.posterior_settings import check_seed
    from railsusp.input_checks import check_output_file
    from railsusp.measured import read_index

    try:
        if out is not None:
            check_output_file(out)
            check_result_file(out, {"--measured": measured, "--estimator": estimator})
        check_seed(seed, "--seed")  # numpy's generators take no negative seed
        check_long_record_option(long_record)
        # the estimator and the recordings are read as wholes: no posterior train rewrites
        # the one, no synth-field, sections --write or align-track --write the other
        # meanwhile (a read in a field's swap mixed two truths' recordings: the concurrency
        # audit)
        hold_folders(reads=[("--estimator", estimator), ("--measured", measured)])
        listed = read_index(measured)  # the folder and its index before the estimator
        joined = (estimator / "posterior" / "joint.json").exists()
        if joined and long_record != "synthetic-likelihood":
            raise RailsuspInputError(
                f"--estimator {estimator}: a joint posterior (railsusp posterior join) reads "
                "--long-record synthetic-likelihood; accepted that method"
            )
        if joined:
            from railsusp.estimate import posterior_joint as method
        elif long_record == "synthetic-likelihood":
            from railsusp.estimate import posterior_synthetic_run as method
        else:
            method = posterior
        est = method.load(estimator)
        # the recordings are read as the wagon's the estimator simulated (its wheel load)
        recordings = read_for_estimator(listed, est.settings.wagon, estimator)
        result = method.estimate(est, recordings, seed=seed)
    except RailsuspInputError as exc:
        fail(str(exc))
    console.print(frame_table(result.to_dataframe(), "posterior: median and 90 % interval"))
    for name, used in result.sections.items():
        console.print(
            f"{name}: {used['sections']} section(s) of {est.settings.section_s:g} s, "
            f"{used['seconds_left_out']:g} s left out"
        )
    if out is not None:
        result.save(out)
        console.print(f"wrote {out}")


@posterior_app.command(
    "join",
    epilog="Example: railsusp posterior join --estimators runs/post_sc,runs/post_up "
    "--out runs/post_all",
)
def join_command(
    estimators: Annotated[
        str,
        typer.Option(
            help="run directories of synthetic-likelihood estimators of different conditions "
            "of the same wagon (trained with the same seed and held-out counts, each later "
            "one with --condition-offset past the conditions before it), comma-separated"
        ),
    ],
    out: Annotated[Path, typer.Option(help="folder of the joint posterior (posterior/joint.json)")],
) -> None:
    """One posterior of all the estimators' conditions (their likelihoods multiply), widened
    where its calibration records say so and checked on their held-out records; then
    railsusp posterior estimate --estimator OUT --long-record synthetic-likelihood."""
    from railsusp.estimate import posterior_joint
    from railsusp.input_checks import check_output_folder

    runs = [Path(r.strip()) for r in estimators.split(",") if r.strip()]
    try:
        if len(runs) < 2:
            raise RailsuspInputError(
                f"--estimators {estimators}: accepted two or more run folders, comma-separated"
            )
        check_output_folder(out)
        from railsusp.measured.field_folder import check_not_recordings

        check_not_recordings(out)  # written among recordings (the QA of stop 73)
        hold_folders(  # the joint posterior's folder, and the estimators it reads
            creates=[("--out", out)], reads=[("--estimators", r) for r in runs]
        )
        if is_quiet():
            joint = posterior_joint.train(runs, out)
        else:
            with console.status("widening and checking the joint posterior"):
                joint = posterior_joint.train(runs, out)
    except RailsuspInputError as exc:
        fail(str(exc))
    names = [c.name for p in joint.parts for c in p.settings.conditions]
    console.print(f"joint posterior of {', '.join(names)} in {out / 'posterior' / 'joint.json'}")
    for k, c in sorted(joint.corrections.items()):
        most = max(range(len(c.factors)), key=lambda i: c.factors[i])
        console.print(
            f"{k} section(s): widened by up to {c.factors[most]:.2f} ({c.parameters[most]}), "
            f"fitted on {c.n} calibration records"
        )
    print_checks(joint.checks, widened=lambda k: joint.correction_for(k) is not None)
    if not all(c.passed for c in joint.checks):
        err_console.print(
            "warning: the joint posterior FAILED its coverage check (intervals too narrow); "
            "train its estimators on more simulations"
        )
