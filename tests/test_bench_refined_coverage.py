"""bench/refined_coverage.py: the drawn wagons as the pipeline's field truth, and the scoring
of the validator's recovery table."""

import pandas as pd
import pytest

from conftest import BENCH, bench_script
from railsusp.params import MAIN_SUSPENSION, ParameterSet, bounds
from railsusp.pipeline import demo_config


@pytest.fixture(scope="module")
def bench():
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(BENCH))  # it imports its sibling estimate_tracks
        yield bench_script("refined_coverage")


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
