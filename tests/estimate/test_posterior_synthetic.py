"""The synthetic likelihood of a long record's mean statistics (railsusp.estimate.
posterior_synthetic, posterior_emulator, posterior_smc) against a linear-Gaussian
simulator whose exact posterior is known: x = A u + b + e, e ~ N(0, S) per section,
independent sections, so the mean of k sections is N(A u + b, S / k) and, away from the
box's edges, the posterior of u is Gaussian with precision A' (S / k)^-1 A. The method's
posterior must match it while the sections' scatter dominates (k = 10, 30), and must stay
as wide as the emulator's own uncertainty when k grows without bound (where the exact
posterior collapses onto the truth): an emulator whose variance were dropped would be
over-confident there, which the last test shows."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.errors import RailsuspInputError
from railsusp.estimate.posterior_emulator import StatisticsEmulator, fit
from railsusp.estimate.posterior_smc import smc_sample
from railsusp.estimate.posterior_synthetic import (
    SyntheticLikelihood,
    check_long_record,
    gain_covariance,
)
from railsusp.estimate.posterior_synthetic_information import (
    Z90,
    cramer_rao_width,
    fisher_information,
)
from railsusp.estimate.posterior_synthetic_model_error import (
    fit_model_error,
    fit_scales,
    shrunk_excess_covariance,
)

A = np.array([[2.0, 0.5], [0.3, 1.5], [1.0, -1.0]])
B = np.array([1.0, -2.0, 0.5])
L = np.array([[0.5, 0.0, 0.0], [0.2, 0.4, 0.0], [0.1, -0.1, 0.3]])
S = L @ L.T
TRUTH = np.array([0.45, 0.55])


class _Exact(StatisticsEmulator):
    """Base of the emulators of known moments below: the mean is that of ``moments``."""

    def mean(self, u):
        return self.moments(np.atleast_2d(u))[0]


@pytest.fixture(scope="module")
def emulator() -> StatisticsEmulator:
    rng = np.random.default_rng(1)
    u = rng.random((1000, 2))
    x = u @ A.T + B + rng.standard_normal((1000, 3)) @ L.T
    return fit(u, x, members=8, hidden=16, seed=0)


def _exact(s_bar: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of the Gaussian posterior of u for a mean statistic s_bar ~
    N(A u + B, cov) under a flat prior (the box's edges far in standard deviations)."""
    prec = A.T @ np.linalg.solve(cov, A)
    c = np.linalg.inv(prec)
    return c @ A.T @ np.linalg.solve(cov, s_bar - B), c


def _draws(sl: SyntheticLikelihood, s_bar: np.ndarray, k: int) -> np.ndarray:
    return smc_sample(lambda u: sl.log_likelihood(u, s_bar, k), 2, 4000,
                      np.random.default_rng(3))  # fmt: skip


def test_the_emulator_learns_the_mean_and_the_section_covariance(emulator):
    mean, section, spread = emulator.moments(TRUTH[None])
    assert mean[0] == pytest.approx(A @ TRUTH + B, abs=0.06)
    assert np.diag(section[0]) == pytest.approx(np.diag(S), rel=0.25)
    assert np.all(np.diag(spread[0]) > 0) and np.all(np.diag(spread[0]) < 0.05 * np.diag(S))


@pytest.mark.parametrize("k", [10, 30])
def test_the_posterior_of_k_sections_matches_the_exact_one(emulator, k):
    rng = np.random.default_rng(k)
    sections = TRUTH @ A.T + B + rng.standard_normal((k, 3)) @ L.T
    sl = SyntheticLikelihood(emulator)
    draws = sl.sample(sections, 4000, seed=3)
    mean, cov = _exact(sections.mean(axis=0), S / k)
    sd = np.sqrt(np.diag(cov))
    assert draws.std(axis=0) == pytest.approx(sd, rel=0.2)
    assert np.all(np.abs(draws.mean(axis=0) - mean) < 0.5 * sd)


