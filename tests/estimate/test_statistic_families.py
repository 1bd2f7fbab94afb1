"""Families of statistics of the posterior (railsusp.estimate.statistic_families): the
spectra, coherencies and correlations on analytic signals, the gain model against finite
differences, the settings that choose them, and the same families from a simulation and
from a recording of both wheels of the measured wheelset."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import statistic_families as sf
from railsusp.estimate.posterior_data import simulate_long_cases
from railsusp.estimate.posterior_recordings import recording_summaries
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.posterior_synthetic import gain_covariance
from railsusp.estimate.summaries import section_summary
from railsusp.measured import read_field, synthesise_field
from railsusp.params import ParameterSet

FS = 50.0
SPEED = 60 / 3.6
CONDITION = get_condition("straight").with_changes(lead_in_m=30.0)


def _wheelset(seed: int = 4, n: int = 1000) -> tuple[np.ndarray, ...]:
    """Y, Q, Yp, Qp (kN) of a wheelset with a shared lateral sway at 1.3 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    sway = 3.0 * np.sin(2 * np.pi * 1.3 * t)
    return (
        5 + sway + rng.standard_normal(n),
        100 + 2 * sway + 5 * rng.standard_normal(n),
        -4 - sway + rng.standard_normal(n),
        96 - 2 * sway + 5 * rng.standard_normal(n),
    )


def test_band_rms_of_a_sine_is_its_rms_in_its_third_octave_band():
    t = np.arange(1000) / FS
    x = 3.0 * np.sin(2 * np.pi * 10.7 * t) + 0.5
    out = 10 ** sf.log_band_rms(x, FS, sf.THIRD_OCTAVE_HZ)
    k = next(i for i, (lo, hi) in enumerate(sf.THIRD_OCTAVE_HZ) if lo <= 10.7 < hi)
    assert out[k] == pytest.approx(3.0 / np.sqrt(2), rel=0.02)
    assert np.delete(out, k).max() < 0.01 * out[k]


def test_coherency_of_identical_and_delayed_signals():
    rng = np.random.default_rng(2)
    x = rng.standard_normal(1000)
    re_im = sf.band_coherency(x, 2.5 * x, FS)
    n = len(sf.CROSS_BANDS_HZ)
    assert re_im[:n] == pytest.approx(np.ones(n)) and re_im[n:] == pytest.approx(np.zeros(n))
    t = np.arange(1000) / FS
    tau = 0.05
    c = sf.band_coherency(np.sin(2 * np.pi * 2.2 * t), np.sin(2 * np.pi * 2.2 * (t - tau)), FS)
    k = next(i for i, (lo, hi) in enumerate(sf.CROSS_BANDS_HZ) if lo <= 2.2 < hi)
    z = complex(c[k], c[n + k])
    assert abs(z) == pytest.approx(1.0, abs=1e-3)
    assert np.angle(z) == pytest.approx(-2 * np.pi * 2.2 * tau, abs=0.02)
    # independent noises: small coherency in every band
    assert np.abs(sf.band_coherency(x, rng.standard_normal(1000), FS)).max() < 0.4


def test_cross_spectra_of_a_sway_shared_by_four_channels_and_of_independent_noise():
    """Four channels that are multiples of one sine at 3.4 Hz (the partner's lateral
    force the opposite sign, Q delayed): in the sine's band each channel's RMS is its
    amplitude / sqrt 2, every pair's coherency has magnitude 1 and the phase of the
    channels' delay; the statistics are one to one with the band's Hermitian matrix (16
    per band, 15 bands); independent noises have small coherencies everywhere."""
    t = np.arange(1000) / FS
    tau = 0.03
    s = np.sin(2 * np.pi * 3.4 * t)
    late = np.sin(2 * np.pi * 3.4 * (t - tau))
    amps = np.array([2.0, 5.0, 2.0, 5.0])
    x = np.stack([2 * s + 5, 5 * late + 100, -2 * s - 4, 5 * late + 96])
    out = sf.band_cross_spectra(x, FS)
    names = sf.family_names("cross-spectra")
    assert out.shape == (len(names),) == (15 * 16,) and len(set(names)) == len(names)
    k = next(i for i, (lo, hi) in enumerate(sf.SPECTRAL_BANDS_HZ) if lo <= 3.4 < hi)
    band = out[16 * k : 16 * (k + 1)]
    assert names[16 * k] == "Y_xs_3-4Hz" and names[16 * k + 4] == "xcohYQ_re_3-4Hz"
    assert 10 ** band[:4] == pytest.approx(amps / np.sqrt(2), rel=0.03)
    coh = band[4:10] + 1j * band[10:]
    assert np.abs(coh) == pytest.approx(np.ones(6), abs=1e-3)
    # pairs Y-Q, Y-Yp, Y-Qp, Q-Yp, Q-Qp, Yp-Qp: phase of the second on the first
    lag = -2 * np.pi * 3.4 * tau
    want = np.array([lag, np.pi, lag, np.pi - lag, 0.0, lag - np.pi])
    assert np.angle(coh * np.exp(-1j * want)) == pytest.approx(np.zeros(6), abs=0.03)
    # the other bands hold next to nothing (the sine's leakage, the floor)
    others = np.delete(out.reshape(15, 16)[:, :4], k, axis=0)
    assert np.all(10**others < 0.05 * amps / np.sqrt(2))
    rng = np.random.default_rng(8)
    noise = sf.band_cross_spectra(rng.standard_normal((4, 1000)), FS).reshape(15, 16)
    assert np.abs(noise[:, 4:]).max() < 0.6
    assert np.abs(noise[1:, 4:]).mean() < 0.15


