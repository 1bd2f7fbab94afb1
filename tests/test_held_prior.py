"""The user's prior for the main-suspension parameters an estimate holds at nominal
(railsusp.estimate.config.HeldPrior, ``[estimate] held_prior``) and the second moment of
the error they cause (railsusp.estimate.refine_intervals): validation with one-line errors,
analytic moments, a Monte Carlo check of the linear error's second moment."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.estimate.config import HeldPrior
from railsusp.estimate.refine_intervals import (
    held_assumptions,
    held_error_variance,
    held_moments,
    held_values,
)
from railsusp.params import MAIN_SUSPENSION, ParameterSet, bounds, spec
from railsusp.pipeline import PipelineConfig, load_config
from railsusp.pipeline_inputs import stage_section

X19_NOMINAL = 30000.0  # kN/m, Table 2 range 15000-45000


def test_a_prior_is_read_in_display_units_and_held_in_si():
    p = HeldPrior.from_display({"X19": [20000, 40000], "primary_vertical_stiffness": (100, 200)})
    assert p.ranges_si == {"X19": (20e6, 40e6), "X15": (100e6, 200e6)}
    assert p.range_si("X20") == spec("X20").bounds  # no prior: Table 2's range
    assert p.given("X19") and not p.given("X20")
    assert p.to_display() == {"X19": [20000.0, 40000.0], "X15": [100.0, 200.0]}
    assert p.unused(("X13", "X15")) == ["X15"]


@pytest.mark.parametrize(
    ("ranges", "needle"),
    [
        ({"X99": [1, 2]}, "estimate.held_prior.X99: unknown parameter; accepted the main"),
        ({"X3": [100, 110]}, "estimate.held_prior.X3: X3 is fixed"),
        ({"X19": [40000, 20000]}, "low must be below high; accepted [low, high] with 15000 <="),
        ({"X19": [30000, 30000]}, "low must be below high"),
        (
            {"X19": [10000, 20000]},
            "reaches outside X19's Table 2 range; accepted [low, high] "
            "with 15000 <= low < high <= 45000 kN/m",
        ),
        ({"X14": [6, 16]}, "X14 = [6, 16] MN/m reaches outside"),
        ({"X19": [1, 2, 3]}, "estimate.held_prior.X19 = [1, 2, 3]: accepted [low, high]"),
        ({"X19": 20000}, "estimate.held_prior.X19 = 20000: accepted"),
        ({"X19": "20000-40000"}, "accepted [low, high]"),
        ({"X19": [True, 2]}, "accepted [low, high]"),
        ({"X19": [float("nan"), 40000]}, "accepted [low, high]"),
        ({"X19": [20000, 40000], "x19": [20000, 40000]}, "X19 is given twice"),
    ],
)
def test_bad_priors_are_refused_in_one_line_naming_the_field(ranges, needle):
    with pytest.raises(RailsuspInputError) as info:
        HeldPrior.from_display(ranges)
    assert needle in str(info.value)
    assert "\n" not in str(info.value)


BASE = """
name = "t"
conditions = [{base="straight", name="short", duration_s=1.0, n_steps=50, lead_in_m=20.0}]
[field]
truth = { X13 = 16.1 }
with_track = true
[estimate]
refine = true
"""


def _write(tmp_path, text: str):
    p = tmp_path / "c.toml"
    p.write_text(text)
    return p


def test_the_configuration_takes_a_prior_and_refuses_a_bad_one_before_any_stage(tmp_path):
    cfg = load_config(_write(tmp_path, BASE + "held_prior = {X19 = [20000, 40000]}\n"))
    assert cfg.estimate.held_prior == {"X19": [20000, 40000]}
    for text, needle in [
        ("held_prior = {X19 = [20000, 50000]}\n", "estimate.held_prior.X19 = [20000, 50000]"),
        (
            "held_prior = {X19 = [true, 40000]}\n",
            "estimate.held_prior.X19 = [True, 40000]: accepted [low, high] with 15000",
        ),
        ("held_prior = {X19 = 20000}\n", "estimate.held_prior.X19 = 20000"),
    ]:
        with pytest.raises(RailsuspInputError) as info:
            load_config(_write(tmp_path, BASE + text))
        assert needle in str(info.value) and "\n" not in str(info.value)
    alone = BASE.replace("refine = true", "refine = false")
    with pytest.raises(RailsuspInputError, match="used by the refinement's intervals only"):
        load_config(_write(tmp_path, alone + "held_prior = {X19 = [20000, 40000]}\n"))
    polish = BASE + 'statistic = "aligned"\n'
    with pytest.raises(RailsuspInputError, match='held_prior with estimate.statistic "aligned"'):
        load_config(_write(tmp_path, polish + "held_prior = {X19 = [20000, 40000]}\n"))
    out = tmp_path / "run"
    bad = _write(tmp_path, BASE + "held_prior = {X9 = [0.9, 1.1]}\n")
    result = CliRunner().invoke(app, ["run", str(bad), "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "estimate.held_prior.X9: X9 is fixed" in result.output
    assert not out.exists()


def test_no_prior_leaves_the_estimate_stage_hash_as_before():
    """Runs made before ``held_prior`` existed stay up to date; a prior re-runs the stage."""
    plain = PipelineConfig()
    assert "held_prior" not in stage_section(plain, "estimate")
    with_prior = PipelineConfig(estimate={"refine": True, "held_prior": {"X19": [2e4, 4e4]}})
    assert stage_section(with_prior, "estimate")["held_prior"] == {"X19": [2e4, 4e4]}
    # since stop 78 such a parameter is held at its range's centre: a run made before, which
    # held it at nominal, estimates again; one without a prior does not
    assert stage_section(with_prior, "estimate")["held_prior_held_at"] == "centre of the range"
    assert "held_prior_held_at" not in stage_section(plain, "estimate")


def test_every_nominal_is_the_centre_of_its_table_2_range_so_the_default_has_no_offset():
    """Table 2 is nominal ± 50 %: holding at nominal with each held parameter uniform over
    its whole range, the second moment about nominal is the variance range²/12 (1/12 in
    unit coordinates) and the offset is zero: the default's term is unchanged."""
    var, offset = held_moments(MAIN_SUSPENSION, held_values(MAIN_SUSPENSION))
    assert var == pytest.approx(np.full(10, 1 / 12), rel=1e-12)
    assert offset == pytest.approx(np.zeros(10), abs=1e-12)


