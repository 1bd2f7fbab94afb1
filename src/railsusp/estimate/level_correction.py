"""The surrogate's level error at the estimate, taken from the simulator: output space mapping.

A network set trained on many tracks follows a parameter change about as the simulator
does (the comparison's Jacobians agree within 0-24 % for X18, X13 and X11, bench/README.md,
"Is the remaining estimate error the networks' gains?"), but at a given parameter set its
forces differ from the simulator's by a level error in directions the parameters' columns
share, and its least squares lands off by that much (X13 and X14 up to 10-16 % of range on
issue 19's sets). One simulation of the estimate measures that error on the recordings'
own tracks: d = simulator(x) - surrogate(x), per recording, sample by sample. The surrogate
plus d is then exact at x and keeps the surrogate's slopes, and its time-aligned least
squares from x is repeated (:func:`correct_by_simulator`). This is the zeroth-order output
space mapping of Bandler et al. (IEEE Trans. MTT 52(1), 2004, "Space mapping: the state of
the art", section IV) or the additive correction of multi-fidelity optimisation (Eldred,
Giunta & Collis, AIAA 2004-4457); repeated, it converges where the surrogate's slopes are
close to the simulator's. On geometry of stated accuracy both sides are expected forces
(the mean over the same drawn true tracks, :mod:`railsusp.estimate.expected_forces`).

**With slopes** (``slopes=True``): where the surrogate's slopes differ from the simulator's
(the networks pass on 0.51-0.69 of X14's effect), the zeroth-order fixed point is not the
simulator's optimum, and where NSGA-II left a parameter the forces hardly fix on its bound
(X19, along the X13/X14-X19 valley) one zeroth-order correction can move a key the wrong
way. Each correction then also simulates the estimate stepped by
:data:`~railsusp.estimate.config.SLOPE_STEP` of each key's range, so that the corrected
surrogate has the simulator's value *and* slopes at x (first-order consistency, the
condition under which a corrected surrogate's optimisation converges to the simulator's
optimum: Alexandrov, Dennis, Lewis & Torczon, Structural Optimization 15, 1998), and its
least squares is kept within a trust box about x, :data:`~railsusp.estimate.config.TRUST_BOX`
of each range at first, where the correction is trusted; repeated, the steps move toward the
simulator's own least-squares point. k + 1 simulations per recording (and drawn track) per
step instead of one. The next step's simulation of the point a step proposed also checks it
(:mod:`railsusp.estimate.trust_region`): a point where the simulator's cost did not fall as
the corrected surrogate predicted (or whose simulation stopped) is rejected, and the least
squares is repeated from the step's start in a smaller box, without simulating its slopes;
after a confirmed step on its edge the box grows.

The simulator holds the other main-suspension parameters at nominal (or where the estimate
route's held prior puts them: :func:`~railsusp.estimate.route.held_simulator`); the networks
average their effect over the ranges they were trained on.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import ExitStack

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.estimate.config import (
    BROYDEN,
    BROYDEN_MIN_STEP,
    CORRECTIONS_RANGE,
    SIMULATED,
    SLOPE_STEP,
    TRUST_BOX,
    check_range,
    check_slope_update,
)
from railsusp.estimate.expected_forces import ExpectedForces, averaged_model
from railsusp.estimate.forces import ForceModel, SimulatorForces, series_in_conditions
from railsusp.estimate.geometry_bias import stated_accuracy
from railsusp.estimate.nsga_geometry import POLISH_EVALUATIONS, local_least_squares
from railsusp.estimate.problem import check_aligned
from railsusp.estimate.refine import Refinement
from railsusp.estimate.result import CalibrationResult
from railsusp.estimate.statistics import ALIGNED, parse_statistics
from railsusp.estimate.trust_region import StepCheck, profiled_cost, step_extent
from railsusp.measured import Recording, SimulationFailedError
from railsusp.params import bounds

#: per key index, per condition (:func:`condition_key`), (T, 2) kN per SI unit of the key
Slopes = dict[int, dict[str, np.ndarray]]


class LevelCorrected:
    """``model``'s series plus a fixed series per condition (``corrections``, (T, 2) kN, by
    :func:`condition_key`): the surrogate made exact where the corrections were taken; with
    ``slopes`` (:func:`slope_corrections`) taken at ``at`` (SI), plus each key's slope
    correction times its distance from there, so that its slopes there are the
    simulator's too."""

    def __init__(
        self,
        model: ForceModel,
        corrections: dict[str, np.ndarray],
        slopes: Slopes | None = None,
        at: np.ndarray | None = None,
    ):
        if slopes and at is None:
            raise ValueError("slope corrections need the point they were taken at")
        self.model = model
        self.parameters = tuple(model.parameters)  # type: ignore[attr-defined]
        self.corrections = corrections
        self.slopes = slopes or {}
        self.at = None if at is None else np.asarray(at, dtype=float)

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        return self.series_conditions(x_si, [condition])[0]

    def series_conditions(
        self, x_si: np.ndarray, conditions: Sequence[WorkingCondition]
    ) -> list[np.ndarray]:
        """The model's series in each condition (together, where it can) plus its
        correction."""
        x = np.atleast_2d(np.asarray(x_si, dtype=float))
        out = series_in_conditions(self.model, x, conditions)
        corrected = []
        for s, c in zip(out, conditions, strict=True):
            key = condition_key(c)
            add = s + self.corrections[key][None]
            for j, slope in self.slopes.items():
                assert self.at is not None
                add += slope[key][None] * (x[:, j] - self.at[j])[:, None, None]
            corrected.append(add)
        return corrected


