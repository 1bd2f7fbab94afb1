"""The answer of a run, read from its run directory alone: per suspension element the nominal
value, the estimate with an interval in engineering units, the change from nominal and a
verdict against the wagon's tolerances; per condition the force agreement before and after
calibration; the wagon and the recordings used.

The report's summary card and :class:`railsusp.api.RunResult` both read these tables, so the
Python API and the report never disagree. The tolerances themselves (the wagon data's
``[tolerances]`` table, read and checked before any stage runs) are
:mod:`railsusp.suspension_tolerances`; this module takes the ones a run recorded
(:func:`run_tolerances`).
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from railsusp.errors import RailsuspInputError
from railsusp.numbers import sig3
from railsusp.params import MAIN_SUSPENSION, spec
from railsusp.store import read_json
from railsusp.summary_files import (
    campaign_config,
    check_table_fields,
    damaged,
    read_estimate,
    read_validation,
)
from railsusp.suspension_tolerances import Tolerances, read_tolerances

WITHIN = "within tolerance"
DEGRADED = "degraded"
NOT_IDENTIFIABLE = "not identifiable from these recordings"
#: an estimate whose route gives no confidence interval (NSGA-II alone): the recordings
#: may well fix the parameter (a refinement or the posterior says how well), this
#: estimate does not say
NOT_IDENTIFIED = "not identified: no confidence interval from this estimate"
NOT_ESTIMATED = "not estimated"


def _state(run: Path) -> dict:
    state = read_json(run / "pipeline.json") if (run / "pipeline.json").exists() else {}
    return state if isinstance(state, dict) else {}


def run_tolerances(run: str | Path) -> Tolerances:
    """The tolerances of the wagon that a run used: as ``pipeline.json`` recorded them when
    the run started, else (a run made before they were recorded) read from its
    configuration's ``wagon`` file."""
    state = _state(Path(run))
    if "tolerances" in state:
        return Tolerances.from_dict(state["tolerances"], f"{run}: pipeline.json tolerances")
    return read_tolerances((state.get("config") or {}).get("wagon"))


