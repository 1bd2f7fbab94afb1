"""The ``estimate`` command: NSGA-II on a surrogate (or the simulator) against measured
recordings, the optional refinement and its intervals (Tables 3-5, Figs 8-9 of the study).

The command's options and the run of the route are here; how its messages name the options,
``--held-prior`` and the other checks that need more than a range are in
:mod:`railsusp.cli.estimation_options`."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated

import typer

from railsusp.cli.common import app, console, fail, frame_table, given_options, hold_folders
from railsusp.cli.estimation_options import (
    campaign_of_surrogate,
    check_held_prior_unused,
    interrupted,
    option_naming,
    option_text,
    parse_held_prior,
    warnings_as_options,
)
from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_replaced_folder
from railsusp.store import atomic_folder

#: the defaults of the options that only some routes use (one typed is refused, or said in a
#: warning, where the route does not use it: :func:`~railsusp.cli.common.given_options`)
REFINE_EVALUATIONS, REFINE_SCREEN, REFINE_STARTS = 40, 64, 2
PREVIEW_S = 20.0
GEOMETRY_DRAWS = 8


@app.command()
def estimate(
    measured: Annotated[Path, typer.Option(help="field folder (index.json) of recordings")],
    out: Annotated[Path, typer.Option(help="output folder for the estimate")],
    surrogate: Annotated[
        Path | None,
        typer.Option(
            help="folder of surrogate bundles per condition, e.g. RUN/surrogates/cnn-gru "
            "or RUN/surrogates/gp-stats"
        ),
    ] = None,
    simulator: Annotated[
        bool, typer.Option(help="use the batched simulator instead of a surrogate (slow reference)")
    ] = False,
    parameters: Annotated[
        str | None, typer.Option(help="key parameters (default: the surrogate's)")
    ] = None,
    statistic: Annotated[
        str,
        typer.Option(
            help="mean, rms, p99, std, p99.85 (EN 14363 maximum), aligned (time-aligned "
            "forces on the recordings' measured track: a surrogate trained on a track family, "
            "or --simulator), or a combination such as mean+p99+std"
        ),
    ] = "mean",
    per_condition: Annotated[bool, typer.Option(help="two objectives per condition")] = False,
    channel_gains: Annotated[
        bool,
        typer.Option(
            help="with --statistic aligned: profile each force channel's gain (calibration "
            "factor, within 1 ± 0.1) out of the comparison"
        ),
    ] = False,
    expected_draws: Annotated[
        int,
        typer.Option(
            help="with --statistic aligned, on recordings whose geometry states its "
            "accuracy: polish NSGA-II's choice by the model's least squares on its mean over "
            "this many draws of the true track geometry given the measured one (instead of "
            "the SIMEX step); --refine compares such means too (0 to 64; 0: neither)"
        ),
    ] = 0,
    simulator_corrections: Annotated[
        int,
        typer.Option(
            help="with --statistic aligned alone: correct the surrogate's level error at "
            "NSGA-II's estimate by this many simulations of it, repeating the surrogate's "
            "least squares with each (output space mapping; 0 to 5; 0: the surrogate alone)"
        ),
    ] = 0,
    correction_slopes: Annotated[
        bool,
        typer.Option(
            help="with --simulator-corrections: each correction matches the simulator's "
            "slopes too (first order; k + 1 simulations per recording and step), its least "
            "squares within a trust region about the estimate"
        ),
    ] = False,
    slope_update: Annotated[
        str,
        typer.Option(
            help="with --correction-slopes: the slopes at each later point simulated again "
            "('simulated') or carried by Broyden's update from the level's change ('broyden', "
            "no simulation; not across a step under 1 % of range)"
        ),
    ] = "simulated",
    expected_generations: Annotated[
        bool,
        typer.Option(
            help="NSGA-II's generations compare the expected forces too (--expected-draws "
            "times the predictions; --statistic aligned, alone or with mean)"
        ),
    ] = False,
    preview_generations: Annotated[
        int,
        typer.Option(
            help="the first this many generations (below --n-gen) compare each recording's "
            "first --preview-s seconds only, the rest start from their Pareto set on the "
            "whole records (0: none)"
        ),
    ] = 0,
    preview_s: Annotated[
        float, typer.Option(help="seconds of each recording the preview generations compare")
    ] = PREVIEW_S,
    weighting: Annotated[
        str,
        typer.Option(
            help="relative (errors relative to the measured statistic) or noise (in units of "
            "a gp-stats surrogate's predictive standard deviation)"
        ),
    ] = "relative",
    pop_size: Annotated[int, typer.Option(help="NSGA-II population")] = 50,
    n_gen: Annotated[int, typer.Option(help="generations")] = 100,
    crossover: Annotated[float, typer.Option(help="crossover probability")] = 0.9,
    mutation: Annotated[float, typer.Option(help="mutation probability per variable")] = 0.05,
    seed: Annotated[int, typer.Option(help="NSGA-II seed")] = 0,
    seeds: Annotated[int, typer.Option(help="independent runs for the seed spread")] = 1,
    refine: Annotated[
        bool,
        typer.Option(
            help="then refine the estimate by output-error least squares with the simulator "
            "on the recordings' measured track geometry (time-aligned); after --statistic "
            "aligned a polish shown beside NSGA-II's estimate, which stays the estimate"
        ),
    ] = False,
    refine_evaluations: Annotated[
        int, typer.Option(help="most residual evaluations of the refinement")
    ] = REFINE_EVALUATIONS,
    refine_screen: Annotated[
        int, typer.Option(help="Latin hypercube points screened for refinement starts")
    ] = REFINE_SCREEN,
    refine_starts: Annotated[
        int, typer.Option(help="best screened starts refined")
    ] = REFINE_STARTS,
    geometry_draws: Annotated[
        int,
        typer.Option(
            help="draws of the recordings' stated track-geometry error propagated into "
            "NSGA-II's time-aligned estimate and the refined estimate's standard errors (0: "
            "sensor noise only; not used with --expected-draws, which compares the mean over "
            "drawn true tracks instead)"
        ),
    ] = GEOMETRY_DRAWS,
    remove_geometry_bias: Annotated[
        bool,
        typer.Option(
            "--remove-geometry-bias/--keep-geometry-bias",
            help="take the bias that the geometry-error draws estimate (first SIMEX step) "
            "off NSGA-II's time-aligned estimate and off the refined estimate (not used with "
            "--expected-draws)",
        ),
    ] = True,
    held_prior: Annotated[
        str | None,
        typer.Option(
            help="with --refine: ranges the held parameters are known to lie in, display "
            "units, e.g. X15=100:200,X19=20000:40000 (the intervals take them uniform over these "
            "instead of Table 2's ranges; docs/intervals.md)"
        ),
    ] = None,
    wagon: Annotated[
        str | None,
        typer.Option(
            help="wagon data TOML, or a packaged name: loaded (default), tare: the wagon the "
            "simulator runs (--simulator, the corrections, the refinement) and whose static "
            "wheel load the recordings' wheel loads are checked against"
        ),
    ] = None,
) -> None:
    """NSGA-II estimate of the key parameters from measured recordings (Tables 3-5, Figs 8-9)."""
    from railsusp.estimate import (
        NSGAConfig,
        SimulatorForces,
        open_force_model,
        parse_statistics,
    )
    from railsusp.estimate.config import (
        CORRECTIONS_RANGE,
        NSGA_RANGES,
        REFINE_RANGES,
        SEEDS_RANGE,
        check_range,
        check_slope_update,
    )
    from railsusp.estimate.route import EstimateRoute
    from railsusp.measured import read_field
    from railsusp.measured.field_folder import check_not_recordings
    from railsusp.measured.recording import recordings_digest
    from railsusp.surrogate import not_estimated

    try:
        # every option is checked before the recordings are read or NSGA-II runs
        for name, value, (low, high) in (
            ("--pop-size", pop_size, NSGA_RANGES["pop_size"]),
            ("--n-gen", n_gen, NSGA_RANGES["n_gen"]),
            ("--crossover", crossover, NSGA_RANGES["crossover_prob"]),
            ("--mutation", mutation, NSGA_RANGES["mutation_prob"]),
            ("--seed", seed, NSGA_RANGES["seed"]),
            ("--seeds", seeds, SEEDS_RANGE),
            ("--refine-evaluations", refine_evaluations, REFINE_RANGES["max_evaluations"]),
            ("--refine-screen", refine_screen, REFINE_RANGES["screen"]),
            ("--refine-starts", refine_starts, REFINE_RANGES["starts"]),
            ("--geometry-draws", geometry_draws, REFINE_RANGES["geometry_draws"]),
            ("--expected-draws", expected_draws, NSGA_RANGES["expected_draws"]),
            ("--simulator-corrections", simulator_corrections, CORRECTIONS_RANGE),
            ("--preview-generations", preview_generations, (0, n_gen - 1)),
            ("--preview-s", preview_s, NSGA_RANGES["preview_s"]),
        ):
            check_range(name, value, low, high)
        # checked and in its canonical spelling (" aligned" read as a statistic other than
        # aligned where the text was tested, and was stored so)
        statistic = "+".join(parse_statistics(statistic))
        # options of a step that does not run: refused, not ignored (typed, even as the
        # default: click's parameter source tells a typed value from one left out)
        typed = given_options("refine_evaluations", "refine_screen", "refine_starts")
        for name, value in (
            ("--refine-evaluations", refine_evaluations),
            ("--refine-screen", refine_screen),
            ("--refine-starts", refine_starts),
        ):
            if not refine and name in typed:
                raise RailsuspInputError(
                    f"{name} {value} sets the refinement, which runs only with --refine: "
                    f"accepted --refine with it, or no {name}"
                )
        if not preview_generations and given_options("preview_s"):
            raise RailsuspInputError(
                f"--preview-s {preview_s:g} sets the preview generations' record, and "
                "--preview-generations 0 asks for none: accepted --preview-generations 1 or "
                "more (below --n-gen) with it, or no --preview-s"
            )
        if refine and refine_screen and refine_screen < refine_starts:  # as a configuration
            raise RailsuspInputError(
                f"--refine-screen {refine_screen} screens fewer points than --refine-starts "
                f"{refine_starts} starts; accepted --refine-screen 0 (no screening) or at "
                "least --refine-starts"
            )
        prior = parse_held_prior(held_prior, refine, statistic)
        if correction_slopes and not simulator_corrections:
            raise RailsuspInputError(
                "--correction-slopes makes each simulator correction first order; "
                "--simulator-corrections 0 asks for none: give --simulator-corrections 1 to "
                f"{CORRECTIONS_RANGE[1]}"
            )
        check_slope_update(
            slope_update, correction_slopes, "--slope-update", "no --correction-slopes"
        )
        if (surrogate is None) == (not simulator):
            raise RailsuspInputError("give --surrogate FOLDER or --simulator (one of them)")
        check_not_recordings(out)
        # an existing file, an unwritable folder, the folder it runs in or one of the user's
        check_replaced_folder(out, "--out", "estimate", own=("estimate.json",))
        # the output for the command's duration, and what it reads shared: the recordings'
        # folder (a synth-field or sections --write rewrote it under a running estimate,
        # and a read of it in the swap got recordings of two truths under one index.json:
        # the concurrency audit) and the campaign whose surrogates are read
        hold_folders(
            creates=[("--out", out)],
            reads=[("--measured", measured)]
            + [("--surrogate", c) for c in [campaign_of_surrogate(surrogate)] if c is not None],
            near=[("--surrogate", surrogate)] if surrogate is not None else [],
        )
        cfg = NSGAConfig(
            pop_size=pop_size,
            n_gen=n_gen,
            crossover_prob=crossover,
            mutation_prob=mutation,
            seed=seed,
            statistic=statistic,
            per_condition=per_condition,
            weighting=weighting,
            channel_gains=channel_gains,
            expected_draws=expected_draws,
            expected_generations=expected_generations,
            preview_generations=preview_generations,
            preview_s=preview_s,
        )
        route = EstimateRoute(
            nsga=cfg,
            seeds=seeds,
            geometry_draws=geometry_draws,
            remove_geometry_bias=remove_geometry_bias,
            simulator_corrections=simulator_corrections,
            correction_slopes=correction_slopes,
            slope_update=slope_update,
            refine=refine,
            refine_evaluations=refine_evaluations,
            refine_screen=refine_screen,
            refine_starts=refine_starts,
            held_prior=prior,
            refine_setting="--refine",
            corrections_setting="--simulator-corrections",
            held_prior_setting="--held-prior",
        )
        from railsusp.estimate.nsga_geometry import geometry_draws_unused
        from railsusp.params import STUDY_KEY_PARAMETERS, parse_sampled
        from railsusp.surrogate.pretrained import wagon_hash
        from railsusp.vehicle.wagon import load_wagon, wagon_reference

        chosen = parse_sampled(parameters) if parameters is not None else None
        try:
            wagon_data = load_wagon(wagon)  # a packaged name or a file, one-line errors
        except (RailsuspInputError, ValueError, FileNotFoundError) as exc:
            raise RailsuspInputError(option_naming("--wagon", wagon, str(exc))) from None
        if surrogate is not None:
            try:
                model, params = open_force_model(surrogate, chosen)
            except FileNotFoundError as exc:
                raise RailsuspInputError(
                    option_naming("--surrogate", surrogate, str(exc))
                ) from None
            trained = getattr(model, "wagon", None)  # surrogates that know their wagon
            if trained is not None and wagon is None:
                wagon_data = trained  # the surrogates' wagon, unless --wagon says another
            elif trained is not None and wagon_hash(trained) != wagon_hash(wagon_data):
                raise RailsuspInputError(
                    f"--wagon {wagon}: the surrogates in {surrogate} were trained on another "
                    f"wagon ({trained.name}); accepted that wagon, or surrogates trained on "
                    f"{wagon_data.name}"
                )
        else:
            params = chosen or STUDY_KEY_PARAMETERS
        check_held_prior_unused(prior, params, parameters, surrogate is not None)
        try:
            recs = read_field(measured, wagon=wagon_data)
        except (RailsuspInputError, FileNotFoundError) as exc:
            raise RailsuspInputError(option_naming("--measured", measured, str(exc))) from None
        if surrogate is None:
            model = SimulatorForces(params, wagon=wagon_data)
        # the corrections' and the refinement's simulator: the model itself without surrogates
        sim = model if surrogate is None else SimulatorForces(params, wagon=wagon_data)
        given = []  # 0 draws asks for none: nothing ignored where none are drawn
        if geometry_draws and given_options("geometry_draws"):
            given.append(f"--geometry-draws {geometry_draws}")
        if given_options("remove_geometry_bias") and not remove_geometry_bias:
            given.append("--keep-geometry-bias")
        why = geometry_draws_unused(cfg, recs, refine, geometry_draws) if given else ""
        if why:  # as expected_draws without an accuracy: the recordings decide, so a warning
            warnings.warn(f"{' '.join(given)}: not used: {option_text(why)}", stacklevel=1)
        with warnings_as_options():
            res = route.run(model, recs, params, progress=console.status, simulator=sim)
        # the folder as one artefact: a full disk or a kill while the figures are drawn
        # leaves the folder as it was, not an estimate.json without its figures
        # (an earlier estimate's validation is not carried into it: it validated that one)
        with atomic_folder(out, drop=("validation",)) as tmp:  # a link: where it points
            res.save(
                tmp,
                extra={
                    "measured": str(measured.resolve()),
                    "measured_digest": recordings_digest(recs),  # validate's check
                    "model": str(surrogate.resolve()) if surrogate else "simulator",
                    "not_estimated": not_estimated(surrogate, params),
                    # validate's default: the wagon the estimate simulated (the option's,
                    # else the surrogates'), as data (a custom file's name loads nothing)
                    "wagon": wagon_reference(wagon),
                    "wagon_data": wagon_data.model_dump(mode="json"),
                },
            )
    except (RailsuspInputError, ValueError, FileNotFoundError) as exc:
        fail(option_text(str(exc)))
    except KeyboardInterrupt:  # nothing kept to resume from: said so, not the common line
        raise interrupted() from None
    console.print(
        frame_table(
            res.log.tail(8), "NSGA-II log (last generations; the study's Table 4)", fmt="{:.6g}"
        )
    )
    console.print(frame_table(res.table(), "Estimate (the study's Table 5 layout)"))
    console.print(f"wrote {out}")
