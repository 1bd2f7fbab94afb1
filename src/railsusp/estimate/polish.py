"""The simulator polish of an NSGA-II estimate: screened starts, output-error refinement.

Time-aligned costs have local minima, and an estimate from statistics can sit in the wrong
basin: :func:`refine_estimate` scores candidate starts by their time-aligned cost
(:func:`aligned_cost`), refines the best together
(:func:`railsusp.estimate.refine.refine_starts`) and attaches the winner to the
:class:`~railsusp.estimate.result.CalibrationResult`.
:func:`check_refinable` refuses, before NSGA-II runs, recordings the refinement cannot use.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.estimate.comparison import check_time_base
from railsusp.estimate.config import NSGA_RANGES, REFINE_RANGES, check_count
from railsusp.estimate.expected_forces import ExpectedForces
from railsusp.estimate.forces import ForceModel, SimulatorForces, series_in_conditions
from railsusp.estimate.geometry_bias import GEOMETRY_DRAWS, stated_accuracy
from railsusp.estimate.output_error import OutputError
from railsusp.estimate.problem import CalibrationProblem, check_aligned, display_values
from railsusp.estimate.refine import CHOICE, GEOMETRY_CORRECTED, refine_starts
from railsusp.estimate.result import CalibrationResult
from railsusp.estimate.statistics import ALIGNED, parse_statistics
from railsusp.measured import Recording
from railsusp.params import ParameterSet, bounds

#: Latin hypercube points screened for refinement starts, and the starts refined
REFINE_SCREEN = 64
REFINE_STARTS = 2


def check_refinable(recordings: Sequence[Recording], setting: str = "refine") -> None:
    """Refuse, with a one-line input error naming ``setting`` (``--refine`` on the command
    line, ``estimate.refine`` in a configuration), recordings the refinement cannot use:
    it compares series sample by sample on the track they were recorded on, so every
    recording must carry its measured track geometry. Call it before NSGA-II runs."""
    blind = [r.condition.name for r in recordings if r.condition.track_geometry is None]
    if blind:
        raise RailsuspInputError(
            f"{setting} compares time-aligned series on the recordings' measured track, but "
            f"{', '.join(blind)} carry no track geometry (condition.track_geometry, "
            "docs/data-format.md; synthetic recordings: synth-field --with-track or "
            "field.with_track = true); drop the refinement or give recordings on measured track"
        )
    check_time_base(recordings, f"{setting} (the output-error refinement)")


def aligned_cost(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
) -> np.ndarray:
    """(n,) half the sum over recordings and forces of the squared :func:`aligned_error`:
    the refinement's cost at unit channel gains, for many parameter sets in one batch."""
    e = CalibrationProblem(model, recordings, parameters, ALIGNED).errors(np.atleast_2d(x_si))
    return 0.5 * (e**2).sum(axis=(1, 2))