def test_a_record_without_end_is_as_uncertain_as_the_emulator_not_more(emulator):
    """k = 10^6 sections: the exact posterior's sd is 0.0002; the method's stays at the
    emulator's own uncertainty (its covariance E at the truth), and the truth lies within
    a few of its standard deviations of the posterior mean."""
    k = 10**6
    s_bar = A @ TRUTH + B  # the mean of endless sections is the truth's mean statistic
    _, exact = _exact(s_bar, S / k)
    _, _, spread = emulator.moments(TRUTH[None])
    _, floor = _exact(s_bar, S / k + spread[0])
    draws = _draws(SyntheticLikelihood(emulator), s_bar, k)
    sd = draws.std(axis=0)
    assert np.all(sd > 0.7 * np.sqrt(np.diag(floor)))
    assert np.all(sd > 10 * np.sqrt(np.diag(exact)))
    z = (draws.mean(axis=0) - TRUTH) / sd
    assert np.all(np.abs(z) < 4.0), z


def test_dropping_the_emulator_variance_makes_the_endless_record_over_confident(emulator):
    """The broken variant of the test above (E left out of the covariance): the
    posterior collapses to the exact one's width about the emulator's biased mean, and
    the truth lies tens of standard deviations away (the check above would fail)."""
    k = 10**6
    s_bar = A @ TRUTH + B
    draws = _draws(SyntheticLikelihood(emulator, emulator_variance=False), s_bar, k)
    z = (draws.mean(axis=0) - TRUTH) / draws.std(axis=0)
    assert np.max(np.abs(z)) > 4.0


def test_a_shared_part_does_not_average_out():
    """With a gain error shared by all sections, the mean of k sections keeps it:
    C_k = G + (Sigma - G) / k -> G; without sections' scatter left, G alone."""
    names = ["c:Y_p50", "c:Q_p50", "c:YQ_p50", "c:Y_band_1-2Hz"]
    shared = gain_covariance(names, 0.01)
    mean = np.array([[40.0, 100.0, 0.4, 0.5]])
    g = shared(mean)[0]
    # Y percentile 40 kN, 1 % gain: sd 0.4 kN; Y/Q 0.4 with Y's and Q's gains: 0.4 * 0.01 * sqrt 2
    assert np.sqrt(np.diag(g)) == pytest.approx([0.4, 1.0, 0.004 * np.sqrt(2), 0.01 / np.log(10)])
    assert g[0, 2] == pytest.approx(40 * 0.4 * 1e-4)  # Y and Y/Q share Y's gain
    assert g[1, 2] == pytest.approx(-100 * 0.4 * 1e-4)  # Q's gain lowers Y/Q
    assert g[0, 3] == pytest.approx(40 * 1e-4 / np.log(10))
    assert g[0, 1] == 0.0

    class Fixed(_Exact):
        def moments(self, u):
            n = len(u)
            return (np.repeat(mean, n, 0), np.repeat((g + np.eye(4))[None], n, 0),
                    np.zeros((n, 4, 4)))  # fmt: skip

    emu = Fixed([], np.zeros(4), np.ones(4), np.zeros((1, 4)), np.eye(4))
    _, cov = SyntheticLikelihood(emu, shared).mean_and_covariance(np.zeros((1, 2)), 10**9)
    assert cov[0] == pytest.approx(g, abs=1e-8)
    _, one = SyntheticLikelihood(emu, shared).mean_and_covariance(np.zeros((1, 2)), 1)
    assert one[0] == pytest.approx(g + np.eye(4))


def test_smc_draws_a_truncated_gaussian_on_the_box():
    """N(0.9, 0.1^2) in each of two coordinates, cut at 1: the truncated normal's mean
    0.9 - 0.1 phi(1) / Phi(1) = 0.8712 and sd 0.0760."""
    draws = smc_sample(lambda u: -0.5 * np.sum(((u - 0.9) / 0.1) ** 2, axis=1), 2, 4000,
                       np.random.default_rng(0))  # fmt: skip
    assert draws.max() < 1.0 and draws.min() > 0.0
    assert draws.mean(axis=0) == pytest.approx([0.8712, 0.8712], abs=0.006)
    assert draws.std(axis=0) == pytest.approx([0.0760, 0.0760], rel=0.06)


def test_the_saved_emulator_is_read_back_the_same(emulator, tmp_path):
    path = emulator.save(tmp_path / "posterior" / "synthetic" / "emulator.npz")
    back = StatisticsEmulator.load(path)
    u = np.random.default_rng(5).random((7, 2))
    for a, b in zip(emulator.moments(u), back.moments(u), strict=True):
        assert np.array_equal(a, b)
    assert back.members == emulator.members and back.cases == 1000


