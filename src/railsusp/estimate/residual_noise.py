"""Standard errors that residual noise causes in a least-squares estimate.

Two formulas for the same quantity: :func:`standard_errors`, the Gauss-Newton s² (JᵀJ)⁻¹ of
one pooled variance and white residuals, and :func:`noise_standard_errors`, the sandwich
covariance with each block of residuals (one recording's force channel) its own variance
and integrated autocorrelation time (:func:`autocorrelation_time`), the noise model of
:func:`channel_variances`. The output-error refinement (:mod:`railsusp.estimate.refine`)
reports the second and its intervals (:mod:`railsusp.estimate.refine_intervals`) use it;
the time-aligned Cramér-Rao bounds of :mod:`railsusp.estimate.aligned_identifiability`
weight the residuals by the same per-channel variances; the first stays for comparison.
Pure functions on arrays, so that those modules import them from here and not one from
another.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: how :func:`noise_standard_errors` forms them (``noise_standard_error_method`` in
#: estimate.json's refinement record and intervals)
PER_CHANNEL = "per-channel variance and autocorrelation time (sandwich covariance)"


def autocorrelation_time(r: np.ndarray) -> float:
    """Integrated autocorrelation time τ = 1 + 2 Σ ρ(l) of a series, ρ summed over Geyer's
    initial positive sequence (pairs ρ(2m) + ρ(2m+1) while positive): the factor by which
    correlation inflates the variance of an average, so a series of n samples carries the
    information of n / τ independent ones. 1 for white residuals, at least 1."""
    x = np.asarray(r, dtype=float)
    x = x - x.mean()
    n = x.size
    if n < 4 or not np.any(x):
        return 1.0
    f = np.fft.rfft(x, 2 * n)
    acov = np.fft.irfft(f * np.conj(f))[:n] / n
    rho = acov / acov[0]
    tau = -1.0  # 1 + 2 sum_{l >= 1} rho(l) = -1 + 2 sum over pairs from l = 0
    for m in range(n // 2):
        pair = rho[2 * m] + rho[2 * m + 1]
        if pair <= 0.0:
            break
        tau += 2.0 * pair
    return float(max(tau, 1.0))


def _block_sizes(r: np.ndarray, blocks: Sequence[int]) -> list[int]:
    """The lengths of ``r``'s consecutive blocks; the whole series as one block where none
    are given. Blocks that do not add up to its length are a caller's error (residuals of
    every row with the blocks of the compared rows only, as a refinement with a washout
    stored them): a ValueError, not one block, which pooled the channels silently and gave
    the intervals a wrong effective sample size, autocorrelation time and degrees of
    freedom."""
    if len(blocks) == 0:
        return [r.size]
    sizes = [int(b) for b in blocks]
    if sum(sizes) != r.size:
        raise ValueError(
            f"internal error: residual blocks {tuple(sizes)} add up to {sum(sizes)}, not to "
            f"the {r.size} residuals they divide"
        )
    return sizes


def effective_sample_size(residuals: np.ndarray, blocks: Sequence[int]) -> tuple[float, float]:
    """(n_eff, τ) of residuals made of consecutive ``blocks`` (one per recording and
    channel): the sum of each block's length over its autocorrelation time, and the overall
    inflation n / n_eff."""
    r = np.asarray(residuals, dtype=float).ravel()
    n_eff, start = 0.0, 0
    for size in _block_sizes(r, blocks):
        n_eff += size / autocorrelation_time(r[start : start + size])
        start += size
    return n_eff, r.size / max(n_eff, 1e-12)


def channel_variances(residuals: np.ndarray, blocks: Sequence[int], n_fit: int) -> np.ndarray:
    """(n,) per residual its block's long-run variance s_b² τ_b: s_b² = Σ r_b² / n_b ·
    n / (n − n_fit), the block's mean square with the fit's degrees of freedom shared out
    over all n residuals, τ_b its integrated autocorrelation time
    (:func:`autocorrelation_time`). Blocks are consecutive, one per recording's force
    channel (the whole series as one where no ``blocks`` are given; blocks that do not add
    up to it are refused, :func:`_block_sizes`). The diagonal of
    Σ in :func:`noise_standard_errors` and the inverse weights of the time-aligned
    Cramér-Rao bound."""
    r = np.asarray(residuals, dtype=float).ravel()
    scale = r.size / max(r.size - n_fit, 1)
    w, start = np.empty(r.size), 0
    for size in _block_sizes(r, blocks):
        block = r[start : start + size]
        if size:  # a channel with no compared samples (never defined) has no variance
            w[start : start + size] = scale * (block @ block) / size * autocorrelation_time(block)
        start += size
    return w


def standard_errors(jac: np.ndarray, s2: float) -> np.ndarray:
    """Standard errors sqrt(diag(s² (JᵀJ)⁻¹)) of least-squares estimates: one pooled
    residual variance ``s2``, white residuals. A column the residuals do not depend on at
    all (e.g. a stop clearance never reached) gets an infinite error without spoiling the
    others."""
    jtj = jac.T @ jac
    d = np.diag(jtj)
    active = d > 1e-12 * max(float(d.max()), 1e-300)
    se = np.full(d.size, np.inf)
    try:
        cov = s2 * np.linalg.inv(jtj[np.ix_(active, active)])
        se[active] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        pass
    return se


def noise_standard_errors(
    jac: np.ndarray, residuals: np.ndarray, blocks: Sequence[int], n_fit: int
) -> np.ndarray:
    """(columns,) standard errors of the least-squares estimate that the residuals' noise
    causes, each block of residuals (one recording's channel) with its own variance and
    autocorrelation time: sqrt(diag((JᵀJ)⁻¹ Jᵀ Σ J (JᵀJ)⁻¹)), Σ diagonal with block b's
    s_b² τ_b, s_b² = Σ r_b² / n_b · n / (n - n_fit) (the heteroscedasticity-consistent
    "sandwich" covariance, White 1980, with each block's long-run variance). The
    autocorrelation time is included: multiply by nothing more for correlated residuals.

    One pooled s² (JᵀJ)⁻¹ assumes every residual equally noisy; the channels are not: each
    is scaled by its measured series' spread, and 3 % noise on the vertical force, whose
    spread is small beside its static load, leaves residuals 10 to 40 times the lateral
    force's in variance (the demo's recordings). The pooled variance then overstates the
    error of a parameter the lateral force fixes (measured on 12 refinements: 2-4 times,
    bench/README.md) and understates one fixed by the vertical force. With one block this
    is the pooled formula times √τ. Columns the residuals do not depend on get an infinite
    error."""
    j = np.asarray(jac, dtype=float)
    w = channel_variances(residuals, blocks, n_fit)
    d = np.einsum("ij,ij->j", j, j)
    active = d > 1e-12 * max(float(d.max()), 1e-300)
    se = np.full(j.shape[1], np.inf)
    try:
        ja = j[:, active]
        bread = np.linalg.inv(ja.T @ ja)
        cov = bread @ (ja.T @ (w[:, None] * ja)) @ bread
        se[active] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        pass
    return se
