"""The statistics emulator's training with a linear trend and mini-batches (stop 32):
a statistic that one parameter moves by tens of section standard deviations is learnt to
a fraction of a section's scatter, and the members' spread still covers the error that is
left (the likelihood adds that spread to its covariance, so an error outside it makes a
long record's posterior over-confident)."""

import numpy as np
import pytest

from railsusp.estimate.posterior_emulator import StatisticsEmulator, fit, linear_features


def _truth(u: np.ndarray) -> np.ndarray:
    """Two statistics' means: the first falls by ~30 section standard deviations over the
    first parameter's range (X18's first combination falls by about that much), with a
    wave and a second parameter's curvature on it; the second is gentle."""
    steep = -30.0 * u[:, 0] + 3.0 * np.sin(4.0 * u[:, 0]) + 2.0 * u[:, 1] ** 2
    return np.c_[steep, u[:, 1] - u[:, 2]]


@pytest.fixture(scope="module")
def cases():
    rng = np.random.default_rng(0)
    u = rng.random((3000, 3))
    return u, _truth(u) + rng.standard_normal((3000, 2))


@pytest.fixture(scope="module")
def trended(cases):
    return fit(*cases, members=4, hidden=16, seed=0, batch=128, trend=True)


def test_a_steep_statistic_is_learnt_to_a_fraction_of_its_scatter(trended):
    """Held-out points: the steep statistic's mean is within 0.2 of a section's standard
    deviation (rms), and its error squared is on average within the members' spread
    (mean z^2 below 4; 0.7-2.6 over seeds with 4 members). On these 3000 cases the
    full-batch networks of before leave 0.31 rms with a mean z^2 of 15.6: their spread
    missed most of their error. The section's standard deviation (1 here) is learnt from
    out-of-bag residuals that must hold each member's trend: without it they would be
    the trend itself, about ten times too wide."""
    u = np.random.default_rng(1).random((3000, 3))
    mean, _, spread = trended.moments(u)
    err = mean - _truth(u)
    assert np.sqrt(np.mean(err[:, 0] ** 2)) < 0.2
    z2 = err[:, 0] ** 2 / spread[:, 0, 0]
    assert 0.2 < z2.mean() < 4.0
    assert np.sqrt(np.mean(err[:, 1] ** 2)) < 0.12
    np.testing.assert_allclose(np.median(trended.section_sd(u), axis=0), 1.0, rtol=0.15)


def test_mini_batch_training_is_reproducible(cases):
    u, x = cases
    a, b = (fit(u[:300], x[:300], members=2, hidden=4, seed=3, batch=32, trend=True)
            for _ in range(2))  # fmt: skip
    np.testing.assert_array_equal(a.mean(u[:50]), b.mean(u[:50]))
    np.testing.assert_array_equal(a.trends, b.trends)


def test_full_batch_training_is_that_of_every_stored_emulator():
    """The full-batch path (the emulator of all statistics, and every emulator stored
    before stop 32, whose hashes name only settings) gives the weights it gave before
    the trend and mini-batches were added: values from the code of 583e53d."""
    rng = np.random.default_rng(5)
    u = rng.random((200, 2))
    x = np.c_[np.sin(3 * u[:, 0]), u[:, 1] ** 2] + 0.1 * rng.standard_normal((200, 2))
    e = fit(u, x, members=2, hidden=4, seed=0)
    before = (
        [0.9117040412363238, -1.951037568627759, 0.043552062824812186, 1.2809688899802536],
        [-1.0670333060488537, 0.3805059484837267],
        [-3.850409595390617, -0.5214488261916148],
    )
    got = (e.weights[0][0][0].ravel()[:4], e.weights[1][-1][1], e.logvar_coef[:2, 0])
    for a, b in zip(got, before, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-9)


def test_each_member_has_its_own_trend(trended, cases):
    """The trends are fitted on each member's resample (so their sampling error is in the
    members' spread): they differ, and each is near the least-squares line of all cases."""
    u, x = cases
    assert trended.trends.shape == (4, 4, 2)
    assert not np.allclose(trended.trends[0], trended.trends[1])
    y = (x - trended.x_mean) / trended.x_scale
    line = np.linalg.lstsq(linear_features(u), y, rcond=None)[0]
    # a resample's sampling error: 4 standard errors of a slope on 2u - 1 (variance 1/3)
    # of statistics whose scatter is at most 1 in the standardised units
    assert np.abs(trended.trends - line).max() < 4.0 / np.sqrt(len(u) / 3.0)


