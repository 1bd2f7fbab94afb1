"""bench/statistics_information.py: the unbiased information estimator
(bench/information_estimate.py) on an analytic linear-Gaussian case, and the candidate
statistics' groups (bench/statistics_candidates.py), which are the posterior's families
(their own tests: tests/estimate/test_statistic_families.py)."""

import numpy as np
import pytest

from conftest import bench_script


@pytest.fixture(scope="module")
def bench():
    return bench_script("information_estimate")


@pytest.fixture(scope="module")
def cand():
    return bench_script("statistics_candidates")


def _linear_gaussian(rng, reps, k=16, d=40):
    """Jacobian samples d_k = A + e_k of statistics s = A theta + noise: three parameters,
    the third with no effect (A's column zero), e_k ~ N(0, Ce); the statistics' covariance
    C known. Returns (A, C, samples (reps, 3, k, d))."""
    a = rng.standard_normal((d, 3)) * np.array([1.0, 0.3, 0.0])
    m = rng.standard_normal((d, d)) / np.sqrt(d)
    c = m @ m.T + 0.5 * np.eye(d)
    ce = 0.5 * c  # a noise on the Jacobian of the size of the statistics' own scatter
    e = rng.multivariate_normal(np.zeros(d), ce, size=(reps, 3, k))
    return a, c, a.T[None, :, None, :] + e


def test_unbiased_information_matches_the_analytic_one_and_finds_none_where_none_is(bench):
    """s = A theta + noise: the information is A^T C^-1 A. Over 300 replications of 16
    pairs the unbiased estimate's mean lies within 4 standard errors of it for every
    entry; the zero-effect parameter's comes out ~0, where the plug-in estimate is biased
    up by tr(C^-1 Ce) / K = D / (2 K) = 1.25 (40 statistics, 16 pairs)."""
    rng = np.random.default_rng(3)
    a, c, d = _linear_gaussian(rng, reps=300)
    w = np.linalg.inv(c)
    truth = a.T @ w @ a
    est = np.array([bench.information_unbiased(x, w) for x in d])
    naive = np.array([bench.information_naive(x, w) for x in d])
    split = np.array([bench.information_split(x, w) for x in d])
    se = est.std(axis=0) / np.sqrt(len(est))
    assert np.all(np.abs(est.mean(axis=0) - truth) < 4 * se + 1e-12)
    assert abs(est.mean(axis=0)[2, 2]) < 4 * se[2, 2]
    assert abs(split.mean(axis=0)[2, 2]) < 4 * split.std(axis=0)[2, 2] / np.sqrt(len(split))
    assert naive.mean(axis=0)[2, 2] == pytest.approx(40 / (2 * 16), rel=0.1)
    assert truth[0, 0] > 10  # the informative parameter is well above the bias scale
    # the U-statistic is the less noisy of the two unbiased estimates
    assert est.std(axis=0)[1, 1] < split.std(axis=0)[1, 1]


def test_unbiased_information_on_noise_free_pairs_is_the_exact_one(bench):
    rng = np.random.default_rng(0)
    a = rng.standard_normal((12, 4))
    d = np.repeat(a.T[:, None, :], 5, axis=1)
    w = np.eye(12) * 2.0
    assert bench.information_unbiased(d, w) == pytest.approx(2.0 * a.T @ a)
    assert bench.information_split(d, w) == pytest.approx(2.0 * a.T @ a)


def test_no_weight_is_the_identity_without_forming_it(bench):
    rng = np.random.default_rng(5)
    d = rng.standard_normal((3, 8, 20))
    eye = np.eye(20)
    assert bench.information_unbiased(d, None) == pytest.approx(bench.information_unbiased(d, eye))
    assert bench.information_split(d, None) == pytest.approx(bench.information_split(d, eye))


def test_ledoit_wolf_is_the_sample_covariance_with_many_samples_and_invertible_with_few(bench):
    rng = np.random.default_rng(1)
    scale = np.array([1.0, 10.0, 0.1, 3.0])
    x = rng.standard_normal((20000, 4)) * scale
    lw = bench.ledoit_wolf(x)
    assert np.sqrt(np.diag(lw)) == pytest.approx(scale, rel=0.02)
    assert np.abs(lw - np.diag(np.diag(lw))).max() < 0.05 * lw.max()
    few = rng.standard_normal((10, 30))  # fewer samples than statistics
    assert np.linalg.matrix_rank(np.cov(few.T)) < 30
    assert np.linalg.eigvalsh(bench.ledoit_wolf(few)).min() > 0


def test_widths_of_a_known_information_and_of_an_unidentified_direction(bench):
    info = np.diag([100.0, 4.0])
    w = bench.widths_pct(info, prior=0.0)
    assert w == pytest.approx([100 * 2 * 1.6448536 / 10, 100 * 2 * 1.6448536 / 2])
    assert bench.widths_pct(np.diag([100.0, -1.0]), 0.0)[1] > 1e4  # no information: no interval
    # with the uniform prior's variance as a Gaussian prior: 2 x 1.645 / sqrt(12) = 95 %
    assert bench.widths_pct(np.diag([100.0, -1e-9]))[1] == pytest.approx(95.0, abs=0.1)
    assert bench.widths_pct(info)[0] == pytest.approx(100 * 2 * 1.6448536 / np.sqrt(112))
    # one parameter alone: the others known, so a correlation does not widen it
    corr = np.array([[100.0, 18.0], [18.0, 4.0]])
    assert bench.widths_alone_pct(corr) == pytest.approx(w)
    assert np.all(bench.widths_pct(corr, 0.0) > w)
    assert bench.widths_alone_pct(np.diag([1.0, -1.0]))[1] == np.inf


def test_section_statistics_have_their_names_and_today_is_the_posteriors(cand):
    from railsusp.estimate.summaries import section_summary

    fs, speed = 50.0, 60 / 3.6
    rng = np.random.default_rng(4)
    t = np.arange(1000) / fs
    sig = np.stack(
        [
            5 + rng.standard_normal(1000) + np.sin(2 * np.pi * 1.3 * t),
            100 + 5 * rng.standard_normal(1000),
            -5 + rng.standard_normal(1000),
            100 + 5 * rng.standard_normal(1000),
        ]
    )
    st = cand.section_statistics(sig, fs, speed)
    assert set(st) == set(cand.GROUPS)
    for g, v in st.items():
        assert v.shape == (len(cand.group_names(g)),) and np.all(np.isfinite(v))
    assert np.array_equal(st["today"], section_summary(sig[0], sig[1], fs, speed))
    with pytest.raises(ValueError, match="accepted today"):
        cand.group_names("cross-spectra")
