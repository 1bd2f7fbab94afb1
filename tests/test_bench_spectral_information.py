"""bench/spectral_information.py: the Whittle information of a record's means and
cross-spectra, on cases whose information is known in closed form."""

import numpy as np
import pytest

from conftest import bench_script


@pytest.fixture(scope="module")
def bench():
    return bench_script("spectral_information")


def _hermitian(rng, n, c):
    a = rng.standard_normal((n, c, c)) + 1j * rng.standard_normal((n, c, c))
    return a + np.swapaxes(a.conj(), -1, -2)


def test_features_dot_products_are_the_whittle_bilinear_form(bench):
    rng = np.random.default_rng(0)
    a, b = _hermitian(rng, 5, 3), _hermitian(rng, 5, 3)
    m = rng.standard_normal((5, 3, 3)) + 1j * rng.standard_normal((5, 3, 3))
    s = m @ np.swapaxes(m.conj(), -1, -2) + np.eye(3)
    fa, fb = bench.hermitian_features(a), bench.hermitian_features(b)
    assert np.sum(fa * fb, axis=-1) == pytest.approx(np.trace(a @ b, axis1=1, axis2=2).real)
    n_b = np.array([3.0, 1.0, 7.0, 2.0, 5.0])
    si = np.linalg.inv(s)
    expected = np.sum(n_b * np.trace(si @ a @ si @ b, axis1=1, axis2=2).real)
    got = bench.whitened_features(a, s, n_b) @ bench.whitened_features(b, s, n_b)
    assert got == pytest.approx(expected, rel=1e-10)


def test_band_edges_and_a_frequency_on_an_edge(bench):
    edges = bench.band_edges(0.1, 15.0, 0.1)
    assert len(edges) == 150 and edges[0] == 0.1 and edges[-1] == 15.0
    # the last band reaches fmax, no sliver: 0.1-0.35-0.6-1.0
    assert bench.band_edges(0.1, 1.0, 0.25) == pytest.approx([0.1, 0.35, 0.6, 1.0])
    x = np.random.default_rng(1).standard_normal((2, 1000))
    # 20 s at 50 Hz in 10 s segments: a Fourier frequency in every 0.1 Hz band, none lost
    # at an edge
    means, (spec,) = bench.section_spectra(x, 50.0, [edges], segments=2)
    assert means.shape == (2,)
    assert spec.shape == (149, 2, 2) and np.all(np.isfinite(spec))
    with pytest.raises(ValueError, match="no Fourier frequency"):
        bench.section_spectra(x, 50.0, [np.array([0.11, 0.14])], segments=2)


def _white_noise_case(bench, rng, covariance="whittle"):
    """One channel of white noise of standard deviation exp(theta) (theta = 0): pairs at
    theta +- delta on common noise, sections at theta; bands 0.1-15 Hz of 0.5 Hz."""
    fs, n, k, delta = 50.0, 1000, 60, 0.05
    edges = bench.band_edges(0.1, 15.0, 0.5)
    noise = rng.standard_normal((k, 1, n))
    md, sd = [], []
    for e in noise:
        (mp, (sp,)), (mm, (sm,)) = (
            bench.section_spectra(np.exp(s * delta) * e, fs, [edges]) for s in (1, -1)
        )
        md.append((mp - mm) / (2 * delta))
        sd.append((sp - sm) / (2 * delta))
    cov = [bench.section_spectra(x, fs, [edges]) for x in rng.standard_normal((300, 1, n))]
    info = bench.condition_information(
        np.array(md)[None],
        np.array(sd)[None],
        np.array([c[0] for c in cov]),
        np.array([c[1][0] for c in cov]),
        edges=edges,
        channels=(0,),
        seconds=600.0,
        section_s=n / fs,
        covariance=covariance,
    )
    return info, edges


