"""Before/after validation of an estimate against the recordings (the study's Tables 8 and 9,
Figures 12 and 13), and parameter-recovery scoring when the truth is known.

The measured conditions are re-simulated with the simulator (not the surrogate) with the
nominal and with the estimated parameters, on the recordings' measured track geometry when
they carry one, else on the design track of each condition, and their record statistics
(and, on measured track, the time-aligned mismatch) are compared with the recordings'.
Where the estimate compared expected forces (``expected_draws``) and a recording states its
geometry's accuracy, each simulation is one per draw of the true geometry given the measured
one (the estimate's draws: same seed), and the comparison is with their mean series
(time-aligned) and the mean of their statistics, as the estimate was made.
For synthetic recordings the validator, and only the validator, reads the hidden truth: the
recovery error per parameter, and the noise floor, i.e. the error that a simulation with the
true parameters itself makes against the same recording.
"""

from __future__ import annotations

import tempfile
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import (
    ALIGNED,
    aligned_error,
    measured_statistics,
    parse_statistics,
)
from railsusp.estimate.comparison import check_time_base
from railsusp.estimate.config import NSGA_RANGES, check_range
from railsusp.estimate.expected_forces import draw_true_tracks
from railsusp.estimate.intervals import intervals_of
from railsusp.estimate.statistics import force_statistic
from railsusp.identification_verdict import (
    IDENTIFIED,
    RECORDINGS,
    ROUTE,
    identification_verdicts,
    max_st,
)
from railsusp.measured import Recording, SimulationFailedError, read_field
from railsusp.measured.recording import same_recordings
from railsusp.measured.synthetic import recording_from_simulation
from railsusp.measured.truth import check_truth_of, read_truth
from railsusp.params import ParameterSet, bounds, spec
from railsusp.store import atomic_folder, read_json, write_csv, write_json
from railsusp.validation_inputs import (
    check_estimate_fields,
    check_estimate_revision,
    measured_of,
)
from railsusp.vehicle.simulation_result import statistic_segments

#: what validate reads of an estimate.json
ESTIMATE_KEYS = ("parameters", "estimate_display", "config")


#: the files :meth:`ValidationResult.save` writes (glob patterns): an earlier
#: validation's that a new one does not write are removed (the folder may be the user's)
VALIDATION_FILES = ("validation.csv", "validation.json", "recovery.csv", "validation-*.png")


@dataclass
class ValidationResult:
    """Tables 8/9 (``forces``) and, with a known truth, the recovery table."""

    forces: pd.DataFrame
    recovery: pd.DataFrame | None
    series: dict  # condition -> {"time", "measured", "before", "after"} for the overlays
    #: simulations that stopped (derailment, divergence): their rows hold NaN
    failures: list[str] = field(default_factory=list)
    #: draws of the true track geometry each simulation on geometry of stated accuracy is
    #: averaged over (the estimate's ``expected_draws``; 0: on the measured geometry)
    expected_draws: int = 0
    #: rows whose relative error is NaN for another reason than a stopped simulation (a
    #: measured statistic of 0 kN: nothing to be relative to), one line each
    notes: list[str] = field(default_factory=list)

    def save(self, out: str | Path) -> Path:
        """Write the tables and figures into ``out`` as one artefact
        (:func:`~railsusp.store.atomic_folder`): a kill or a full disk while the figures are
        drawn leaves the earlier validation as it was, not a new table beside old figures.
        Other files in ``out`` are kept; an earlier validation's that this one does not
        write (a recovery table of another field's truth, a removed condition's figure),
        which went on being shown as its, are not carried over."""
        from railsusp.report import plot_validation_overlay

        out = Path(out)
        with atomic_folder(out, drop=VALIDATION_FILES) as tmp:
            write_csv(tmp / "validation.csv", self.forces)
            payload = {
                "forces": self.forces.to_dict(orient="records"),
                "failures": self.failures,
                "expected_draws": self.expected_draws,
                "notes": self.notes,
            }
            if self.recovery is not None:
                write_csv(tmp / "recovery.csv", self.recovery)
                payload["recovery"] = self.recovery.to_dict(orient="records")
            write_json(tmp / "validation.json", payload)
            for cond, s in self.series.items():
                plot_validation_overlay(s, tmp / f"validation-{cond}.png", title=cond)
        return out