def test_bad_input_is_refused_in_one_line(emulator, tmp_path):
    with pytest.raises(RailsuspInputError, match="long_record = 'exact': accepted fusion, "):
        check_long_record("exact")
    sl = SyntheticLikelihood(emulator)
    with pytest.raises(RailsuspInputError, match=r"sections \(2, 4\): accepted finite"):
        sl.sample(np.zeros((2, 4)), 100)
    with pytest.raises(RailsuspInputError, match="accepted finite"):
        sl.sample(np.array([[0.0, np.nan, 1.0]]), 100)
    with pytest.raises(RailsuspInputError, match="emulator.npz does not exist: fit the"):
        StatisticsEmulator.load(tmp_path / "emulator.npz")
    with pytest.raises(RailsuspInputError, match="accepted at least 20 cases"):
        fit(np.zeros((5, 2)), np.zeros((5, 3)))


class _Known(_Exact):
    """An emulator of known moments: mean 0, one section's covariance I, spread E = e I."""

    def __init__(self, d: int, e: float):
        super().__init__([], np.zeros(d), np.ones(d), np.zeros((1, d)), np.eye(d))
        self.e = e

    def moments(self, u):
        n, d = len(u), self.dim
        eye = np.repeat(np.eye(d)[None], n, 0)
        return np.zeros((n, d)), eye.copy(), self.e * eye


def test_the_covariance_scales_recover_an_underestimated_scatter_and_emulator_error():
    """Records whose sections scatter 1.5 times the emulator's Sigma = I about a mean
    that is off by N(0, 0.04 I) per record, where the emulator says E = 0.01 I: the
    scatter's scale comes back near 1.5 and the model error near 0.03 of Sigma; records
    drawn as the emulator says leave them at 1 and 0."""
    rng = np.random.default_rng(0)
    n, k, d = 400, 30, 5
    sl = SyntheticLikelihood(_Known(d, 0.01))
    u = np.zeros((n, 2))
    bias = 0.2 * rng.standard_normal((n, 1, d))
    records = bias + np.sqrt(1.5) * rng.standard_normal((n, k, d))
    within, model = fit_scales(sl, u, records)
    assert within == pytest.approx(1.5, rel=0.05)
    assert model == pytest.approx(0.03, abs=0.01)
    honest = 0.1 * rng.standard_normal((n, 1, d)) + rng.standard_normal((n, k, d))
    assert fit_scales(sl, u, honest) == pytest.approx((1.0, 0.0), abs=0.06)
    with pytest.raises(RailsuspInputError, match="records of 1 section: accepted at least 2"):
        fit_scales(sl, u, records[:, :1])


class _Scaled(_Exact):
    """An emulator of known moments: mean 0, one section's covariance diag(sd^2), no spread."""

    def __init__(self, sd: np.ndarray):
        d = sd.size
        super().__init__([], np.zeros(d), np.ones(d), np.zeros((1, d)), np.eye(d))
        self.sd = sd

    def moments(self, u):
        n, d = len(u), self.dim
        return np.zeros((n, d)), np.repeat(np.diag(self.sd**2)[None], n, 0), np.zeros((n, d, d))


def _anisotropic(d: int) -> np.ndarray:
    """A model error concentrated in two directions (eigenvalues 0.5 and 0.2) over a
    floor of 0.005: its mean eigenvalue, all an isotropic m can hold, is 0.12."""
    rng = np.random.default_rng(7)
    q, _ = np.linalg.qr(rng.standard_normal((d, d)))
    return 0.5 * np.outer(q[:, 0], q[:, 0]) + 0.2 * np.outer(q[:, 1], q[:, 1]) + 0.005 * np.eye(d)