def estimate_table(run: str | Path, tolerances: Tolerances | None = None) -> pd.DataFrame:
    """One row per main suspension parameter (display units): element, unit, nominal,
    estimate, standard error, interval (low, high, and how it was formed), change from
    nominal (%), tolerance (%), verdict and a note saying why."""
    from railsusp.estimate.config import held_at_of
    from railsusp.estimate.identifiability import on_range_bound
    from railsusp.estimate.intervals import intervals_of
    from railsusp.identification_verdict import identification_issues, max_st, route_only

    run = Path(run)
    tol = tolerances or run_tolerances(run)
    path = run / "estimate" / "estimate.json"
    est = read_estimate(path)
    sens = run / "campaign" / "sensitivity"
    st = max_st(sens) if (sens / "key_parameters.json").exists() else {}
    try:  # the intervals and their verdicts, as the estimate stored them
        why_not = identification_issues(est, st)
        intervals = intervals_of(est)
    except RailsuspInputError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        raise damaged(path, f"its intervals do not read ({type(exc).__name__}: {exc})") from None
    check_table_fields(est, intervals.details, path)
    params = list(est["parameters"])
    # the standard errors the intervals were formed from; else the refinement's, where it
    # made the estimate (a polish beside NSGA-II's estimate is another point: its errors
    # are not the estimate's)
    made_by_refinement = est.get("estimate_source", "refinement") == "refinement"
    se_pct = intervals.details.get("total_standard_error_pct_range") or (
        (est.get("refinement") or {}).get("standard_error_pct_range", {})
        if made_by_refinement
        else {}
    )
    camp = campaign_config(run) if st or sens.exists() else {}
    sampled = set(camp.get("parameters", MAIN_SUSPENSION))
    assumed = {r["symbol"]: r for r in est.get("not_estimated", [])}
    # the simulator polish beside NSGA-II's estimate (time-aligned route), when there is one
    polished = est.get("polished_display") or {}
    held_at = held_at_of(est, str(path))
    rows = []
    for p in MAIN_SUSPENSION:
        s = spec(p)
        lo, hi = s.bounds_display  # type: ignore[misc]
        row = {
            "parameter": p,
            "element": s.description,
            "unit": s.display_unit,
            "nominal": s.nominal_display,
            "estimate": float("nan"),
            "standard_error": float("nan"),
            "low": float("nan"),
            "high": float("nan"),
            "interval": "",
            "change_pct": float("nan"),
            "tolerance_pct": tol.of(p),
            "verdict": "",
            "note": "",
        }
        if polished:
            row["polished"] = float(polished.get(p, float("nan")))
        if p not in params:
            # held at nominal, or at the centre of the user's held_prior range (the value
            # the estimate's simulations and the validation took)
            value = float(held_at.get(p, s.nominal_display))
            row["estimate"] = value
            row["change_pct"] = 100.0 * (value - s.nominal_display) / s.nominal_display
            row["verdict"] = f"{NOT_ESTIMATED}: held at {sig3(value)} {s.display_unit}"
            held = (intervals.details.get("held_parameters_assumed") or {}).get(p)
            if held:  # the refinement's intervals took it uniform over a range
                row["verdict"] = (
                    f"{NOT_ESTIMATED}: held at {sig3(held['held_at_display'])} {s.display_unit}, "
                    f"in the intervals anywhere in {sig3(held['low_display'])}-"
                    f"{sig3(held['high_display'])} {s.display_unit} ("
                    + ("estimate.held_prior" if held["range"] == "prior" else "Table 2 range")
                    + ")"
                )
            varied = assumed.get(p, {})  # the force model's training varied it (a range)
            if varied.get("assumed") == "varied" and not held:
                where = (
                    "the estimate's simulations and the validation"
                    if estimate_simulated(est)
                    else "the validation's simulations"
                )
                row["verdict"] = (
                    f"{NOT_ESTIMATED}: held at {sig3(s.nominal_display)} {s.display_unit} in "
                    f"{where} (varied over {sig3(varied['low'])}-{sig3(varied['high'])} "
                    f"{s.display_unit} in the surrogate's training)"
                )
            if varied.get("assumed") == "varied":  # a network set's, whatever the sensitivity
                row["note"] = "not an input of the force model (varied in its training)"
            else:
                row["note"] = (
                    "not a key parameter of the sensitivity analysis"
                    if p in sampled
                    else "not varied in the campaign"
                )
            rows.append(row)
            continue
        v = float(est["estimate_display"][p])
        row["estimate"] = v
        row["change_pct"] = 100.0 * (v - s.nominal_display) / s.nominal_display
        if p in se_pct:
            row["standard_error"] = se_pct[p] / 100.0 * (hi - lo)
        if p in intervals:
            row["low"], row["high"] = intervals[p].low, intervals[p].high
            row["interval"] = intervals.description
        limit = tol.of(p)
        single = p in intervals and not intervals[p].statistical and row["low"] == row["high"]
        if why_not.get(p):
            # the route alone (NSGA-II's Pareto range is no confidence interval) is not the
            # recordings' fault: the same recordings refined identify it
            only_route = route_only(intervals, p, why_not[p])
            row["verdict"] = NOT_IDENTIFIED if only_route else NOT_IDENTIFIABLE
            row["note"] = why_not[p]
        else:
            inside = abs(row["change_pct"]) <= limit
            row["verdict"] = WITHIN if inside else DEGRADED
            band = (s.nominal_display * (1 - limit / 100), s.nominal_display * (1 + limit / 100))
            if math.isfinite(row["low"]):
                reaches_out = row["low"] < band[0] or row["high"] > band[1]
                reaches_in = row["high"] >= band[0] and row["low"] <= band[1]
                if single:
                    row["note"] = "a one-point Pareto set: no spread to judge the uncertainty"
                elif inside and not reaches_in:
                    row["note"] = "the interval lies wholly beyond the tolerance"
                elif inside and reaches_out:
                    row["note"] = "the interval reaches beyond the tolerance"
                elif not inside and not reaches_out:
                    row["note"] = "the interval lies wholly within the tolerance"
                elif not inside and reaches_in:
                    row["note"] = "the interval reaches back within the tolerance"
        if on_range_bound([p], [v * s.scale])[0]:
            row["note"] = "; ".join(
                n for n in (row["note"], "on the bound of the search range (Table 2): the "
                            "search stopped there, the change is the range's") if n
            )  # fmt: skip
        rows.append(row)
    return pd.DataFrame(rows).set_index("parameter")


#: what the error of each validation statistic means, for the one-line agreement
_MEANING = {
    "aligned": "time-aligned RMS difference over the measured standard deviation",
    "mean": "error of the record mean",
    "rms": "error of the record RMS",
    "p99": "error of the 99th percentile",
    "std": "error of the standard deviation",
}


def estimate_simulated(est: dict) -> bool:
    """Whether an ``estimate.json``'s route ran the simulator: NSGA-II on it, a refinement
    comparing it (older files name none: theirs did; a polish is the refinement's point) or
    simulator corrections. The network set's route without them simulates nothing until
    the validation."""
    from railsusp.estimate.refine import SIMULATOR_TEXT, compared_model_of

    ref = est.get("refinement")
    refined = bool(ref) and compared_model_of(ref) == SIMULATOR_TEXT
    return bool(est.get("model") == "simulator" or refined or est.get("simulator_corrections"))


