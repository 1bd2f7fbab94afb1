"""The track geometry's measurement error in NSGA-II's estimate on time-aligned forces.

Two ways, one per estimate (:func:`account_for_geometry` picks): the shifts that draws of
the error cause, with the model NSGA-II ran on, and their mean taken off its choice (the
first SIMEX step, :func:`remove_nsga_geometry_bias`; :mod:`railsusp.estimate.geometry_bias`);
or, with ``expected_draws``, the model's own time-aligned least squares from its choice on
its expected forces, the mean over draws of the true geometry given the measured one
(:func:`polish_on_expected_forces`; :mod:`railsusp.estimate.expected_forces`), which
removes the bias the SIMEX step leaves (bench/README.md)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.estimate.config import NSGAConfig
from railsusp.estimate.expected_forces import ExpectedForces
from railsusp.estimate.forces import ForceModel
from railsusp.estimate.geometry_bias import GEOMETRY_DRAWS, geometry_shifts_at, stated_accuracy
from railsusp.estimate.refine import Refinement, refine
from railsusp.estimate.result import CalibrationResult
from railsusp.estimate.statistics import ALIGNED, parse_statistics
from railsusp.measured import Recording

#: the expected-forces polish's most evaluations of the residuals (its Jacobians are more)
POLISH_EVALUATIONS = 40


def _geometry_error_applies(config: NSGAConfig, recordings: Sequence[Recording]) -> bool:
    """What both ways of giving NSGA-II's estimate the geometry's error need
    (:func:`takes_geometry_bias`, :func:`takes_expected_polish`): it compared time-aligned
    forces alone (statistic ``aligned``: each acts on the time-aligned least squares) and a
    recording states its geometry's accuracy (else nothing is known of the error)."""
    return parse_statistics(config.statistic) == (ALIGNED,) and stated_accuracy(recordings)


def geometry_draws_unused(
    config: NSGAConfig, recordings: Sequence[Recording], refine: bool, draws: int
) -> str:
    """Why no step of an estimate draws the recordings' track-geometry error (neither
    NSGA-II's SIMEX step, :func:`takes_geometry_bias`, nor the refinement's standard
    errors, :func:`~railsusp.estimate.polish.refine_estimate`), so that its number of draws
    and whether their bias is removed change nothing, or why ``draws`` = 0 leaves no bias
    to keep where a step would draw; '' where a step draws it."""
    if not stated_accuracy(recordings):
        return (
            "no recording states its track geometry's accuracy (condition.track_accuracy_mm), "
            "so no error is drawn"
        )
    if config.expected_draws:
        return (
            f"with expected_draws {config.expected_draws} the geometry's error is in the "
            "comparison (the mean over drawn true tracks) instead"
        )
    if refine or parse_statistics(config.statistic) == (ALIGNED,):
        return "" if draws else "geometry_draws 0 draws none, so no bias is estimated to keep"
    return (
        f"NSGA-II on statistic {config.statistic!r} draws none (only 'aligned' alone does) "
        "and there is no refinement"
    )