def condition_key(condition: WorkingCondition) -> str:
    """What a correction is kept by: the whole condition (two recordings of one name on
    different tracks keep their own)."""
    return condition.model_dump_json()


def check_correctable(
    recordings: Sequence[Recording],
    statistic: str,
    setting: str,
    model: ForceModel | None = None,
) -> None:
    """Refuse, before NSGA-II runs, simulator corrections the recordings, the comparison or
    the force ``model`` cannot take (``setting`` names the option): they compare
    time-aligned series (the statistic ``aligned`` alone) on the recordings' measured
    track, at the wheel the simulator gives, and correct a surrogate (the simulator
    corrected by itself would be a second refinement)."""
    if parse_statistics(statistic) != (ALIGNED,):
        raise RailsuspInputError(
            f"{setting} corrects the time-aligned least squares; statistic {statistic!r}: "
            "accepted 'aligned' alone"
        )
    if model is not None and isinstance(averaged_model(model), SimulatorForces):
        raise RailsuspInputError(
            f"{setting} corrects a surrogate's level error by the simulator; the force model "
            "is the simulator itself: use a surrogate, or the refinement"
        )
    try:
        check_aligned(SimulatorForces(()), recordings)
    except ValueError as exc:
        raise RailsuspInputError(f"{setting}: {exc}") from None


def level_corrections(
    model: ForceModel,
    simulator: ForceModel,
    recordings: Sequence[Recording],
    x_si: np.ndarray,
) -> dict[str, np.ndarray]:
    """Per recording's condition (:func:`condition_key`), (T, 2) simulator minus ``model``
    at ``x_si``: the model's level error there (both through the same wrapper, e.g.
    expected forces over the same draws). A simulation that stopped (derailment,
    divergence: NaN series) is an error naming the condition."""
    conds = [r.condition for r in recordings]
    x = np.atleast_2d(np.asarray(x_si, dtype=float))
    sim = _simulated(simulator, x, conds, "the estimate", "correction")
    own = series_in_conditions(model, x, conds)
    return {condition_key(c): s[0] - m[0] for c, s, m in zip(conds, sim, own, strict=True)}


def _simulated(
    simulator: ForceModel,
    x: np.ndarray,
    conds: Sequence[WorkingCondition],
    what: str,
    taken: str,
) -> list[np.ndarray]:
    """The simulator's series of the sets ``x`` in each condition; a simulation that
    stopped (derailment, divergence: NaN series) is an error naming the conditions, what
    was simulated and what cannot be taken."""
    sim = series_in_conditions(simulator, x, conds)
    stopped = [c.name for c, s in zip(conds, sim, strict=True) if not np.isfinite(s).all()]
    if stopped:
        raise SimulationFailedError(
            f"simulator_corrections: the simulation of {what} stopped in "
            f"{', '.join(stopped)} (derailment or divergence); no {taken} can be taken there"
        )
    return sim


def slope_corrections(
    model: ForceModel,
    simulator: ForceModel,
    recordings: Sequence[Recording],
    x_si: np.ndarray,
    level: dict[str, np.ndarray],
) -> Slopes:
    """Per key j, per recording's condition, the simulator's slope less ``model``'s at
    ``x_si`` (SI), (T, 2) kN per SI unit: forward differences of
    :data:`~railsusp.estimate.config.SLOPE_STEP` of each range (inwards at the upper bound),
    all k stepped sets in one batched call of each model, ``level`` the corrections at
    ``x_si`` (:func:`level_corrections`). A stopped simulation is an error naming the
    condition, as there."""
    conds = [r.condition for r in recordings]
    x = np.asarray(x_si, dtype=float)
    lo, hi = bounds(tuple(model.parameters))  # type: ignore[attr-defined]
    step = SLOPE_STEP * (hi - lo)
    step = np.where(x + step > hi, -step, step)
    stepped = x[None] + np.diag(step)
    sim = _simulated(simulator, stepped, conds, "the estimate's slopes", "slope")
    own = series_in_conditions(model, stepped, conds)
    return {
        j: {
            condition_key(c): (s[j] - m[j] - level[condition_key(c)]) / step[j]
            for c, s, m in zip(conds, sim, own, strict=True)
        }
        for j in range(x.size)
    }


