"""NSGA-II calibration of the key suspension parameters against measured wheel-rail forces.

One module per job, imports running one way (top to bottom depends only on those above):

- :mod:`~railsusp.estimate.statistics`: record statistics of recordings and predictions
- :mod:`~railsusp.estimate.comparison`: the time-aligned comparison on measured track
- :mod:`~railsusp.estimate.forces`: force models (window surrogates, the simulator)
- :mod:`~railsusp.estimate.statistics_forces`: statistics surrogates as a force model, and the
  surrogate kind of a folder
- :mod:`~railsusp.estimate.expected_forces`: a model's mean over draws of the true track
  geometry given a measured one
- :mod:`~railsusp.estimate.problem`: the calibration problem (objectives), input checks
- :mod:`~railsusp.estimate.config`: NSGA-II settings and their accepted ranges
- :mod:`~railsusp.estimate.identifiability`: Cramér-Rao bounds of the statistics
- :mod:`~railsusp.estimate.lockstep`: independent solvers in step, their requests batched
- :mod:`~railsusp.estimate.output_error`: the refinement's least-squares problem, simulations
- :mod:`~railsusp.estimate.residual_noise`: least-squares standard errors, pooled or per channel
- :mod:`~railsusp.estimate.geometry_bias`: the track geometry's error in an estimate (SIMEX)
- :mod:`~railsusp.estimate.refine`: output-error refinement with the simulator
- :mod:`~railsusp.estimate.alignment`: registration of measured track with the forces
- :mod:`~railsusp.estimate.intervals`: the interval every route reports, the verdict
- :mod:`~railsusp.estimate.refine_intervals`: the refinement's confidence intervals
- :mod:`~railsusp.estimate.aligned_identifiability`: Cramér-Rao bounds of the time-aligned
  comparison
- :mod:`~railsusp.estimate.estimate_point`: which point is the estimate, its intervals and
  spreads (the Pareto set and what the steps after NSGA-II left)
- :mod:`~railsusp.estimate.result`: the estimate result (route, save, table)
- :mod:`~railsusp.estimate.nsga`: the NSGA-II run (pymoo), log, choice rule, seed spread
- :mod:`~railsusp.estimate.nsga_geometry`: the geometry error in NSGA-II's estimate: its
  bias off the choice (first SIMEX step) or the choice polished on expected forces
- :mod:`~railsusp.estimate.polish`: screened starts and refinement of an NSGA-II estimate
- :mod:`~railsusp.estimate.level_correction`: the surrogate's level error at the estimate
  from the simulator, its least squares repeated with it (output space mapping)
- :mod:`~railsusp.estimate.route`: the estimate's steps in order (NSGA-II, the geometry
  error, the simulator corrections, the refinement), for the command line and the pipeline

This package re-exports the public names other code uses, so ``from railsusp.estimate
import estimate, NSGAConfig, refine_estimate`` works; the refinement's own
:func:`~railsusp.estimate.refine.refine` is imported from its module.
"""

from __future__ import annotations

from railsusp.estimate.alignment import TrackAlignment, align_track
from railsusp.estimate.comparison import (
    FAILED_ALIGNED_ERROR,
    aligned_error,
    compared_measurement,
    comparison_band_hz,
    comparison_filter,
    comparison_samples,
    measurement_filter,
)
from railsusp.estimate.config import NSGAConfig
from railsusp.estimate.forces import ForceModel, SimulatorForces, SurrogateForces
from railsusp.estimate.identifiability import BOUND_LIMIT_PCT, cramer_rao_pct_range
from railsusp.estimate.nsga import choose, estimate, estimate_with_seeds
from railsusp.estimate.polish import aligned_cost, check_refinable, refine_estimate
from railsusp.estimate.problem import (
    CalibrationProblem,
    check_aligned,
    check_recordings,
    display_values,
)
from railsusp.estimate.refine import Refinement
from railsusp.estimate.result import CalibrationResult
from railsusp.estimate.statistics import (
    ALIGNED,
    STATISTICS,
    WEIGHTINGS,
    check_weighting,
    measured_statistics,
    parse_statistics,
    recording_segments,
    series_statistics,
    yq_statistics,
)
from railsusp.estimate.statistics_forces import (
    StatisticsForces,
    force_statistics,
    open_force_model,
)

__all__ = [
    "ALIGNED",
    "BOUND_LIMIT_PCT",
    "FAILED_ALIGNED_ERROR",
    "STATISTICS",
    "WEIGHTINGS",
    "CalibrationProblem",
    "CalibrationResult",
    "ForceModel",
    "NSGAConfig",
    "Refinement",
    "SimulatorForces",
    "StatisticsForces",
    "SurrogateForces",
    "TrackAlignment",
    "align_track",
    "aligned_cost",
    "aligned_error",
    "check_aligned",
    "check_recordings",
    "check_refinable",
    "check_weighting",
    "choose",
    "compared_measurement",
    "comparison_band_hz",
    "comparison_filter",
    "comparison_samples",
    "cramer_rao_pct_range",
    "display_values",
    "estimate",
    "estimate_with_seeds",
    "force_statistics",
    "measured_statistics",
    "measurement_filter",
    "open_force_model",
    "parse_statistics",
    "recording_segments",
    "refine_estimate",
    "series_statistics",
    "yq_statistics",
]
