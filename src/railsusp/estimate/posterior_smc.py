"""Draws of a posterior on the unit box whose prior is uniform: adaptive tempered
sequential Monte Carlo (Del Moral, Doucet & Jasra 2006; the temperatures chosen so that
each step keeps half the effective sample size, Jasra et al. 2011).

Particles start as prior draws; the likelihood is raised to temperatures 0 < b_1 < ... < 1,
each step reweights, resamples and moves the particles by random-walk Metropolis whose
proposal is the particles' own covariance (scaled 2.38 / sqrt(d), Roberts & Rosenthal
2001); a proposal outside the box is rejected (the prior is zero there). Vectorised over
the particles: the likelihood is called on (N, d) arrays. No simulation, no gradient: a
long record's synthetic likelihood (:mod:`railsusp.estimate.posterior_synthetic`) costs
a few hundred calls of its emulator.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

LogLikelihood = Callable[[np.ndarray], np.ndarray]


def _next_temperature(loglik: np.ndarray, beta: float, target_ess: float) -> float:
    """The largest temperature above ``beta`` (at most 1) whose incremental weights keep
    an effective sample size of at least ``target_ess`` (bisection)."""

    def ess(b: float) -> float:
        w = (b - beta) * loglik
        w = np.exp(w - w.max())
        return w.sum() ** 2 / np.sum(w**2)

    if ess(1.0) >= target_ess:
        return 1.0
    lo, hi = beta, 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ess(mid) >= target_ess else (lo, mid)
    return max(lo, beta + 1e-12)


def _systematic(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    n = weights.size
    positions = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(np.cumsum(weights), positions), n - 1)


def smc_sample(
    loglik: LogLikelihood,
    d: int,
    n: int,
    rng: np.random.Generator,
    moves: int = 3,
    max_steps: int = 200,
) -> np.ndarray:
    """(n, d) draws of prior(u) exp(loglik(u)), the prior uniform on [0, 1]^d. At each
    temperature the particles move until every one has had ``moves`` accepted steps on
    average (at least 5, at most 40 proposals), and twice that at the last. numpy's BLAS
    runs on one thread meanwhile: its small products thrash on a shared machine (measured
    9.5 s against 1.1 s for one posterior on the loaded 2-core machine)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        return _smc(loglik, d, n, rng, moves, max_steps)


def _smc(loglik, d, n, rng, moves, max_steps):
    u = rng.random((n, d))
    ll = loglik(u)
    beta = 0.0
    scale = 2.38 / np.sqrt(d)
    for _ in range(max_steps + 1):
        if beta >= 1.0:
            break
        new = _next_temperature(np.where(np.isfinite(ll), ll, -1e300), beta, 0.5 * n)
        w = (new - beta) * ll
        w = np.where(np.isfinite(w), w, -np.inf)
        w = np.exp(w - w.max())
        idx = _systematic(w / w.sum(), rng)
        u, ll, beta = u[idx], ll[idx], new
        u, ll, scale = _move(loglik, u, ll, beta, scale, 2 * moves if beta >= 1 else moves, rng)
    return u


def _move(loglik, u, ll, beta, scale, moves, rng):
    """Random-walk Metropolis steps at temperature ``beta`` until ``moves`` accepted
    steps per particle on average (5 to 40 proposals); the proposal's scale adapts
    towards an acceptance near 0.3."""
    n, d = u.shape
    cov = np.cov(u.T) + 1e-12 * np.eye(d)
    chol = np.linalg.cholesky(cov)
    accepted = 0.0
    for step in range(40):
        if step >= 5 and accepted >= moves:
            break
        prop = u + scale * rng.standard_normal((n, d)) @ chol.T
        inside = np.all((prop > 0.0) & (prop < 1.0), axis=1)
        lp = np.full(n, -np.inf)
        if inside.any():
            lp[inside] = loglik(prop[inside])
        accept = inside & (np.log(rng.random(n)) < beta * (lp - ll))
        u = np.where(accept[:, None], prop, u)
        ll = np.where(accept, lp, ll)
        rate = accept.mean()
        accepted += rate
        scale *= np.exp(rate - 0.3)
    return u, ll, scale
