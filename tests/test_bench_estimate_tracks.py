"""bench/estimate_tracks.py: the sets it draws, the conditions it synthesises, and a tiny end
to end run (a random-weight surrogate, two seconds, NSGA-II 4 x 2) that writes its JSON and
resumes per set."""

import json

import numpy as np
import pytest

from conftest import bench_script
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import SurrogateForces
from railsusp.params import MAIN_SUSPENSION, bounds, spec
from test_estimate_aligned import KEYS, tiny_surrogate


@pytest.fixture(scope="module")
def bench():
    return bench_script("estimate_tracks")


def test_sets_are_drawn_inside_the_middle_80_percent(bench):
    lo, hi = bounds(MAIN_SUSPENSION)
    x = bench.draw_sets(300, seed=5)
    assert x.shape == (300, 10)
    u = (x - lo) / (hi - lo)
    assert u.min() >= 0.1 and u.max() <= 0.9
    assert u.min() < 0.12 and u.max() > 0.88  # spread over the whole middle
    np.testing.assert_array_equal(bench.draw_sets(3, seed=5), x[:3])  # set i whatever n
    assert not np.array_equal(bench.draw_sets(3, seed=6), x[:3])
    with pytest.raises(RailsuspInputError, match="sets 0"):
        bench.draw_sets(0, seed=5)


def test_conditions_are_moved_into_the_track_family(bench, tmp_path):
    folder = tiny_surrogate(tmp_path / "s", family=(4, 6))
    sur = SurrogateForces(folder).surrogate("straight")
    sur.meta["track_family"]["cant_mm"] = [0.0, 100.0]
    sur.condition = get_condition("curve").with_changes(name="straight")  # cant 110 mm
    model = SurrogateForces(folder)
    model._models["straight"] = sur
    conds, moved = bench.family_conditions(model, 60.0)
    assert conds[0].cant_mm == 100.0 and conds[0].duration_s == 60.0
    assert moved == {"straight": {"cant_mm": [110.0, 100.0]}}
    with pytest.raises(RailsuspInputError, match="'uphill': no surrogate"):
        bench.family_conditions(model, 60.0, ["uphill"])