def test_the_model_error_per_direction_is_recovered_where_an_isotropic_m_is_not():
    """Records of k = 30 sections, each section N(0, S^2) (S = diag(sd)), whose means are
    off by a bias N(0, S A S) with A anisotropic: the fitted A is A within sampling error
    (800 records, 6 statistics), in the sections' units, and the record means'
    variance along A's leading direction is what the fitted model says. The isotropic
    m Sigma of fit_scales holds only A's average: it is three times too narrow there."""
    rng = np.random.default_rng(0)
    n, k, d = 800, 30, 6
    sd = np.array([1.0, 2.0, 0.5, 1.5, 3.0, 0.8])
    truth = _anisotropic(d)
    sl = SyntheticLikelihood(_Scaled(sd))
    u = np.zeros((n, 2))
    bias = (rng.standard_normal((n, d)) @ np.linalg.cholesky(truth).T) * sd
    records = bias[:, None, :] + sd * rng.standard_normal((n, k, d))
    within, model = fit_scales(sl, u, records)
    matrix, rho = fit_model_error(sl, u, records, within)
    assert np.linalg.norm(matrix - truth) < 0.12 * np.linalg.norm(truth)
    assert rho < 0.2
    lead = np.linalg.eigh(truth)[1][:, -1] * sd  # the leading direction in the statistics
    seen = np.var(records.mean(axis=1) @ lead)
    sl.within_scale, sl.model_error = within, model
    isotropic = lead @ sl.mean_and_covariance(u[:1], k)[1][0] @ lead
    sl.model_error_matrix = matrix
    per_direction = lead @ sl.mean_and_covariance(u[:1], k)[1][0] @ lead
    assert per_direction == pytest.approx(seen, rel=0.15)
    assert seen > 2.5 * isotropic


def test_few_records_are_shrunk_towards_the_isotropic_model():
    """With 15 records of 10 statistics whose model error IS isotropic (0.1 I), the raw
    moment estimate is noise in most directions; the shrunk one is nearer the truth,
    leans on the target (rho > 0.5) and is positive semi-definite. Records that the
    known covariance already explains give A near 0."""
    rng = np.random.default_rng(3)
    n, d = 15, 10
    base = np.repeat((np.eye(d) / 30.0)[None], n, 0)
    z = rng.standard_normal((n, d)) * np.sqrt(1.0 / 30.0 + 0.1)
    matrix, rho = shrunk_excess_covariance(z, base, np.eye(d))
    raw = np.mean(z[:, :, None] * z[:, None, :], axis=0) - base[0]
    truth = 0.1 * np.eye(d)
    assert rho > 0.5
    assert np.linalg.norm(matrix - truth) < 0.6 * np.linalg.norm(raw - truth)
    assert np.linalg.eigvalsh(matrix).min() >= -1e-12
    honest = rng.standard_normal((2000, d)) * np.sqrt(1.0 / 30.0)
    none, _ = shrunk_excess_covariance(honest, np.repeat(base[:1], 2000, 0), np.eye(d))
    assert np.abs(np.linalg.eigvalsh(none)).max() < 0.01


class _Linear(_Exact):
    """The linear-Gaussian simulator's exact moments: mean A u + B, covariance S, no spread."""

    def __init__(self):
        super().__init__([], np.zeros(3), np.ones(3), np.zeros((1, 3)), np.eye(3))

    def moments(self, u):
        n = len(u)
        return u @ A.T + B, np.repeat(S[None], n, 0), np.zeros((n, 3, 3))


def test_the_cramer_rao_width_of_a_linear_gaussian_record_is_the_exact_posterior_width(emulator):
    """For x = A u + B + e (e ~ N(0, S)) the mean of k sections carries Fisher information
    A' (S / k)^-1 A about u, and the exact posterior's 90 % width away from the box's
    edges is 2 x 1.645 sd: the bound from the exact moments is it (to the central
    differences' rounding), the one from the fitted emulator within its error (its slopes
    are 10 % off on 1000 cases), and the emulator's spread bounds it for any length."""
    for k in (1, 30):
        exact = 2 * Z90 * np.sqrt(np.diag(np.linalg.inv(A.T @ np.linalg.solve(S / k, A))))
        info = fisher_information(SyntheticLikelihood(_Linear()), TRUTH[None], k)
        assert cramer_rao_width(info)[0] == pytest.approx(exact, rel=1e-6)
        info = fisher_information(
            SyntheticLikelihood(emulator), TRUTH[None], k, emulator_error=False
        )
        assert cramer_rao_width(info)[0] == pytest.approx(exact, rel=0.25)
    sl = SyntheticLikelihood(emulator)
    endless = cramer_rao_width(fisher_information(sl, TRUTH[None], 10**6, emulator_error=False))
    wider = cramer_rao_width(fisher_information(sl, TRUTH[None], 10**6))
    assert np.all(wider > 20 * endless)  # the emulator's spread: a bound no length passes


