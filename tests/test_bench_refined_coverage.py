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


def test_the_lower40_prior_is_off_nominal_and_its_sets_are_drawn_in_it(bench):
    """``--held-prior lower40``: 10-50 % of every range, up to nominal (the range's centre),
    centred 20 % of the range below it; the sets are the middle-80 draws' uniform numbers
    mapped into it, so every drawn value lies in its prior, and the pipeline accepts the
    prior (held at its centre)."""
    prior = bench.held_prior("lower40")
    assert prior["X19"] == pytest.approx([18000.0, 30000.0])
    assert prior["X14"] == pytest.approx([6.0, 10.0])
    sets = bench.drawn_sets(12, 0, "lower40")
    assert np.array_equal(bench.drawn_sets(12, 0, "middle80"), bench.draw_sets(12, 0))
    for j, p in enumerate(MAIN_SUSPENSION):
        lo, hi = (v * spec(p).scale for v in prior[p])
        assert np.all((lo <= sets[:, j]) & (sets[:, j] <= hi)) and hi <= spec(p).nominal * (
            1 + 1e-12
        )
    assert sets[:, 0].std() > 0.05 * (prior["X11"][1] - prior["X11"][0]) * spec("X11").scale
    check_config(bench.set_config(demo_config(), bench.truth_display(sets[0]), 100, 0.0, prior))


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


@pytest.mark.parametrize("held_at", [{}, {"X19": 20000.0}])
def test_rescore_rebuilds_a_stored_refinement_and_gives_its_intervals(bench, tmp_path, held_at):
    """``--rescore``: a set's refinement rebuilt from its estimate.json (estimate, channel
    gains, where it held the parameters it did not estimate) and field folder gives the
    intervals the refinement itself gives, and the scored rows carry them beside the stored
    ones. With X19 held at a prior's centre (20000 kN/m), the rebuilt refinement held it at
    nominal: its intervals took the offset (X13's error quantiles -23.5/+17.3 % of range
    against the refinement's -22.4/+22.4; the review of stop 78)."""
    from railsusp.conditions import get_condition
    from railsusp.estimate import SimulatorForces
    from railsusp.estimate.config import HeldPrior
    from railsusp.estimate.problem import display_values
    from railsusp.estimate.refine import refine
    from railsusp.estimate.refine_intervals import refinement_intervals
    from railsusp.measured import read_field, synthesise_field
    from railsusp.store import write_json

    params = ("X13", "X14")
    cond = get_condition("curve", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    truth = ParameterSet({"X13": 16.1, "X14": 8.3}, units="display")
    field = synthesise_field(truth, [cond], tmp_path / "set-00" / "field", with_track=True)
    lo, hi = bounds(params)
    base = ParameterSet(held_at, units="display") if held_at else None
    prior = HeldPrior.from_display({"X19": [15000, 25000]} if held_at else {})
    r = refine(SimulatorForces(params, base=base), read_field(field), params,
               lo + 0.5 * (hi - lo), max_evaluations=2, geometry_draws=0)  # fmt: skip
    est = tmp_path / "set-00" / "estimate"
    write_json(
        est / "estimate.json",
        {
            "parameters": list(params),
            "estimate_display": display_values(params, r.estimate_si),
            "refinement": {"channel_gains": r.channel_gains, "geometry_draws": 0},
            "held_at_display": held_at,
        },
    )
    (est / "validation").mkdir()
    pd.DataFrame(
        {
            "parameter": list(params),
            "truth": [16.1, 8.3],
            "estimate": [spec(p).to_display(x) for p, x in zip(params, r.estimate_si, strict=True)],
            "interval_low": [6.0, 3.0],
            "interval_high": [26.0, 15.0],
            "interval_width_pct_range": [100.0, 100.0],
            "error_pct_of_range": [0.0, 0.0],
            "truth_in_interval": [True, True],
            "identifiable": [True, False],
        }
    ).to_csv(est / "validation" / "recovery.csv", index=False)
    rebuilt = bench.stored_refinement(tmp_path / "set-00")
    assert rebuilt.residuals == pytest.approx(r.residuals, rel=1e-6, abs=1e-9)
    want = refinement_intervals(r, prior=prior)
    got = refinement_intervals(rebuilt, prior=prior)
    for p in params:
        assert got[p].low_si == pytest.approx(want[p].low_si, rel=1e-6)
        assert got[p].high_si == pytest.approx(want[p].high_si, rel=1e-6)
    rows = bench.rescore_set(tmp_path / "set-00", prior.to_display())
    assert [row["parameter"] for row in rows] == ["X13"]  # identifiable only
    assert rows[0]["interval_low"] == pytest.approx(want["X13"].low, rel=1e-6)
    assert rows[0]["stored_interval_low"] == 6.0
    assert rows[0]["truth_in_interval"] == (want["X13"].low <= 16.1 <= want["X13"].high)


def test_stored_sets_are_reused_only_with_their_seed_run_and_config(bench, tmp_path, capsys):
    """A JSON's sets are those of its work folder, seed, run and configuration: a call with
    another seed (or run, or configuration) is refused naming what differs and leaves the
    file as it was, instead of reporting the stored sets as its own; the same settings
    resume them (nothing run again)."""
    import json

    work, run, out = tmp_path / "w", tmp_path / "run", tmp_path / "cov.json"
    row = {
        "parameter": "X13", "truth": 16.0, "estimate": 16.5, "interval_low": 15.0,
        "interval_high": 18.0, "interval_width_pct_range": 10.0, "error_pct_of_range": 1.0,
        "truth_in_interval": True,
    }  # fmt: skip
    doc = {
        "work": str(work / "noise-0"),
        "run": str(run),
        "seed": 0,
        "config_hash": bench.config_hash(demo_config()),
        "per_set": [{"set": k, "truth": {}, "rows": [row]} for k in (0, 1)],
    }
    out.write_text(json.dumps(doc))
    argv = ["--run", str(run), "--work", str(work), "--sets", "2", "--out", str(out)]
    for more, named in [
        (["--seed", "5"], "seed 0 (now 5)"),
        (["--run", str(tmp_path / "other")], f"run '{run}' (now '{tmp_path / 'other'}')"),
    ]:
        with pytest.raises(SystemExit) as exc:
            bench.main([*argv, *more])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"error: {out} holds sets made with")
        assert named in err and "give another --out" in err
        assert json.loads(out.read_text()) == doc  # untouched
    stale = {**doc, "config_hash": "0123456789abcdef"}  # another [campaign] or estimate
    out.write_text(json.dumps(stale))
    with pytest.raises(SystemExit):
        bench.main(argv)
    assert "config_hash '0123456789abcdef'" in capsys.readouterr().err
    out.write_text(json.dumps(doc))
    got = bench.main(argv)  # the same: resumed, reported, nothing run (no run folder exists)
    assert [s["set"] for s in got["per_set"]] == [0, 1] and got["cases"] == 2
    assert got["seed"] == 0 and got["config_hash"] == doc["config_hash"]
