"""bench/projection_information.py and the unbiased precision of bench/information_estimate.py:
the inverse-Wishart correction on Gaussian samples of a known covariance, a projection that
spans C^-1 J keeping all the information, and the columns of a run's statistics."""

import numpy as np
import pytest

from conftest import bench_script
from railsusp.estimate.posterior_synthetic import top_directions, whitening


@pytest.fixture(scope="module")
def est():
    return bench_script("information_estimate")


@pytest.fixture(scope="module")
def bench():
    return bench_script("projection_information")


def _covariance(rng, d):
    m = rng.standard_normal((d, d)) / np.sqrt(d)
    return m @ m.T + 0.3 * np.eye(d)


def test_unbiased_precision_removes_the_inverse_wishart_bias(est):
    """30 statistics from 45 rows: S^-1 overstates Sigma^-1 by (N - 1) / (N - D - 2) =
    44 / 13 = 3.4 on average; the corrected estimate's trace against Sigma averages D
    within 3 %, the raw one's 3.4 D."""
    rng = np.random.default_rng(5)
    d, n = 30, 45
    c = _covariance(rng, d)
    corrected, raw = [], []
    for _ in range(400):
        x = rng.multivariate_normal(np.zeros(d), c, size=n)
        corrected.append(np.trace(est.unbiased_precision(x) @ c))
        raw.append(np.trace(np.linalg.inv(np.cov(x.T)) @ c))
    assert np.mean(corrected) == pytest.approx(d, rel=0.03)
    # the raw inverse's bias is what the correction removes (the case is one where it shows)
    assert np.mean(raw) == pytest.approx(d * (n - 1) / (n - d - 2), rel=0.03)


def test_unbiased_precision_refuses_too_few_rows(est):
    """N = D + 2 rows leave the inverse Wishart without a mean: refused; D + 3 read."""
    with pytest.raises(ValueError, match="11 rows for 9 statistics: need more than 11"):
        est.unbiased_precision(np.zeros((11, 9)))
    x = np.random.default_rng(0).standard_normal((12, 9))
    assert est.unbiased_precision(x) == pytest.approx(np.linalg.inv(np.cov(x.T)) / 11)


def test_projection_spanning_the_score_keeps_all_the_information(bench):
    """With P's rows spanning C^-1 J (the local score), J^T W_P J = J^T C^-1 J exactly;
    a projection missing part of that span keeps strictly less; and the sample-size
    factor of :func:`projected_weight` is (n - r - 2) / (n - 1)."""
    rng = np.random.default_rng(2)
    d, q = 25, 3
    c = _covariance(rng, d)
    jac = rng.standard_normal((d, q))
    full = jac.T @ np.linalg.solve(c, jac)
    extra = rng.standard_normal((4, d))
    p = np.vstack([np.linalg.solve(c, jac).T, extra])  # 7 combinations, the score among them
    assert jac.T @ bench.projected_weight(p, c) @ jac == pytest.approx(full, rel=1e-9)
    partial = jac.T @ bench.projected_weight(p[1:], c) @ jac
    assert partial[0, 0] < full[0, 0] * (1 - 1e-3)
    w = bench.projected_weight(p, c, n=100)
    assert w == pytest.approx(bench.projected_weight(p, c) * (100 - 7 - 2) / 99, rel=1e-12)


def test_top_directions_are_the_score_directions(bench):
    """(:mod:`railsusp.estimate.posterior_synthetic`'s, which the informative projection
    uses.) Whitened by C^-1/2, the top q combinations of a rank-q Jacobian span C^-1 J: they
    keep all of its information, which fewer cannot."""
    rng = np.random.default_rng(4)
    d, q = 20, 2
    c = _covariance(rng, d)
    jac = rng.standard_normal((d, q))
    full = jac.T @ np.linalg.solve(c, jac)
    p, kept = top_directions(whitening(c), jac, q)
    assert kept == pytest.approx(1.0)
    assert jac.T @ bench.projected_weight(p, c) @ jac == pytest.approx(full, rel=1e-8)
    one, kept_one = top_directions(whitening(c), jac, 1)
    assert kept_one < 1.0
    assert np.linalg.det(jac.T @ bench.projected_weight(one, c) @ jac) == pytest.approx(0, abs=1e-8)


def test_columns_follow_the_run_and_name_a_statistic_the_bench_lacks(bench):
    """The curve's statistics follow the straight's 375 (five groups); the run's order is
    kept; a condition the bench did not compute is named."""
    cols = bench.columns_of(["curve:Y_p50", "straight:Y_p50"], ["straight", "curve"])
    assert cols == [1 + 375, 1]
    with pytest.raises(ValueError, match="statistic 'uphill:Y_p50' of the run"):
        bench.columns_of(["uphill:Y_p50"], ["straight", "curve"])
