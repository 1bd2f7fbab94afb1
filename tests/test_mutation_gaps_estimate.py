"""Tests that close gaps found by the mutation review of stop 74: behaviours of the
estimate (the intervals' accepted levels, the identification verdict of an NSGA-II
estimate, the posterior check's verdict on an excessive widening) that no test checked, so
that a mutation of each survived the suite."""

import re
from types import SimpleNamespace

import numpy as np
import pytest

from posterior_fakes import ConfidentEstimator, synthetic_cases
from railsusp.cli.posterior_tables import print_verdict
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import posterior_check
from railsusp.estimate.calibration import ParameterCalibration, SpreadCorrection
from railsusp.estimate.intervals import from_pareto, from_samples, from_standard_errors
from railsusp.estimate.posterior_check import ProductCalibration
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.identification_verdict import (
    RECORDINGS,
    ROUTE,
    identification_verdicts,
)
from railsusp.params import spec
from railsusp.store import read_json


# ---------------------------------------------------------------- 5. intervals' levels
@pytest.mark.parametrize("level", [0.3, 0.49, 1.0])
def test_an_interval_level_outside_one_half_to_below_one_is_refused(level):
    x = np.array([18.0 * spec("X13").scale])
    draws = x + 0.01 * x * np.random.default_rng(0).standard_normal((200, 1))
    message = f"^{re.escape(f'interval level {level}: accepted 0.5 to below 1')}$"
    with pytest.raises(RailsuspInputError, match=message):
        from_samples(["X13"], draws, level=level)
    with pytest.raises(RailsuspInputError, match=message):
        from_standard_errors(["X13"], x, 0.01 * x, level=level)


@pytest.mark.parametrize("level", [0.5, 0.9])
def test_an_interval_level_from_one_half_to_below_one_is_accepted(level):
    x = np.array([18.0 * spec("X13").scale])
    draws = x + 0.01 * x * np.random.default_rng(0).standard_normal((200, 1))
    assert from_samples(["X13"], draws, level=level).level == level
    got = from_standard_errors(["X13"], x, 0.01 * x, level=level)
    assert got.level == level and got["X13"].low_si < x[0] < got["X13"].high_si


# ---------------------------------------------------------------- 6. route_only
def _nsga_estimate() -> dict:
    """An estimate.json of NSGA-II alone: X13's interval the Pareto set's range."""
    chosen = np.array([18.0 * spec("X13").scale])
    pareto = np.array([[17.0 * spec("X13").scale], [19.0 * spec("X13").scale]])
    return {
        "parameters": ["X13"],
        "estimate_display": {"X13": 18.0},
        "intervals": from_pareto(["X13"], pareto, chosen).to_dict(),
    }


def test_an_nsga_estimate_of_a_parameter_the_recordings_hardly_move_is_a_recordings_verdict():
    """NSGA-II's Pareto range alone is the route's reason (ROUTE: refined or through the
    posterior the same recordings may fix it); a small Sobol index besides makes the
    recordings the reason (RECORDINGS), whatever the route."""
    est = _nsga_estimate()
    for max_st in ({}, {"X13": 0.5}, None):
        verdict, why = identification_verdicts(est, max_st)["X13"]
        assert verdict == ROUTE and why.startswith("no confidence interval: the NSGA-II")
    verdict, why = identification_verdicts(est, {"X13": 0.01})["X13"]
    assert verdict == RECORDINGS
    assert why.startswith("no confidence interval") and "largest Sobol ST 0.01 < 0.1" in why


# ---------------------------------------------------------------- 9. calibrate's record
def test_the_stored_check_fails_an_excessive_widening_whose_coverage_passes(tmp_path, monkeypatch):
    """calibration.json's ``passed`` is False where the corrected coverage passes but the
    widening exceeds its bound: the record says what the estimator's verdict says."""
    monkeypatch.setattr(posterior_check, "cached_cases", synthetic_cases)
    cond = get_condition("straight").with_changes(lead_in_m=30.0)
    s = PosteriorSettings(
        (cond,), parameters=("X13",), section_s=3.0, n_train=150, n_check=300,
        n_calibration=300, samples=400, hidden_features=20, num_transforms=2,
    )  # fmt: skip
    s = PosteriorSettings.from_dict({**s.to_dict(), "product_sections": []})
    correction, after, products = posterior_check.calibrate(
        ConfidentEstimator(s, spread=0.12), tmp_path
    )
    assert correction.excessive == ["X13"] and correction.factors[0] > 2.0
    (c,) = after
    assert c.passed and products == []
    record = read_json(tmp_path / "calibration.json")
    assert record["parameters"][0]["passed"] is True
    assert record["excessive_correction"] == ["X13"]
    assert record["passed"] is False


# ---------------------------------------------------------------- 10. ProductCalibration
def _product(factor: float, passed: bool = True) -> ProductCalibration:
    return ProductCalibration(
        2,
        SpreadCorrection(("X13",), (factor,), 40),
        (ParameterCalibration("X13", 40, 0.9, 0.5, 0.5, passed),),
    )


def test_a_fused_check_widened_beyond_its_bound_fails_and_is_named(tmp_path, capsys):
    """A fused check of 2 sections whose coverage passed after a widening of 2.6 times
    (the bound: 2) failed; the closing line names its number of sections."""
    assert _product(1.5).passed is True
    assert _product(2.6).passed is False
    assert _product(1.5, passed=False).passed is False
    est = SimpleNamespace(calibrated=True, correction=None, products=[_product(2.6)])
    print_verdict(est, tmp_path)
    said = " ".join(capsys.readouterr().err.split())
    assert "passed its one-section coverage check, but FAILED those of 2 sections" in said
    est = SimpleNamespace(calibrated=True, correction=None, products=[_product(1.5)])
    print_verdict(est, tmp_path)
    out = capsys.readouterr()
    assert "coverage check passed" in " ".join(out.out.split()) and "FAILED" not in out.err
