"""Training: bitwise reproducible on the CPU, resumed equals uninterrupted, checkpoints read
without running code, settings that would train nothing refused."""

from __future__ import annotations

import logging
import pickle

import numpy as np
import pytest
import torch

import railsusp.surrogate.train as train_mod
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.surrogate.data import Normaliser, SeriesData
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.models import NetConfig, build_network
from railsusp.surrogate.train import TrainConfig, WindowSampler, train_network

SPEC = FeatureSpec(parameters=("X13", "X14"), window=6, track_channels=("zL", "yL"), axles=(0,))


def _data(n: int, seed: int) -> SeriesData:
    rng = np.random.default_rng(seed)
    t = 40
    params = rng.random((n, 2))
    track = rng.standard_normal((1, t, SPEC.n_features - 2)).astype(np.float32)
    targets = (params[:, None, :] * 10 + track[..., :2]).astype(np.float32)
    return SeriesData(
        np.arange(n), params, track, targets, get_condition("straight"), np.zeros(n, int)
    )


def _train(epochs: int, checkpoint=None, kind: str = "cnn-gru", **settings) -> tuple[dict, list]:
    train, val = _data(6, 0), _data(3, 1)
    norm = Normaliser.fit(train)
    cfg = NetConfig(
        kind=kind,
        n_features=SPEC.n_features,
        window=SPEC.window,
        conv_channels=(SPEC.n_features, 8),
        rnn_hidden=(8, 4),
        dense=(8,),
        mlp_hidden=(8,),
    )
    torch.manual_seed(np.random.default_rng().integers(1000))  # the global state must not count
    net = build_network(cfg)
    tcfg = TrainConfig(
        **{
            "epochs": epochs,
            "batches_per_epoch": 3,
            "batch_size": 16,
            "val_windows": 50,
            "seed": 3,
            **settings,
        }
    )
    hist = train_network(
        net,
        WindowSampler(train, norm, SPEC.window),
        WindowSampler(val, norm, SPEC.window),
        tcfg,
        checkpoint=checkpoint,
    )
    return {k: v.clone() for k, v in net.state_dict().items()}, hist


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _checkpoint_history(ck) -> list[dict]:
    return torch.load(ck, weights_only=True)["history"]


def test_two_cpu_trainings_with_one_seed_give_identical_weights():
    w1, h1 = _train(3)
    w2, h2 = _train(3)
    assert _same(w1, w2)
    assert [h["val_loss"] for h in h1] == [h["val_loss"] for h in h2]


def test_interrupted_and_resumed_training_equals_an_uninterrupted_one(tmp_path, trained_epochs):
    ck = tmp_path / "checkpoint.pt"
    _train(2, ck)  # "killed" after two epochs: the checkpoint holds epoch 2
    before = _checkpoint_history(ck)
    trained_epochs()
    resumed, h_res = _train(4, ck)
    # it resumed: two epochs trained, the first two the checkpoint's (their own seconds)
    assert trained_epochs() == 2
    assert h_res[:2] == before
    whole, h_whole = _train(4)
    assert len(h_res) == len(h_whole) == 4
    assert [h["val_loss"] for h in h_res] == [h["val_loss"] for h in h_whole]
    assert _same(resumed, whole)


def test_a_checkpoint_save_killed_midway_leaves_no_temporary_after_the_resume(tmp_path):
    """A kill while the checkpoint was written left ``.checkpoint.pt.XXXXXXXX.tmp`` (a
    network's size) in the surrogate's folder for good; the resume removes it, and only it."""
    ck = tmp_path / "checkpoint.pt"
    _train(1, ck)
    stale = tmp_path / ".checkpoint.pt.ab12cd34.tmp"
    stale.write_bytes(ck.read_bytes()[:100])  # cut short, as a kill mid-write leaves it
    other = tmp_path / ".model.pt.ab12cd34.tmp"  # another file's: not the training's to remove
    other.write_bytes(b"x")
    _train(2, ck)
    assert not stale.exists() and other.exists()
    assert len(_checkpoint_history(ck)) == 2


def test_a_crafted_pickle_checkpoint_is_refused_and_runs_no_code(tmp_path):
    marker = tmp_path / "pwned"
    code = f"open({str(marker)!r}, 'w').write('ran')"

    class Evil:
        def __reduce__(self):
            return (exec, (code,))

    ck = tmp_path / "checkpoint.pt"
    ck.write_bytes(pickle.dumps({"key": "x", "evil": Evil()}, protocol=2))
    # unpickled without weights_only, the file would run code:
    pickle.loads(ck.read_bytes())
    assert marker.exists()
    marker.unlink()
    with pytest.raises(RailsuspInputError, match="checkpoint .* refused"):
        _train(1, ck)
    assert not marker.exists()
    # torch.save'd too (a zip with a pickle inside)
    torch.save({"key": "x", "evil": Evil()}, ck)
    with pytest.raises(RailsuspInputError, match="refused"):
        _train(1, ck)
    assert not marker.exists()