def test_the_trends_are_saved_and_read_back(trended, tmp_path):
    back = StatisticsEmulator.load(trended.save(tmp_path / "emulator.npz"))
    u = np.random.default_rng(2).random((50, 3))
    for a, b in zip(trended.moments(u), back.moments(u), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(back.trends, trended.trends)


def test_an_emulator_without_trends_reads_back_without(cases, tmp_path):
    """Full-batch networks alone (the emulator of all statistics, and every emulator
    stored before stop 32) keep no trend array, and read back without one."""
    u, x = cases
    plain = fit(u[:400], x[:400], members=2, hidden=4, seed=0)
    assert plain.trends is None
    assert StatisticsEmulator.load(plain.save(tmp_path / "emulator.npz")).trends is None


def _double(emu: StatisticsEmulator, u: np.ndarray) -> np.ndarray:
    """(members, N, D) the networks read in double precision, one by one (the reading of
    before stop 67, and the precision they were trained in)."""
    out = []
    for m, layers in enumerate(emu.weights):
        h = 2.0 * u - 1.0
        for i, (w, b) in enumerate(layers):
            h = h @ w + b
            h = np.tanh(h) if i < len(layers) - 1 else h
        if emu.trends is not None:
            h = h + linear_features(u) @ emu.trends[m]
        out.append(h)
    return np.stack(out) * emu.x_scale + emu.x_mean


def test_single_precision_reading_is_the_double_precision_networks(trended):
    """The networks are read in single precision (four times faster: most of a synthetic-
    likelihood posterior's time). On the steep statistic, which the networks carry ~30
    section standard deviations over the range, the members' means are within 1e-4 of a
    section's standard deviation (here 1) of the networks read in double precision; a
    600 s record's 30 sections narrow the likelihood to 0.18 of it, so the reading moves
    the posterior by under 1e-3 of its width."""
    u = np.random.default_rng(3).random((500, 3))
    got, want = trended.member_means(u), _double(trended, u)
    assert got.dtype == np.float64
    assert np.abs(got - want).max() < 1e-4
    assert not np.array_equal(got, want)  # single precision indeed


def test_product_sized_networks_read_in_single_precision_agree():
    """Ten members of 64 hidden units, the product's emulators (MEMBERS, HIDDEN), with
    weights of twice the spread of their initialisation: within 1e-5 of a statistic's
    spread over the prior (x_scale) everywhere in the unit cube."""
    rng = np.random.default_rng(4)
    d, h, out = 10, 64, 17

    def layer(n_in, n_out):
        return 2.0 * rng.standard_normal((n_in, n_out)) / np.sqrt(n_in), rng.standard_normal(n_out)

    weights = [[layer(d, h), layer(h, h), layer(h, out)] for _ in range(10)]
    emu = StatisticsEmulator(
        weights, rng.standard_normal(out), np.exp(rng.standard_normal(out)),
        np.zeros((1 + d + d * (d + 1) // 2, out)), np.eye(out),
        trends=rng.standard_normal((10, d + 1, out)),
    )  # fmt: skip
    u = rng.random((400, d))
    err = np.abs(emu.member_means(u) - _double(emu, u)) / emu.x_scale
    assert err.max() < 1e-5


def test_members_of_different_layouts_are_read_one_by_one_in_double_precision(trended):
    """An emulator whose members differ in shape (none railsusp fits, but a stored file
    may hold them) cannot be stacked: each network is read on its own, as before."""
    rng = np.random.default_rng(6)
    narrow = [(rng.standard_normal((3, 5)), rng.standard_normal(5)),
              (rng.standard_normal((5, 2)), rng.standard_normal(2))]  # fmt: skip
    emu = StatisticsEmulator(
        [trended.weights[0], narrow], trended.x_mean, trended.x_scale,
        trended.logvar_coef, trended.correlation, trends=trended.trends[:2],
    )  # fmt: skip
    u = rng.random((40, 3))
    np.testing.assert_allclose(emu.member_means(u), _double(emu, u), rtol=1e-13, atol=1e-12)


def test_weights_replaced_are_read_anew(trended):
    """The single-precision stack is made once per set of weight arrays: weights put in
    place of others are read, not the stack of the old ones."""
    emu = StatisticsEmulator(
        list(trended.weights), trended.x_mean, trended.x_scale, trended.logvar_coef,
        trended.correlation, trends=trended.trends,
    )  # fmt: skip
    u = np.random.default_rng(7).random((20, 3))
    before = emu.member_means(u)
    emu.weights = [[(w * 0.5, b) for w, b in layers] for layers in trended.weights]
    after = emu.member_means(u)
    assert not np.allclose(before, after)
    assert np.abs(after - _double(emu, u)).max() < 1e-4
