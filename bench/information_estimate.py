"""Estimates of the Fisher information of section statistics from Jacobian samples of
common-random-number pairs, and the Cramer-Rao widths they give, for
bench/statistics_information.py.

The plug-in J-bar^T W J-bar is biased upwards by the noise in the mean Jacobian J-bar (by
about tr(W Cov d) / K for K pairs, large with many statistics); the U-statistic over
different pairs (:func:`information_unbiased`) and the split-half product
(:func:`information_split`) are unbiased. The covariance behind W is Ledoit-Wolf shrunk
(:func:`ledoit_wolf`), as a few hundred sections cannot pin a hundred statistics' covariance.
Information in units of fractions of the ranges; widths in % of range.
"""

from __future__ import annotations

import numpy as np

from railsusp.estimate.posterior_synthetic_information import Z90, cramer_rao_width

#: a Gaussian prior's information with the uniform prior's variance (1/12 of the range^2)
PRIOR_INFORMATION = 12.0


def ledoit_wolf(x: np.ndarray) -> np.ndarray:
    """Covariance (D, D) of the rows of ``x`` (N, D), Ledoit-Wolf shrunk (2004, "A
    well-conditioned estimator for large-dimensional covariance matrices"): the sample
    correlation matrix pulled towards the identity by the weight that minimises the
    expected squared error, then scaled back by the columns' standard deviations (so the
    statistics' units do not decide the shrinkage)."""
    x = np.asarray(x, dtype=float)
    n, d = x.shape
    sd = x.std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    z = (x - x.mean(axis=0)) / sd
    s = z.T @ z / n
    mu = np.trace(s) / d
    delta2 = np.sum((s - mu * np.eye(d)) ** 2)
    beta2 = sum(np.sum((np.outer(r, r) - s) ** 2) for r in z) / n**2
    shrink = min(beta2, delta2) / delta2 if delta2 > 0 else 1.0
    corr = shrink * mu * np.eye(d) + (1.0 - shrink) * s
    return corr * np.outer(sd, sd)


def unbiased_precision(x: np.ndarray) -> np.ndarray:
    """Sigma^-1 (D, D) estimated without bias from the rows of ``x`` (N, D; Gaussian, N >
    D + 2): (N - D - 2) / (N - 1) S^-1, S the sample covariance, whose own inverse
    overstates Sigma^-1 by (N - 1) / (N - D - 2) on average (the inverse Wishart's mean,
    Anderson 2003, "An introduction to multivariate statistical analysis", 7.7). An
    information read through S^-1 is inflated by the same factor: 1.72 for 375 statistics
    per condition from 900 sections."""
    x = np.asarray(x, dtype=float)
    n, d = x.shape
    if n <= d + 2:
        raise ValueError(f"{n} rows for {d} statistics: need more than {d + 2}")
    return np.linalg.inv(np.cov(x.T)) * inverse_wishart_factor(n, d)


def inverse_wishart_factor(n: int, d: int) -> float:
    """(n - d - 2) / (n - 1): what makes the inverse of the sample covariance of ``n``
    Gaussian rows in ``d`` dimensions an unbiased estimate of Sigma^-1
    (:func:`unbiased_precision`)."""
    return (n - d - 2) / (n - 1)


def information_naive(d: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """J-bar^T W J-bar (P, P), J-bar the mean over the K pairs of ``d`` (P, K, D): biased
    upwards by the noise in J-bar."""
    jb = d.mean(axis=1)
    return jb @ weight @ jb.T


def _gram(x: np.ndarray, weight: np.ndarray | None, y: np.ndarray) -> np.ndarray:
    """x^T W y over the last axis (x (A, D), y (B, D)); ``weight`` None: the identity,
    without forming a (D, D) matrix."""
    return x @ y.T if weight is None else x @ weight @ y.T


def information_unbiased(d: np.ndarray, weight: np.ndarray | None) -> np.ndarray:
    """J^T W J (P, P) from the Jacobian samples ``d`` (P, K, D: K independent pairs per
    parameter): the mean of d_ak^T W d_bl over pairs k != l only, (K^2 J-bar^T W J-bar -
    sum_k d_k^T W d_k) / (K (K - 1)). Each product is of independent noises, so the noise
    adds nothing on average (a U-statistic); it can come out negative where there is
    no information. ``weight`` None: the identity (features already whitened)."""
    k = d.shape[1]
    jb = d.mean(axis=1)
    if weight is None:
        same = np.einsum("akd,bkd->ab", d, d)
    else:
        same = np.einsum("akd,de,bke->ab", d, weight, d)
    return (k**2 * _gram(jb, weight, jb) - same) / (k * (k - 1))


def information_split(d: np.ndarray, weight: np.ndarray | None) -> np.ndarray:
    """The split-half estimate: sym(J1^T W J2), J1 and J2 the means of the first and the
    second half of the pairs (independent noises): unbiased, noisier than the
    U-statistic. ``weight`` None: the identity."""
    h = d.shape[1] // 2
    j1, j2 = d[:, :h].mean(axis=1), d[:, h : 2 * h].mean(axis=1)
    m = _gram(j1, weight, j2)
    return 0.5 * (m + m.T)


def widths_pct(information: np.ndarray, prior: float = PRIOR_INFORMATION) -> np.ndarray:
    """Cramer-Rao 90 % widths (% of range) of all parameters, all unknown, from an
    estimated information (P, P) plus ``prior`` times the identity: the information of a
    Gaussian prior with the variance of the uniform one on the range (1/12 of its square;
    the van Trees bound of that prior). It matters only for parameters the statistics say
    next to nothing about (their width stays near the prior's 95 %, where without it the
    estimate's noise in their near-zero information is inverted and spreads into every
    other parameter's width); a width of 10 % needs an information of 1082, against which
    12 moves it by 0.6 %. An estimate that is not positive definite (noise where there is
    next to no information, without a prior) has its negative eigenvalues set to a
    millionth of the largest first, so those directions come out unidentified."""
    m = 0.5 * (information + information.T) + prior * np.eye(len(information))
    w, v = np.linalg.eigh(m)
    w = np.maximum(w, 1e-6 * w.max())
    return 100.0 * cramer_rao_width(((v * w) @ v.T)[None])[0]


def widths_alone_pct(information: np.ndarray) -> np.ndarray:
    """The 90 % widths (% of range) each parameter would have if the nine others were
    known, 2 x 1.645 / sqrt(I_jj): a floor under the width with all ten unknown, from the
    diagonal alone (no inverse to amplify the estimate's noise); infinite where the
    estimated information is not positive."""
    diag = np.diag(information)
    with np.errstate(divide="ignore"):
        return np.where(diag > 0, 100.0 * 2.0 * Z90 / np.sqrt(np.abs(diag)), np.inf)