def refine_estimate(
    result: CalibrationResult,
    recordings: Sequence[Recording],
    model: ForceModel | None = None,
    max_evaluations: int = 40,
    gains: bool = True,
    screen: int = REFINE_SCREEN,
    starts: int = REFINE_STARTS,
    seed: int = 0,
    geometry_draws: int = GEOMETRY_DRAWS,
    remove_geometry_bias: bool = True,
    polish: bool | None = None,
    expected_draws: int | None = None,
) -> CalibrationResult:
    """Refine NSGA-II's estimate in place and return the result (its estimate is now the
    refined one); by default with the simulator itself.

    Time-aligned costs have local minima, and an estimate from statistics can sit in the
    wrong basin, so the starts are screened first: NSGA-II's choice and its estimate (the
    choice less its geometry bias, where removed), the Pareto set, the nominal parameters
    and ``screen`` Latin hypercube points are scored by :func:`aligned_cost` in one batch
    (each distinct point once), the ``starts`` best are refined together
    (:func:`~railsusp.estimate.refine.refine_starts`: their simulations share batches, and
    the screened series of the starts are not simulated again), and the lowest final cost
    wins. Every start's result is kept in ``result.refinement.starts``. The winner's
    uncertainty then takes in the geometry's stated measurement error (``geometry_draws``
    draws; see :meth:`~railsusp.estimate.output_error.OutputError.geometry_shifts`), and with
    ``remove_geometry_bias`` the estimate is the refined point less the bias those draws
    estimate (:attr:`~railsusp.estimate.refine.Refinement.geometry_bias_si`).
    The standard errors stay those of the refined point (the removal is itself uncertain by
    about its size).

    ``expected_draws`` (default: the estimate's, ``result.config.expected_draws``) > 0, on
    recordings whose geometry states its accuracy: the starts are refined on the model's
    expected forces, its mean over that many draws of the true geometry given the measured
    one (:class:`~railsusp.estimate.expected_forces.ExpectedForces`, seeded by the
    estimate's ``config.seed``, so the draws of its polish and of its validation; that many
    times the simulations), and the geometry's error is then in the comparison, so no draws
    of it are propagated (``geometry_draws`` is not used; the standard errors then have no
    geometry part: the Monte-Carlo error of the mean over draws is left out too). The
    expected forces stay open with the refinement's problem (its drawn files are removed
    when it is collected). The screen stays on the measured geometry: it picks basins, which the
    geometry's bias (a few % of range) does not move. With the simulator as the model its
    least squares from the truth put 39 of 44 identifiable key parameters within 5 % of
    range on issue 19's 12 sets, against 33 with the SIMEX step (bench/README.md).

    ``polish``: whether the refinement is a polish shown beside NSGA-II's estimate, which
    then stays the estimate (:attr:`~railsusp.estimate.result.CalibrationResult.polished_x`),
    rather than the estimate itself; by default it is one when NSGA-II compared time-aligned
    forces (statistic ``aligned``), where the force model on the recordings' own track gives
    the answer, and not after record statistics, which the refinement corrects."""
    from scipy.stats import qmc

    settings = {
        "max_evaluations": max_evaluations,
        "screen": screen,
        "starts": starts,
        "geometry_draws": geometry_draws,
    }
    for name, value in settings.items():
        check_count(name, value, *REFINE_RANGES[name])
    if expected_draws is None:
        expected_draws = result.config.expected_draws
    for name, value in (("seed", seed), ("expected_draws", expected_draws)):
        low, high = NSGA_RANGES[name]
        check_count(name, value, int(low), int(high))
    check_refinable(recordings)
    params = result.parameters
    model = SimulatorForces(params) if model is None else model
    check_aligned(model, recordings)  # the screen below sees the model through _Kept
    lo, hi = bounds(params)
    nominal = np.array([ParameterSet.nominal()[p] for p in params])
    lhs = qmc.LatinHypercube(d=len(params), seed=seed).random(screen) if screen else None
    groups = [(result.pareto_x[result.chosen][None], CHOICE)]
    if result.geometry_bias_removed or result.expected_polish is not None:
        groups.append((result.nsga_x[None], GEOMETRY_CORRECTED))
    if result.corrections:
        groups.append((result.corrected_x[None], "the simulator-corrected estimate"))
    groups += [
        (result.pareto_x, "a point of the Pareto set"),
        (nominal[None], "the nominal parameters"),
    ]
    if lhs is not None:
        groups.append((lo + lhs * (hi - lo), "a Latin-hypercube screening point"))
    candidates = np.vstack([x for x, _ in groups])
    origins = [name for x, name in groups for _ in range(len(x))]
    # each distinct candidate once (the chosen point is also on the Pareto set: it was
    # refined twice as two of the starts), named by its first appearance, and the series
    # kept, so that a refinement starting from a candidate need not simulate it again
    distinct, inverse = _distinct_rows(candidates)
    first = [int(np.flatnonzero(inverse == j)[0]) for j in range(len(distinct))]
    kept = _Kept(model)
    costs = aligned_cost(kept, recordings, params, distinct)
    expected = expected_draws if stated_accuracy(recordings) else 0
    if expected:  # compared as the mean over drawn true tracks: the screen's series differ
        drawn = ExpectedForces(model, expected, seed=result.config.seed)
        problem = OutputError(drawn, recordings, params, gains=gains)
        geometry_draws = 0
    else:
        problem = OutputError(model, recordings, params, gains=gains)
        problem.remember(distinct, kept.returned)
    best = np.argsort(costs, kind="stable")[:starts]
    runs = refine_starts(problem, [distinct[i] for i in best], max_evaluations)
    won = min(range(len(runs)), key=lambda k: runs[k].cost)
    winner = runs[won]
    assert winner.solution is not None
    winner.geometry_shifts_si = problem.geometry_shifts(winner.solution, geometry_draws, seed)
    winner.geometry_bias_removed = remove_geometry_bias and winner.geometry_shifts_si.size > 0
    winner.start_origin = origins[first[best[won]]]
    winner.starts = [
        {
            "origin": origins[first[i]],
            "start_display": display_values(params, r.start_si),
            "screened_cost": float(costs[i]),
            "cost": r.cost,
            "refined_display": display_values(params, r.x_si),
        }
        for i, r in zip(best, runs, strict=True)
    ]
    winner.screened = len(distinct)  # each distinct candidate scored once
    winner.expected_draws = expected
    result.refinement = winner
    if polish is None:
        polish = ALIGNED in parse_statistics(result.config.statistic)
    result.refinement_is_polish = polish
    return result


def _distinct_rows(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of ``x`` in order of first appearance, and for each row of ``x``
    the index of its distinct row."""
    _, first, inverse = np.unique(x, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return x[first[order]], rank[inverse.reshape(-1)]


class _Kept:
    """A force model that keeps the series it returns (``returned``, one per call)."""

    def __init__(self, model: ForceModel):
        self.model = model
        self.returned: list[np.ndarray] = []

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        out = self.model.series(x_si, condition)
        self.returned.append(out)
        return out

    def series_conditions(
        self, x_si: np.ndarray, conditions: Sequence[WorkingCondition]
    ) -> list[np.ndarray]:
        """All conditions at once where the model can (the simulator: one call of all the
        candidates in every recording, which keeps the cores busier than one per recording;
        each set's numbers are those it gets alone), one kept series per condition."""
        out = series_in_conditions(self.model, x_si, conditions)
        self.returned.extend(out)
        return out
