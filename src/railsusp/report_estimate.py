"""The report's estimation and validation sections (study Tables 3-5 and 8-9): what made
the estimate, said in words beside its tables and figures, and how it was validated."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from railsusp.estimate.intervals import IDENTIFIED_WIDTH_PCT
from railsusp.estimate.refine import CHOICE, compared_model_of
from railsusp.report_doc import Doc, fraction_errors_to_pct, header
from railsusp.store import read_json


def validation_section(doc: Doc, val: Path) -> None:
    """The before/after validation (``val``: its folder), when it was run."""
    if not (val / "validation.csv").exists():
        return
    doc.h("Validation before and after calibration (study Tables 8/9, Figures 12/13)")
    doc.p(
        "Errors in % of the measured value. The kN columns hold the statistic itself, of "
        "|Y| for the lateral force and of Q for the vertical (a record statistic of the "
        "lateral force is of its magnitude); for the statistic 'aligned' they hold the "
        "measured series' standard deviation and the RMS of the sample-by-sample "
        "difference from it, the error being that RMS in % of the standard deviation."
    )
    table = pd.read_csv(val / "validation.csv")
    table["statistic"] = [
        statistic_label(str(st), str(force))
        for st, force in zip(table["statistic"], table["force"], strict=True)
    ]
    doc.table(fraction_errors_to_pct(table))
    checked = read_json(val / "validation.json")
    if checked.get("expected_draws"):
        doc.p(
            "As the estimate was made, on recordings whose track geometry states its "
            "accuracy each simulation is the mean over "
            f"{checked['expected_draws']} draws of the true geometry given the measured "
            "one (its statistics the mean of the draws' statistics)."
        )
    for line in checked.get("failures", []):
        doc.p(f"Simulation stopped (its rows are empty): {line}")
    for png in sorted(val.glob("validation-*.png")):
        doc.figure(
            png,
            f"Measured vs simulated, {png.stem.removeprefix('validation-')}: an excerpt of "
            "the series and the whole record's statistics",
        )
    if (val / "recovery.csv").exists():
        doc.h("Parameter recovery against the hidden truth", 3)
        recovery = pd.read_csv(val / "recovery.csv")
        if "verdict" in recovery:  # the older name of 'identified' is not shown beside it
            doc.p(RECOVERY_VERDICTS)
            recovery = recovery.drop(columns=["identifiable"], errors="ignore")
        doc.table(recovery)


#: what the recovery table's verdicts mean (the summary card's, docs/api.md)
RECOVERY_VERDICTS = (
    "Verdict, as in the summary card: identified where the estimate's interval is a "
    f"statistical one at most {IDENTIFIED_WIDTH_PCT:g} % of the range wide and nothing "
    "speaks against it; not identified (no confidence interval from this estimate) where "
    "this route alone is the reason: NSGA-II's Pareto range is no confidence interval, and "
    "the same recordings, refined or through the posterior, may fix the parameter; not "
    "identifiable from these recordings where the recordings are the reason (a wide "
    "interval, a small Sobol index, a Cramér-Rao bound). The truth's error is scored "
    "whatever the verdict."
)


#: what the kN columns of the validation table's time-aligned rows hold (the report says it
#: in its text: its numbers are not force statistics), marked ``aligned*`` in the table
ALIGNED_NOTE = (
    "* aligned: measured (kN) is the measured series' standard deviation, the other kN "
    "columns the RMS of each simulation's sample-by-sample difference from it, and their "
    "errors that RMS in % of the standard deviation."
)


def statistic_label(statistic: str, force: str) -> str:
    """A validation row's statistic as the report shows it: what its kN columns hold."""
    if statistic == "aligned":
        return "aligned (kN: measured s.d.; simulated: RMS difference)"
    return f"{statistic} of |Y|" if force == "Y" else f"{statistic} of Q"


#: the intervals of an estimate.json written before they were stored with it: the
#: refinement's 90 % confidence intervals, ± 1.645 standard errors
OLD_INTERVALS = "the refinement's 90 % confidence intervals (± 1.645 standard errors)"