def broyden_slopes(
    slopes: Slopes,
    level_before: dict[str, np.ndarray],
    level_after: dict[str, np.ndarray],
    step_si: np.ndarray,
    span_si: np.ndarray,
    min_step: float = BROYDEN_MIN_STEP,
) -> Slopes:
    """The slope corrections after a step ``step_si`` (SI) without simulating the slopes
    again: Broyden's update (Broyden, Math. Comp. 19, 1965; in space mapping Bakr, Bandler,
    Madsen et al., IEEE Trans. MTT 46(12), 1998), the least change of ``slopes`` (in each
    key's range as its unit, ``span_si``) that makes them carry the level correction's
    change along the step, sum_j G'_j s_j = d_after - d_before, per condition and sample.
    Along other directions the slopes stay as they were. A step shorter than ``min_step``
    of range (Euclidean, in range units;
    :data:`~railsusp.estimate.config.BROYDEN_MIN_STEP`, 1 %) leaves the slopes as they
    were: across it the level's change is mostly the simulator's small-scale roughness
    (falls of a few millionths of the cost near convergence), which the secant would divide
    by the step's length. On issue 19's 12 sets the 1 % floor left the count as it was
    (42 of 44) and kept the last steps of two near-converged sets from moving 0.2-0.4 % of
    range on such a secant; a floor at the slopes' own 5 % lost two keys of one set whose
    3.8 % step had carried the curvature (bench/README.md, "Broyden's update: a floor")."""
    u = np.asarray(step_si, dtype=float) / span_si
    uu = float(u @ u)
    if uu == 0.0 or uu < min_step * min_step:
        return slopes
    out: Slopes = {j: {} for j in slopes}
    for key, after in level_after.items():
        carried = sum(slopes[j][key] * step_si[j] for j in slopes)
        miss = after - level_before[key] - carried
        for j in slopes:
            out[j][key] = slopes[j][key] + miss * (u[j] / (uu * span_si[j]))
    return out


def _broyden_at(
    corrected: LevelCorrected,
    level: dict[str, np.ndarray],
    x_si: np.ndarray,
    start_si: np.ndarray,
    span_si: np.ndarray,
    min_step: float,
) -> Slopes:
    """:func:`broyden_slopes` of the corrected surrogate made at ``start_si`` after the step
    to ``x_si``, where the level correction ``level`` was simulated."""
    step = x_si - start_si
    return broyden_slopes(corrected.slopes, corrected.corrections, level, step, span_si, min_step)