def takes_geometry_bias(config: NSGAConfig, draws: int, recordings: Sequence[Recording]) -> bool:
    """Whether NSGA-II's estimate (run with ``config``) gets the geometry's error: it
    compared time-aligned forces alone (statistic ``aligned``: its choice is then the
    time-aligned least-squares point whose shifts the draws measure; a combination with
    record statistics is chosen by the ideal point of another front), not with expected
    forces (``config.expected_draws``: their polish, or NSGA-II's generations on them, take
    the error in instead, :func:`takes_expected_polish`), ``draws`` > 0, and a recording
    states its accuracy."""
    return _geometry_error_applies(config, recordings) and not config.expected_draws and draws > 0


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
    its configuration asks for expected forces instead (``expected_draws``: their polish
    takes the SIMEX step's place; :func:`takes_geometry_bias`). With several
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


def takes_expected_polish(config: NSGAConfig, recordings: Sequence[Recording]) -> bool:
    """Whether NSGA-II's estimate (run with ``config``) is polished on expected forces:
    ``config.expected_draws`` > 0, statistic ``aligned`` alone (the polish is the
    time-aligned least squares), and a recording states its geometry's accuracy (elsewhere
    the expected forces are the model's own)."""
    return bool(config.expected_draws) and _geometry_error_applies(config, recordings)


def local_least_squares(
    model: ForceModel,
    recordings: Sequence[Recording],
    result: CalibrationResult,
    start_si: np.ndarray,
    expected_draws: int,
    max_evaluations: int = POLISH_EVALUATIONS,
    box: float | None = None,
) -> Refinement:
    """``model``'s bounded time-aligned least squares from ``start_si`` as NSGA-II's
    configuration compares (channel gains alongside where it profiled them), no geometry
    draws (:func:`~railsusp.estimate.refine.refine`; ``box`` its trust region): what the
    expected-forces polish and each simulator correction
    (:mod:`railsusp.estimate.level_correction`) solve. The result records the
    ``expected_draws`` its model averaged over and keeps no problem (the drawn files of an
    expected-forces model go with it; no series cache is kept)."""
    step = refine(
        model,
        recordings,
        result.parameters,
        start_si,
        max_evaluations=max_evaluations,
        gains=result.config.channel_gains,
        geometry_draws=0,
        box=box,
    )
    step.problem = None
    step.expected_draws = expected_draws
    return step


def polish_on_expected_forces(
    result: CalibrationResult,
    recordings: Sequence[Recording],
    model: ForceModel,
    max_evaluations: int = POLISH_EVALUATIONS,
) -> CalibrationResult:
    """Polish NSGA-II's choice in place, where :func:`takes_expected_polish` says so: the
    bounded least squares of the time-aligned residuals
    (:func:`~railsusp.estimate.refine.refine`, channel gains alongside where NSGA-II
    profiled them) with ``model``'s mean over ``config.expected_draws`` draws of the true
    track geometry given each recording's measured one
    (:class:`~railsusp.estimate.expected_forces.ExpectedForces`, seeded by
    ``config.seed``), started at the choice; the result
    (:attr:`~railsusp.estimate.result.CalibrationResult.expected_polish`) becomes NSGA-II's
    estimate and its Pareto range moves with it. The measured geometry carries its error as
    extra short-wavelength roughness, which biases a comparison on it (the wedge friction
    X18 by about +10 % of range at 0.5 mm); the expected forces are what the model predicts
    on the tracks the measurement allows. A local search of a few Jacobians, not expected
    forces in all of NSGA-II's generations: on the shipped networks the two land alike, at
    8-10 s against 800-1200 s per estimate (bench/README.md). With several NSGA-II seeds the
    first seed's choice is polished."""
    if not takes_expected_polish(result.config, recordings):
        return result
    cfg = result.config
    with ExpectedForces(model, cfg.expected_draws, seed=cfg.seed) as expected:
        polish = local_least_squares(
            expected,
            recordings,
            result,
            result.pareto_x[result.chosen],
            cfg.expected_draws,
            max_evaluations,
        )
    result.expected_polish = polish
    if cfg.channel_gains:  # the estimate's gains are the polish's
        result.channel_gains = dict(polish.channel_gains)
    return result


def account_for_geometry(
    result: CalibrationResult,
    recordings: Sequence[Recording],
    model: ForceModel,
    draws: int = GEOMETRY_DRAWS,
    seed: int = 0,
    remove: bool = True,
) -> CalibrationResult:
    """Give NSGA-II's estimate the recordings' stated geometry error, in place, the way its
    configuration asks: the expected-forces polish (:func:`polish_on_expected_forces`)
    with ``expected_draws``, else the first SIMEX step with ``draws`` draws
    (:func:`remove_nsga_geometry_bias`, ``remove``: take the bias off); nothing where the
    comparison is not time-aligned alone or no recording states its accuracy."""
    if takes_expected_polish(result.config, recordings):
        return polish_on_expected_forces(result, recordings, model)
    if takes_geometry_bias(result.config, draws, recordings):
        return remove_nsga_geometry_bias(result, recordings, model, draws, seed, remove)
    return result