def _start(ref: dict) -> str:
    """Where the refinement started, in words, where it was not NSGA-II's choice (the
    starts are screened: the nominal set or a screening point can win)."""
    origin = ref.get("start_origin") or CHOICE
    if origin == CHOICE:
        return " from NSGA-II's choice"
    n = len(ref.get("starts", []))
    if n == 1:  # ("of the 1 starts refined ... it ended lowest" read as a choice among many)
        return (
            f" from {origin}, not NSGA-II's choice: the one start refined (the best of "
            f"{ref.get('screened_starts', 0)} screened by time-aligned cost)"
        )
    return (
        f" from {origin}, not NSGA-II's choice: of the {n} starts "
        f"refined (the best of {ref.get('screened_starts', 0)} screened by time-aligned "
        "cost) it ended lowest"
    )


def _against_spread(info: dict, ref: dict) -> str:
    """How the standard errors compare with the Pareto spread, parameter by parameter, as
    the numbers say (it used to claim them far below the spread always). The standard error
    compared is the one the estimate table shows: the intervals' total, with the held
    parameters' part, where estimate.json stores it, else the refinement's own (the noise
    and geometry part alone was compared once, under the table's total)."""
    spread = info.get("pareto_spread_pct_range") or {}
    own = ref.get("standard_error_pct_range") or {}
    total = ((info.get("intervals") or {}).get("details") or {}).get(
        "total_standard_error_pct_range"
    ) or {}
    se = {p: total.get(p, v) for p, v in own.items()}
    common = [p for p in se if p in spread]
    above = [p for p in common if se[p] >= spread[p]]
    if not common:
        return ""
    which = " (the table's total)" if total else ""
    if not above:
        return f", which tell them apart: every standard error{which} is below the spread"
    return (
        ", which tell them apart for "
        + (", ".join(p for p in common if p not in above) or "none of them")
        + "; for "
        + ", ".join(above)
        + f" the standard error{which} is as large as the spread or larger"
    )


#: the Surrogates table's ``role`` of the row of the model NSGA-II ran on, and of the others
ROLE_USED = "the estimate's force model"
ROLE_COMPARED = "comparison only"


def force_model_name(model: object) -> str | None:
    """The force model an ``estimate.json`` records (``model``): the pipeline's model name,
    ``railsusp estimate``'s surrogate folder (named as its model) or "simulator"; None
    where it records none (written before it did)."""
    if not isinstance(model, str) or not model:
        return None
    return model if model == "simulator" else Path(model).name


def force_model_text(model: str | None, configured: bool = True) -> str:
    """The NSGA-II section's sentence on the force model it ran on (``model``:
    :func:`force_model_name`; ``configured``: named by the pipeline's ``surrogate.model``,
    not a folder given to ``railsusp estimate``): the section never said which of the
    Surrogates table's rows it was."""
    if model is None:
        return (
            "This estimate does not record the force model NSGA-II ran on (an estimate.json "
            "written before it was recorded)."
        )
    if model == "simulator":
        return "NSGA-II ran on the simulator itself, not on a surrogate."
    setting = " (surrogate.model)" if configured else ""
    return (
        f"NSGA-II ran on the surrogate {model}{setting}: where the Surrogates section scored "
        f"it on held-out simulations, its rows are marked '{ROLE_USED}' there, and any other "
        "rows are comparison only."
    )


