"""How precisely can the recordings' statistics fix each key parameter? The Cramér-Rao bound.

For statistics compared with a statistics surrogate (Gaussian processes, ``gp-stats``), the
Fisher information of the measured statistics about the key parameters is F = Jᵀ Σ⁻¹ J,
with J the gradient of the GP means (central differences) and Σ the variance of each
measured statistic about its expectation: the GP's own uncertainty plus the scatter between
track realisations, scaled to the recording's length
(:meth:`railsusp.estimate.statistics_forces.StatisticsForces.measurement_std`). The square
roots of the diagonal of F⁻¹ are the smallest standard deviations that any unbiased
estimator can reach from these statistics (Cramér-Rao; e.g. Kay, *Fundamentals of
Statistical Signal Processing: Estimation Theory*, 1993, ch. 3). A parameter whose bound exceeds
:data:`BOUND_LIMIT_PCT` of its range cannot be recovered to that precision by any
optimiser: more or longer recordings, or measured track geometry, are needed.

The bound is local (evaluated at one parameter set) and assumes independent statistics, so
it is a guide, not a guarantee; sensor noise is not in Σ. It is a bound on unbiased
estimates inside the range: an estimate on a range bound (within :data:`AT_BOUND_PCT`) is
where the search stopped, not where the data put it, and the differences there see the
model on one side only, so no bound is given for it (NaN: "does not apply"), rather than
a small number that reads as precision the estimate lacks.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from railsusp.params import bounds

if TYPE_CHECKING:
    from railsusp.estimate.statistics_forces import StatisticsForces
    from railsusp.measured import Recording

#: a parameter whose Cramér-Rao bound exceeds this share of its range is flagged
BOUND_LIMIT_PCT = 5.0
#: an estimate this close to a range bound (% of range) is on it: its bound does not apply
AT_BOUND_PCT = 0.5


def on_range_bound(parameters: Sequence[str], x_si: np.ndarray) -> list[bool]:
    """Per parameter, whether ``x_si`` lies within :data:`AT_BOUND_PCT` of its range's
    lower or upper bound."""
    lo, hi = bounds(parameters)
    u = 100.0 * (np.asarray(x_si, dtype=float) - lo) / (hi - lo)
    return [bool(v <= AT_BOUND_PCT or v >= 100.0 - AT_BOUND_PCT) for v in u]


def fisher_information(
    model: StatisticsForces,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
    statistics: Sequence[str],
    step: float = 0.02,
) -> np.ndarray:
    """(k, k) Fisher information about the key parameters in unit-range coordinates, from
    the lateral and vertical ``statistics`` of every recording."""
    lo, hi = bounds(parameters)
    u = (np.asarray(x_si, dtype=float) - lo) / (hi - lo)
    k = len(parameters)
    # central differences, kept inside the ranges
    up = np.clip(u + step * np.eye(k), 0.0, 1.0)
    down = np.clip(u - step * np.eye(k), 0.0, 1.0)
    width = (up - down)[np.arange(k), np.arange(k)]
    info = np.zeros((k, k))
    for rec in recordings:
        pts = lo + (hi - lo) * np.vstack([up, down])
        pred = model.predict_statistics(pts, rec.condition, statistics).reshape(2 * k, -1)
        jac = (pred[:k] - pred[k:]).T / width  # (n_features, k)
        sd = model.measurement_std(x_si[None, :], rec, statistics).reshape(-1)
        weighted = jac / np.maximum(sd, 1e-9)[:, None]
        info += weighted.T @ weighted
    return info


def cramer_rao_pct_range(
    model: StatisticsForces,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
    statistics: Sequence[str],
) -> dict[str, float]:
    """Cramér-Rao bound of each key parameter at ``x_si`` (SI), in % of its range; infinite
    for a parameter (combination) that the statistics do not inform at all; NaN (does not
    apply) for one whose value lies on its range bound (module docstring)."""
    info = fisher_information(model, recordings, parameters, x_si, statistics)
    try:
        cov = np.linalg.inv(info)
        bound = 100.0 * np.sqrt(np.maximum(np.diag(cov), 0.0))
        if not np.all(np.isfinite(bound)) or np.any(np.diag(cov) < 0.0):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        bound = np.full(len(parameters), np.inf)
    bound[on_range_bound(parameters, x_si)] = np.nan
    return {p: float(b) for p, b in zip(parameters, bound, strict=True)}