def test_tiny_run_writes_its_json_and_resumes_per_set(bench, tmp_path, capsys):
    run = tmp_path / "run"
    tiny_surrogate(run / "surrogates" / "cnn-gru")
    out = tmp_path / "out.json"
    argv = [str(run), "--sets", "2", "--limit", "1", "--duration", "2", "--pop-size", "4"]
    argv += ["--n-gen", "2", "--threads", "1", "--work", str(tmp_path / "w"), "--out", str(out)]
    doc = bench.main(argv)
    first = json.loads(out.read_text())
    assert [s["set"] for s in first["per_set"]] == [0]
    s0 = first["per_set"][0]
    assert set(s0["error_pct_range"]) == set(KEYS) == set(first["key_parameters"])
    assert all(np.isfinite(v) for v in s0["error_pct_range"].values())
    assert all(p in KEYS for p in s0["identifiable"])
    assert s0["choice_rule"] == "least-squares" and s0["seconds"] > 0
    assert s0["predict_calls"] == 2  # one condition, two generations
    assert 0 < s0["predict_cpu_seconds_per_generation"]
    assert s0["truth_display"].keys() == set(MAIN_SUSPENSION)
    assert doc["overall"]["sets"] == 1
    # the geometry's 0.5 mm error drawn (8 by default): the estimate is the choice less the
    # bias of the parameters the draws do not throw by more than half the range; both scored
    assert set(s0["geometry_bias_pct_range"]) == set(KEYS)
    for p in KEYS:
        moved = s0["error_pct_range"][p] - s0["choice_error_pct_range"][p]
        at_bound = s0["estimate_display"][p] in spec(p).bounds_display
        if s0["geometry_scatter_pct_range"][p] > 50.0:
            assert moved == 0.0
        elif not at_bound:
            assert moved == pytest.approx(-s0["geometry_bias_pct_range"][p], abs=1e-6)
    assert 0 <= doc["overall"]["identifiable_choice_within"] <= doc["overall"]["identifiable"]
    # resumed: set 0 kept as it was, set 1 added
    second = bench.main(argv)
    assert [s["set"] for s in second["per_set"]] == [0, 1]
    assert second["per_set"][0] == s0
    assert second["overall"]["sets"] == 2
    # other settings: the stored sets are neither mixed in nor overwritten unasked
    kept = out.read_text()
    capsys.readouterr()  # the runs' own output before (NSGA-II's log lines where shown)
    with pytest.raises(SystemExit) as exc:
        bench.main([*argv, "--seed", "1"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert "holds 2 set(s) of other settings: seed 0 (now 1)" in err and "--replace" in err
    assert out.read_text() == kept
    third = bench.main([*argv, "--seed", "1", "--replace"])
    assert [s["set"] for s in third["per_set"]] == [0]
    assert third["per_set"][0]["truth_display"] != s0["truth_display"]
    assert json.loads(out.read_text())["settings"]["seed"] == 1


def test_recordings_are_made_again_for_other_conditions(bench, tmp_path):
    """A set's recordings are reused only when made for the same conditions and settings:
    a folder written for one condition is not read as the recordings of another."""
    import argparse

    args = argparse.Namespace(seed=0, noise=0.03, duration=2.0, track_noise=0.5)
    straight = get_condition("straight").with_duration(2.0)
    curve = get_condition("curve").with_duration(2.0)
    truth = bench.draw_sets(1, seed=0)[0]
    _, recs = bench.set_recordings(0, truth, [straight], tmp_path, args)
    assert [r.condition.name for r in recs] == ["straight"]
    _, again = bench.set_recordings(0, truth, [straight, curve], tmp_path, args)
    assert sorted(r.condition.name for r in again) == ["curve", "straight"]
    stamp = (tmp_path / "set-00" / "synthesis.json").stat().st_mtime_ns
    bench.set_recordings(0, truth, [straight, curve], tmp_path, args)  # reused
    assert (tmp_path / "set-00" / "synthesis.json").stat().st_mtime_ns == stamp


def test_recordings_of_another_model_are_made_again(bench, tmp_path, monkeypatch):
    """The recordings' cache (shared by jacobian_check, estimate_ceiling and
    sequence_predict) is keyed on the force laws' revision and the wagon's data too: a
    folder simulated by other force laws, or another wagon, is simulated again, not
    reused."""
    import argparse

    from railsusp.vehicle import MODEL_REVISION

    args = argparse.Namespace(seed=0, noise=0.03, duration=2.0, track_noise=0.5)
    straight = [get_condition("straight").with_duration(2.0)]
    truth = bench.draw_sets(1, seed=0)[0]
    made = tmp_path / "set-00" / "synthesis.json"
    bench.set_recordings(0, truth, straight, tmp_path, args)
    stamp = json.loads(made.read_text())
    assert stamp["model_revision"] == MODEL_REVISION and stamp["wagon_data"]
    monkeypatch.setattr(bench, "MODEL_REVISION", "1999-01-01.1")
    bench.set_recordings(0, truth, straight, tmp_path, args)
    assert json.loads(made.read_text())["model_revision"] == "1999-01-01.1"  # made again
    monkeypatch.setattr(bench, "wagon_hash", lambda wagon: "another wagon")
    bench.set_recordings(0, truth, straight, tmp_path, args)
    assert json.loads(made.read_text())["wagon_data"] == "another wagon"
    before = made.stat().st_mtime_ns
    bench.set_recordings(0, truth, straight, tmp_path, args)  # the same model: reused
    assert made.stat().st_mtime_ns == before


def test_rescore_keeps_the_estimates_and_scores_them_again(bench, tmp_path):
    """--rescore recomputes each stored set's bounds on its own recordings, keeps the
    estimate and runs no NSGA-II (no new sets, no predictions counted again)."""
    run = tmp_path / "run"
    tiny_surrogate(run / "surrogates" / "cnn-gru")
    out = tmp_path / "out.json"
    argv = [str(run), "--sets", "2", "--limit", "1", "--duration", "2", "--pop-size", "4"]
    argv += ["--n-gen", "2", "--threads", "1", "--work", str(tmp_path / "w"), "--out", str(out)]
    first = bench.main(argv)["per_set"][0]
    doc = json.loads(out.read_text())
    doc["per_set"][0]["cramer_rao_pct_range"] = dict.fromkeys(KEYS, 99.0)  # a stale score
    doc["per_set"][0]["identifiable"] = []
    doc["torch_threads"], doc["date"] = 2, "2026-01-01 00:00"  # the original run's
    out.write_text(json.dumps(doc))
    again = bench.main([*argv, "--rescore"])
    assert (again["torch_threads"], again["date"]) == (2, "2026-01-01 00:00")
    assert again["rescored"]
    assert [s["set"] for s in again["per_set"]] == [0]  # set 1 not run
    row = again["per_set"][0]
    assert row["error_pct_range"] == first["error_pct_range"]
    assert row["seconds"] == first["seconds"] and row["predict_calls"] == first["predict_calls"]
    assert row["cramer_rao_pct_range"] == pytest.approx(first["cramer_rao_pct_range"])
    assert row["identifiable"] == first["identifiable"]


def test_expected_forces_arm_is_its_own_setting(bench, tmp_path, capsys):
    """--expected-draws: NSGA-II's choice polished on the networks' mean over drawn true
    geometries (the setting stored, so such sets never resume into a plain run's JSON), its
    seconds and Jacobians recorded; --expected-generations: NSGA-II compares them in its
    generations too (stored too; without --expected-draws refused). A negative count exits
    2."""
    run = tmp_path / "run"
    tiny_surrogate(run / "surrogates" / "cnn-gru")
    argv = [str(run), "--sets", "1", "--duration", "2", "--pop-size", "4", "--n-gen", "2"]
    argv += ["--threads", "1", "--work", str(tmp_path / "w"), "--geometry-draws", "0"]
    doc = bench.main([*argv, "--expected-draws", "2", "--out", str(tmp_path / "e.json")])
    s0 = doc["per_set"][0]
    assert doc["settings"]["expected_draws"] == 2
    assert doc["settings"]["expected_generations"] is False  # stored: the route resumed
    assert s0["polish_jacobians"] >= 1 and 0.0 < s0["polish_seconds"] < s0["seconds"]
    assert s0["error_pct_range"] != s0["choice_error_pct_range"]  # the polish moved it
    assert doc["overall"]["polish_seconds"] == pytest.approx(s0["polish_seconds"])
    both = bench.main(
        [
            *argv,
            "--expected-draws",
            "2",
            "--expected-generations",
            "--out",
            str(tmp_path / "g.json"),
        ]
    )
    assert both["settings"]["expected_generations"] is True
    assert both["per_set"][0]["predict_calls"] > s0["predict_calls"]  # 2 draws per prediction
    corrected = bench.main(
        [*argv, "--expected-draws", "2", "--simulator-corrections", "1", "--out",
         str(tmp_path / "c.json")]
    )  # fmt: skip
    c0 = corrected["per_set"][0]
    assert corrected["settings"]["simulator_corrections"] == 1
    assert c0["correction_seconds"] > 0 and set(c0["nsga_error_pct_range"]) == set(KEYS)
    assert len(c0["correction_jacobians"]) == 1 and c0["correction_jacobians"][0] >= 1
    assert c0["nsga_error_pct_range"] == s0["error_pct_range"]  # before: the polished one
    assert (
        0
        <= corrected["overall"]["identifiable_nsga_within"]
        <= corrected["overall"]["identifiable"]
    )
    plain = bench.main([*argv, "--out", str(tmp_path / "p.json")])
    assert "expected_draws" not in plain["settings"] and "polish_seconds" not in plain["overall"]
    assert "simulator_corrections" not in plain["settings"]
    assert plain["per_set"][0]["truth_display"] == s0["truth_display"]
    assert plain["per_set"][0]["error_pct_range"] == plain["per_set"][0]["choice_error_pct_range"]
    with pytest.raises(SystemExit) as exc:
        bench.main([*argv, "--expected-generations"])
    assert exc.value.code == 2
    assert "--expected-generations needs --expected-draws" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        bench.main([*argv, "--expected-draws", "-1"])
    assert exc.value.code == 2
    assert "--expected-draws -1" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        bench.main([*argv, "--broyden-min-step", "1.5"])
    assert exc.value.code == 2
    assert "--broyden-min-step 1.5: accepted 0 to under 1" in capsys.readouterr().err


def test_broydens_floor_is_a_setting_of_broyden_runs_only(bench, tmp_path):
    """The floor of Broyden's update is stored with the settings of runs that use the
    update (so runs with another floor, or stop 52's without one, never resume into each
    other's JSON), and not with simulated slopes."""
    import argparse

    common = dict(seed=0, duration=60.0, track_noise=0.5, noise=0.03, pop_size=50, n_gen=100)
    common |= dict(conditions="", geometry_draws=8, gains=True, expected_draws=8)
    common |= dict(expected_generations=False, simulator_corrections=3, correction_slopes=True)

    def settings(update: str, floor: float) -> dict:
        args = argparse.Namespace(**common, slope_update=update, broyden_min_step=floor)
        return bench.settings_of(args, tmp_path)

    assert settings("broyden", 0.01)["broyden_min_step"] == 0.01
    assert settings("broyden", 0.01) != settings("broyden", 0.05)
    assert "broyden_min_step" not in settings("simulated", 0.01)
    assert settings("simulated", 0.01) == settings("simulated", 0.05)


def test_the_efficient_expectation_sums_each_identifiable_keys_chance(bench):
    """An identifiable key at a bound of 5 % of range is within 5 % about 68 % of the time,
    one at 1 % nearly always; keys not identifiable are not counted. The mean squared error
    over bound is per key, over the sets where it is identifiable."""
    sets = [
        {
            "identifiable": ["X18", "X14"],
            "cramer_rao_pct_range": {"X18": 1.0, "X14": 5.0, "X19": 9.0},
            "error_pct_range": {"X18": 2.0, "X14": -5.0, "X19": 30.0},
        },
        {
            "identifiable": ["X14"],
            "cramer_rao_pct_range": {"X14": 2.0, "X19": 12.0},
            "error_pct_range": {"X14": 6.0, "X19": 1.0},
        },
    ]
    got = bench.efficient_expectation(sets)
    assert got["count"] == pytest.approx(1.0 + 0.6827 + 0.9876, abs=1e-3)
    assert got["share"] == pytest.approx(got["count"] / 3)
    var = 0.6827 * 0.3173 + 0.9876 * 0.0124
    assert got["sd"] == pytest.approx(var**0.5, abs=1e-3)
    assert got["mean_squared_z"] == pytest.approx({"X18": 4.0, "X14": (1.0 + 9.0) / 2})


def test_the_preview_generations_compare_the_records_first_seconds(bench, tmp_path):
    """--preview-generations N: the first N generations on each record's first
    --preview-s seconds (their predictions over as many steps), the rest on the whole
    record; a setting of its own; N must leave at least one whole generation."""
    run = tmp_path / "run"
    tiny_surrogate(run / "surrogates" / "cnn-gru")
    out = tmp_path / "out.json"
    argv = [str(run), "--sets", "1", "--duration", "4", "--pop-size", "4", "--n-gen", "3"]
    argv += ["--threads", "1", "--work", str(tmp_path / "w"), "--out", str(out)]
    doc = bench.main([*argv, "--preview-generations", "2", "--preview-s", "2"])
    assert doc["settings"]["preview"] == [2, 2.0]
    assert doc["per_set"][0]["predict_calls"] == 3  # two preview generations, one whole
    with pytest.raises(SystemExit):
        bench.main([*argv, "--preview-generations", "3"])


def test_networks_trained_again_under_the_same_folder_are_other_settings(bench, tmp_path):
    """The networks' files are part of the settings: stored sets of the shipped set's
    straight network resumed into a run of its fine-tuned successor in the same folder
    (stop 75), their errors mixed into the new network's score."""
    import argparse

    args = argparse.Namespace(
        seed=0, duration=60.0, track_noise=0.5, noise=0.03, pop_size=50, n_gen=100,
        conditions="", geometry_draws=8, gains=False, expected_draws=0,
        simulator_corrections=0, correction_slopes=False, slope_update="simulated",
        broyden_min_step=0.01,
    )  # fmt: skip
    (tmp_path / "straight").mkdir()
    (tmp_path / "straight" / "model.pt").write_bytes(b"weights")
    (tmp_path / "straight" / "surrogate.json").write_text("{}")
    before = bench.settings_of(args, tmp_path)
    assert bench.settings_of(args, tmp_path) == before
    (tmp_path / "straight" / "model.pt").write_bytes(b"fine-tuned weights")
    after = bench.settings_of(args, tmp_path)
    assert after["networks"] != before["networks"]
    out = tmp_path / "et.json"
    out.write_text(json.dumps({"settings": before, "per_set": [{"set": 0}]}))
    with pytest.raises(SystemExit):
        bench.resumed_sets(out, after)
    assert bench.resumed_sets(out, before) == [{"set": 0}]
