"""Standard errors that residual noise causes in a least-squares estimate
(railsusp.estimate.residual_noise): the per-channel sandwich covariance against the pooled
formula on one channel, and against the exact variance and Monte Carlo on a linear model
with one quiet and one noisy channel; the per-channel variances they are formed with."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.estimate.residual_noise import (
    autocorrelation_time,
    channel_variances,
    noise_standard_errors,
    standard_errors,
)


def test_one_block_is_the_pooled_formula_times_the_autocorrelation_time():
    rng = np.random.default_rng(0)
    jac = rng.standard_normal((400, 3))
    r = rng.standard_normal(400)
    for i in range(1, r.size):  # correlated: τ well above 1
        r[i] += 0.6 * r[i - 1]
    pooled = standard_errors(jac, float(r @ r) / (400 - 3))
    got = noise_standard_errors(jac, r, (400,), 3)
    assert got == pytest.approx(pooled * np.sqrt(autocorrelation_time(r)), rel=1e-10)
    # a column the residuals do not depend on: infinite, the others untouched
    jac0 = np.c_[jac, np.zeros(400)]
    got0 = noise_standard_errors(jac0, r, (400,), 4)
    assert got0[3] == np.inf and got0[:3] == pytest.approx(got * np.sqrt(397 / 396), rel=1e-10)


def test_unequally_noisy_channels_match_the_monte_carlo_spread_of_the_estimate():
    """y₁ = a θ + ε₁ (quiet, σ₁ = 0.01), y₂ = b θ + ε₂ (noisy, σ₂ = 1), least squares on
    both: Var θ̂ = Σ(a² σ₁² + b² σ₂²) / (Σ a² + b²)². The per-channel errors match the spread
    of 2000 estimates; the pooled variance overstates it tenfold."""
    rng = np.random.default_rng(1)
    n = 500
    a = np.sin(np.linspace(0, 20, n)) + 1.5
    b = 0.05 * np.cos(np.linspace(0, 7, n))
    jac = np.r_[a, b][:, None]
    sd = np.r_[np.full(n, 0.01), np.full(n, 1.0)]
    est, per_channel, pooled = [], [], []
    for _ in range(2000):
        r = sd * rng.standard_normal(2 * n)
        theta = np.linalg.lstsq(jac, r, rcond=None)[0]
        est.append(theta[0])
    for _ in range(20):
        r = sd * rng.standard_normal(2 * n)
        res = r - jac @ np.linalg.lstsq(jac, r, rcond=None)[0]
        per_channel.append(noise_standard_errors(jac, res, (n, n), 1)[0])
        pooled.append(standard_errors(jac, float(res @ res) / (2 * n - 1))[0])
    spread = np.std(est)
    exact = np.sqrt((a**2 * 0.01**2 + b**2).sum()) / (a**2 + b**2).sum()
    assert spread == pytest.approx(exact, rel=0.05)
    assert np.mean(per_channel) == pytest.approx(exact, rel=0.1)
    assert np.mean(pooled) > 10 * exact


def test_channel_variances_are_each_blocks_mean_square_times_its_autocorrelation_time():
    """Two blocks, one white-like (alternating, τ = 1) and one correlated: each residual
    gets its own block's Σ r² / n_b · n / (n − n_fit) · τ_b; an empty block adds nothing;
    no blocks make the series one block, and blocks that do not add up to it are refused
    (they were taken as one block, silently)."""
    rng = np.random.default_rng(3)
    quiet = 0.1 * np.tile([1.0, -1.0], 100)
    loud = rng.standard_normal(300)
    for i in range(1, loud.size):
        loud[i] += 0.7 * loud[i - 1]
    r = np.r_[quiet, loud]
    w = channel_variances(r, (200, 0, 300), 5)
    scale = 500 / 495
    assert autocorrelation_time(quiet) == 1.0 and autocorrelation_time(loud) > 2.0
    assert w[:200] == pytest.approx(np.full(200, 0.01 * scale), rel=1e-12)
    expected = scale * (loud @ loud) / 300 * autocorrelation_time(loud)
    assert w[200:] == pytest.approx(np.full(300, expected), rel=1e-12)
    whole = channel_variances(r, (), 0)
    assert whole == pytest.approx(np.full(500, (r @ r) / 500 * autocorrelation_time(r)))
    with pytest.raises(ValueError, match=r"blocks \(200, 200\) add up to 400, not to the 500"):
        channel_variances(r, (200, 200), 0)