class _Hetero(_Exact):
    """u[0] moves the mean (2 u0, u0, -u0); u[1] only one section's scatter, (0.05 + u1)^2 I."""

    def __init__(self):
        super().__init__([[(np.zeros((2, 1)), np.zeros(1))]], np.zeros(3), np.ones(3),
                         np.zeros((1, 3)), np.eye(3))  # fmt: skip

    def moments(self, u):
        n = len(u)
        mean = u[:, :1] * np.array([2.0, 1.0, -1.0])
        section = (0.05 + u[:, 1])[:, None, None] ** 2 * np.eye(3)
        return mean, section, np.zeros((n, 3, 3))


def test_the_plug_in_covariance_takes_no_information_from_the_scatter_model():
    """A parameter that moves only the emulated scatter: with C_k(u) the posterior of one
    record's mean leans on -log|C_k(u)| / 2 and piles up where the scatter is small; with
    C_k held at a first posterior's mean it stays the prior (uniform: mean 0.5, sd
    0.289), while the parameter that moves the mean is found as before."""
    s = np.array([0.8, 0.4, -0.4])  # the mean at u0 = 0.4
    full = SyntheticLikelihood(_Hetero(), plug_in_covariance=False).sample(s, 2000, seed=1)
    plug = SyntheticLikelihood(_Hetero()).sample(s, 2000, seed=1)
    assert np.mean(full[:, 1]) < 0.3
    assert np.mean(plug[:, 1]) == pytest.approx(0.5, abs=0.05)
    assert np.std(plug[:, 1]) == pytest.approx(1 / np.sqrt(12), rel=0.1)
    assert np.median(plug[:, 0]) == pytest.approx(0.4, abs=0.05)


def test_a_first_pass_at_the_centre_is_the_same_posterior_when_the_scatter_is_constant():
    """The first SMC run of a posterior of hundreds of statistics holds C_k at the box's
    centre (its C_k(u) per particle costs N D^3); where C_k does not depend on u the two
    first runs' log-likelihoods differ by a constant, which tempering ignores, so the
    draws are the same; the estimator sets it only beyond the EN 14363 summary."""
    from railsusp.conditions import get_condition
    from railsusp.estimate.posterior_settings import PosteriorSettings
    from railsusp.estimate.posterior_synthetic_fit import likelihood

    s = A @ TRUTH + B
    emu = _Linear()
    emu.weights = [[(np.zeros((2, 1)), np.zeros(1))]]  # two inputs, as sample reads them
    full = SyntheticLikelihood(emu).sample(s[None], 500, seed=3)
    centre = SyntheticLikelihood(emu, first_pass_at_centre=True).sample(s[None], 500, seed=3)
    assert np.allclose(full, centre, atol=1e-9)
    assert np.all(np.abs(np.median(full, axis=0) - TRUTH) < 0.05)
    cond = (get_condition("straight"),)
    assert not likelihood(PosteriorSettings(cond), _Linear()).first_pass_at_centre
    rich = PosteriorSettings(cond, statistics=("coherence",))
    assert likelihood(rich, _Linear()).first_pass_at_centre


def test_a_projection_on_the_jacobian_keeps_the_information_and_the_posterior():
    """x = A u + B + e with two parameters: the two combinations of the three statistics
    that informative_projection keeps carry all the information (kept = 1, the same
    Cramer-Rao widths) and the likelihood of them differs from the full one by a constant,
    so the posterior's draws are the same; one combination keeps less."""
    from railsusp.estimate.posterior_synthetic_information import informative_projection

    emu = _Linear()
    emu.weights = [[(np.zeros((2, 1)), np.zeros(1))]]
    full = SyntheticLikelihood(emu)
    u = np.random.default_rng(0).random((50, 2))
    p, kept = informative_projection(full, u, 10, 2)
    assert p.shape == (2, 3) and kept == pytest.approx(1.0, abs=1e-12)
    projected = SyntheticLikelihood(emu, projection=p)
    for k in (1, 30):
        assert cramer_rao_width(fisher_information(projected, TRUTH[None], k)) == pytest.approx(
            cramer_rao_width(fisher_information(full, TRUTH[None], k)), rel=1e-6
        )
    s = (A @ TRUTH + B)[None]
    assert np.allclose(projected.sample(s, 500, seed=3), full.sample(s, 500, seed=3), atol=1e-9)
    _, one = informative_projection(full, u, 10, 1)
    assert one < 0.99
