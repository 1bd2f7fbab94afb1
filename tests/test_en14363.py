"""EN 14363 processing against analytic cases: the Butterworth amplitude response, the
sliding mean of linear and sinusoidal functions of distance, the percentiles of known
distributions."""

import numpy as np
import pytest

from railsusp.en14363 import lowpass, percentiles, section_statistics, sliding_mean


def test_lowpass_amplitude_response_is_the_squared_butterworth():
    """Forwards and backwards: the squared response 1 / (1 + r^8) of a 4th-order
    Butterworth, r the (warped) frequency over the cut-off."""
    fs = 1000.0
    t = np.arange(20_000) / fs
    for f in (2.0, 20.0, 40.0):
        y = lowpass(np.sin(2 * np.pi * f * t), fs, 20.0)
        mid = slice(5000, 15000)  # away from the ends
        gain = np.sqrt(2 * np.mean(y[mid] ** 2))
        # digital Butterworth (bilinear transform): frequencies warped as tan(pi f / fs)
        r = np.tan(np.pi * f / fs) / np.tan(np.pi * 20.0 / fs)
        assert gain == pytest.approx(1 / (1 + r**8), rel=2e-3)
    with pytest.raises(ValueError, match="cut-off"):
        lowpass(t, fs, 600.0)


def test_sliding_mean_keeps_a_linear_function_and_scales_a_sine_by_the_sinc():
    rng = np.random.default_rng(1)
    s = np.cumsum(rng.uniform(0.02, 0.2, 4000))  # varying speed: uneven positions
    lin = 3.0 + 0.5 * s
    inner = (s > s[0] + 1) & (s < s[-1] - 1)
    np.testing.assert_allclose(sliding_mean(lin, s)[inner], lin[inner], rtol=1e-12)
    wavelength = 8.0
    y = sliding_mean(np.sin(2 * np.pi * s / wavelength), s, 2.0)
    x = np.pi * 2.0 / wavelength
    expected = np.sin(x) / x * np.sin(2 * np.pi * s / wavelength)
    # the trapezoidal rule on ~0.1 m steps: error of order (ds / L)^2
    np.testing.assert_allclose(y[inner], expected[inner], atol=2e-3)
    with pytest.raises(ValueError, match="increasing"):
        sliding_mean(lin, s[::-1])


def test_percentiles_of_a_sine_and_of_a_uniform_variable():
    phase = np.linspace(0, 2 * np.pi, 2_000_001)[:-1]
    p = percentiles(5.0 * np.sin(phase))
    # quantile q of A sin(uniform phase): A sin(pi (q - 1/2))
    expected = [5.0 * np.sin(np.pi * (q / 100 - 0.5)) for q in (0.15, 50, 99.85)]
    np.testing.assert_allclose(p, expected, atol=1e-4)
    u = np.random.default_rng(0).uniform(size=2_000_000)
    np.testing.assert_allclose(percentiles(u), [0.0015, 0.5, 0.9985], atol=1e-3)


def test_section_statistics_of_a_steady_force_and_a_short_wave():
    fs, v = 200.0, 20.0  # 72 km/h
    t = np.arange(40_000) / fs  # 200 s: the cut-short window ends are < 0.15 %
    # a 2 m wave (10 Hz at 20 m/s) vanishes in the 2 m mean; the 100 kN level stays
    x = 100.0 + 10.0 * np.sin(2 * np.pi * (v / 2.0) * t)
    st = section_statistics(x, fs, v)
    assert st.p50 == pytest.approx(100.0, abs=0.05)
    assert st.p99_85 - st.p0_15 < 1.0  # of 20 kN peak to peak before
    assert set(st.to_dict()) == {"p0.15", "p50", "p99.85"}


def test_a_section_standing_or_with_a_stop_is_refused_in_one_line():
    """Speed 0 in a section (a stop): "positions must be strictly increasing", a bare
    ValueError from inside the sliding mean (stop 78's hunt). One line naming the speed."""
    from railsusp.errors import RailsuspInputError

    x = np.ones(200)
    v = np.full(200, 15.0)
    assert section_statistics(x, 100.0, v).p50 == pytest.approx(1.0)
    v[50:60] = 0.0
    for speed in (v, 0.0):
        with pytest.raises(RailsuspInputError, match=r"speed 0 m/s in the section: the 2 m "):
            section_statistics(x, 100.0, speed)
