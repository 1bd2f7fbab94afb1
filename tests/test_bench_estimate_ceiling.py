"""bench/estimate_ceiling.py: the simulator as the perfect surrogate. On noise-free recordings
of exactly known track, with the channel gains estimated and the held parameters at their
true values, the simulator's least squares stays at the truth; without either it does not;
the scoring counts as estimate_tracks.py's does."""

import json

import numpy as np
import pytest

from conftest import bench_script
from railsusp.params import MAIN_SUSPENSION, bounds
from test_estimate_aligned import KEYS, tiny_surrogate


@pytest.fixture(scope="module")
def bench():
    return bench_script("estimate_ceiling")


def test_errors_are_in_percent_of_each_range(bench):
    lo, hi = bounds(["X18", "X13"])
    truth = np.array([lo[0] + 0.5 * (hi[0] - lo[0]), lo[1] + 0.2 * (hi[1] - lo[1])])
    x = truth + np.array([0.03 * (hi[0] - lo[0]), -0.1 * (hi[1] - lo[1])])
    got = bench.pct_of_range(["X18", "X13"], x, truth)
    assert got == pytest.approx({"X18": 3.0, "X13": -10.0})


def test_overall_counts_identifiable_parameters_within_five_percent(bench):
    def row(err, ident, sim_ident):
        within = [p for p in ident if abs(err[p]) <= 5.0]
        return {
            "error_pct_range": err,
            "refined_error_pct_range": {p: 2 * e for p, e in err.items()},
            "identifiable": ident,
            "identifiable_within": within,
            "simulator_identifiable": sim_ident,
            "simulator_identifiable_within": [p for p in sim_ident if abs(err[p]) <= 5.0],
            "seconds": 10.0,
        }

    sets = [
        row({"X18": 1.0, "X14": -12.0}, ["X18", "X14"], ["X18", "X14"]),
        row({"X18": -4.0, "X14": 6.0}, ["X18"], ["X18", "X14"]),
    ]
    got = bench.overall(sets, ["X18", "X14"])
    assert (got["identifiable"], got["identifiable_within"]) == (3, 2)
    assert got["share_identifiable_within"] == pytest.approx(2 / 3)
    assert (got["simulator_identifiable"], got["simulator_identifiable_within"]) == (4, 2)
    x14 = got["parameters"]["X14"]
    assert x14["mean_abs_error_pct_range"] == pytest.approx(9.0)
    assert x14["mean_error_pct_range"] == pytest.approx(-3.0)
    assert x14["mean_abs_refined_error_pct_range"] == pytest.approx(18.0)
    assert (x14["identifiable_sets"], x14["identifiable_within_sets"]) == (1, 0)


def test_the_simulator_finds_the_truth_only_with_gains_and_held_parameters_known(bench, tmp_path):
    """Noise-free recordings on exactly known track (each channel still read through a 1 %
    gain error, as the synthetic wheelset has): with the gains estimated and the five
    parameters not estimated held at their true values, the least squares from the truth
    stays there; without the gains, or with the others held at nominal (the set's truth has
    them drawn away from it), it does not."""
    nets = tiny_surrogate(tmp_path / "nets")
    argv = ["--networks", str(nets), "--sets", "1", "--duration", "2", "--noise", "0"]
    argv += ["--track-noise", "0", "--geometry-draws", "0", "--work", str(tmp_path / "w")]

    def run(name: str, *more: str) -> dict:
        return bench.main([*argv, *more, "--out", str(tmp_path / f"{name}.json")])

    exact = run("exact", "--held", "truth", "--gains")
    s = exact["per_set"][0]
    assert set(s["error_pct_range"]) == set(KEYS)
    assert max(abs(e) for e in s["error_pct_range"].values()) < 0.1
    assert s["cost"] < 1e-6 * s["cost_start"]
    assert exact["held_parameters"] == [p for p in MAIN_SUSPENSION if p not in KEYS]
    for name, more in [("no-gains", ["--held", "truth"]), ("nominal", ["--gains"])]:
        off = run(name, *more)["per_set"][0]
        assert max(abs(e) for e in off["error_pct_range"].values()) > 1.0, name
    stored = json.loads((tmp_path / "nominal.json").read_text())
    assert stored["settings"]["held"] == "nominal" and stored["settings"]["gains"]
    assert stored["overall"]["sets"] == 1
    # resumed with the same settings: nothing run again
    assert run("nominal", "--gains")["per_set"] == stored["per_set"]


def test_bad_settings_are_refused_naming_the_flag(bench, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main(["--track-noise", "-1"])
    assert exc.value.code == 2
    assert "--track-noise: -1: accepted a finite number 0 or more" in capsys.readouterr().err


def test_expected_draws_are_a_setting_and_refused_below_zero(bench, capsys):
    """The arm comparing the simulator's mean over drawn true geometries is stored as a
    setting only when on (JSON written before it resumes), and a negative count exits 2."""
    import argparse

    args = argparse.Namespace(
        networks=".",
        seed=0,
        duration=60.0,
        track_noise=0.5,
        noise=0.03,
        held="nominal",
        gains=False,
        geometry_draws=0,
        conditions="",
        expected_draws=0,
        independent_draws=False,
    )
    assert "expected_draws" not in bench.settings_of(args)
    args.expected_draws = 8
    assert bench.settings_of(args)["expected_draws"] == 8
    assert bench.settings_of(args)["antithetic"]
    with pytest.raises(SystemExit) as exc:
        bench.main(["--expected-draws", "-1"])
    assert exc.value.code == 2
    assert "--expected-draws -1" in capsys.readouterr().err


def test_an_out_of_other_settings_is_refused_not_overwritten(bench, tmp_path, capsys):
    """An --out written with other settings (here another seed) is refused, naming the
    settings that differ, and left as it was: before, the first new set overwrote it."""
    nets = tiny_surrogate(tmp_path / "nets")
    out = tmp_path / "ceiling.json"
    stored = {"settings": {"seed": 7}, "per_set": [{"set": 0}]}
    out.write_text(json.dumps(stored))
    argv = ["--networks", str(nets), "--sets", "1", "--duration", "2", "--seed", "0"]
    with pytest.raises(SystemExit) as exc:
        bench.main([*argv, "--work", str(tmp_path / "w"), "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds 1 set(s) of other settings: " in err
    assert "seed 7 (now 0)" in err and "held 'unset' (now 'nominal')" in err
    assert json.loads(out.read_text()) == stored