def estimate_section(doc: Doc, est: Path) -> None:
    """NSGA-II's estimate: its log, how it was made (choice, SIMEX step or expected-forces
    polish, the simulator refinement beside it or making it), the table and figures."""
    doc.h("NSGA-II estimation (study Tables 3-5, Figures 8/9)")
    info = read_json(est / "estimate.json")
    model = info.get("model")
    configured = isinstance(model, str) and Path(model).name == model  # not a folder
    doc.p(force_model_text(force_model_name(model), configured))
    log = pd.read_csv(est / "nsga_log.csv")
    doc.p("First and last generations of the NSGA-II log:")
    doc.table(pd.concat([log.head(4), log.tail(4)]).drop_duplicates())
    ref = info.get("refinement")
    drawn = (ref or {}).get("expected_draws")
    on_drawn = f" (the mean over {drawn} draws of the true track geometry)" if drawn else ""
    corrected = bool(info.get("simulator_corrections"))
    compared = compared_model_of(ref)
    made = (
        "The estimate starts from NSGA-II's on the surrogate against the recordings' "
        "time-aligned forces on their measured track ("
        + info.get("choice_rule", "")
        + "), corrected by the simulator as said below."
        if corrected
        else "The estimate is NSGA-II's on the surrogate against the recordings' time-aligned "
        "forces on their measured track (" + info.get("choice_rule", "") + "); the study's "
        "method gives it without the simulator."
    )
    if ref and info.get("polished_display"):
        doc.p(
            made + " Beside it, as a polish, "
            f"the output-error refinement with {compared} on the same track{on_drawn}"
            f"{_start(ref)}: time-aligned cost "
            f"{ref['cost_start']:.3g} -> {ref['cost']:.3g} in {ref['n_evaluations']} "
            f"evaluations (the '{header('polished')}' column of the tables). Its interval "
            "is the Pareto set's range, not a confidence interval."
        )
    elif ref:
        doc.p(
            f"The estimate was refined by output-error least squares with {compared} on "
            f"the recordings' measured track{on_drawn}{_start(ref)}: time-aligned cost "
            f"{ref['cost_start']:.3g} -> {ref['cost']:.3g} in {ref['n_evaluations']} "
            "evaluations. The estimate is the refined point"
            + (
                " less the bias that draws of the track geometry's stated error estimate "
                "(the first SIMEX step)"
                if ref.get("geometry_bias_removed")
                else ""
            )
            + ". Its intervals are "
            + (info.get("intervals") or {}).get("description", OLD_INTERVALS)
            + (
                f" (geometry error from {ref['geometry_draws']} draws)."
                if ref.get("geometry_draws")
                else "."
            )
            + " The Pareto spread is the range of parameter sets whose force statistics the "
            "surrogate objectives cannot tell apart; the refinement's standard errors come "
            "from its time-aligned series" + _against_spread(info, ref) + "."
        )
    elif corrected or info.get("expected_polish") or info.get("choice") == "least-squares":
        doc.p(
            made + " Its interval is the Pareto set's range, moved with the estimate: not a "
            "confidence interval (a narrow Pareto set can lie far from the truth), so no "
            "parameter is called identified from it."
        )
    else:
        doc.p(
            "The estimate is NSGA-II's choice on the Pareto front (closest to the ideal "
            "point). Its interval is the Pareto set's range: the parameter sets whose force "
            "statistics the objectives cannot tell apart. That is not a confidence interval "
            "(a narrow Pareto set can lie far from the truth), so no parameter is called "
            "identified from it."
        )
    geometry = info.get("nsga_geometry") or {}
    if geometry.get("draws"):
        doc.p(
            f"{geometry['draws']} draws of the track geometry's stated measurement error, "
            "each added to the measured geometry, moved NSGA-II's choice (columns: the track "
            "geometry error's bias, their mean, and its scatter, their RMS): a least-squares "
            "fit on forces computed from erroneous geometry is biased (errors in variables). "
            + (
                "NSGA-II's estimate is its choice less that mean (the first SIMEX step); the "
                "choice itself is shown beside it"
                + (
                    f", and {', '.join(geometry['bias_kept'])} keep the choice: the draws move "
                    "them by more than half their range, so the forces do not fix them."
                    if geometry.get("bias_kept")
                    else "."
                )
                if geometry.get("bias_removed")
                else "The bias was kept in the estimate (remove_geometry_bias = false, "
                "--keep-geometry-bias)."
            )
        )
    polish = info.get("expected_polish")
    if polish:
        doc.p(
            "The recordings' track geometry states its accuracy, and the measured geometry "
            "carries its error as extra roughness, which biases a comparison on it. NSGA-II's "
            f"choice (column '{header('nsga_choice')}') was therefore polished by the force "
            "model's own time-aligned least squares on its expected forces, the mean over "
            f"{polish['draws']} draws of the true geometry given the measured one: cost "
            f"{polish['cost_start']:.3g} -> {polish['cost']:.3g} in {polish['n_evaluations']} "
            "evaluations. That is NSGA-II's estimate, and its Pareto range moved with it."
        )
    _corrections_paragraphs(doc, info)
    if info.get("simulator_corrections_stopped"):
        doc.p(f"Simulator corrections stopped: {info['simulator_corrections_stopped']}.")
    if info.get("cramer_rao_pct_range"):
        doc.p(
            "Cramér-Rao bound: the smallest standard deviation (% of the range) that any "
            "estimator can reach from these statistics, at the estimate; above 5 % the data "
            "cannot fix the parameter to that precision."
        )
    doc.table(pd.read_csv(est / "estimate.csv"))
    doc.figure(
        est / "pareto.png", "Pareto front, and each parameter's Pareto set with the final estimate"
    )
    doc.figure(est / "convergence.png", "Convergence of the estimate towards the final one")


