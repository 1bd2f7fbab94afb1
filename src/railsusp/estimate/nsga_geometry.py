"""The track geometry's measurement error in NSGA-II's estimate on time-aligned forces: the
shifts that draws of it cause, with the model NSGA-II ran on, and their mean taken off its
choice (the first SIMEX step; :mod:`railsusp.estimate.geometry_bias`)."""

from __future__ import annotations

from collections.abc import Sequence

from railsusp.estimate.config import NSGAConfig
from railsusp.estimate.forces import ForceModel
from railsusp.estimate.geometry_bias import GEOMETRY_DRAWS, geometry_shifts_at, stated_accuracy
from railsusp.estimate.result import CalibrationResult
from railsusp.estimate.statistics import ALIGNED, parse_statistics
from railsusp.measured import Recording


def takes_geometry_bias(config: NSGAConfig, draws: int, recordings: Sequence[Recording]) -> bool:
    """Whether NSGA-II's estimate (run with ``config``) gets the geometry's error: it
    compared time-aligned forces alone (statistic ``aligned``: its choice is then the
    time-aligned least-squares point whose shifts the draws measure; a combination with
    record statistics is chosen by the ideal point of another front), on the measured
    geometry itself (not expected forces, ``config.expected_draws``: the error is then
    already in its comparison, and the draws' shifts of an estimate on them would cost draws
    x expected draws predictions per step), ``draws`` > 0, and a recording states its
    accuracy."""
    return (
        parse_statistics(config.statistic) == (ALIGNED,)
        and not config.expected_draws
        and draws > 0
        and stated_accuracy(recordings)
    )


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
    ``remove`` its estimate becomes the choice less their mean, for the parameters whose
    draws' scatter is at most half their range
    (:func:`~railsusp.estimate.geometry_bias.removable`), and its Pareto range moves with it.
    Needs the statistic ``aligned`` alone, and does nothing where no recording states its
    geometry's accuracy or ``draws`` is 0 (then nothing is known of the error), and where
    NSGA-II compared expected forces (:func:`takes_geometry_bias`). With several
    NSGA-II seeds (:func:`~railsusp.estimate.nsga.estimate_with_seeds`) the shifts are taken
    at the first seed's choice, and the seed spread stays that of the choices. On 12
    parameter sets with 0.5 mm geometry it took NSGA-II on the shipped CNN-GRUs from 15 to
    29 of 44 identifiable key parameters within 5 % of range, X18 from 0 to 12 of 12
    (bench/README.md)."""
    if parse_statistics(result.config.statistic) != (ALIGNED,):
        raise ValueError(
            "the geometry's bias is that of the time-aligned least squares (statistic "
            f"'aligned' alone); NSGA-II compared {result.config.statistic!r}"
        )
    if not takes_geometry_bias(result.config, draws, recordings):
        return result
    result.geometry_shifts_si = geometry_shifts_at(
        model,
        recordings,
        result.parameters,
        result.pareto_x[result.chosen],
        draws,
        seed,
        gains=result.config.channel_gains,
    )
    result.geometry_bias_removed = remove
    return result