def test_moments_of_a_prior_about_the_value_held():
    held = ("X19", "X20")
    at = held_values(held)  # nominal: 30000 kN/m, 1000 MN/m
    # centred on nominal, two thirds of the range: variance (2/3)²/12, no offset
    var, off = held_moments(held, at, HeldPrior.from_display({"X19": [20000, 40000]}))
    assert var == pytest.approx([(2 / 3) ** 2 / 12, 1 / 12]) and off == pytest.approx([0, 0])
    # the upper half: variance (1/2)²/12, offset a quarter of the range
    var, off = held_moments(held, at, HeldPrior.from_display({"X19": [30000, 45000]}))
    assert var == pytest.approx([0.5**2 / 12, 1 / 12]) and off == pytest.approx([0.25, 0])
    # nominal outside the user's range: held at nominal all the same, the offset says how far
    var, off = held_moments(held, at, HeldPrior.from_display({"X20": [500, 700]}))
    assert var == pytest.approx([1 / 12, 0.2**2 / 12]) and off == pytest.approx([0, -0.4])
    # held at another value (a simulator base): the offset is from that value
    base = ParameterSet({"X19": 21000.0}, units="display")
    var, off = held_moments(held, held_values(held, base))
    assert off == pytest.approx([0.3, 0.0])


def test_second_moment_of_the_linear_error_analytic_and_by_monte_carlo():
    r = np.array([[1.0, 2.0], [0.5, -1.0]])
    var = np.array([1 / 12, 1 / 27])
    off = np.array([0.25, 0.1])
    got = held_error_variance(r, var, off)
    # Σ R² var + (R m)²: the offsets add coherently, and in the second row they cancel
    expected = [1 / 12 + 4 / 27 + (0.25 + 0.2) ** 2, 0.25 / 12 + 1 / 27 + (0.125 - 0.1) ** 2]
    assert got == pytest.approx(expected, rel=1e-12)
    naive = (r**2) @ (var + off**2)  # per-parameter squares: wrong where offsets mix
    assert not np.allclose(got, naive)
    assert held_error_variance(r, var, np.zeros(2)) == pytest.approx((r**2) @ var)
    # δ uniform with those moments: a = m - w/2, b = m + w/2 with w = sqrt(12 var)
    rng = np.random.default_rng(0)
    w = np.sqrt(12 * var)
    delta = off + (rng.random((400_000, 2)) - 0.5) * w
    mc = ((delta @ r.T) ** 2).mean(axis=0)
    assert mc == pytest.approx(got, rel=0.01)