def _simulate(
    sets: dict[str, ParameterSet],
    recs: Sequence[Recording],
    conditions: Sequence[Sequence[WorkingCondition]],
    failures: list[str],
    wagon: Any = None,
) -> dict[str, list[np.ndarray]]:
    """Per label of ``sets``, per recording, (draws, T, 2) series in kN of its first wheel in
    each of that recording's ``conditions`` (its own, or its drawn true tracks), the sets and
    conditions of a recording in one batched call; a simulation that stops gives NaN and a
    line in ``failures`` (the parameters derail there: a finding, not a crash)."""
    from railsusp.vehicle.simulate import simulate_conditions

    out: dict[str, list[np.ndarray]] = {label: [] for label in sets}
    labels = list(sets)
    for rec, conds in zip(recs, conditions, strict=True):
        runs = simulate_conditions([sets[label] for label in labels], conds, wagon=wagon)
        for k, label in enumerate(labels):
            series, stopped = [], []
            for run in runs:
                try:
                    series.append(recording_from_simulation(run, rec.wheels[:1], k).forces())
                except SimulationFailedError as exc:
                    stopped.append(str(exc))  # the condition's record, as the others
                    series.append(np.full((run.time.size, 2), np.nan))
            if stopped:  # one line per recording: the first reason, and how many draws
                many = f" ({len(stopped)} of {len(runs)} drawn tracks)" if len(runs) > 1 else ""
                failures.append(f"{label}: {stopped[0]}{many}")
            out[label].append(np.stack(series))
    return out


def relative_error(simulated: float, measured: float) -> float:
    """|simulated - measured| / |measured|, the error of a record statistic as the estimate
    weighs it; NaN where the measured statistic is 0 kN (or not finite): no relative error
    exists (it divided by zero: inf, or NaN with a runtime warning). The estimate refuses
    such a recording; a validation with another statistic or recordings may meet one."""
    if not relatable(measured):
        return float("nan")
    return float(abs(simulated - measured) / abs(measured))


def relatable(measured: float) -> bool:
    """Whether a measured statistic has errors relative to it: finite and not 0 kN."""
    return bool(np.isfinite(measured)) and measured != 0.0


