"""bench/projection_information.py and the unbiased precision of bench/information_estimate.py:
the inverse-Wishart correction on Gaussian samples of a known covariance, a projection that
spans C^-1 J keeping all the information, and the columns of a run's statistics."""

import numpy as np
import pytest

from conftest import bench_script
from railsusp.estimate.posterior_synthetic_information import top_directions, whitening


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
    """(:mod:`railsusp.estimate.posterior_synthetic_information`'s, which the informative projection
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


class _LinearEmulator:
    """Exact moments of statistics s = J u + e, e ~ N(0, C) per section, no spread."""

    def __init__(self, jac, cov):
        self.jac, self.cov = jac, cov
        self.dim, self.inputs = jac.shape[0], jac.shape[1]

    def mean(self, u):
        return np.atleast_2d(u) @ self.jac.T

    def moments(self, u):
        n = len(np.atleast_2d(u))
        cov = np.repeat(self.cov[None], n, 0)
        return self.mean(u), cov, np.zeros_like(cov)


def test_point_readings_of_two_conditions_against_the_exact_information(bench):
    """Two conditions of twelve statistics each, independent runs (block-diagonal C), pairs
    and sections drawn from the exact Jacobian and covariance: the unbiased full reading,
    the reading through a projection spanning C^-1 J and the exact emulator's own bound
    all give the exact Cramer-Rao widths of 30 sections; the raw sample inverse is
    narrower (its bias); the emulator's Jacobian points along the pairs'."""
    from types import SimpleNamespace

    from railsusp.estimate.posterior_synthetic import SyntheticLikelihood

    rng = np.random.default_rng(11)
    per, k, pairs, n = 12, 30, 600, 4000
    blocks = [_covariance(rng, per) for _ in range(2)]
    cov = np.zeros((2 * per, 2 * per))
    cov[:per, :per], cov[per:, per:] = blocks
    jac = 3.0 * rng.standard_normal((2 * per, 10))
    data = {}
    for i, name in enumerate(("straight", "curve")):
        b = slice(i * per, (i + 1) * per)
        noise = rng.multivariate_normal(np.zeros(per), blocks[i], size=(10, pairs))
        data[name] = {"d_all": jac[b].T[:, None, :] + noise,
                      "cov_all": rng.multivariate_normal(np.zeros(per), blocks[i], size=n),
                      "gains_all": np.zeros((1, per))}  # fmt: skip
    p = np.linalg.solve(cov, jac).T  # the 10 score directions
    sl = SyntheticLikelihood(_LinearEmulator(jac, cov), projection=p)
    est = bench_script("information_estimate")
    exact = est.widths_pct(jac.T @ np.linalg.solve(cov / k, jac))
    got = bench.point_readings(data, list(range(2 * per)), SimpleNamespace(likelihood=sl),
                               np.full(10, 0.5), k, np.random.default_rng(0))  # fmt: skip
    w = {key: np.array(list(v.values())) for key, v in got["widths_pct"].items()}
    assert w["full_unbiased_gains_known"] == pytest.approx(exact, rel=0.06)
    assert w["projection_gains_known"] == pytest.approx(exact, rel=0.06)
    assert w["emulator_bound"] == pytest.approx(exact, rel=1e-6)
    assert np.all(w["full_sample_raw_gains_known"] < w["full_unbiased_gains_known"])
    assert all(j["cosine"] > 0.99 for j in got["jacobians"].values())
    assert got["sections"] == n and got["pairs"] == pairs
