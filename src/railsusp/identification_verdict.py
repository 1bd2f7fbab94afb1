"""Whether each estimated parameter is identified from the recordings, from a result JSON
alone (``estimate.json`` or a posterior result; no truth needed): the verdict the validator's
recovery table, the run summary and the report give, and why not where it is not. Kept apart
from the validation run (:mod:`railsusp.validate`), which re-simulates, because the verdict
reads only what the estimate wrote and the sensitivity's largest total Sobol indices
(:func:`max_st`): the summary gives it without simulating anything.
"""

from __future__ import annotations

from pathlib import Path

from railsusp.errors import first_listed
from railsusp.estimate import BOUND_LIMIT_PCT
from railsusp.estimate.intervals import identification, intervals_of
from railsusp.store import read_parquet

#: a parameter whose largest total Sobol index on the used features is below this is not
#: identified (nor one whose interval is wider than IDENTIFIED_WIDTH_PCT of its range)
SOBOL_ST_LIMIT = 0.1


def identification_issues(est: dict, max_st: dict[str, float] | None = None) -> dict[str, str]:
    """Why each estimated parameter is not identified from the recordings ('' when it is),
    from a result JSON alone (``estimate.json`` or a posterior result; no truth needed).

    The verdict follows the estimate's interval (:func:`~railsusp.estimate.intervals.
    identification`): identified only by a statistical interval (posterior, refinement) at
    most :data:`~railsusp.estimate.intervals.IDENTIFIED_WIDTH_PCT` % of the range wide; the
    NSGA-II Pareto range is not one, so an estimate from NSGA-II alone is never called
    identified. Further reasons: a posterior whose estimator failed its coverage check, a
    largest total Sobol index (``max_st``) below :data:`SOBOL_ST_LIMIT`, a Cramér-Rao bound
    of the statistics above its limit, or none because the estimate lies on its range bound
    (:func:`~railsusp.estimate.identifiability.cramer_rao_pct_range`)."""
    max_st = max_st or {}
    intervals = intervals_of(est)
    details = intervals.details
    geometry = details.get("geometry_error_pct_range") or {}
    held = details.get("held_parameters_error_pct_range") or {}
    out = {}
    for p in est["parameters"]:
        reasons = []
        why = identification(intervals[p]) or _cut_by_the_range(intervals, p)
        if why:
            parts = [
                f"{name} {d[p]:.1f} % of range"
                for name, d in (("track-geometry error", geometry), ("held parameters", held))
                if d.get(p, 0.0) >= 0.05
            ]
            reasons.append(why + (f" (standard error from {', '.join(parts)})" if parts else ""))
        if est.get("calibrated") is False:
            reasons.extend(_not_calibrated(est))
        if p in max_st and max_st[p] < SOBOL_ST_LIMIT:
            reasons.append(f"largest Sobol ST {max_st[p]:.3g} < {SOBOL_ST_LIMIT:g}")
        # the bound is that of the statistics; a refined estimate used the series instead
        bound = (
            0.0 if est.get("refinement") else (est.get("cramer_rao_pct_range") or {}).get(p, 0.0)
        )
        if bound > BOUND_LIMIT_PCT:
            reasons.append(f"Cramér-Rao bound {bound:.1f} % of range")
        elif bound != bound:  # NaN: the estimate lies on its range bound
            reasons.append("on its range bound, where no Cramér-Rao bound applies")
        out[p] = "; ".join(reasons)
    return out


def _cut_by_the_range(intervals, p: str) -> str:
    """Why a refinement's interval does not identify ``p`` though its width, cut by the
    parameter's range (an estimate on or near its bound), is within the limit: its error
    quantiles span more ('' where they do not, or are not stored). Stop 77's hunt: X14 on
    its bound with errors of +-17 % of range, cut to 17 % wide, read as identified."""
    from railsusp.estimate.intervals import IDENTIFIED_WIDTH_PCT

    quantiles = (intervals.details.get("error_quantiles_pct_range") or {}).get(p)
    if not quantiles:
        return ""
    uncut = float(quantiles[1]) - float(quantiles[0])
    if uncut <= IDENTIFIED_WIDTH_PCT:
        return ""
    iv = intervals[p]
    return (
        f"{100 * (iv.level or 0.0):g} % interval {uncut:.1f} % of range wide, cut by the "
        f"range's bound to {iv.width_pct_range:.1f} %"
    )