def test_lagged_correlation_of_a_sine():
    t = np.arange(2000) / FS
    x = np.sin(2 * np.pi * 2.5 * t)  # a period of 20 samples
    r = sf.lagged_correlation(x, x, FS, (0.0, 0.2, 0.1, -0.2))
    assert r == pytest.approx([1.0, -1.0, 0.0, -1.0], abs=0.01)


def test_families_parse_in_order_with_the_en14363_summary_always_first():
    assert sf.parse_families("coherence,wheelset") == ("en14363", "wheelset", "coherence")
    assert sf.parse_families("all") == sf.ALL_FAMILIES == sf.FAMILIES[:4]
    assert sf.parse_families("all,cross-spectra") == sf.FAMILIES
    assert sf.parse_families(("en14363",)) == ("en14363",)
    with pytest.raises(
        RailsuspInputError,
        match=r"statistics = spectra: accepted 'all' \(en14363, third-octave, wheelset, "
        r"coherence\) or a comma-separated choice of .*, cross-spectra$",
    ):
        sf.parse_families("spectra")
    with pytest.raises(RailsuspInputError, match=r"statistics = \(none\)"):
        sf.parse_families("")
    assert sf.parse_families("all,en14363") == sf.ALL_FAMILIES
    for bad in (None, 5, ("wheelset", 1)):
        with pytest.raises(RailsuspInputError, match="statistics = .*: accepted 'all'"):
            sf.parse_families(bad)


def test_every_family_has_its_names_and_the_first_is_the_en14363_summary():
    Y, Q, Yp, Qp = _wheelset()
    x = sf.section_statistics(sf.FAMILIES, Y, Q, FS, SPEED, Yp, Qp)
    names = sf.statistic_names(sf.FAMILIES)
    assert x.shape == (len(names),) == (17 + 36 + 31 + 51 + 240,) and np.all(np.isfinite(x))
    assert len(set(names)) == len(names)
    assert np.array_equal(x[:17], section_summary(Y, Q, FS, SPEED))
    wheelset = sf.family_statistics("wheelset", Y, Q, FS, SPEED, Yp, Qp)
    assert np.array_equal(wheelset[:17], section_summary(Yp, Qp, FS, SPEED))  # the partner's
    with pytest.raises(RailsuspInputError, match="'coherence' needs the partner wheel"):
        sf.family_statistics("coherence", Y, Q, FS, SPEED)


def _gain_derivatives(chans, channel_index: int, base=None):
    """(names, finite-difference d statistic / d gain of one channel, the model's);
    ``base``: the statistics of ``chans`` where already computed."""
    fams = sf.FAMILIES
    names = sf.statistic_names(fams)
    if base is None:
        base = sf.section_statistics(fams, *chans[:2], FS, SPEED, *chans[2:])
    index = {n: i for i, n in enumerate(names)}
    h = 1e-4
    moved = [x * (1 + h) if i == channel_index else x for i, x in enumerate(chans)]
    got = (sf.section_statistics(fams, *moved[:2], FS, SPEED, *moved[2:]) - base) / h
    channel = ("Y", "Q", "Yp", "Qp")[channel_index]
    want = np.zeros(len(names))
    for i, name in enumerate(names):
        for src, factor, scale in sf.gain_dependence(name):
            if src == channel:
                want[i] += factor * (sum(w * base[index[n]] for n, w in scale) if scale else 1)
    return np.array(names), got, want