def correct_by_simulator(
    result: CalibrationResult,
    recordings: Sequence[Recording],
    model: ForceModel,
    steps: int = 1,
    max_evaluations: int = POLISH_EVALUATIONS,
    simulator: ForceModel | None = None,
    slopes: bool = False,
    slope_update: str = SIMULATED,
    broyden_min_step: float = BROYDEN_MIN_STEP,
) -> CalibrationResult:
    """Correct NSGA-II's estimate in place by ``steps`` simulator corrections: at the
    estimate x (NSGA-II's, after its geometry step: the expected-forces polish or the
    first SIMEX step), the level error d = simulator(x) - model(x) on each recording's
    track, then the bounded time-aligned least squares of model + d from x
    (:func:`~railsusp.estimate.refine.refine`, channel gains alongside where NSGA-II
    profiled them), whose point is the next x (with slopes: unless the check rejects it,
    below); where NSGA-II's estimate had the geometry
    error's bias taken off (the first SIMEX step: the least squares on the measured geometry
    lands on the biased point again), the same bias comes off each corrected point
    (measured only with expected forces, bench/README.md). If a simulation of x stops
    (derailment, divergence) the corrections made so far stand and the reason is kept
    (``result.corrections_stopped``). The model must be a surrogate: the simulator
    corrected by itself is refused. With ``config.expected_draws`` on recordings
    of stated accuracy, both are the expected forces over the same draws (seeded by
    ``config.seed``). The last point is the estimate
    (:attr:`~railsusp.estimate.result.CalibrationResult.corrected_x`); each step's least
    squares is kept (``result.corrections``). The simulator runs one parameter set per
    recording (and drawn track) per step, in one batched call. ``simulator``: the reference
    model (default the simulator on the estimated parameters, the others at nominal).
    ``slopes``: first-order corrections (the module's docstring): the simulator's slopes
    too, k more simulations per step, each least squares within a trust box
    (:data:`~railsusp.estimate.config.TRUST_BOX` at first), each proposed point checked by
    the next step's simulation of it (``result.correction_checks``,
    :mod:`railsusp.estimate.trust_region`): a rejected point is not a start, and a point
    whose simulation stopped is rejected rather than ending the corrections (a stepped set
    of the slopes that stops still ends them, at the last kept point). ``slope_update``:
    the slopes at each later kept point simulated again (``"simulated"``) or carried by
    Broyden's update (``"broyden"``, :func:`broyden_slopes`, also at rejected points; not
    across a step shorter than ``broyden_min_step`` of range, Euclidean);
    refused without ``slopes``.

    On issue 19's 12 sets (shipped networks, 60 s per condition, 0.5 mm geometry, 8 drawn
    tracks) one step took the identifiable key parameters within 5 % of range from 30 to
    39 of 44 (the simulator's own least squares from the truth: 39) for 10.7-14.5 s per
    estimate, and on exactly known track from 41 to 47 of 50 for 1.6-3.2 s (bench/README.md,
    "The networks' level error from one simulation")."""
    check_range("simulator_corrections", steps, *CORRECTIONS_RANGE)
    check_slope_update(slope_update, slopes, "slope_update", "slopes = False")
    if not steps:
        return result
    cfg = result.config
    check_correctable(recordings, cfg.statistic, "simulator_corrections", model)
    params = result.parameters
    drawn = cfg.expected_draws if stated_accuracy(recordings) else 0
    x = result.nsga_x  # the point simulated next
    span = np.diff(bounds(params), axis=0)[0]
    done: list[Refinement] = []
    checks: list[StepCheck] = []
    box = TRUST_BOX
    with ExitStack() as stack:
        surrogate = model
        simulator = SimulatorForces(params) if simulator is None else simulator
        if drawn:  # both as the mean over the same drawn true tracks
            surrogate = stack.enter_context(ExpectedForces(model, drawn, seed=cfg.seed))
            simulator = stack.enter_context(ExpectedForces(simulator, drawn, seed=cfg.seed))

        def cost(m: ForceModel, at: np.ndarray) -> float:
            return profiled_cost(m, recordings, params, at, cfg.channel_gains)

        base, corrected, base_cost = x, None, 0.0
        for _ in range(steps):
            # the point the previous first-order step proposed, checked by this simulation
            checked = checks[-1] if slopes and checks else None
            d: dict[str, np.ndarray] | None = None
            try:
                d = level_corrections(surrogate, simulator, recordings, x)
            except SimulationFailedError as exc:
                if checked is None:  # nothing to fall back on: stop here
                    result.corrections_stopped = str(exc)
                    break
                checked.reject_stopped(str(exc))  # a proposed point that derailed
            if checked is not None:
                if d is not None:
                    checked.judge(cost(LevelCorrected(surrogate, d), x))
                box = checked.next_box()
            if checked is None or checked.accepted:  # x becomes the start, made exact there
                assert d is not None
                g: Slopes | None = None
                try:
                    if checked is not None and slope_update == BROYDEN:
                        assert corrected is not None
                        g = _broyden_at(corrected, d, x, base, span, broyden_min_step)
                    elif slopes:
                        g = slope_corrections(surrogate, simulator, recordings, x, d)
                except SimulationFailedError as exc:  # a stepped set derailed: stop here
                    result.corrections_stopped = str(exc)
                    break
                base, corrected = x, LevelCorrected(surrogate, d, g, x)
                if checked is not None:  # judged just now, at x, where g adds nothing
                    assert checked.cost_simulated is not None
                    base_cost = checked.cost_simulated
                elif slopes:
                    base_cost = cost(corrected, x)
            elif d is not None and slope_update == BROYDEN:  # the rejected point's secant
                assert corrected is not None
                g = _broyden_at(corrected, d, x, base, span, broyden_min_step)
                corrected = LevelCorrected(surrogate, corrected.corrections, g, base)
            assert corrected is not None
            step = local_least_squares(
                corrected,
                recordings,
                result,
                base,
                drawn,
                max_evaluations,
                box=box if slopes else None,
            )
            if result.geometry_bias_removed:  # its least squares is biased as NSGA-II's was
                step.geometry_shifts_si = result.geometry_shifts_si
                step.geometry_bias_removed = True
            done.append(step)
            x = step.estimate_si
            if slopes:
                extent = step_extent(params, step.start_si, step.x_si)  # the move in the box
                checks.append(StepCheck(box, base_cost, cost(corrected, x), extent))
    result.corrections = done
    result.correction_checks = checks
    result.correction_slopes = slopes and bool(done)
    result.correction_slope_update = slope_update if result.correction_slopes else SIMULATED
    if cfg.channel_gains and done:
        result.channel_gains = dict(done[-1].channel_gains)
    return result
