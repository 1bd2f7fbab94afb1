"""bench/refined_coverage.py: the drawn wagons as the pipeline's field truth, and the scoring
of the validator's recovery table."""

import numpy as np
import pandas as pd
import pytest

from conftest import bench_script
from railsusp.config import check_config
from railsusp.params import MAIN_SUSPENSION, ParameterSet, bounds, spec
from railsusp.pipeline import demo_config


@pytest.fixture(scope="module")
def bench():
    return bench_script("refined_coverage")  # it imports its sibling estimate_tracks


def test_drawn_sets_become_the_field_truth_in_display_units(bench):
    row = bench.draw_sets(3, 0)[2]
    truth = bench.truth_display(row)
    assert list(truth) == list(MAIN_SUSPENSION)
    back = ParameterSet(truth, units="display").to_array(MAIN_SUSPENSION)
    assert back == pytest.approx(row, rel=1e-12)
    lo, hi = bounds(MAIN_SUSPENSION)
    assert all(lo + 0.1 * (hi - lo) <= row) and all(row <= hi - 0.1 * (hi - lo))
    base = demo_config()
    cfg = bench.set_config(base, truth, 107, 0.5)
    assert cfg.field.truth == truth and cfg.field.seed == 107 and cfg.field.track_noise_mm == 0.5
    assert cfg.campaign == base.campaign and cfg.estimate == base.estimate  # reused stages


def test_only_identifiable_parameters_are_scored(bench):
    rec = pd.DataFrame(
        {
            "parameter": ["X11", "X12"],
            "truth": [1.3, 12.0],
            "estimate": [1.31, 10.0],
            "interval_low": [1.28, 6.0],
            "interval_high": [1.32, 18.0],
            "interval_width_pct_range": [3.0, 100.0],
            "error_pct_of_range": [0.3, -16.0],
            "truth_in_interval": [True, True],
            "identifiable": [True, False],
        }
    )
    assert bench.score(rec)["parameter"].tolist() == ["X11"]


def test_the_middle80_prior_is_the_draws_own_distribution(bench):
    """``--held-prior middle80``: every main-suspension parameter's prior is the middle 80 %
    of its range, which holds every drawn set and is accepted by the pipeline; the default
    passes none, leaving the estimate section as it was."""
    assert bench.held_prior("table2") == {}
    prior = bench.held_prior("middle80")
    assert list(prior) == list(MAIN_SUSPENSION)
    assert prior["X19"] == pytest.approx([18000.0, 42000.0])
    assert prior["X14"] == pytest.approx([6.0, 14.0])
    sets = bench.draw_sets(12, 0)
    for j, p in enumerate(MAIN_SUSPENSION):
        lo, hi = (v * spec(p).scale for v in prior[p])
        assert np.all((lo <= sets[:, j]) & (sets[:, j] <= hi))
    base = demo_config()
    cfg = bench.set_config(base, bench.truth_display(sets[0]), 100, 0.0, prior)
    assert cfg.estimate.held_prior == prior
    assert cfg.estimate.model_copy(update={"held_prior": {}}) == base.estimate
    check_config(cfg)  # the pipeline takes it
    assert bench.set_config(base, {}, 100, 0.0).estimate == base.estimate


def test_error_over_half_width_on_the_truths_side(bench):
    rows = pd.DataFrame(
        {
            "truth": [1.0, 1.0, 2.0, 3.0],
            "estimate": [1.1, 1.1, 2.0, 2.9],
            "interval_low": [0.8, 1.05, 1.9, 2.8],
            "interval_high": [1.2, 1.3, 2.0, 2.9],
        }
    )
    got = bench.error_over_half_width(rows)
    # the 2nd and 4th (interval clipped at the estimate) do not cover the truth
    assert got.tolist() == pytest.approx([0.1 / 0.3, 0.1 / 0.05, 0.0, np.inf])