def _swaying(seed: int, n: int = 1000) -> tuple[np.ndarray, ...]:
    """Y, Q, Yp, Qp (kN) of wheels whose Y sway about zero (straight track, no flange
    contact) and whose Q differ by a few kN: the fluctuation dominates the wheelset's
    differences (sumY = Y - Yp, dQ = Q - Qp), not the wheels' levels. Each wheel's Y is +
    towards its own field side, so the wheelset's lateral sway has opposite signs in the
    two."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    sway = 3.0 * np.sin(2 * np.pi * 0.9 * t + seed)
    return (
        sway + 2 * rng.standard_normal(n),
        100 + 4 * sway + 5 * rng.standard_normal(n),
        -(0.5 * sway + 2 * rng.standard_normal(n)),
        97 - 4 * sway + 5 * rng.standard_normal(n),
    )


@pytest.mark.parametrize("wheels", [_wheelset, _swaying], ids=["levels", "sway"])
def test_the_gain_model_matches_finite_differences(wheels):
    """Each channel's gain moved by 1e-4: every statistic's change against gain_dependence.
    Exact, section by section, for one channel's percentiles and band RMS, Y/Q, the
    coherencies and correlations (zero); for the percentiles of the wheelset's differences
    (sumY = Y - Yp, dQ = Q - Qp) the two wheels' terms add up to the percentile itself
    (both gains moved together scale it). One wheel's term is its mean force where the
    percentile falls (the partner's with a minus): over 40 sections the model within 30 %
    of the derivatives' scale (the wheel's level plus the difference's excursion; the
    model's share 1/2 of the excursion assumes equal wheels, and the swaying wheels here
    differ by 2 in sway), both on wheels of opposite-sign levels and on wheels that sway
    about zero, where the wheels' medians alone (this model's first form) fall far short."""
    size = len(sf.statistic_names(sf.FAMILIES))
    got, want = np.zeros((4, size)), np.zeros((4, size))
    for seed in range(40):
        chans = wheels(seed)
        base = sf.section_statistics(sf.FAMILIES, *chans[:2], FS, SPEED, *chans[2:])
        model = []
        for c in range(4):
            names, g, w = _gain_derivatives(chans, c, base)
            combined = np.char.startswith(names, "sumY") | np.char.startswith(names, "dQ")
            assert g[~combined] == pytest.approx(w[~combined], rel=1e-3, abs=1e-4), c
            got[c] += g / 40
            want[c] += w / 40
            model.append(w)
        pct = combined & (np.char.find(names, "band") < 0)
        for first, second in ((0, 2), (1, 3)):  # Y and Yp; Q and Qp
            sel = pct & np.char.startswith(names, ("sumY", "dQ")[first])
            assert (model[first] + model[second])[sel] == pytest.approx(
                base[sel], rel=1e-9, abs=1e-9
            )
    for c in range(4):
        sel = pct & (want[c] != 0)
        scale = np.abs(got[c][sel]).max()
        assert np.all(np.abs(got[c][sel] - want[c][sel]) <= 0.3 * scale), (names[sel], c)


def test_the_band_rms_of_the_sum_and_difference_move_half_with_each_wheel():
    """Two wheels of uncorrelated fluctuations of equal size: the sum's and difference's
    band RMS move by half of each wheel's gain / ln 10, as modelled."""
    rng = np.random.default_rng(9)
    chans = (5 + rng.standard_normal(4000), 100 + 5 * rng.standard_normal(4000),
             -4 + rng.standard_normal(4000), 96 + 5 * rng.standard_normal(4000))  # fmt: skip
    for c in range(4):
        names, got, want = _gain_derivatives(chans, c)
        sel = np.char.startswith(names, "sumY_band") | np.char.startswith(names, "dQ_band")
        sel &= want != 0
        assert sel.sum() == 4 and got[sel] == pytest.approx(want[sel], rel=0.25), c


