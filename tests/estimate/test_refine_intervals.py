"""The refinement's intervals (railsusp.estimate.refine_intervals) where the force channels
are unequally noisy: each channel's own residual variance in the noise part (the sandwich
covariance), checked against the pooled formula on one channel, against Monte Carlo on a
linear model, and by coverage on the series model of the tests, where the pooled variance
of 2026-11-24 covered the parameter the quiet channel fixes every time."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.estimate.intervals import REFINEMENT
from railsusp.estimate.refine import refine, standard_errors
from railsusp.estimate.refine_intervals import (
    PER_CHANNEL,
    STUDENT_T,
    autocorrelation_time,
    noise_standard_errors,
    refinement_intervals,
)
from railsusp.measured import Recording
from railsusp.params import bounds
from test_estimate import WaveForces  # the series model with a known answer
from test_intervals import (  # its 20 s recording of a known truth, and the simulator's
    LONG,
    PARAMS,
    TRUTH,
    simulator_refinement,
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


def hetero_recording(seed: int, y_level: float, q_level: float) -> Recording:
    """WaveForces of the truth with white noise of ``y_level`` and ``q_level`` times each
    channel's standard deviation: the lateral force quiet, the vertical one noisy."""
    s = WaveForces().series(TRUTH[None], LONG)[0]
    rng = np.random.default_rng(seed)
    s = s + np.array([y_level, q_level]) * s.std(axis=0) * rng.standard_normal(s.shape)
    t = np.arange(LONG.n_steps) * LONG.sample_interval
    return Recording(t, {"w1L": s[:, 0]}, {"w1L": s[:, 1]}, LONG)


def test_intervals_cover_the_truth_when_one_channel_is_far_noisier():
    """X13 moves the lateral force only, X14 both: with 2 % noise on Y and 60 % on Q, one
    pooled residual variance (mostly Q's) made X13's interval some ten times too wide
    (coverage 1.0, with 90 % stated); with each channel's own variance X13 and X14 are
    covered about 90 % of the time over 100 recordings."""
    lo, hi = bounds(PARAMS)
    covered = np.zeros(2)
    pooled_ratio = []
    n = 100
    for seed in range(n):
        rec = hetero_recording(seed, 0.02, 0.6)
        r = refine(WaveForces(), [rec], PARAMS, lo + 0.4 * (hi - lo), gains=False)
        iv = refinement_intervals(r)
        covered += [iv[p].contains(x) for p, x in zip(PARAMS, TRUTH, strict=True)]
        half = (iv["X13"].high_si - iv["X13"].low_si) / 2
        pooled_ratio.append(1.645 * r.standard_error_si[0] / half)
    assert iv.method == REFINEMENT
    assert iv.details["noise_standard_error_method"] == PER_CHANNEL
    assert iv.details["interval_quantiles"] == STUDENT_T  # no held part: Student-t
    assert np.all((0.82 <= covered / n) & (covered / n <= 0.97))
    assert np.median(pooled_ratio) > 5.0  # the pooled interval: far too wide for X13


def test_with_held_parameters_the_interval_is_the_quantiles_of_the_errors_distribution(tmp_path):
    """With the simulator (parameters held): the interval is the estimate less the central
    90 % quantiles of the error's distribution, which are within 1.645 total standard
    deviations (uniform parts have lighter tails than a normal), symmetric for a prior
    centred on the values held and lopsided for one in the upper part of every range."""
    from railsusp.estimate.config import HeldPrior
    from railsusp.estimate.refine_intervals import MONTE_CARLO, held_parameters
    from railsusp.params import spec

    r = simulator_refinement(tmp_path)
    iv = refinement_intervals(r)
    d = iv.details
    assert d["interval_quantiles"] == MONTE_CARLO and d["monte_carlo_draws"] == 200_000
    assert d["noise_standard_error_method"] == PER_CHANNEL
    for p, x in zip(PARAMS, r.estimate_si, strict=True):
        span = spec(p).bounds[1] - spec(p).bounds[0]
        q_lo, q_hi = (v / 100 * span for v in d["error_quantiles_pct_range"][p])
        assert iv[p].low_si == pytest.approx(max(x - q_hi, spec(p).bounds[0]), rel=1e-12)
        assert iv[p].high_si == pytest.approx(min(x - q_lo, spec(p).bounds[1]), rel=1e-12)
        total = d["total_standard_error_pct_range"][p] / 100 * span
        assert q_lo == pytest.approx(-q_hi, rel=0.02)  # centred: symmetric
        assert q_hi <= 1.645 * total * 1.01
    upper = HeldPrior.from_display(
        {
            p: [spec(p).to_display(spec(p).nominal), spec(p).to_display(spec(p).bounds[1])]
            for p in held_parameters(PARAMS)
        }
    )
    lopsided = refinement_intervals(r, prior=upper).details["error_quantiles_pct_range"]
    assert any(abs(a + b) > 0.2 * (b - a) for a, b in lopsided.values())
