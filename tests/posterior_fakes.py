"""A posterior check's cases and estimator, made up where their numbers are known: one
parameter (X13) seen through x = logit(u) + N(0, 0.5^2), and an estimator whose draws are
N(x, spread^2) in logit coordinates, narrower than the likelihood's 0.5 (the logistic
prior is much wider): over-confident by a factor the check's correction must find."""

import numpy as np

from railsusp.estimate import posterior_data, posterior_fusion


class ConfidentEstimator:
    """Draws N(x, ``spread``^2) in logit coordinates (0.3: 0.6 of the likelihood's spread;
    0.12: a quarter, so its correction widens it more than MAX_INFLATION times)."""

    def __init__(self, settings, spread: float = 0.3):
        self.settings = settings
        self.spread = spread

    def sample_raw(self, x, n, seed=0):
        rng = np.random.default_rng(seed)
        z = x[:, None, :] + self.spread * rng.standard_normal((x.shape[0], n, 1))
        return posterior_fusion.from_logit(z)


def synthetic_cases(settings, folder, kind, n, sections=1):
    """In place of posterior_check.cached_cases: the prior's draws and x = logit(u_X13) +
    N(0, 0.5^2), seeded per kind as the simulated cases are."""
    u = posterior_data.prior_draws(settings, kind, n)
    rng = np.random.default_rng(posterior_data.SEED_BASE[kind])
    x = posterior_fusion.to_logit(u[:, [2]]) + 0.5 * rng.standard_normal((n, 1))
    return u, x
