"""bench/jacobian_check.py: a tiny end-to-end run (a random-weight surrogate against the
simulator on two seconds of one recording)."""

import json

import numpy as np
import pytest

from conftest import bench_script
from test_estimate_aligned import KEYS, tiny_surrogate


@pytest.fixture(scope="module")
def bench():
    return bench_script("jacobian_check")  # it imports its sibling estimate_tracks


def test_tiny_check_compares_the_surrogate_with_the_simulator(bench, tmp_path):
    run = tmp_path / "run"
    tiny_surrogate(run / "surrogates" / "cnn-gru")
    out = tmp_path / "out.json"
    argv = [str(run), "--sets", "1", "--duration", "2", "--work", str(tmp_path / "w")]
    doc = bench.main([*argv, "--out", str(out)])
    assert json.loads(out.read_text())["kind"] == "cnn-gru"
    row = doc["per_set"][0]
    assert set(row["agreement"]) == set(KEYS) == set(row["effect"])
    chans = {"straight:Y", "straight:Q"}
    assert set(row["agreement"]["X14"]["by_channel"]) == chans
    # the simulator is the recording's own model: its residual is the 3 % noise and the
    # geometry error, far below a random-weight network's
    res = row["residual_rms"]
    for c in chans:
        assert res["simulator"][c] < 0.5 < res["surrogate"][c]
    # the primary lateral stiffness moves the simulated lateral force
    assert row["effect"]["X14"]["straight:Y"] > 0.0
    cos = [a["cosine"] for a in row["agreement"].values()]
    assert all(np.isnan(c) or -1.0 <= c <= 1.0 for c in cos)
    assert set(doc["median"]) == set(KEYS)


def test_simulator_steps_compare_its_own_differences(bench, tmp_path):
    run = tmp_path / "run"
    tiny_surrogate(run / "surrogates" / "cnn-gru")
    argv = [str(run), "--sets", "1", "--duration", "2", "--work", str(tmp_path / "w")]
    # half the range: from any truth above the middle the step must go inwards (it stepped
    # outwards once, past the bound, and the simulator refused the point)
    doc = bench.main([*argv, "--steps", "0.05,0.01,0.5", "--out", str(tmp_path / "o.json")])
    steps = doc["per_set"][0]["simulator_steps"]
    assert set(steps) == set(KEYS)
    for by_step in steps.values():
        assert list(by_step) == ["0.05", "0.01", "0.5"]
        assert all(-1.0 - 1e-12 <= v["cosine"] <= 1.0 + 1e-12 for v in by_step.values())
    # the primary lateral stiffness is smooth over a fifth of the step: the same column
    assert steps["X14"]["0.01"]["cosine"] > 0.9
    assert steps["X14"]["0.01"]["gain"] == pytest.approx(1.0, abs=0.2)


@pytest.mark.parametrize("steps", ["0.7", "a,b", "0"])
def test_simulator_steps_refuse_a_bad_step(bench, tmp_path, steps, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main([str(tmp_path), "--steps", steps])
    assert exc.value.code == 2
    assert "--steps" in capsys.readouterr().err
