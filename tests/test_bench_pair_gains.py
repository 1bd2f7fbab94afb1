"""bench/pair_gains.py: the gain of a surrogate's parameter difference on the simulator's,
overall and per frequency band, on analytic signals."""

import numpy as np
import pytest

from conftest import bench_script


@pytest.fixture(scope="module")
def bench():
    return bench_script("pair_gains")


def test_a_network_passing_on_half_has_gain_one_half_in_every_band(bench):
    rng = np.random.default_rng(0)
    dy = rng.standard_normal((20, 500))
    s = bench.pair_scores(dy, 0.5 * dy, 0.02)
    assert s["gain"] == pytest.approx(0.5) and s["cosine"] == pytest.approx(1.0)
    assert s["pair_error"] == pytest.approx(0.25)
    assert [b["gain"] for b in s["bands"]] == pytest.approx([0.5] * len(bench.BANDS))
    assert sum(b["share"] for b in s["bands"]) == pytest.approx(1.0)


def test_a_network_that_loses_the_high_frequencies_is_seen_per_band(bench):
    """The difference holds a 0.25 Hz and a 10 Hz sine of equal amplitude; the network
    passes on only the slow one: overall gain 0.5, band gains 1 and 0 where they lie."""
    t = np.arange(1000) * 0.02
    slow, fast = np.sin(2 * np.pi * 0.25 * t), np.sin(2 * np.pi * 10.0 * t)
    dy = np.tile(slow + fast, (3, 1))
    s = bench.pair_scores(dy, np.tile(slow, (3, 1)), 0.02)
    assert s["gain"] == pytest.approx(0.5, abs=1e-3)
    bands = {tuple(b["band_hz"]): b for b in s["bands"]}
    assert bands[(0.0, 0.5)]["gain"] == pytest.approx(1.0, abs=1e-6)
    assert bands[(0.0, 0.5)]["share"] == pytest.approx(0.5, abs=1e-3)
    assert bands[(8.0, None)]["gain"] == pytest.approx(0.0, abs=1e-6)
    assert bands[(1.0, 2.0)]["share"] < 1e-20  # no effect in between