def _corrections_paragraphs(doc: Doc, info: dict) -> None:
    """What the simulator corrections did (estimate.json's ``simulator_corrections``): how
    many, from how many simulations, and, for first-order ones, the simulator's check of
    each step and the trust boxes."""
    corrections = info.get("simulator_corrections") or []
    if not corrections:
        return
    n, last = len(corrections), corrections[-1]
    drawn = last.get("expected_draws")
    slopes = info.get("correction_slopes")
    checks = [c["check"] for c in corrections if c.get("check")]
    checked = [c for c in checks if c["accepted"] is not None]
    rejected = sum(c["accepted"] is False for c in checked)
    per_point = len(info["parameters"]) + 1
    if not slopes:
        how = (
            "The surrogate's level error at NSGA-II's estimate was then measured by "
            f"{n} simulation{'s' if n > 1 else ''} of it"
        )
        added = (
            ", added to the surrogate, whose time-aligned least squares was repeated "
            "(output space mapping): "
        )
    else:
        how = (
            f"The surrogate's error at NSGA-II's estimate was then corrected {n} time"
            f"{'s' if n > 1 else ''} to first order, "
        )
        if slopes.get("slope_update") == "broyden" and n > 1:
            how += (
                f"the first from {per_point} simulations of the estimate and its steps in "
                "every key per recording, the later ones from one each (the slopes carried "
                "by Broyden's update)"
            )
        else:
            how += (
                f"each kept point from {per_point} simulations of the estimate and its steps "
                "in every key per recording" + (" (a rejected one from one)" if rejected else "")
            )
        added = (
            ", and the same for their slopes in every key (the estimate stepped by "
            f"{100 * slopes['step_of_range']:g} % of each range), added to the surrogate, "
            "whose time-aligned least squares was repeated within a trust box of "
            f"{100 * slopes['trust_box_of_range']:g} % of each range at first (output space "
            "mapping): "
        )
    doc.p(
        how
        + " on the recordings' tracks"
        + (f" (the mean over the same {drawn} drawn true tracks)" if drawn else "")
        + ": the simulator's forces less the surrogate's, sample by sample"
        + added
        + f"least-squares cost {corrections[0]['cost_start']:.5g} at the first start -> "
        f"{last['cost']:.5g} after the last ({n} step(s); the corrected surrogate's "
        "time-aligned cost, half the sum of squared aligned errors as the polish's). The "
        "estimate is that point"
        + (", less the same geometry bias" if last.get("geometry_bias_removed") else "")
        + f"; NSGA-II's own is the column '{header('nsga_estimate')}', and the Pareto range "
        "moved with it."
    )
    if not checked:
        return
    boxes = ", ".join(f"{100 * c['box']:.3g}" for c in checks)
    stopped = sum(bool(c["stopped"]) for c in checked)
    doc.p(
        "The simulator checked the point each step proposed at the next correction: "
        f"{len(checked) - rejected} of {len(checked)} kept (its cost fell by at least a tenth "
        "of the fall the corrected surrogate predicted, or did not rise where none was "
        f"predicted), {rejected} rejected"
        + (f", {stopped} of them because the simulation stopped" if stopped else "")
        + (
            " (the next least squares then started from the same point in a smaller box)"
            if rejected
            else ""
        )
        + ("; the last step's point is unchecked" if checks[-1]["accepted"] is None else "")
        + f". Trust boxes, % of each range: {boxes}."
    )