def test_the_assumptions_listed_for_the_report():
    prior = HeldPrior.from_display({"X19": [20000, 40000], "X13": [10, 12]})
    got = held_assumptions(("X13", "X14", "X18"), prior)
    assert list(got) == [p for p in MAIN_SUSPENSION if p not in ("X13", "X14", "X18")]
    assert got["X19"] == {
        "held_at_display": pytest.approx(X19_NOMINAL),
        "low_display": pytest.approx(20000.0),
        "high_display": pytest.approx(40000.0),
        "unit": "kN/m",
        "range": "prior",
    }
    lo, hi = (spec("X20").to_display(v) for v in spec("X20").bounds)
    assert got["X20"]["range"] == "Table 2" and got["X20"]["low_display"] == pytest.approx(lo)
    assert got["X20"]["high_display"] == pytest.approx(hi)
    assert bounds(["X20"])[0][0] == pytest.approx(500e6)


def test_a_parameter_with_a_prior_is_held_at_its_centre_by_the_simulator():
    """The reference simulator of the corrections and the refinement holds a parameter the
    user gave a range for, and that is not estimated, at the range's centre (nominal for
    the others); an estimated one, no prior, or a reference model that is not the
    simulator leave the simulator as it was and hold nothing off nominal."""
    from railsusp.estimate import SimulatorForces
    from railsusp.estimate.route import held_simulator

    prior = HeldPrior.from_display({"X19": [15000, 25000], "X13": [12, 16]})
    assert prior.held_at_si(("X13", "X14")) == {"X19": pytest.approx(20e6)}
    given = SimulatorForces(("X13", "X14"), "w1L", wagon="tare")
    sim, held = held_simulator(given, prior, ("X13", "X14"))
    assert held == {"X19": pytest.approx(20e6)}
    assert (sim.parameters, sim.wheel, sim.wagon) == (("X13", "X14"), "w1L", "tare")
    assert sim.base["X19"] == pytest.approx(20e6)
    assert all(sim.base[p] == ParameterSet.nominal()[p] for p in MAIN_SUSPENSION if p != "X19")
    default, held = held_simulator(None, prior, ("X13", "X14"))
    assert isinstance(default, SimulatorForces) and default.base["X19"] == pytest.approx(20e6)
    assert held_simulator(given, prior, ("X13", "X19")) == (given, {})
    assert held_simulator(given, None, ("X13", "X14")) == (given, {})
    other = object()
    assert held_simulator(other, prior, ("X13", "X14")) == (other, {})


