"""The time-aligned Cramér-Rao bound's noise model (railsusp.estimate.aligned_identifiability):
each recording's force channel with its own residual variance and autocorrelation time, as
the refinement's standard errors have it, and the bound the inverse of the weighted
information (JᵀWJ)⁻¹, not one pooled variance times (JᵀJ)⁻¹. Checked against the analytic
bound and the Monte Carlo spread of the efficient estimator with one quiet and one noisy
channel, against the pooled formula where every channel is equally noisy, and through the
series model of the refinement's tests."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.estimate.aligned_identifiability import (
    aligned_cramer_rao_pct_range,
    bounds_pct_range,
)
from railsusp.estimate.residual_noise import (
    effective_sample_size,
    noise_standard_errors,
    standard_errors,
)
from test_estimate import WaveForces  # the series model with a known answer
from test_intervals import PARAMS, TRUTH, hetero_recording


def pooled_bounds(r: np.ndarray, jac: np.ndarray, blocks) -> np.ndarray:
    """(% of range) the formula before 2026-11-24 stop 24: one pooled residual variance over
    all channels times the residuals' overall autocorrelation inflation, times (JᵀJ)⁻¹."""
    _, tau = effective_sample_size(r, list(blocks))
    return 100.0 * standard_errors(jac, float(r @ r) / (r.size - jac.shape[1]) * tau)


def test_unequally_noisy_channels_give_the_analytic_bound_not_the_pooled_one():
    """One parameter seen by a quiet channel (σ₁) and a noisy one (σ₂ = √40 σ₁, the vertical
    force's residual variance 40 times the lateral's as on the demo's tangent), equally
    sensitive (Σa² = Σb² = A). The Fisher information of Gaussian noise with a per-channel
    variance is A/(σ₁²τ) + A/(σ₂²τ) (τ the residuals' autocorrelation time); the pooled
    formula's variance is (σ₁² + σ₂²)/2 · τ / 2A, too wide by the known factor
    √((σ₁² + σ₂²)(1/σ₁² + 1/σ₂²)) / 2 = 41/(2√40) = 3.24."""
    n = 600
    t = np.linspace(0.0, 30.0, n)
    a = np.sin(t) + 0.3
    b = np.cos(0.7 * t) * np.sqrt((a @ a) / (np.cos(0.7 * t) @ np.cos(0.7 * t)))
    assert a @ a == pytest.approx(b @ b)
    jac = np.r_[a, b][:, None]
    u = np.random.default_rng(4).standard_normal(n)
    u /= np.sqrt(u @ u / n)  # unit mean square, the same series (and τ) in both channels
    s1, s2 = 0.02, 0.02 * np.sqrt(40.0)
    r = np.r_[s1 * u, s2 * u]
    _, tau = effective_sample_size(u, [n])
    dof = 2 * n / (2 * n - 1)  # the residual variance over n − p, p = 1
    info = (a @ a) / (s1**2 * tau * dof) + (b @ b) / (s2**2 * tau * dof)
    got = bounds_pct_range(r, jac, (n, n))
    assert got[0] == pytest.approx(100.0 / np.sqrt(info), rel=1e-9)
    factor = np.sqrt((s1**2 + s2**2) * (1 / s1**2 + 1 / s2**2)) / 2.0
    assert factor == pytest.approx(41.0 / (2.0 * np.sqrt(40.0)))
    assert pooled_bounds(r, jac, (n, n))[0] / got[0] == pytest.approx(factor, rel=1e-9)


