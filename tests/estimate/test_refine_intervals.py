"""The refinement's intervals (railsusp.estimate.refine_intervals) where the force channels
are unequally noisy: each channel's own residual variance in the noise part (the sandwich
covariance, formula checks in test_residual_noise.py), checked by coverage on the series
model of the tests, where the pooled variance of 2026-11-24 covered the parameter the quiet
channel fixes every time; the noise part is the refinement's own standard error."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.estimate.intervals import REFINEMENT
from railsusp.estimate.refine import refine
from railsusp.estimate.refine_intervals import PER_CHANNEL, STUDENT_T, refinement_intervals
from railsusp.params import bounds
from test_estimate import WaveForces  # the series model with a known answer
from test_intervals import (  # the truth, unequally noisy recordings, the simulator's
    PARAMS,
    TRUTH,
    hetero_recording,
    pooled_standard_errors,
    simulator_refinement,
)


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
        pooled_ratio.append(1.645 * pooled_standard_errors(r)[0] / half)
    assert iv.method == REFINEMENT
    assert iv.details["noise_standard_error_method"] == PER_CHANNEL
    assert iv.details["interval_quantiles"] == STUDENT_T  # no held part: Student-t
    assert np.all((0.82 <= covered / n) & (covered / n <= 0.97))
    assert np.median(pooled_ratio) > 5.0  # the pooled interval: far too wide for X13


def test_with_held_parameters_the_interval_is_the_quantiles_of_the_errors_distribution(tmp_path):
    """With the simulator (parameters held): the interval is the estimate less the central
    90 % quantiles of the error's distribution, which are within the Student-t quantile of
    the noise's degrees of freedom times the total standard deviation (uniform and normal
    parts have lighter tails than the t; the noise part is a t variable, whose quantile
    1.645 alone does not bound: stop 62's forces took it 1.4 % beyond), symmetric for a
    prior centred on the values held and lopsided for one in the upper part of every
    range."""
    from scipy.stats import t as student_t

    from railsusp.estimate.config import HeldPrior
    from railsusp.estimate.refine_intervals import MONTE_CARLO, held_parameters
    from railsusp.params import spec

    r = simulator_refinement(tmp_path)
    iv = refinement_intervals(r)
    d = iv.details
    assert d["interval_quantiles"] == MONTE_CARLO and d["monte_carlo_draws"] == 200_000
    assert d["noise_standard_error_method"] == PER_CHANNEL
    # the noise part is the refinement's own standard error, as estimate.json reports it
    assert d["noise_standard_error_pct_range"] == r.to_dict()["noise_standard_error_pct_range"]
    for p, x in zip(PARAMS, r.estimate_si, strict=True):
        span = spec(p).bounds[1] - spec(p).bounds[0]
        q_lo, q_hi = (v / 100 * span for v in d["error_quantiles_pct_range"][p])
        assert iv[p].low_si == pytest.approx(max(x - q_hi, spec(p).bounds[0]), rel=1e-12)
        assert iv[p].high_si == pytest.approx(min(x - q_lo, spec(p).bounds[1]), rel=1e-12)
        total = d["total_standard_error_pct_range"][p] / 100 * span
        assert q_lo == pytest.approx(-q_hi, rel=0.02)  # centred: symmetric
        assert q_hi <= student_t.ppf(0.95, d["degrees_of_freedom"]) * total * 1.01
    upper = HeldPrior.from_display(
        {
            p: [spec(p).to_display(spec(p).nominal), spec(p).to_display(spec(p).bounds[1])]
            for p in held_parameters(PARAMS)
        }
    )
    lopsided = refinement_intervals(r, prior=upper).details["error_quantiles_pct_range"]
    assert any(abs(a + b) > 0.2 * (b - a) for a, b in lopsided.values())