def force_agreement(run: str | Path) -> pd.DataFrame:
    """Per condition, one comparison: lateral and vertical force error (%) with the nominal
    and with the estimated parameters (and with the true ones, for synthetic recordings:
    the noise floor). Time-aligned where the recordings carry their track, else the first
    statistic of the estimate."""
    val = read_validation(Path(run) / "estimate" / "validation" / "validation.csv")
    rows = []
    for cond, g in val.groupby("condition", sort=False):
        stats = list(dict.fromkeys(g.statistic))
        st = "aligned" if "aligned" in stats else stats[0]
        h = g[g.statistic == st].set_index("force")
        row = {"condition": cond, "statistic": st, "meaning": _MEANING.get(st, st)}
        for force, name in (("Y", "lateral"), ("Q", "vertical")):
            for key in ("before", "after", "truth"):
                col = f"{key}_error"
                if col in h and force in h.index:
                    row[f"{name}_{key}_pct"] = 100.0 * float(h.loc[force, col])
        rows.append(row)
    return pd.DataFrame(rows)


#: a force error that is not a number: the validation's simulation stopped (its rows are
#: empty) or the measured statistic is 0 kN (no relative error)
NO_ERROR = "n/a (simulation stopped, or measured 0 kN)"


def _pct(value: float) -> str:
    """A force error (%) of the agreement lines; :data:`NO_ERROR` for NaN (it read
    "85.0 % →  %")."""
    return f"{sig3(value)} %" if math.isfinite(value) else NO_ERROR


def agreement_lines(table: pd.DataFrame) -> list[str]:
    """The force agreement as one readable line per condition."""
    lines = []
    for r in table.to_dict(orient="records"):
        parts = []
        for name, label in (("lateral", "lateral Y"), ("vertical", "vertical Q")):
            b, a = r.get(f"{name}_before_pct"), r.get(f"{name}_after_pct")
            if b is None or a is None:
                continue
            text = f"{label} {_pct(b)} → {_pct(a)}"
            t = r.get(f"{name}_truth_pct")
            if t is not None and math.isfinite(t):
                text += f" (true parameters: {_pct(t)})"
            parts.append(text)
        lines.append(f"{r['condition']}: " + ", ".join(parts) + f" — {r['meaning']}")
    return lines


def field_recordings(run: str | Path) -> list:
    """The run's recordings (``RUN/field``), read as the run's wagon's as ``pipeline.json``
    recorded it: its static wheel load (a tare wagon's recordings were refused by the report)
    and its data (a shorter wagon's measured track was checked against the packaged C80's
    axle spread: the review of stop 60); None where a run recorded neither (the packaged
    C80's)."""
    from railsusp.measured import read_field
    from railsusp.vehicle.wagon import WagonData

    state = _state(Path(run))
    wagon = None
    if isinstance(state.get("wagon_data"), dict):
        try:
            wagon = WagonData.model_validate(state["wagon_data"])
        except ValueError:  # another railsusp's wagon fields: the wheel load alone
            wagon = None
    load = state.get("static_wheel_load_N")
    return read_field(Path(run) / "field", wheel_load_N=load, wagon=wagon)


def recordings(run: str | Path, read: list | None = None) -> pd.DataFrame:
    """The recordings the run used: name, condition, measured wheel, duration, whether they
    carry their track geometry (``read``: :func:`field_recordings` of the run, where the
    caller has them already)."""

    folder = Path(run) / "field"
    names = read_json(folder / "index.json").get("recordings", [])
    rows = []
    read = field_recordings(run) if read is None else read
    for name, rec in zip(names, read, strict=True):
        rows.append(
            {
                "recording": str(name),
                "condition": rec.condition.name,
                "wheel": ", ".join(rec.wheels),
                # n samples of one interval each, as a condition's duration_s counts them
                # (the span from first to last sample read 0.98 s for a 1 s record)
                "duration_s": rec.time.size / rec.sampling_rate if rec.time.size > 1 else 0.0,
                "measured_track": rec.condition.track_geometry is not None,
            }
        )
    return pd.DataFrame(rows)


def wagon_name(run: str | Path) -> str:
    """The name of the wagon the run simulated (from its campaign)."""
    meta = read_json(Path(run) / "campaign" / "campaign.json")
    return meta["config"]["wagon"]["wagon"]["name"]


def is_synthetic(run: str | Path) -> bool:
    """Whether the recordings were synthesised from a hidden truth (``field/truth.json``)."""
    return (Path(run) / "field" / "truth.json").exists()