def test_the_refined_point_is_held_where_its_interval_centres_the_prior(tmp_path):
    """A refinement with a prior for X19 off nominal (15-25 MN/m, nominal 30): the route
    holds X19 at 20 MN/m, so the interval's held part has no offset and its error
    quantiles are about symmetric, and estimate.json says where X19 was held; the summary
    and the validation read it. Holding it at nominal, the interval took the offset and
    the point did not: its error quantiles were lopsided (the point could lie beside its
    own interval, X14 = 10.13 MN/m with 6.06-7.79 at stop 77)."""
    from railsusp.conditions import get_condition
    from railsusp.estimate import NSGAConfig, SimulatorForces
    from railsusp.estimate.route import EstimateRoute
    from railsusp.measured import read_field, synthesise_field

    cond = get_condition("curve", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    truth = ParameterSet({"X13": 16.1, "X14": 8.3, "X19": 20000.0}, units="display")
    recs = read_field(synthesise_field(truth, [cond], tmp_path / "f", with_track=True))
    params = ("X13", "X14")
    route = EstimateRoute(
        nsga=NSGAConfig(pop_size=4, n_gen=1, seed=1), seeds=1, geometry_draws=0,
        remove_geometry_bias=False, simulator_corrections=0, refine=True,
        refine_evaluations=2, refine_screen=0, refine_starts=1,
        held_prior=HeldPrior.from_display({"X19": [15000, 25000]}),
    )  # fmt: skip
    res = route.run(SimulatorForces(params), recs, params)
    assert res.held_at_si == {"X19": pytest.approx(20e6)}
    iv = res.intervals()
    assumed = iv.details["held_parameters_assumed"]["X19"]
    assert assumed["held_at_display"] == pytest.approx(20000.0) and assumed["range"] == "prior"
    for p in params:
        a, b = iv.details["error_quantiles_pct_range"][p]
        assert abs(a + b) < 0.1 * (b - a), (p, a, b)  # no offset: about symmetric
        assert iv[p].contains(iv[p].value_si)
    res.save(tmp_path / "estimate")
    doc = json.loads((tmp_path / "estimate" / "estimate.json").read_text())
    assert doc["held_at_display"] == {"X19": pytest.approx(20000.0)}


def test_nsga_ii_on_the_simulator_holds_them_at_the_centre_too(monkeypatch):
    """``railsusp estimate --simulator --refine --held-prior``: NSGA-II's force model is the
    simulator, and it held X19 at nominal while the refinement held it at the centre (its
    Pareto set, choice and log fitted at 30000 kN/m; the review of stop 78). A surrogate
    as the model is left as it is."""
    import railsusp.estimate.route as route_module
    from railsusp.estimate import NSGAConfig, SimulatorForces
    from railsusp.estimate.route import EstimateRoute

    seen = []

    def captured(model, *args, **kwargs):
        seen.append(model)
        raise RuntimeError("captured")

    monkeypatch.setattr(route_module, "estimate_with_seeds", captured)
    monkeypatch.setattr(EstimateRoute, "check", lambda self, recordings, model: None)
    route = EstimateRoute(
        nsga=NSGAConfig(pop_size=4, n_gen=1), seeds=1, geometry_draws=0,
        remove_geometry_bias=False, simulator_corrections=0, refine=True,
        refine_evaluations=2, refine_screen=0, refine_starts=1,
        held_prior=HeldPrior.from_display({"X19": [15000, 25000]}),
    )  # fmt: skip
    surrogate = object()
    for model in (SimulatorForces(("X13",), wagon="tare"), surrogate):
        with pytest.raises(RuntimeError, match="captured"):
            route.run(model, [], ("X13",))  # type: ignore[arg-type]
    assert seen[0].base["X19"] == pytest.approx(20e6) and seen[0].wagon == "tare"
    assert seen[1] is surrogate


@pytest.mark.parametrize(
    ("held", "needle"),
    [
        (["X19"], "held_at_display = ['X19']: accepted an object {symbol: value}"),
        ({"X19": "twenty"}, "held_at_display.X19 = 'twenty': accepted"),
        ({"X13": 16.0}, "held_at_display.X13 = 16.0: accepted"),  # estimated
        ({"X19": 90000.0}, "held_at_display.X19 = 90000.0: accepted"),  # beyond Table 2
        ({"X9": 1.0}, "held_at_display.X9 = 1.0: accepted"),  # not main suspension
    ],
)
def test_a_damaged_held_at_is_refused_in_one_line_by_the_summary_and_validate(
    tmp_path, held, needle
):
    """estimate.json's held_at_display, read by the summary and the validation: a hand-edited
    or damaged one gave an AttributeError's, ValueError's or TypeError's traceback."""
    from railsusp import summary
    from railsusp.estimate.config import held_at_of
    from railsusp.validation_inputs import check_estimate_fields

    doc = {
        "parameters": ["X13"], "estimate_display": {"X13": 16.0}, "held_at_display": held,
        "config": {"statistic": "mean"}, "measured": "field",
    }  # fmt: skip
    assert held_at_of({**doc, "held_at_display": {"X19": 20000}}, "f") == {"X19": 20000.0}
    path = tmp_path / "estimate.json"
    path.write_text(json.dumps(doc))
    for read in (lambda: summary.read_estimate(path), lambda: check_estimate_fields(doc, path)):
        with pytest.raises(RailsuspInputError) as err:
            read()
        assert needle in str(err.value) and "\n" not in str(err.value)
        assert str(err.value).startswith(str(path))
