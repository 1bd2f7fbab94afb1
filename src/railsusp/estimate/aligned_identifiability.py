"""How precisely can time-aligned forces fix each key parameter? A Cramér-Rao bound.

The time-aligned counterpart of :mod:`railsusp.estimate.identifiability` (which bounds what
record statistics can tell): for recordings on measured track compared sample by sample
(:func:`~railsusp.estimate.comparison.aligned_error`), the Fisher information about the key
parameters in unit-range coordinates is JᵀJ / σ², with J the forward-difference Jacobian of
the scaled residuals of every recording's lateral and vertical force
(:class:`~railsusp.estimate.output_error.OutputError`, the refinement's problem, without
channel gains) and σ² their variance, inflated by the residuals' integrated autocorrelation
time (:func:`~railsusp.estimate.refine_intervals.effective_sample_size`: filtered residuals
are not independent). The square roots of the diagonal of its inverse are the smallest
standard deviations any unbiased estimator can reach from these recordings; a parameter
whose bound exceeds :data:`~railsusp.estimate.identifiability.BOUND_LIMIT_PCT` of its range
is not identifiable to that precision.

Evaluated at a given point (for synthetic recordings, the truth: a property of the
recordings and the force model, not of any estimate), with whatever force model is given
(a surrogate, or the simulator); local and linearised, so a guide, not a guarantee.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.estimate.forces import ForceModel
from railsusp.estimate.identifiability import BOUND_LIMIT_PCT
from railsusp.estimate.output_error import OutputError
from railsusp.estimate.refine import standard_errors
from railsusp.estimate.refine_intervals import effective_sample_size
from railsusp.measured import Recording


def aligned_cramer_rao_pct_range(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
) -> dict[str, float]:
    """Cramér-Rao bound of each key parameter at ``x_si`` (SI) from the time-aligned
    comparison of ``model`` with ``recordings``, in % of its range; infinite for a parameter
    the residuals do not depend on. σ² is the residual variance at ``x_si`` (measurement
    noise, geometry error and model error alike), times the autocorrelation time."""
    problem = OutputError(model, recordings, parameters, gains=False)
    unit = np.clip((np.asarray(x_si, dtype=float) - problem.lo) / (problem.hi - problem.lo), 0, 1)
    preds = problem.predictions(problem.steps(unit))
    jac = problem.jacobian_of(preds, unit)
    r = problem.residuals(preds, np.ones(0))[0]
    blocks = [u[c].size for u in problem.samples for c in range(2)]
    _, tau = effective_sample_size(r, blocks)
    s2 = float(r @ r) / max(r.size - problem.k, 1) * tau
    bound = 100.0 * standard_errors(jac, s2)
    return {p: float(b) for p, b in zip(parameters, bound, strict=True)}


def identifiable(bounds_pct: dict[str, float], limit_pct: float = BOUND_LIMIT_PCT) -> list[str]:
    """The parameters whose bound is at most ``limit_pct`` of their range."""
    return [p for p, b in bounds_pct.items() if b <= limit_pct]
