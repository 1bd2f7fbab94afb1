"""The track geometry's measurement error in NSGA-II's estimate on time-aligned forces: the
shifts that draws of it cause, with the model NSGA-II ran on, and their mean taken off its
choice (the first SIMEX step; :mod:`railsusp.estimate.geometry_bias`)."""

from __future__ import annotations

from collections.abc import Sequence

from railsusp.estimate.forces import ForceModel
from railsusp.estimate.geometry_bias import GEOMETRY_DRAWS, geometry_shifts_at, stated_accuracy
from railsusp.estimate.result import CalibrationResult
from railsusp.estimate.statistics import ALIGNED, parse_statistics
from railsusp.measured import Recording


def remove_nsga_geometry_bias(
    result: CalibrationResult,
    recordings: Sequence[Recording],
    model: ForceModel,
    draws: int = GEOMETRY_DRAWS,
    seed: int = 0,
    remove: bool = True,
) -> CalibrationResult:
    """Give NSGA-II's time-aligned estimate the geometry's measurement error, in place: the
    shifts of :func:`geometry_shifts_at` with the model NSGA-II ran on, at its choice; with
    ``remove`` its estimate becomes the choice less their mean (the Pareto set moves with
    it). Needs the statistic ``aligned``, and does nothing where no recording states its
    geometry's accuracy or ``draws`` is 0 (then nothing is known of the error). On 12
    parameter sets with 0.5 mm geometry it took NSGA-II on the shipped CNN-GRUs from 15 to
    29 of 44 identifiable key parameters within 5 % of range, X18 from 0 to 12 of 12
    (bench/README.md)."""
    if ALIGNED not in parse_statistics(result.config.statistic):
        raise ValueError(
            f"the geometry's bias is that of time-aligned forces; NSGA-II compared "
            f"{result.config.statistic!r}"
        )
    if draws <= 0 or not stated_accuracy(recordings):
        return result
    result.geometry_shifts_si = geometry_shifts_at(
        model, recordings, result.parameters, result.pareto_x[result.chosen], draws, seed
    )
    result.geometry_bias_removed = remove
    return result
