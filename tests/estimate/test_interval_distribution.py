"""The refined estimate's error as a distribution (railsusp.estimate.interval_distribution):
central quantiles of uniform, Student-t and normal parts summed, against analytic cases
(one uniform: 0.9 of its half-range, not 1.645 standard deviations; a normal: 1.645; two
equal uniforms: a triangle) and an exact convolution of a uniform with a normal."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.stats import norm, t

from railsusp.estimate.interval_distribution import error_quantiles


def test_one_uniform_part_alone_has_its_90_percent_within_0_9_of_its_half_range():
    lower, upper = error_quantiles(np.array([[2.0]]), np.array([-0.5]), np.array([0.5]), 0.0)
    # e uniform on [-1, 1]: the central 90 % is [-0.9, 0.9]; 1.645 sd would say 0.950
    assert lower[0] == pytest.approx(-0.9, abs=0.005)
    assert upper[0] == pytest.approx(0.9, abs=0.005)
    assert upper[0] < 1.645 * 2.0 / np.sqrt(12.0) - 0.04


def test_a_normal_part_alone_gives_the_normal_or_student_t_quantile():
    zero = np.zeros((2, 1))
    sd = np.array([2.0, 0.5])
    lower, upper = error_quantiles(zero, np.array([-1.0]), np.array([1.0]), sd)
    assert upper == pytest.approx(norm.ppf(0.95) * sd, rel=0.01)
    assert lower == pytest.approx(-norm.ppf(0.95) * sd, rel=0.01)
    _, upper_t = error_quantiles(zero, np.array([-1.0]), np.array([1.0]), sd, dof=3.0)
    assert upper_t == pytest.approx(t.ppf(0.95, 3) * sd, rel=0.02)  # 2.353, not 1.645
    # a normal "other" part (the geometry's) adds in quadrature
    _, both = error_quantiles(zero, np.array([-1.0]), np.array([1.0]), 0.3, other_sd=0.4)
    assert both == pytest.approx(norm.ppf(0.95) * 0.5, rel=0.01)


def test_two_equal_uniform_parts_make_a_triangle():
    """U(-1/2, 1/2) + U(-1/2, 1/2) is triangular on [-1, 1]: P(e > q) = (1 - q)²/2, so
    the 95 % quantile is 1 - sqrt(0.1) = 0.684 (1.645 sd: 0.672)."""
    r = np.array([[1.0, 1.0]])
    lower, upper = error_quantiles(r, np.full(2, -0.5), np.full(2, 0.5), 0.0)
    assert upper[0] == pytest.approx(1 - np.sqrt(0.1), abs=0.005)
    assert lower[0] == pytest.approx(-(1 - np.sqrt(0.1)), abs=0.005)


def test_a_uniform_and_a_normal_part_match_their_exact_convolution():
    """e = U(-a, a) + N(0, s²): P(e <= x) = (G((x + a)/s) - G((x - a)/s)) s / 2a with
    G(z) = z Φ(z) + φ(z), the integral of Φ; its quantiles solved exactly."""
    a, s = 1.0, 0.4

    def g(z):
        return z * norm.cdf(z) + norm.pdf(z)

    def cdf(x):
        return (g((x + a) / s) - g((x - a) / s)) * s / (2 * a)

    exact = brentq(lambda x: cdf(x) - 0.95, 0.0, 5.0)
    lower, upper = error_quantiles(np.array([[2 * a]]), np.array([-0.5]), np.array([0.5]), s)
    assert upper[0] == pytest.approx(exact, rel=0.005)
    assert lower[0] == pytest.approx(-exact, rel=0.005)
    sd = np.sqrt(a**2 / 3 + s**2)
    assert upper[0] < 1.645 * sd  # lighter tails than a normal of the same spread


def test_an_offset_range_makes_the_error_asymmetric_and_rows_share_the_draws():
    """Held at the lower end of its range (δ uniform on [0, 1]): the error lies on one side;
    a response of the opposite sign mirrors it exactly (the same draws serve every row)."""
    r = np.array([[1.0], [-1.0]])
    lower, upper = error_quantiles(r, np.array([0.0]), np.array([1.0]), 0.0, level=0.8)
    assert lower[0] == pytest.approx(0.1, abs=0.005) and upper[0] == pytest.approx(0.9, abs=0.005)
    assert lower[1] == pytest.approx(-upper[0], abs=1e-12)
    again = error_quantiles(r, np.array([0.0]), np.array([1.0]), 0.0, level=0.8)
    assert np.array_equal(again[0], lower)  # fixed seed: the same interval every time


def test_an_unbounded_part_gives_an_unbounded_error_and_bad_input_is_refused():
    lower, upper = error_quantiles(
        np.array([[1.0], [1.0]]), np.array([-0.5]), np.array([0.5]), np.array([np.inf, 0.1])
    )
    assert lower[0] == -np.inf and upper[0] == np.inf and np.isfinite(upper[1])
    with pytest.raises(ValueError, match="low and high"):
        error_quantiles(np.array([[1.0]]), np.array([0.5]), np.array([-0.5]), 0.0)
    with pytest.raises(ValueError, match="level"):
        error_quantiles(np.array([[1.0]]), np.array([-0.5]), np.array([0.5]), 0.0, level=1.0)
