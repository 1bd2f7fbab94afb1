"""bench/posterior_estimators.py (NPE against NLE and NRE): the statistics it reads out of a
run's richer files, its importance resampling and effective sample size, and the logistic
prior every estimator shares with production."""

import numpy as np
import pytest
import torch

from conftest import bench_script
from railsusp.condition_files import resolve_conditions
from railsusp.estimate.posterior_fusion import logistic_prior
from railsusp.estimate.posterior_settings import PosteriorSettings


def test_logistic_prior_is_the_uniform_box_in_logit_coordinates():
    prior = logistic_prior(3)
    torch.manual_seed(0)
    z = prior.sample((20_000,))
    u = torch.sigmoid(z).numpy()
    # uniform on the box: every decile of every coordinate holds a tenth
    counts = np.stack([np.histogram(u[:, j], bins=10, range=(0, 1))[0] for j in range(3)])
    assert np.all(np.abs(counts / 20_000 - 0.1) < 0.01)
    # the standard logistic density, summed over the coordinates
    zz = torch.tensor([[0.0, 1.5, -3.0]])
    expected = float(torch.sum(-zz - 2 * torch.log1p(torch.exp(-zz))))
    assert float(prior.log_prob(zz)) == pytest.approx(expected, rel=1e-6)


def test_reads_the_en14363_statistics_out_of_the_families_files():
    bench = bench_script("posterior_estimators")
    conds = resolve_conditions("straight,curve")
    stored = PosteriorSettings(conds, statistics=("en14363", "third-octave", "wheelset"))
    read = PosteriorSettings(conds)
    cols = bench.read_columns(stored, read)
    assert [stored.summary_names[i] for i in cols] == list(read.summary_names)
    with pytest.raises(SystemExit, match="coherence|cohYQ"):
        bench.read_columns(read, PosteriorSettings(conds, statistics=("en14363", "coherence")))


class _Posterior:
    """sbi's importance-sampling posterior as the bench calls it: draws and log weights."""

    def __init__(self, z, logw):
        self.z, self.logw = torch.as_tensor(z), torch.as_tensor(logw)

    def sample(self, shape, x, method, show_progress_bars):
        assert method == "importance" and shape == (len(self.z),)
        return self.z, self.logw


def test_importance_resampling_follows_the_weights_and_counts_them():
    bench = bench_script("posterior_estimators")
    z = np.linspace(-3, 3, 7)[:, None].repeat(2, axis=1)
    # all the weight on one draw: every resampled draw is it, one effective sample
    logw = np.full(7, -800.0)
    logw[4] = 0.0
    draws, ess = bench.draws_importance(_Posterior(z, logw), np.zeros((2, 5)), 100, 7, seed=1)
    assert ess == pytest.approx(1.0)
    assert np.allclose(draws, 1 / (1 + np.exp(-z[4])))
    # weights 1 : 3 on two draws: a quarter and three quarters of the draws, ESS 1.6
    logw = np.full(7, -np.inf)
    logw[1], logw[5] = 0.0, np.log(3.0)
    draws, ess = bench.draws_importance(_Posterior(z, logw), np.zeros((1, 5)), 400, 7, seed=2)
    assert ess == pytest.approx(1 / (0.25**2 + 0.75**2))
    share = np.mean(np.isclose(draws[:, 0], 1 / (1 + np.exp(-z[5, 0]))))
    assert share == pytest.approx(0.75, abs=1 / 400)


class _Likelihood:
    """A posterior whose potential is the logistic prior times a narrow Gaussian
    likelihood in z: the posterior is that Gaussian to within 0.1 % in its width."""

    def __init__(self, d):
        self.proposal = logistic_prior(d)

    def potential(self, z, x):
        return self.proposal.log_prob(z) - 0.5 * torch.sum(((z - 0.3) / 0.05) ** 2, dim=1)


def test_guided_proposal_keeps_the_samples_of_a_narrow_posterior():
    bench = bench_script("posterior_estimators")
    post = _Likelihood(2)
    guide = (np.array([0.25, 0.35]), np.diag([0.06, 0.04]) ** 2)  # near, not exact
    draws, ess = bench.draws_importance(post, np.zeros((6, 5)), 2000, 4000, seed=3, guide=guide)
    z = np.log(draws) - np.log1p(-draws)
    assert ess > 500  # from the prior alone: about 4000 x 0.05^2 x 2 pi / 4^2, i.e. 4
    assert np.allclose(z.mean(axis=0), 0.3, atol=0.01)
    assert np.allclose(z.std(axis=0), 0.05, rtol=0.1)


@pytest.mark.parametrize("method", ["nle", "nre"])
def test_sbi_importance_posterior_is_the_prior_and_sums_the_sections(method, tmp_path, monkeypatch):
    """What the bench relies on in sbi itself: an importance posterior's proposal is the
    prior, and its potential over k sections is the prior plus the k sections' terms."""
    monkeypatch.chdir(tmp_path)  # anything sbi writes stays here
    bench = bench_script("posterior_estimators")
    rng = np.random.default_rng(0)
    z = rng.logistic(size=(200, 2))
    x = np.c_[z, z[:, :1] ** 2] + 0.3 * rng.normal(size=(200, 3))
    inference, _, _, _ = bench.train_method(method, z, x, 8, 1, seed=0, max_epochs=2)
    post = inference.build_posterior(sample_with="importance")
    zz = torch.tensor([[0.1, -0.2], [1.0, 0.5]])
    assert torch.allclose(post.proposal.log_prob(zz), logistic_prior(2).log_prob(zz))
    xs = torch.as_tensor(x[:3], dtype=torch.float32)
    with torch.no_grad():
        prior = post.proposal.log_prob(zz)
        whole = post.potential(zz, x=xs) - prior
        parts = sum(post.potential(zz, x=xs[i : i + 1]) - prior for i in range(3))
    assert torch.allclose(whole, parts, rtol=1e-4, atol=1e-3)
    assert not (tmp_path / "sbi-logs").exists()