def test_the_bound_is_the_spread_of_the_efficient_estimator_and_below_least_squares():
    """θ₁ moves the quiet channel only (as X13 the lateral force), θ₂ both (as X14), white
    noise σ₁ = 0.02 and σ₂ = 0.4. Over 3000 noise draws the spread of the weighted
    least-squares estimate (weights 1/σ², the efficient estimator here) matches the bound
    computed from each draw's residuals at the truth; unweighted least squares is wider
    (its sandwich standard errors match its spread: a bound on no estimator in particular
    would be those); the pooled formula overstates θ₁'s bound about tenfold."""
    rng = np.random.default_rng(11)
    n = 400
    t = np.linspace(0.0, 20.0, n)
    jac = np.zeros((2 * n, 2))
    jac[:n, 0] = np.sin(1.3 * t)
    jac[:n, 1] = 0.4 + 0.2 * np.cos(0.5 * t)
    jac[n:, 1] = 3.0 * np.cos(0.7 * t)
    sd = np.r_[np.full(n, 0.02), np.full(n, 0.4)]
    weighted = jac / sd[:, None]
    wls, ols = [], []
    for _ in range(3000):
        e = sd * rng.standard_normal(2 * n)
        wls.append(np.linalg.lstsq(weighted, e / sd, rcond=None)[0])
        ols.append(np.linalg.lstsq(jac, e, rcond=None)[0])
    bound, pooled, sandwich = [], [], []
    for _ in range(30):
        e = sd * rng.standard_normal(2 * n)
        bound.append(bounds_pct_range(e, jac, (n, n)) / 100.0)
        pooled.append(pooled_bounds(e, jac, (n, n)) / 100.0)
        ols_fit = e - jac @ np.linalg.lstsq(jac, e, rcond=None)[0]
        sandwich.append(noise_standard_errors(jac, ols_fit, (n, n), 2))
    exact = np.sqrt(np.diag(np.linalg.inv(weighted.T @ weighted)))
    spread_wls, spread_ols = np.std(wls, axis=0), np.std(ols, axis=0)
    assert spread_wls == pytest.approx(exact, rel=0.05)
    # white residuals: the estimated autocorrelation time is a little above 1
    assert np.mean(bound, axis=0) == pytest.approx(spread_wls, rel=0.1)
    assert np.all(spread_ols >= 0.98 * spread_wls) and spread_ols[1] > 2.0 * spread_wls[1]
    assert np.mean(sandwich, axis=0) == pytest.approx(spread_ols, rel=0.1)
    assert np.mean(pooled, axis=0)[0] > 8.0 * spread_wls[0]


def test_equally_noisy_channels_give_the_pooled_result():
    """Where every channel has the same residual variance and autocorrelation time the
    per-channel bound is the pooled one to rounding (one channel; two channels with the same
    residual series), and within sampling for independent draws of equal noise."""
    rng = np.random.default_rng(2)
    n = 500
    jac = rng.standard_normal((2 * n, 3))
    r1 = rng.standard_normal(n)
    for i in range(1, n):  # correlated: τ well above 1
        r1[i] += 0.6 * r1[i - 1]
    one = np.r_[r1, r1[::-1]]
    assert bounds_pct_range(one, jac, (2 * n,)) == pytest.approx(
        pooled_bounds(one, jac, (2 * n,)), rel=1e-10
    )
    same = np.r_[r1, -r1]
    assert bounds_pct_range(same, jac, (n, n)) == pytest.approx(
        pooled_bounds(same, jac, (n, n)), rel=1e-10
    )
    r2 = rng.standard_normal(n)
    for i in range(1, n):
        r2[i] += 0.6 * r2[i - 1]
    draws = np.r_[r1, r2]
    assert bounds_pct_range(draws, jac, (n, n)) == pytest.approx(
        pooled_bounds(draws, jac, (n, n)), rel=0.1
    )


def test_a_noiseless_channel_gives_a_vanishing_bound_not_nan():
    """A channel whose residual is zero (a noiseless synthetic record at its truth) carries
    unbounded information: the parameters it sees get a bound near zero, one seen only by the
    noisy channel keeps its finite bound, a parameter nothing sees stays infinite; with every
    residual zero every seen parameter's bound is zero, as the pooled formula gave."""
    n = 300
    t = np.linspace(0.0, 10.0, n)
    jac = np.zeros((2 * n, 3))
    jac[:n, 0] = np.sin(t)
    jac[n:, 1] = np.cos(0.4 * t)
    r = np.r_[np.zeros(n), 0.1 * np.random.default_rng(0).standard_normal(n)]
    got = bounds_pct_range(r, jac, (n, n))
    assert not np.isnan(got).any()
    assert got[0] < 1e-3 * got[1] and 0.0 < got[1] < np.inf and got[2] == np.inf
    zero = bounds_pct_range(np.zeros(2 * n), jac, (n, n))
    assert list(zero) == [0.0, 0.0, np.inf]


def test_a_parameter_only_the_lateral_force_sees_keeps_its_bound_whatever_the_vertical_noise():
    """WaveForces: X13 moves the lateral force only. With 2 % noise on Y its bound is the
    same whether Q carries 2 % or 60 % noise (the same Y noise drawn in both); the pooled
    variance, mostly Q's at 60 %, made it about twenty times wider."""
    quiet = aligned_cramer_rao_pct_range(
        WaveForces(), [hetero_recording(5, 0.02, 0.02)], PARAMS, TRUTH
    )
    noisy = aligned_cramer_rao_pct_range(
        WaveForces(), [hetero_recording(5, 0.02, 0.6)], PARAMS, TRUTH
    )
    assert noisy["X13"] == pytest.approx(quiet["X13"], rel=0.05)
    assert noisy["X14"] > quiet["X14"]  # Q's part of X14's information is lost in its noise