def test_gain_covariance_of_the_families_leaves_the_coherencies_out():
    names = [f"straight:{n}" for n in sf.statistic_names(sf.FAMILIES)]
    Y, Q, Yp, Qp = _wheelset()
    mean = sf.section_statistics(sf.FAMILIES, Y, Q, FS, SPEED, Yp, Qp)
    g = gain_covariance(names, 0.01)(mean)[0]
    coh = [i for i, n in enumerate(names) if "coh" in n or "corr" in n]
    assert len(coh) == 51 + 180 and np.all(g[coh] == 0.0) and np.all(g[:, coh] == 0.0)
    i = names.index("straight:dQ_p50")
    q, dq = mean[names.index("straight:Q_p50")], mean[i]
    assert g[i, i] == pytest.approx(1e-4 * (q**2 + (q - dq) ** 2))  # the partner's: Q - dQ


def test_settings_choose_families_and_keep_the_hash_of_earlier_estimators():
    plain = PosteriorSettings((CONDITION,))
    assert "statistics" not in plain.to_dict() and not plain.partner
    rich = PosteriorSettings((CONDITION,), statistics=("coherence", "third-octave"))
    assert rich.statistics == ("en14363", "third-octave", "coherence") and rich.partner
    assert PosteriorSettings.from_dict(rich.to_dict()) == rich
    assert len(rich.summary_names) == 17 + 36 + 51
    assert rich.summary_names[17] == "straight:Y_3oct_0.3-0.378Hz"
    with pytest.raises(
        RailsuspInputError, match="sum_y = true conflicts with the statistics family 'wheelset'"
    ):
        PosteriorSettings((CONDITION,), statistics=("wheelset",), sum_y=True)


def test_simulated_families_keep_the_en14363_summary_of_the_same_case():
    """The partner's channels draw their instrument noise after the measured wheel's, so
    adding families leaves the EN 14363 statistics of every case as they were."""
    kw = dict(section_s=9.0, n_train=20, n_check=10)  # (third-octave: at least 8.4 s)
    plain = PosteriorSettings((CONDITION,), **kw)
    rich = PosteriorSettings((CONDITION,), statistics=("all",), **kw)
    u = np.full((2, 10), 0.5)
    u[1, 2] = 0.1
    a = simulate_long_cases(plain, u, 0, "train", 1)
    b = simulate_long_cases(rich, u, 0, "train", 1)
    assert b.shape == (2, 1, len(rich.summary_names)) and np.all(np.isfinite(b))
    assert np.array_equal(a, b[:, :, :17])
    assert not np.allclose(b[0, 0, 17:], b[1, 0, 17:])  # X13 moves the new statistics


def test_a_recording_gives_the_families_and_must_hold_the_partner_wheel(tmp_path):
    """The curve's measured wheel is the outer one, w1R in the left-hand curve: it comes
    first, before its partner w1L; the recording of both wheels keeps the measured wheel's
    channels as a recording of it alone (same seed); a partner's missing Y or Q is refused
    in one line."""
    curve = get_condition("curve")
    truth = ParameterSet.nominal()
    synthesise_field(truth, [curve], tmp_path / "one", duration_s=18.0)
    synthesise_field(truth, [curve], tmp_path / "f", duration_s=18.0, wheelset=True)
    (alone,) = read_field(tmp_path / "one")
    (rec,) = read_field(tmp_path / "f")
    assert alone.wheels == ("w1R",) and rec.wheels == ("w1R", "w1L")
    assert np.array_equal(rec.Y["w1R"], alone.Y["w1R"])
    assert np.array_equal(rec.Q["w1R"], alone.Q["w1R"])
    rich = PosteriorSettings(  # (third-octave: sections of at least 8.4 s)
        (curve,), section_s=9.0, n_train=20, n_check=10, statistics=("all",)
    )
    x, used = recording_summaries(rich, [rec])
    assert x.shape == (2, len(rich.summary_names)) and np.all(np.isfinite(x))
    assert used == {"curve": {"sections": 2, "seconds_left_out": 0.0}}
    with pytest.raises(RailsuspInputError, match="needs wheel w1L as well as w1R"):
        recording_summaries(rich, [alone])
    del rec.Q["w1L"]
    with pytest.raises(RailsuspInputError, match="needs wheel w1L as well as w1R"):
        recording_summaries(rich, [rec])
    sum_y = PosteriorSettings((curve,), section_s=9.0, n_train=20, n_check=10, sum_y=True)
    assert recording_summaries(sum_y, [rec])[0].shape == (2, 20)  # the sum reads only Y
