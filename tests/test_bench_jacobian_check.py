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
