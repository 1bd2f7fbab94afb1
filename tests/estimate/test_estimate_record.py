"""What ``estimate.json`` says was done (railsusp.estimate.result): the number of NSGA-II
seeds behind the seed spread, and the geometry bias taken off a refined point in the route."""

from __future__ import annotations

import json

import numpy as np

from railsusp.estimate import NSGAConfig, estimate_with_seeds
from railsusp.estimate.refine import SIMULATOR_TEXT, Refinement
from test_estimate import PARAMS, AnalyticForces, recording


def _nsga(n_seeds: int):
    rec = recording(10.0 * 16.1 / 14.0, 120.0 * 8.3 / 10.0)
    cfg = NSGAConfig(pop_size=8, n_gen=2, seed=3)
    return estimate_with_seeds(AnalyticForces(), [rec], PARAMS, cfg, n_seeds=n_seeds)


def test_estimate_json_records_how_many_seeds_the_spread_is_over(tmp_path):
    """``--seeds 3`` left no trace of its count in estimate.json: the spread over 2 seeds
    and over 10 read alike (and one seed wrote no spread at all)."""
    for n in (1, 3):
        _nsga(n).save(tmp_path / str(n))
        doc = json.loads((tmp_path / str(n) / "estimate.json").read_text())
        assert doc["seeds"] == n
        assert bool(doc["seed_spread_pct_range"]) == (n > 1)


def test_the_route_says_the_refined_point_is_less_the_geometry_bias():
    """The refined estimate (and the polish) less the first SIMEX step's bias was told in
    the route as the refined point itself."""
    res = _nsga(1)
    x = res.nsga_x
    ref = Refinement(
        parameters=PARAMS,
        start_si=x,
        x_si=x,
        cost_start=1.0,
        cost=0.5,
        n_evaluations=1,
        n_jacobians=1,
        message="",
        standard_error_si=np.zeros(2),
        history_si=x[None],
        geometry_shifts_si=np.array([[1e5, -1e5], [3e5, 1e5]]),
        compared_model=SIMULATOR_TEXT,
    )
    res.refinement = ref
    assert "SIMEX" not in res.route and "then refined" in res.route
    ref.geometry_bias_removed = True
    assert not np.allclose(ref.estimate_si, ref.x_si)  # the estimate is not the refined point
    assert res.route.endswith(", less the track geometry error's bias (first SIMEX step)")
    res.refinement_is_polish = True
    assert "less the track geometry error's bias (first SIMEX step) is a polish" in res.route


def test_the_route_says_the_corrected_points_are_less_the_geometry_bias():
    """Each simulator correction's least squares is biased as NSGA-II's was, and its point
    has the same bias taken off (level_correction); the route said so of NSGA-II's choice
    only, before the corrections (stop 79's estimate hunt)."""
    res = _nsga(1)
    res.corrections = [object(), object()]  # (the route reads their count)
    assert "each corrected point" not in res.route
    res.geometry_bias_removed = True
    assert res.route.endswith("(output space mapping), each corrected point less the same bias")