#: the three verdicts of :func:`identification_verdicts`, as the kinds the summary card
#: names (:data:`railsusp.summary.NOT_IDENTIFIED`, ``NOT_IDENTIFIABLE``; the summary reads
#: this module, so the words are looked up there by its readers, not imported here)
IDENTIFIED = "identified"
ROUTE = "route"
RECORDINGS = "recordings"


def identification_verdicts(
    est: dict, max_st: dict[str, float] | None = None
) -> dict[str, tuple[str, str]]:
    """Each estimated parameter's verdict and its reason ('' when identified), the summary
    card's three: :data:`IDENTIFIED`; :data:`ROUTE` where this route alone is the reason
    (NSGA-II's Pareto range is no confidence interval: the same recordings, refined or
    through the posterior, may fix the parameter; the card's "not identified"); else
    :data:`RECORDINGS` (the recordings are the reason: a wide statistical interval, a small
    Sobol index, a Cramér-Rao bound, a failed check; the card's "not identifiable from these
    recordings"). The validator's recovery table called every one of them "not
    identifiable"."""
    why_not = identification_issues(est, max_st)
    intervals = intervals_of(est)
    out = {}
    for p, why in why_not.items():
        if not why:
            out[p] = (IDENTIFIED, "")
        elif route_only(intervals, p, why):
            out[p] = (ROUTE, why)
        else:
            out[p] = (RECORDINGS, why)
    return out


def route_only(intervals, p: str, why: str) -> bool:
    """Whether the estimate's route alone is why ``p`` is not identified: its interval (of
    ``intervals``, :func:`~railsusp.estimate.intervals.intervals_of`) is no statistical one
    and ``why`` says nothing else (the rule :func:`railsusp.summary.estimate_table`
    applies)."""
    return p in intervals and not intervals[p].statistical and why == identification(intervals[p])


def _not_calibrated(est: dict) -> list[str]:
    """Why a posterior result is not calibrated, as its JSON says: statistics of the
    recording outside the training cases' range (``outside_training``), more sections than
    any check covered (``checked_as_sections`` null), its estimator's failed coverage check
    (``check_passed``; in results without it, when neither of the others is the cause).
    Every uncalibrated result was said to have failed its check, a recording outside what
    the estimator learnt from too (the posterior fixes of stop 65)."""
    reasons = []
    outside = est.get("outside_training") or []
    if outside:
        reasons.append(
            f"the recording's statistics outside the estimator's training "
            f"({first_listed(outside, 4)})"
        )
    if "checked_as_sections" in est and est["checked_as_sections"] is None:
        reasons.append("no coverage check covers this number of sections")
    # the check's own verdict (results of before carry none: then the remaining cause)
    if est.get("check_passed") is False or ("check_passed" not in est and not reasons):
        reasons.append("the posterior estimator failed its coverage check")
    return reasons


def max_st(path: str | Path) -> dict[str, float]:
    """Largest total Sobol index of each parameter as the key-parameter rule ranks them, from
    a sensitivity folder or its ``key_parameters.json`` (as that run's rule read them), or
    from ``indices.parquet`` with the rule's defaults (its statistics, flat features left
    out: the largest over every feature gave another verdict than the pipeline's). An
    analysis stamped with another campaign than the one beside it (``RUN/sensitivity`` of a
    campaign replaced since) is refused in one line
    (:func:`~railsusp.key_parameters.check_sensitivity_output`; unstamped: read as before),
    as is a damaged ``indices.parquet`` (its pages' checksums)."""
    from railsusp.key_parameters import (
        check_sensitivity_output,
        read_selection,
        select_key_parameters,
    )

    path = Path(path)
    if path.is_dir():
        path = path / "key_parameters.json"
    check_sensitivity_output(path)
    remedy = f"run `railsusp sensitivity {path.parent.parent}` again"
    if path.suffix == ".json":  # its fields checked: a damaged file is named, one line
        return read_selection(path, remedy, keys=False, max_st=True)["key_parameters"]["max_st"]
    return select_key_parameters(read_parquet(path, remedy)).max_st
