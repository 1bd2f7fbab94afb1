"""bench/refined_error_parts.py: the per-parameter summary of the error's parts (slopes of
the error on the linear held part and the noise part, what they leave, the noise part over
each standard error)."""

import numpy as np
import pandas as pd
import pytest

from conftest import bench_script


def test_the_summary_recovers_the_parts_slopes_and_the_standard_errors_scale():
    bench = bench_script("refined_error_parts")
    rng = np.random.default_rng(0)
    n = 40
    linear, noise = rng.standard_normal(n), 0.3 * rng.standard_normal(n)
    rows = pd.DataFrame(
        {
            "parameter": ["X11"] * n,
            "error": 0.9 * linear + noise,
            "linear": linear,
            "stepped": linear,
            "noise": noise,
            "pooled_se": np.full(n, 0.6),  # twice the noise part's spread
            "per_channel_se": np.full(n, 0.3),
        }
    )
    got = bench.summary(rows).loc["X11"]
    assert got["slope_linear"] == pytest.approx(0.9) and got["slope_noise"] == pytest.approx(1.0)
    assert got["rms_left"] == pytest.approx(0.1 * np.sqrt(np.mean(linear**2)))
    rms_noise = np.sqrt(np.mean(noise**2))
    assert got["noise_over_pooled"] == pytest.approx(rms_noise / 0.6)
    assert got["noise_over_per_channel"] == pytest.approx(rms_noise / 0.3)
    assert got["not_held_over_per_channel"] == pytest.approx(
        np.sqrt(np.mean((noise - 0.1 * linear) ** 2)) / 0.3
    )


def test_coverage_counts_errors_within_each_half_width():
    bench = bench_script("refined_error_parts")
    rows = pd.DataFrame(
        {
            "error": [0.5, -1.5, 0.2, 3.0],
            "half_table2_pooled_normal": [1.0, 1.0, 1.0, 1.0],
            "half_middle80_channel_quantiles": [0.4, 2.0, 0.1, 3.0],
        }
    )
    got = bench.coverage(rows).set_index("prior")
    assert got.loc["table2", "covered"] == 2 and got.loc["table2", "cases"] == 4
    assert got.loc["table2", "noise_standard_error"] == "pooled"
    assert got.loc["middle80", "quantile"] == "quantiles"
    assert got.loc["middle80", "covered"] == 2  # 0.75 and 1.0 in, 1.25 and 2 out
    assert got.loc["table2", "error_over_half_width_p90"] == pytest.approx(
        np.quantile([0.5, 1.5, 0.2, 3.0], 0.9)
    )


def test_half_widths_of_one_uniform_held_part_alone():
    """No noise and one held parameter: the normal half-width is 1.645 of the uniform's
    standard deviation, the quantile one 0.9 of its half-range; the middle 80 % prior
    scales both by 0.8."""
    bench = bench_script("refined_error_parts")
    got = bench.half_widths(np.array([[1.0]]), np.zeros(1), np.zeros(1))
    assert got["half_table2_pooled_normal"] == pytest.approx(1.645 / np.sqrt(12))
    assert got["half_table2_channel_quantiles"] == pytest.approx(0.45, abs=0.003)
    assert got["half_middle80_channel_quantiles"] == pytest.approx(0.36, abs=0.003)
