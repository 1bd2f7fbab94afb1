"""bench/sequence_predict.py: a tiny end-to-end run (a random-weight sequence CNN-GRU on two
seconds of one recording, segments of 40 steps) that times the paths and finds the fast one
equal to the reference."""

import json

import pytest
import torch

from conftest import bench_script
from railsusp.conditions import get_condition
from railsusp.surrogate import recurrence
from railsusp.surrogate.bundle import Surrogate
from railsusp.surrogate.data import Normaliser
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.models import NetConfig, build_network
from railsusp.vehicle import MODEL_REVISION
from railsusp.vehicle.wagon import load_wagon
from test_estimate_aligned import KEYS


@pytest.fixture(scope="module")
def bench():
    return bench_script("sequence_predict")  # it imports its sibling estimate_tracks


def tiny_sequence_surrogate(folder, conditions=("straight",)):
    """Random-weight sequence CNN-GRU bundles of ``conditions`` (each its own weights),
    predicting in segments of 40 steps after a washout of 10, trained (as their metadata
    says) on a track family."""
    spec = FeatureSpec(parameters=KEYS)
    cfg = NetConfig(
        kind="cnn-gru-seq",
        n_features=spec.n_features,
        window=10,
        conv_channels=(spec.n_features, 8),
        rnn_hidden=(8, 6, 4),
        dense=(6, 4),
    )
    torch.manual_seed(0)
    n_track = len(spec.axles) * len(spec.track_channels)
    meta = {
        "track_realisations": 24,
        "track_family": {"irregularity_classes": (4, 6)},
        "segment_steps": 40,
        "model_revision": MODEL_REVISION,
    }
    for name in conditions:
        sur = Surrogate(
            build_network(cfg),
            cfg,
            spec,
            Normaliser([0.0] * n_track, [1.0] * n_track, [10.0, 120.0], [5.0, 20.0]),
            get_condition(name, irregularity_class=5),
            load_wagon(),
            0,
            meta,
        )
        sur.save(folder / name)
    return folder


def test_tiny_run_times_the_paths_and_finds_the_same_outputs(bench, tmp_path):
    run = tmp_path / "run"
    tiny_sequence_surrogate(run / "surrogates" / "seq")
    out = tmp_path / "out.json"
    argv = [str(run), "--kind", "seq", "--duration", "2", "--pop", "3", "--repeats", "1"]
    doc = bench.main([*argv, "--threads", "1", "--work", str(tmp_path / "w"), "--out", str(out)])
    assert json.loads(out.read_text()) == json.loads(json.dumps(doc))
    paths = {r["path"] for r in doc["rows"]}
    assert paths == {
        "reference",
        "fast",
        "in step",
        "series 1by1",
        "series step",
        "objective",
        "recurrence",
    }
    assert all(r["threads"] == 1 and r["min_s"] > 0 for r in doc["rows"])
    (diff,) = doc["differences"]
    assert diff["condition"] == "straight"
    assert 0 <= diff["max_difference_over_rms"] < 1e-4
    assert 0 <= doc["in_step_max_abs_difference_kN"] < 1e-3
    assert doc["networks"] == str(run / "surrogates" / "seq")


def test_a_folder_of_two_conditions_runs_their_networks_in_step(bench, tmp_path):
    folder = tiny_sequence_surrogate(tmp_path / "set", ("straight", "curve"))
    argv = ["--networks", str(folder), "--duration", "2", "--pop", "2", "--repeats", "1"]
    out = tmp_path / "out.json"
    doc = bench.main([*argv, "--threads", "1", "--work", str(tmp_path / "w"), "--out", str(out)])
    assert doc["networks"] == str(folder)
    assert (tmp_path / "w" / "set").is_dir()  # the recordings are kept under the folder's name
    assert {d["condition"] for d in doc["differences"]} == {"straight", "curve"}
    # two networks really ran in step: MKL's sums, not oneDNN's one-network path, so not zero
    assert doc["in_step_max_abs_difference_kN"] < 1e-3
    assert doc["in_step_max_abs_difference_kN"] > 0 or not recurrence.ONEDNN


@pytest.mark.parametrize("argv", [[], ["RUN", "--networks", "SET"]])
def test_a_run_and_a_folder_of_networks_are_one_or_the_other(bench, argv, capsys):
    with pytest.raises(SystemExit) as err:
        bench.main(argv)
    assert err.value.code == 2
    assert "give RUN (with --kind) or --networks FOLDER" in capsys.readouterr().err


def test_a_window_network_is_refused(bench, tmp_path):
    from test_estimate_aligned import tiny_surrogate

    run = tmp_path / "run"
    tiny_surrogate(run / "surrogates" / "cnn-gru")
    argv = [str(run), "--kind", "cnn-gru", "--duration", "2", "--work", str(tmp_path / "w")]
    with pytest.raises(SystemExit, match="not a sequence CNN-GRU"):
        bench.main([*argv, "--out", str(tmp_path / "out.json")])
