"""bench/gpu_train_step.py: the shipped network's sizes, a row per network and chunk count,
bad options refused with exit 2 before anything is timed."""

from __future__ import annotations

import json

import pytest

from conftest import bench_script

gts = bench_script("gpu_train_step")


def test_the_shipped_architecture_is_read_and_variants_only_widen_it():
    cfg = gts.shipped_config()
    assert cfg.kind == "cnn-gru-seq" and cfg.rnn_hidden == (64, 32, 16)
    assert cfg.window < gts.CHUNK_STEPS  # the washout leaves outputs in a chunk


def test_rows_on_the_cpu(tmp_path):
    out = tmp_path / "r.json"
    rows = gts.main(["--device", "cpu", "--chunks", "2,3", "--steps", "1", "--warmup", "0",
                     "--variants", "study,wide", "--out", str(out)])  # fmt: skip
    assert [(r["network"], r["chunks"]) for r in rows] == [
        ("study", 2), ("study", 3), ("wide", 2), ("wide", 3)
    ]  # fmt: skip
    assert rows[2]["rnn_hidden"] == [128, 64, 32]
    assert all(r["ms_per_step"] > 0 and r["chunks_per_s"] > 0 for r in rows)
    doc = json.loads(out.read_text())
    assert doc["rows"] == rows and doc["warmup"] == 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--variants", "huge"], "--variants ['huge']"),
        (["--chunks", "0"], "--chunks 0"),
        (["--chunks", "a"], "--chunks a"),
        (["--device", "tpu"], "--device tpu"),
        (["--warmup", "-1"], "--warmup -1: accepted an integer >= 0"),
    ],
)
def test_bad_options_exit_2_naming_them(args, message, capsys):
    with pytest.raises(SystemExit) as exc:
        gts.main(["--device", "cpu", *args])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
