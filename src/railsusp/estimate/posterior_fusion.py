"""Coordinates and the combination of sections of the simulation-based posterior.

The flows of :mod:`railsusp.estimate.posterior` model z = logit(u), u the fraction of each
parameter's range: the uniform prior on the box becomes the standard logistic distribution
on the unbounded z (variance pi^2 / 3), where a flow cannot leak mass out of the prior's
support, and where the spread correction widens draws without leaving the box.

Several sections of one recording are combined by **information fusion** of Gaussian
approximations in z: section i's posterior draws have precision P_i and mean m_i; its
information about the parameters is P_i less the prior's precision P_0 (its negative part
clipped to zero: a section never removes information, a negative part is noise of the
approximation), with the linear term P_i m_i projected on the same directions. The
informations add: the fused posterior is Gaussian with precision P_0 + sum_i (P_i - P_0)+.
(The exact product prior(z) prod_i q(z | x_i) / prior(z) of the flows' densities is ruled
by their tails: importance sampling of it collapsed to effective sample sizes of 1-10, at
the ends of the ranges, bench/README.md.)
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class SectionSampler(Protocol):
    """What the fusion needs of an estimator (:class:`railsusp.estimate.posterior_estimator.
    PosteriorEstimator`): its settings and uncorrected draws per section."""

    settings: Any

    def sample_raw(self, x: np.ndarray, n: int, seed: int = 0) -> np.ndarray: ...


def logistic_prior(d: int):
    """The prior of the logit coordinates of ``d`` parameters: independent standard
    logistic distributions, the image of the uniform prior on the box (a torch
    distribution, for sbi's trainers)."""
    import torch
    from torch.distributions import Independent, TransformedDistribution, Uniform
    from torch.distributions.transforms import SigmoidTransform

    return Independent(
        TransformedDistribution(Uniform(torch.zeros(d), torch.ones(d)), [SigmoidTransform().inv]),
        1,
    )


def to_logit(u: np.ndarray) -> np.ndarray:
    """Fractions of range -> unbounded coordinates z, where the flows and the spread
    correction act."""
    u = np.clip(np.asarray(u, float), 1e-6, 1.0 - 1e-6)
    return np.log(u) - np.log1p(-u)


def from_logit(z: np.ndarray) -> np.ndarray:
    """Unbounded coordinates z -> fractions of range."""
    return 1.0 / (1.0 + np.exp(-np.asarray(z, float)))


def fused_precision(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Precision (d, d) and mean (d,) of the fused Gaussian of the sections' draws
    ``z`` (sections, S, d) in logit coordinates (module docstring)."""
    d = z.shape[-1]
    prior_precision = np.eye(d) / (np.pi**2 / 3.0)  # the standard logistic's variance
    precision, shift = prior_precision.copy(), np.zeros(d)
    for zi in z:
        p_i = np.linalg.inv(np.cov(zi.T) + 1e-9 * np.eye(d))
        lam, vec = np.linalg.eigh(p_i - prior_precision)
        keep = lam > 0
        precision += (vec[:, keep] * lam[keep]) @ vec[:, keep].T
        shift += vec[:, keep] @ (vec[:, keep].T @ (p_i @ zi.mean(axis=0)))
    return precision, np.linalg.solve(precision, shift)


def fused_gaussian(est: SectionSampler, x: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(mean (d,), covariance (d, d)) in logit coordinates of the fused posterior of the
    sections ``x`` (sections, D), from 1000 uncorrected draws per section (module
    docstring)."""
    z = to_logit(est.sample_raw(x, 1000, seed=seed))  # (k, S, d)
    precision, mean = fused_precision(z)
    cov = np.linalg.inv(precision)
    return mean, (cov + cov.T) / 2


def fused_samples(est: SectionSampler, x: np.ndarray, n: int, rng) -> np.ndarray:
    """(n, d) uncorrected draws (unit box) of the posterior of the sections ``x``
    (sections, D), their informations fused (module docstring)."""
    mean, cov = fused_gaussian(est, x, int(rng.integers(2**31)))
    return from_logit(rng.multivariate_normal(mean, cov, size=n))
