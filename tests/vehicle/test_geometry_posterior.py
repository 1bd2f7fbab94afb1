"""The true track geometry given a measured one (railsusp.vehicle.geometry_posterior): the
error's PSD, the Wiener mean, and draws whose spread is as large as the mean's real error."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import welch

from railsusp.vehicle.geometry_posterior import geometry_posterior, measurement_error_psd
from railsusp.vehicle.track import COMPONENTS, synthesise
from railsusp.vehicle.track_geometry import with_measurement_error

ACCURACY = 0.5e-3
LAMBDA_MIN = 1.0


@pytest.fixture(scope="module")
def tracks():
    """Three true tracks (FRA class 5, 1.5 km, 0.125 m grid) and their measurements to 0.5 mm."""
    out = []
    for seed in range(3):
        true = synthesise(1500.0, 5, seed, wavelength_min=LAMBDA_MIN)
        measured = with_measurement_error(
            true, ACCURACY, LAMBDA_MIN, np.random.default_rng(100 + seed)
        )
        out.append((true, measured))
    return out


def test_error_psd_integrates_to_the_accuracy_and_matches_the_error_model():
    """∫ S_e dk = accuracy² (the RMS stated), and the PSD of with_measurement_error's error
    (Welch over 40 km of it) agrees within 15 % in the measured band."""
    dx = 0.125
    k = np.linspace(0.0, 0.5 / dx, 100_001)
    assert np.trapezoid(measurement_error_psd(k, ACCURACY, LAMBDA_MIN, dx), k) == pytest.approx(
        ACCURACY**2, rel=1e-6
    )
    zero = synthesise(40_000.0, 5, 0, wavelength_min=LAMBDA_MIN)
    zero = replace(zero, **{c: 0.0 * zero.component(c) for c in COMPONENTS})
    err = with_measurement_error(zero, ACCURACY, LAMBDA_MIN, np.random.default_rng(1))
    kw, psd = welch(err.component("vertical")[0], 1.0 / dx, nperseg=2048)
    band = (kw > 0.02) & (kw < 0.8 / LAMBDA_MIN)
    model = measurement_error_psd(kw[band], ACCURACY, LAMBDA_MIN, dx)
    assert np.median(np.abs(psd[band] / model - 1.0)) < 0.15


def test_error_psd_refuses_a_non_positive_accuracy():
    with pytest.raises(ValueError, match="accuracy_m 0"):
        measurement_error_psd(np.array([0.1]), 0.0, LAMBDA_MIN, 0.125)


def test_wiener_mean_is_closer_to_the_truth_and_the_spread_is_honest(tracks):
    """The conditional mean's error is under the measurement's (0.5 mm; 0.33-0.44 mm, least
    gained in the smaller cross-level and gauge), and the draws' RMS spread about it (what
    the posterior claims) matches that error within 10 % in every component (within 5 % on
    these tracks): an uncertainty neither optimistic nor padded."""
    for true, measured in tracks:
        post = geometry_posterior(measured, ACCURACY, LAMBDA_MIN)
        draws = post.draws(12, np.random.default_rng(5))
        for c in COMPONENTS:
            mean = post.mean.component(c)[0]
            actual = np.std(mean - true.component(c)[0])
            claimed = np.std([d.component(c)[0] - mean for d in draws])
            assert actual < 0.9 * ACCURACY, c
            assert claimed == pytest.approx(actual, rel=0.1), c


def test_draws_have_the_true_geometrys_spectrum_not_the_measured_ones(tracks):
    """At wavelengths of 1.25-2 m the measurement carries 5-30 x the true geometry's power
    (the error dominates); the draws carry within a factor 2.5 of the true power, while the
    measured geometry alone would bring the error in as roughness."""
    true, measured = tracks[0]
    dx = float(np.median(np.diff(true.s)))
    post = geometry_posterior(measured, ACCURACY, LAMBDA_MIN)
    draws = post.draws(16, np.random.default_rng(3))
    c = "alignment"
    k, p_true = welch(true.component(c)[0], 1.0 / dx, nperseg=1024)
    p_meas = welch(measured.component(c)[0], 1.0 / dx, nperseg=1024)[1]
    p_draws = np.mean([welch(d.component(c)[0], 1.0 / dx, nperseg=1024)[1] for d in draws], 0)
    short = (k > 0.5) & (k < 0.8)
    ratio_meas = p_meas[short].sum() / p_true[short].sum()
    ratio_draws = p_draws[short].sum() / p_true[short].sum()
    assert ratio_meas > 5.0
    assert 1 / 2.5 < ratio_draws < 2.5


def test_an_accurate_measurement_is_its_own_mean():
    """Where the error is negligible at every measured wavelength (1 µm against mm), the mean
    is the measurement and the draws do not move from it."""
    true = synthesise(800.0, 5, 4, wavelength_min=LAMBDA_MIN)
    post = geometry_posterior(true, 1e-9, LAMBDA_MIN)
    draw = post.draws(1, np.random.default_rng(0))[0]
    for c in COMPONENTS:
        x = true.component(c)[0]
        assert np.max(np.abs(post.mean.component(c)[0] - x)) < 1e-4 * np.std(x)
        assert np.max(np.abs(draw.component(c)[0] - x)) < 1e-4 * np.std(x)


def test_pure_error_has_a_mean_near_zero():
    """A measurement of perfectly straight track (error alone): the Wiener filter passes
    little of it (the mean's RMS under a third of the error's)."""
    flat = synthesise(1500.0, 5, 0, wavelength_min=LAMBDA_MIN)
    flat = replace(flat, **{c: 0.0 * flat.component(c) for c in COMPONENTS})
    measured = with_measurement_error(flat, ACCURACY, LAMBDA_MIN, np.random.default_rng(2))
    post = geometry_posterior(measured, ACCURACY, LAMBDA_MIN)
    for c in COMPONENTS:
        assert np.std(post.mean.component(c)[0]) < ACCURACY / 3.0, c


def test_draws_refuse_a_negative_count(tracks):
    post = geometry_posterior(tracks[0][1], ACCURACY, LAMBDA_MIN)
    with pytest.raises(ValueError, match="draws -1"):
        post.draws(-1, np.random.default_rng(0))
    assert post.draws(0, np.random.default_rng(0)) == []