def test_information_about_a_white_noise_scale_is_whittles_and_the_gain_takes_it(bench):
    """S = exp(2 theta) S0: tr(S^-1 dS)^2 = 4 per Fourier ordinate, (15 - 0.1) x 600 of
    them in the band over 600 s, and the mean carries nothing. A channel gain scales S the
    same way (dS/dg = 2 S), so with the gain unknown only the gain prior's 1 / 0.01^2 is
    left: I (1e4) / (I + 1e4)."""
    info, _ = _white_noise_case(bench, np.random.default_rng(2))
    exact = 4.0 * (15.0 - 0.1) * 600.0
    assert info["gains_known"][0, 0] == pytest.approx(exact, rel=0.03)
    i = info["gains_known"][0, 0]
    assert info["unbiased"][0, 0] == pytest.approx(i * 1e4 / (i + 1e4), rel=0.03)
    assert info["split"][0, 0] == pytest.approx(info["unbiased"][0, 0], rel=0.05)


def test_the_sections_own_covariance_reads_the_same_information_from_white_noise(bench):
    """The band spectra read as statistics with the sections' covariance: for white noise
    the band powers are sufficient for its scale, so they carry Whittle's information
    (within 5 %) when the section's Welch segments overlap by half; a single Hann-tapered
    periodogram of the section would carry about 55 % of it."""
    info, _ = _white_noise_case(bench, np.random.default_rng(5), covariance="sections")
    exact = 4.0 * (15.0 - 0.1) * 600.0
    assert info["gains_known"][0, 0] == pytest.approx(exact, rel=0.05)
    with pytest.raises(ValueError, match="covariance 'gaussian'"):
        _white_noise_case(bench, np.random.default_rng(5), covariance="gaussian")


def test_a_parameter_without_effect_gets_no_information_and_the_null_test_none(bench):
    """Pairs whose + and - runs differ only by fresh noise (no effect): the plug-in
    |mean feature|^2 is biased up by the features' noise, b = tr(Cov f) / K; the U-statistic
    is 0 on average, with a standard deviation of about b sqrt(2 / D) for D features. Five
    such cases: every one within 4 of those, and so is the null test (random signs)."""
    rng = np.random.default_rng(4)
    fs, n, k = 50.0, 1000, 60
    edges = bench.band_edges(0.1, 15.0, 0.5)
    kw = dict(edges=edges, channels=(0, 1), seconds=600.0, section_s=n / fs)
    cov = [bench.section_spectra(x, fs, [edges]) for x in rng.standard_normal((300, 2, n))]
    mc, sc = np.array([c[0] for c in cov]), np.array([c[1][0] for c in cov])
    root_m = bench.inverse_sqrt(np.cov(mc.T) * (n / fs) / 600.0).real
    for case in range(5):
        pairs = [[bench.section_spectra(x, fs, [edges]) for x in rng.standard_normal((2, 2, n))]
                 for _ in range(k)]  # fmt: skip
        md = np.array([(p[0][0] - p[1][0]) / 0.1 for p in pairs])[None]
        sd = np.array([(p[0][1][0] - p[1][1][0]) / 0.1 for p in pairs])[None]
        feats = np.concatenate(
            [md @ root_m, bench.whitened_features(sd, sc.mean(axis=0), np.diff(edges) * 600.0)],
            axis=-1,
        )
        bias = np.sum(feats.var(axis=1)) / k
        sigma = bias * np.sqrt(2.0 / feats.shape[-1])
        info = bench.condition_information(md, sd, mc, sc, **kw)
        plug_in = np.sum(feats.mean(axis=1) ** 2)
        assert plug_in == pytest.approx(bias, rel=0.3)  # the plug-in is all bias here
        assert abs(info["gains_known"][0, 0]) < 4 * sigma < 0.6 * bias
        null = bench.condition_information(md, sd, mc, sc, **kw, rng=np.random.default_rng(case))
        assert abs(null["gains_known"][0, 0]) < 4 * sigma
