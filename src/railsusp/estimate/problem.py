"""The calibration problem: objectives built from a force model and the recordings.

:class:`CalibrationProblem` (a pymoo problem) has two objectives over the key parameters
scaled to [0, 1]: the lateral and vertical mismatch between a force model and the
recordings, as relative errors of a record statistic (or the time-aligned error on measured
track), joint over the conditions by default. :func:`check_recordings` and
:func:`check_aligned` refuse, before any optimisation, recordings the objectives cannot be
computed on.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from pymoo.core.problem import Problem

from railsusp.errors import RailsuspInputError
from railsusp.estimate.comparison import AlignedComparison, check_time_base
from railsusp.estimate.expected_forces import averaged_model
from railsusp.estimate.forces import (
    ForceModel,
    SimulatorForces,
    SurrogateForces,
    series_in_conditions,
)
from railsusp.estimate.statistics import (
    ALIGNED,
    check_weighting,
    measured_statistics,
    parse_statistics,
    series_statistics,
)
from railsusp.estimate.statistics_forces import StatisticsForces, force_statistics
from railsusp.measured import Recording
from railsusp.params import bounds, spec
from railsusp.vehicle.simulation_result import RECORD_STATISTICS

#: the key of each set's errors per recording and force on pymoo's individuals
#: (:meth:`CalibrationProblem._evaluate`)
ERRORS = "errors"


class CalibrationProblem(Problem):
    """Two objectives over the key parameters (decision variables scaled to [0, 1]):
    relative error of the lateral and of the vertical force statistic against the
    recordings (averaged over the statistics of a combination such as ``mean+p99+std``),
    averaged over the conditions (or one pair per condition). ``gains``: the time-aligned
    comparison profiles each recording's channel gain out
    (:func:`~railsusp.estimate.comparison.channel_gains`), and record statistics combined
    with it (``aligned+mean``) are taken of the prediction scaled by the same gains."""

    def __init__(
        self,
        model: ForceModel,
        recordings: Sequence[Recording],
        parameters: Sequence[str],
        statistic: str = "mean",
        per_condition: bool = False,
        weighting: str = "relative",
        gains: bool = False,
    ):
        self.model, self.recordings = model, list(recordings)
        self.gains = gains
        self.parameters = tuple(parameters)
        self.statistic, self.per_condition = statistic, per_condition
        if check_weighting(weighting) == "noise" and not isinstance(model, StatisticsForces):
            raise ValueError(
                "weighting 'noise' needs the predictive standard deviation of a statistics "
                "surrogate (gp-stats force model)"
            )
        self.weighting = weighting
        self.lo, self.hi = bounds(self.parameters)
        combination = parse_statistics(statistic)
        self.aligned = ALIGNED in combination
        self.stats = tuple(st for st in combination if st != ALIGNED)
        if self.aligned:
            check_aligned(model, self.recordings)
        elif isinstance(averaged_model(model), SurrogateForces):
            # on record statistics too: a network of the same name trained at another speed
            # (or grade, radius, ...) stood in for the recording's condition without a word
            # (the command-line audit of stop 60)
            check_sampling(averaged_model(model), self.recordings, self.stats)
        if gains and not self.aligned:
            raise RailsuspInputError(
                f"channel gains with the statistic {statistic!r}: accepted only with the "
                "time-aligned comparison (statistic 'aligned'), whose samples a gain scales"
            )
        if isinstance(model, StatisticsForces):
            check_statistics_model(self.stats)
            for r in self.recordings:  # before any prediction, not in the first generation
                model.check_condition(r.condition, self.stats)
        check_recordings(self.recordings, self.stats, self.aligned, weighting == "relative")
        check_measured_wheel(model, self.recordings, self.aligned)
        self.measured = [measured_statistics(rec, self.stats) for rec in self.recordings]
        # the condition each prediction's series samples (a network's own training record,
        # where it does not read the recording's track): its statistics are taken at its rate
        self.sampled = [prediction_condition(model, r.condition) for r in self.recordings]
        # the measurement side of the time-aligned comparison, once, not every generation
        self.comparisons = [AlignedComparison(r) for r in self.recordings] if self.aligned else []
        n_obj = 2 * len(self.recordings) if per_condition else 2
        super().__init__(n_var=len(self.parameters), n_obj=n_obj, xl=0.0, xu=1.0)

    def to_si(self, unit: np.ndarray) -> np.ndarray:
        return self.lo + np.asarray(unit) * (self.hi - self.lo)

    def errors(self, x_si: np.ndarray) -> np.ndarray:
        """(n, n_conditions, 2) mismatch of the lateral and vertical statistic, averaged over
        the statistics of a combination: relative error, or with ``weighting="noise"`` the
        absolute error over the predictive standard deviation."""
        errs = []
        every = None  # a series model's series, all conditions at once where it can
        if not isinstance(self.model, StatisticsForces):
            every = series_in_conditions(self.model, x_si, [r.condition for r in self.recordings])
        for k, (rec, meas) in enumerate(zip(self.recordings, self.measured, strict=True)):
            parts = []
            if self.aligned:
                series = every[k]
                err, g = self.comparisons[k].profiled(series, self.gains)
                parts.append(err[:, :, None])
                if self.stats:  # on the recording's measured track: its time base
                    series = series * g[:, None, :] if self.gains else series
                    pred = series_statistics(series, rec.condition, self.stats)
                    parts.append(np.abs(pred - meas) / np.abs(meas))
            elif self.weighting == "noise":
                pred, sd = self.model.predict_statistics(
                    x_si, rec.condition, self.stats, with_std=True
                )
                parts.append(np.abs(pred - meas) / np.maximum(sd, 1e-9))
            else:
                pred = (
                    force_statistics(self.model, x_si, rec.condition, self.stats)
                    if every is None
                    else series_statistics(every[k], self.sampled[k], self.stats)
                )
                parts.append(np.abs(pred - meas) / np.abs(meas))
            errs.append(np.concatenate(parts, axis=2).mean(axis=2))
        return np.stack(errs, axis=1)

    def channel_gains_at(self, x_si: np.ndarray) -> dict[str, float]:
        """Each recording's lateral and vertical channel gain at one parameter set ``x_si``
        (SI) as the time-aligned comparison profiles them, by "<condition>:<Y|Q>_<wheel>"
        (the refinement's names)."""
        every = series_in_conditions(
            self.model, np.atleast_2d(x_si), [r.condition for r in self.recordings]
        )
        return {
            f"{rec.condition.name}:{force}_{rec.wheels[0]}": float(g)
            for rec, comp, series in zip(self.recordings, self.comparisons, every, strict=True)
            for force, g in zip(("Y", "Q"), comp.gains(series)[0], strict=True)
        }

    def _evaluate(self, x, out, *args, **kwargs):
        """The objectives ``F``, and each set's errors per recording and force ``ERRORS``
        (n, 2 n_conditions), which pymoo keeps on every individual: the choice rule
        ``least-squares`` ranks a front by the time-aligned cost summed from them
        (:func:`~railsusp.estimate.nsga.choose`), as the objectives averaged over the
        recordings do not give it, and without evaluating the front again."""
        e = self.errors(self.to_si(x))
        out["F"] = e.reshape(len(x), -1) if self.per_condition else e.mean(axis=1)
        out[ERRORS] = e.reshape(len(x), -1)


def check_recordings(
    recordings: Sequence[Recording],
    statistics: Sequence[str] = (),
    aligned: bool = False,
    relative: bool = True,
) -> None:
    """Refuse recordings the objectives cannot be computed on, with a one-line input error
    naming the recording and force, before any optimisation: non-finite samples, a force
    that is zero throughout (e.g. an unconnected channel, or a file of zeros), a force of
    constant value where the time-aligned comparison scales by its standard deviation, and,
    for relative errors, a measured statistic of zero (the relative error divides by it).
    Otherwise the objectives turn infinite or undefined and the optimiser fails deep inside.
    """
    if not recordings:
        raise RailsuspInputError("the estimate needs at least one recording; none given")
    for rec in recordings:
        forces = rec.forces()
        wheel = rec.wheels[0]
        for c, force in enumerate(("Y", "Q")):
            x = forces[:, c]
            what = f"recording {rec.condition.name!r}: force {force} of wheel {wheel}"
            if not np.isfinite(x).all():
                raise RailsuspInputError(f"{what} has non-finite samples; accepted: finite kN")
            if not np.any(x):
                raise RailsuspInputError(
                    f"{what} is zero throughout; the estimate needs recorded forces that vary "
                    "with the suspension (check the channel and the file)"
                )
            if aligned and not np.std(x) > 0.0:
                raise RailsuspInputError(
                    f"{what} is constant; the time-aligned comparison scales by its standard "
                    "deviation, which must be above zero"
                )
        if relative and statistics:
            meas = measured_statistics(rec, statistics)
            zero = np.argwhere(meas == 0.0)
            if zero.size:
                c, k = zero[0]
                raise RailsuspInputError(
                    f"recording {rec.condition.name!r}: statistic {statistics[k]!r} of force "
                    f"{'YQ'[c]} of wheel {wheel} is 0 kN; relative errors need a non-zero "
                    "measured statistic (use another statistic, or weighting 'noise')"
                )


def prediction_condition(model: ForceModel, condition: Any) -> Any:
    """The condition whose record ``model``'s series in ``condition`` sample: a window
    surrogate's own training condition where it predicts its training series
    (:meth:`~railsusp.estimate.forces.SurrogateForces.series_condition`), else ``condition``
    (the simulator, a network on the recording's measured track)."""
    own = getattr(averaged_model(model), "series_condition", None)
    return condition if own is None else own(condition)


def check_sampling(
    model: SurrogateForces, recordings: Sequence[Recording], statistics: Sequence[str]
) -> None:
    """Refuse, before any optimisation and in one line, a recording whose record statistics
    a window surrogate cannot predict: a condition it was not trained on
    (:meth:`~railsusp.estimate.forces.SurrogateForces.check_condition`; its time step too
    where it reads the recording's measured track and predicts on its time base), and a
    statistic that depends on the sampling rate
    (:func:`~railsusp.estimate.statistics.rate_dependent`) where its series, its own
    training record's, are sampled at another rate than the recording's condition: the
    spread of 50 Hz series (content to 20 Hz) is not that of 100 Hz ones."""
    from railsusp.estimate.statistics import check_rate

    for r in recordings:
        cond = r.condition
        model.check_condition(cond, series=False)  # no surrogate of its name: refused here
        if model.reads_track(cond):  # predicted on the recording's time base: the network's
            model.check_condition(cond)
        own = model.series_condition(cond)
        check_rate(
            statistics,
            1.0 / own.sample_interval,
            cond,
            f"the surrogate in {model.folder} predicts its training record",
            "the mean or p99.85, a recording at the training's rate, or a surrogate trained "
            "at the recording's",
        )


def model_wheel(model: Any, condition: Any) -> str:
    """The wheel whose forces ``model`` gives in ``condition``: the simulator's ``wheel``, a
    surrogate's campaign's (``meta["wheel"]``, saved since stop 58), else the automatically
    chosen one (the leading wheelset's left wheel on tangent, its outer wheel in a curve)."""
    from railsusp.vehicle.simulation_result import WHEEL_NAMES, measured_wheel_index

    model = averaged_model(model)
    which = getattr(model, "wheel", "auto")
    if hasattr(model, "surrogate") and hasattr(model, "conditions"):
        if condition.name in model.conditions:
            which = (model.surrogate(condition.name).meta or {}).get("wheel", "auto")
    return WHEEL_NAMES[measured_wheel_index(condition, which)]


def check_measured_wheel(model: Any, recordings: Sequence[Recording], aligned: bool) -> None:
    """Refuse a recording whose first wheel (the one compared) is not the wheel the force
    model gives, where that matters: in a curve (the outer and the inner wheel carry other
    forces) and in the time-aligned comparison (each rail has its own irregularities). A
    two-wheel recording whose columns began with the other wheel was compared with the
    wrong one, silently (the recordings audit of stop 58). On tangent the statistics of
    the left and the right wheel of one wheelset are alike, and a recording of either is
    compared; another wheelset's are not (a trailing wheelset, or the rear bogie's, steers
    otherwise), and one of those was accepted until stop 62 (posterior audit)."""
    for r in recordings:
        wanted = model_wheel(model, r.condition)
        mirror = not (aligned or r.condition.curve_radius_m is not None)
        if r.wheels[0] == wanted or (mirror and r.wheels[0][:-1] == wanted[:-1]):
            continue
        held = f" (it holds {wanted}: list it first)" if wanted in r.wheels else ""
        either = f" or {wanted[:-1]}{'R' if wanted.endswith('L') else 'L'}" if mirror else ""
        raise RailsuspInputError(
            f"recording {r.condition.name!r}: its first wheel is {r.wheels[0]}, the force "
            f"model gives {wanted} in this condition{held}; accepted a recording whose first "
            f"wheel (in the sidecar's wheels) is {wanted}{either}"
        )


def check_statistics_model(statistics: Sequence[str]) -> None:
    """A statistics surrogate predicts the record statistics it was trained on (mean, rms,
    p99, std), not the EN 14363 maximum, which is computed from force series: refused before
    any optimisation, in one line."""
    other = [st for st in statistics if st not in RECORD_STATISTICS]
    if other:
        raise RailsuspInputError(
            f"statistic {'+'.join(other)!r} needs force series; a statistics surrogate "
            f"(gp-stats) predicts {', '.join(RECORD_STATISTICS)}: use one of those, a window "
            "surrogate or the simulator"
        )


def check_aligned(model: Any, recordings: Sequence[Recording]) -> None:
    """Time-aligned comparison needs series from a model and recordings on measured track
    (a model averaged over drawn geometries is checked as the model it averages)."""
    model = averaged_model(model)
    if isinstance(model, StatisticsForces):
        raise ValueError(
            "statistic 'aligned' compares series: use a window surrogate or the simulator, "
            "not a statistics surrogate"
        )
    if isinstance(model, SimulatorForces):
        from railsusp.vehicle.simulation_result import WHEEL_NAMES, measured_wheel_index

        for r in recordings:
            sim_wheel = WHEEL_NAMES[measured_wheel_index(r.condition, model.wheel)]
            if r.wheels[0] != sim_wheel:
                raise ValueError(
                    f"recording {r.condition.name!r} measures {r.wheels[0]}, the simulator "
                    f"force model wheel {model.wheel!r} gives {sim_wheel}"
                )
    if isinstance(model, SurrogateForces):
        for r in recordings:
            model.check_condition(r.condition)
        other = [
            r.condition.name
            for r in recordings
            if r.condition.track_geometry is not None and not model.reads_track(r.condition)
        ]
        if other:
            raise RailsuspInputError(
                f"statistic 'aligned': the surrogates of {', '.join(other)} in {model.folder} "
                "were trained on one track realisation and cannot predict the recordings' "
                "measured track: train them on a campaign over the recordings (railsusp "
                "campaign --conditions FIELD), or use --simulator"
            )
    blind = [r.condition.name for r in recordings if r.condition.track_geometry is None]
    if blind:
        raise ValueError(
            "statistic 'aligned' compares time-aligned samples, which needs recordings that "
            f"carry measured track geometry; {', '.join(blind)} do not (the field recordings "
            "need condition.track_geometry, docs/data-format.md)"
        )
    check_time_base(recordings, "the time-aligned comparison (statistic 'aligned')")


def display_values(parameters: Sequence[str], x_si: np.ndarray) -> dict[str, float]:
    """Parameter values (SI) in their display units, by symbol."""
    return {p: spec(p).to_display(v) for p, v in zip(parameters, x_si, strict=True)}