def validate(
    estimate_dir: str | Path,
    *,
    measured: str | Path | None = None,
    truth: str | Path | None = None,
    sensitivity: str | Path | None = None,
    statistic: str | None = None,
    expected_draws: int | None = None,
    wagon: Any = None,
    truth_option: str = "--truth",
) -> ValidationResult:
    """Validate the estimate in ``estimate_dir`` against its recordings.

    ``measured`` defaults to the folder recorded in ``estimate.json``; ``truth`` is a
    ``truth.json`` of synthetic recordings (scored only when given; the truth of other
    recordings than those validated is refused, :func:`~railsusp.measured.check_truth_of`);
    ``sensitivity`` a ``key_parameters.json`` or ``indices.parquet`` of the campaign, for
    the Sobol flag.
    ``statistic`` defaults to the estimate's, with ``aligned`` added when every recording
    carries measured track geometry; the time-aligned errors profile the channel gains out
    where the estimate did (its ``channel_gains``). ``expected_draws`` defaults to the
    estimate's: on recordings whose geometry states its accuracy the simulations are then
    compared by their mean over that many draws of the true geometry (seeded as the
    estimate's), its statistics by their mean over the draws. ``wagon``: the wagon data
    simulated (a WagonData or a wagon file; None: the packaged C80), and whose static wheel
    load the recordings are checked against. An estimate made with other force laws than
    this railsusp simulates is refused before any simulation, one that records none is
    warned of (:func:`check_estimate_revision`). ``truth_option``: how the truth's errors
    name it (the pipeline's is no option the user typed).
    """
    from railsusp.vehicle.wagon import load_wagon

    est_path = Path(estimate_dir) / "estimate.json"
    est = read_json(est_path)
    lacking = [k for k in ESTIMATE_KEYS if not isinstance(est, dict) or k not in est]
    if lacking:
        raise RailsuspInputError(
            f"{est_path}: no {', '.join(map(repr, lacking))}; accepted the estimate.json of a "
            "folder written by railsusp estimate"
        )
    check_estimate_fields(est, est_path, need_measured=measured is None)
    check_estimate_revision(est, est_path)
    params = tuple(est["parameters"])
    stats = parse_statistics(statistic or est["config"]["statistic"])
    if wagon is None:  # the wagon the estimate simulated (None there: the packaged C80)
        from railsusp.vehicle.wagon import WagonData

        wagon = est.get("wagon")
        if est.get("wagon_data"):
            try:
                wagon = WagonData.model_validate(est["wagon_data"])
            except ValueError:  # another railsusp's wagon fields: its reference, if any
                pass
    wagon = load_wagon(wagon)
    folder = measured if measured is not None else measured_of(est, estimate_dir)
    recs = read_field(folder, wagon=wagon)
    stored = est.get("measured_digest")
    if measured is None and isinstance(stored, str) and not same_recordings(recs, stored):
        raise RailsuspInputError(
            f"{folder}: its recordings are not those the estimate in {est_path} "
            "read (the folder was written again since); accepted the estimate's own "
            "recordings: estimate again, or validate on these with --measured"
        )
    if statistic is None and ALIGNED not in stats:
        if all(r.condition.track_geometry is not None for r in recs):
            unaligned = [r.condition.name for r in recs if r.condition.n_steps != r.time.size]
            if unaligned:  # a default, not asked for: said in one line, not refused
                warnings.warn(
                    f"no time-aligned errors: the condition.n_steps of recording(s) "
                    f"{', '.join(unaligned)} samples another rate than its table's rows, and "
                    "the time-aligned comparison needs one time base (the record statistics "
                    "are compared)",
                    stacklevel=2,
                )
            else:
                stats = (*stats, ALIGNED)  # on measured track, also compare sample by sample
    if ALIGNED in stats:  # asked for: before the simulations, not after them
        check_time_base(recs, "validate's time-aligned errors (statistic 'aligned')")
    # the parameters not estimated where the estimate held them: nominal, or the centre of
    # the user's held_prior range (estimate.json's held_at_display)
    held_at = est.get("held_at_display") or {}
    chosen = ParameterSet({**held_at, **est["estimate_display"]}, units="display")
    nominal = ParameterSet.nominal()
    truth_set = None
    if truth is not None:  # before the simulations: a truth of other recordings refused
        truth_set = read_truth(truth, truth_option)
        check_truth_of(truth, folder, truth_option, recs)
    failures: list[str] = []
    notes: list[str] = []
    labels = {"before": "nominal parameters", "after": "estimate", "truth": "true parameters"}
    sets = {"before": nominal, "after": chosen}
    if truth_set is not None:
        sets["truth"] = truth_set
    config = est["config"]
    draws = int(config.get("expected_draws", 0) if expected_draws is None else expected_draws)
    check_range("expected_draws", draws, *NSGA_RANGES["expected_draws"])
    with tempfile.TemporaryDirectory(prefix="railsusp-validate-") as folder:
        conditions = [
            draw_true_tracks(r.condition, draws, int(config.get("seed", 0)),
                             Path(folder), f"{i:03d}-{r.condition.name}")
            if draws
            else [r.condition]
            for i, r in enumerate(recs)
        ]  # fmt: skip
        named = _simulate(
            {labels[k]: v for k, v in sets.items()}, recs, conditions, failures, wagon
        )
    # draws are made only for recordings that state their geometry's accuracy: a validation
    # without any recorded draws it did not make (stop 79's estimate hunt)
    undrawn = [r.condition.name for r, c in zip(recs, conditions, strict=True) if len(c) == 1]
    if draws and undrawn:
        notes.append(
            f"expected_draws {draws}: {', '.join(undrawn)} states no track geometry accuracy, "
            "so its simulations ran on its measured geometry, not on drawn true tracks"
        )
    if len(undrawn) == len(recs):
        draws = 0
    sims = {key: named[labels[key]] for key in sets}
    aligned = ALIGNED in stats
    gains = bool(config.get("channel_gains", False))
    stats = tuple(st for st in stats if st != ALIGNED)
    rows, series = [], {}
    for i, rec in enumerate(recs):
        w = rec.wheels[0]
        meas = measured_statistics(rec, stats)
        # the simulations' statistics at their own rate, the condition's (as the estimate's
        # objective takes them), which a sidecar may set apart from its table's
        interval = rec.condition.sample_interval
        for j, force in enumerate(("Y", "Q")):
            if aligned:
                # time-aligned: *_kN is the RMS difference, *_error that over the measured SD
                sd = float(np.std(rec.forces()[:, j]))
                row = {
                    "condition": rec.condition.name,
                    "wheel": w,
                    "force": force,
                    "statistic": ALIGNED,
                    "measured_kN": sd,
                }
                for key, s in sims.items():
                    e = float(aligned_error(s[i].mean(axis=0)[None], rec, gains)[0, j])
                    row[f"{key}_kN"], row[f"{key}_error"] = e * sd, e
                rows.append(row)
            for k, st in enumerate(stats):
                if not relatable(meas[j, k]):
                    notes.append(
                        f"{rec.condition.name} {w} {force} {st}: measured {meas[j, k]:g} kN, "
                        "no relative error (its *_error is NaN)"
                    )
                row = {
                    "condition": rec.condition.name,
                    "wheel": w,
                    "force": force,
                    "statistic": st,
                    "measured_kN": float(meas[j, k]),
                }
                for key, s in sims.items():
                    v = float(
                        np.mean(
                            [
                                force_statistic(
                                    drawn[:, j],
                                    st,
                                    force == "Y",
                                    statistic_segments(drawn.shape[0], interval),
                                    rate_hz=1.0 / interval,
                                    speed_ms=rec.condition.speed,
                                )
                                for drawn in s[i]
                            ]
                        )
                    )
                    row[f"{key}_kN"] = v
                    row[f"{key}_error"] = relative_error(v, float(meas[j, k]))
                rows.append(row)
        series[rec.condition.name] = {
            "time": rec.time,
            "measured": rec.forces(),
            "before": _on_time(sims["before"][i].mean(axis=0), rec),
            "after": _on_time(sims["after"][i].mean(axis=0), rec),
            "measured_track": rec.condition.track_geometry is not None,
        }
    forces = pd.DataFrame(rows)
    recovery = None
    if truth_set is not None:
        recovery = _recovery(params, chosen, truth_set, est, sensitivity)
    for line in notes:
        warnings.warn(line, stacklevel=2)
    return ValidationResult(forces, recovery, series, failures, draws, notes)


