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