def test_a_checkpoint_cut_short_is_trained_past_from_the_start(tmp_path):
    """A copy of a run cut short holds a checkpoint whose zip does not read: nothing in it
    can run, so it is not refused (as a crafted file is) but trained past, and the result
    equals an uninterrupted training's. A file of three bytes, or none, likewise."""
    ck = tmp_path / "checkpoint.pt"
    _train(2, ck)
    whole, h_whole = _train(4)
    for damaged in (ck.read_bytes()[:-100], ck.read_bytes()[:3], b""):
        ck.write_bytes(damaged)
        again, h_again = _train(4, ck)
        assert [h["val_loss"] for h in h_again] == [h["val_loss"] for h in h_whole]
        assert _same(again, whole)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("epochs", 0, "epochs = 0: accepted an integer from 1 to 10000"),
        ("batch_size", 0, "batch_size = 0"),
        ("batch_size", 100_000_000, "batch_size = 100000000: accepted an integer from 1 to 65536"),
        ("batches_per_epoch", -1, "batches_per_epoch = -1"),
        ("device", "tpu", "device 'tpu': accepted cpu, cuda, auto"),
        ("learning_rate", float("nan"), "learning_rate = nan"),
        ("max_seconds", 0, "max_seconds = 0: accepted a number of seconds > 0"),
        ("max_seconds", True, "max_seconds = True"),
        ("max_seconds", float("nan"), "max_seconds = nan"),
        ("max_seconds", float("inf"), "max_seconds = inf"),
    ],
)
def test_training_settings_that_would_train_nothing_are_refused(field, value, message):
    with pytest.raises(RailsuspInputError, match=message):
        TrainConfig(**{field: value})


def test_a_wall_clock_budget_stops_each_phase_and_keeps_the_checkpoint_resumable(tmp_path):
    """``max_seconds`` ends the main phase after its share and the fine-tune phase after the
    rest (an exhausted budget leaves the training's first epoch only); it is
    not part of the checkpoint's key, so a training its budget stopped in the main phase
    resumes under another budget into the same result as one run without any."""
    ck = tmp_path / "checkpoint.pt"
    _, h = _train(6, ck, fine_tune_epochs=2, max_seconds=1e-9)
    assert [e["phase"] for e in h] == ["main"]  # the first epoch always, no other
    resumed, h_res = _train(6, ck, fine_tune_epochs=2, max_seconds=3600.0)
    whole, h_whole = _train(6, fine_tune_epochs=2)
    assert [e["phase"] for e in h_res] == ["main"] * 6 + ["fine-tune"] * 2
    assert [e["val_loss"] for e in h_res] == [e["val_loss"] for e in h_whole]
    assert _same(resumed, whole)


def test_a_budget_gives_each_phase_its_share_by_epochs(monkeypatch):
    """With a clock that moves 10 s per epoch, 6 main and 2 fine-tune epochs and 40 s: the
    main phase starts epochs before 30 s (its 6/8 share: 3 epochs), the fine-tune phase
    before 40 s (1 epoch)."""
    import railsusp.surrogate.train as train_mod

    clock = [1000.0]
    real_epoch = train_mod._train_epoch

    def epoch(*args):
        out = real_epoch(*args)
        clock[0] += 10.0
        return out

    monkeypatch.setattr(train_mod.time, "perf_counter", lambda: clock[0])
    monkeypatch.setattr(train_mod, "_train_epoch", epoch)
    _, h = _train(6, fine_tune_epochs=2, max_seconds=40.0)
    assert [e["phase"] for e in h] == ["main"] * 3 + ["fine-tune"]


@pytest.mark.parametrize(("before", "after"), [(1, 4), (4, 1)])
def test_a_checkpoint_past_its_main_phase_under_other_epochs_trains_afresh(tmp_path, before, after):
    """The interrupt/resume audit of stop 58: a pipeline whose ``[surrogate] epochs``
    changed resumed the finished checkpoint of the old limit (its fine-tune phase had begun,
    so the main phase was skipped) and kept that network, silently."""
    ck = tmp_path / "checkpoint.pt"
    _train(before, ck, fine_tune_epochs=2)
    resumed, h_res = _train(after, ck, fine_tune_epochs=2)
    whole, h_whole = _train(after, fine_tune_epochs=2)
    assert [e["phase"] for e in h_res] == ["main"] * after + ["fine-tune"] * 2
    assert [e["val_loss"] for e in h_res] == [e["val_loss"] for e in h_whole]
    assert _same(resumed, whole)


def test_a_main_phase_still_running_trains_on_under_raised_epochs(tmp_path, trained_epochs):
    ck = tmp_path / "checkpoint.pt"
    _train(2, ck)  # main phase only, interrupted or finished at 2
    before = _checkpoint_history(ck)
    trained_epochs()
    _, h_res = _train(5, ck)
    assert [e["epoch"] for e in h_res] == [1, 2, 3, 4, 5]
    assert trained_epochs() == 3 and h_res[:2] == before  # trained on, not afresh


def test_a_resume_under_other_settings_says_what_differs(tmp_path, caplog, trained_epochs):
    """The surrogate options audit: a resume with another batch size started from epoch 1 without a
    word (the checkpoint's key differed; no saved network yet to note as replaced)."""
    ck = tmp_path / "checkpoint.pt"
    _train(2, ck)
    trained_epochs()
    with caplog.at_level(logging.WARNING, logger="railsusp.surrogate.train"):
        _train(2, ck, batch_size=8)
    assert trained_epochs() == 2
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1
    assert "of other settings (batch_size 16 -> 8); training starts afresh" in lines[0]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="railsusp.surrogate.train"):
        _train(2, ck, batch_size=8, seed=4)
    assert "(seed 3 -> 4)" in caplog.records[0].getMessage()


def test_device_auto_on_a_machine_without_cuda_resumes_a_cpu_checkpoint(
    tmp_path, monkeypatch, trained_epochs
):
    """The key held the device as typed: ``--device auto`` without CUDA trains on the CPU
    as ``cpu`` does, yet retrained a ``cpu`` checkpoint from epoch 1 (the surrogate options
    audit)."""
    monkeypatch.setattr(train_mod.torch.cuda, "is_available", lambda: False)
    ck = tmp_path / "checkpoint.pt"
    _train(2, ck)
    trained_epochs()
    _, h = _train(3, ck, device="auto")
    assert trained_epochs() == 1 and len(h) == 3