def _on_time(simulated: np.ndarray, rec: Recording) -> np.ndarray:
    """A simulation's (T, 2) series of a recording's condition on the recording's time base
    for the overlay figure: itself where the condition samples the table's rows, else
    interpolated from its own time step (a sidecar's n_steps at another rate than its
    table's)."""
    if simulated.shape[0] == rec.time.size:
        return simulated
    t = rec.time[0] + np.arange(simulated.shape[0]) * rec.condition.sample_interval
    return np.stack(
        [np.interp(rec.time, t, simulated[:, c]) for c in range(simulated.shape[1])], axis=1
    )


def _recovery(
    params, chosen: ParameterSet, truth: ParameterSet, est: dict, sensitivity: str | Path | None
) -> pd.DataFrame:
    """The recovery table: per parameter the truth, the estimate, their error, the interval
    and whether it holds the truth, and the summary card's verdict
    (:func:`~railsusp.identification_verdict.identification_verdicts`): ``verdict``
    "identified", the card's :data:`~railsusp.summary.NOT_IDENTIFIED` (this route gives no
    confidence interval) or :data:`~railsusp.summary.NOT_IDENTIFIABLE` (the recordings are
    the reason), ``why_not`` its reason. ``identified`` is True where identified;
    ``identifiable``, the same, is kept for readers of the older table (the table called
    every parameter not identified "not identifiable", the route's fault too)."""
    from railsusp.summary import NOT_IDENTIFIABLE, NOT_IDENTIFIED

    words = {IDENTIFIED: IDENTIFIED, ROUTE: NOT_IDENTIFIED, RECORDINGS: NOT_IDENTIFIABLE}
    lo, hi = bounds(params)
    verdicts = identification_verdicts(est, max_st(sensitivity) if sensitivity else {})
    intervals = intervals_of(est)
    rows = []
    for p, low, high in zip(params, lo, hi, strict=True):
        t, e = truth[p], chosen[p]
        iv = intervals[p]
        rows.append(
            {
                "parameter": p,
                "unit": spec(p).display_unit,
                "truth": spec(p).to_display(t),
                "estimate": spec(p).to_display(e),
                "error_pct_of_value": 100 * abs(e - t) / abs(t),
                "error_pct_of_range": 100 * abs(e - t) / (high - low),
                "interval_low": iv.low,
                "interval_high": iv.high,
                "interval_width_pct_range": iv.width_pct_range,
                "interval_method": iv.method,
                "truth_in_interval": iv.contains(t),
                "identified": verdicts[p][0] == IDENTIFIED,
                "verdict": words[verdicts[p][0]],
                "why_not": verdicts[p][1],
                "identifiable": verdicts[p][0] == IDENTIFIED,  # the older table's name
            }
        )
    return pd.DataFrame(rows)
