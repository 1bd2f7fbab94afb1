"""The refined estimate's error as a distribution, and its central quantiles (GUM Supplement 1).

The refinement's error is the sum of independent parts of different shapes
(:mod:`railsusp.estimate.refine_intervals`): the linear response R·δ to the main-suspension
parameters it holds, each δ_j uniform over the user's range less the value held (offsets
included), the sensor noise's part (Student-t on the effective degrees of freedom, scaled by
its standard error) and the track geometry error's (normal). A multiple of the total
standard deviation is the right quantile only for a normal error: one uniform part alone has
its central 90 % within 0.9 of its half-range, 1.559 standard deviations, not 1.645, and an
offset makes the error asymmetric. :func:`error_quantiles` takes the quantiles of the sum
itself, by the Monte Carlo propagation of distributions of JCGM 101:2008 (GUM Supplement 1),
with a fixed seed so that the same refinement always gives the same interval.
"""

from __future__ import annotations

import numpy as np

#: Monte Carlo draws of the error (JCGM 101:2008, 7.2: 10⁶ for a 95 % interval to about two
#: significant figures; 2·10⁵ puts the 5 % and 95 % quantiles within about 0.5 % of the
#: standard deviation)
DRAWS = 200_000
#: the draws' seed: the same refinement gives the same interval
SEED = 20081


def error_quantiles(
    response: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    noise_sd: np.ndarray,
    dof: float | None = None,
    other_sd: np.ndarray | None = None,
    level: float = 0.9,
    draws: int = DRAWS,
    seed: int = SEED,
) -> tuple[np.ndarray, np.ndarray]:
    """((k,), (k,)) the (1 - level)/2 and (1 + level)/2 quantiles of the error

        e_i = Σ_j R_ij δ_j + noise_sd_i · T + other_sd_i · Z

    with R = ``response`` (k, h), δ_j independent and uniform on [low_j, high_j], T a
    Student-t variable on ``dof`` degrees of freedom (normal when None) and Z a normal one,
    all independent; estimated from ``draws`` draws seeded by ``seed`` (one draw of δ, T and
    Z serves every row, as the parts are common to the estimate's parameters). A row with a
    non-finite part gets (-inf, inf): its error is unbounded."""
    r = np.atleast_2d(np.asarray(response, dtype=float))
    k = r.shape[0]
    noise = np.broadcast_to(np.asarray(noise_sd, dtype=float), (k,))
    other = np.zeros(k) if other_sd is None else np.broadcast_to(np.asarray(other_sd, float), (k,))
    lo, hi = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    if lo.shape != (r.shape[1],) or hi.shape != lo.shape or np.any(hi < lo):
        raise ValueError(f"low and high must be {r.shape[1]} bounds with low <= high")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level {level}: accepted between 0 and 1")
    rng = np.random.default_rng(seed)
    delta = lo + (hi - lo) * rng.random((draws, r.shape[1]))
    t = rng.standard_normal(draws) if dof is None else rng.standard_t(max(dof, 1.0), draws)
    z = rng.standard_normal(draws)
    finite = np.isfinite(noise) & np.isfinite(other) & np.all(np.isfinite(r), axis=1)
    lower, upper = np.full(k, -np.inf), np.full(k, np.inf)
    p = [(1.0 - level) / 2.0, (1.0 + level) / 2.0]
    for i in np.flatnonzero(finite):
        e = delta @ r[i] + noise[i] * t + other[i] * z
        lower[i], upper[i] = np.quantile(e, p)
    return lower, upper
