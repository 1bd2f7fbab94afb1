"""The sequence CNN-GRU (cnn-gru-seq): causal, state carried, chunked training, the bundle's
predict contract, save/load, resume, and that a short training learns."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from railsusp.campaign import make_config, run_campaign
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.surrogate import TrainConfig, load, train_surrogate
from railsusp.surrogate.chunks import ChunkSampler
from railsusp.surrogate.data import Normaliser, SeriesData
from railsusp.surrogate.evaluate import evaluate
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.models import (
    DEFAULT_WASHOUT,
    NetConfig,
    build_network,
    default_window,
)
from railsusp.surrogate.sequence import CNNSequence
from railsusp.surrogate.train import WindowSampler, sampler_for, train_network

SPEC = FeatureSpec(parameters=("X13", "X14"), window=5, track_channels=("zL", "yL"), axles=(0,))
KEYS = ("X13", "X14", "X15", "X16", "X17", "X18")


def _small(washout: int = 5, dropout: float = 0.2) -> NetConfig:
    return NetConfig(
        kind="cnn-gru-seq",
        n_features=SPEC.n_features,
        window=washout,
        conv_channels=(SPEC.n_features, 8),
        rnn_hidden=(8, 4),
        dense=(8,),
        dropout=dropout,
    )


def _data(n: int, seed: int, t: int = 60) -> SeriesData:
    """Targets of a first-order lag (time constant 5 steps) of a track channel, scaled by a
    parameter: learnable only with memory beyond the current step."""
    rng = np.random.default_rng(seed)
    params = rng.random((n, 2)).astype(np.float32)
    track = rng.standard_normal((n, t, SPEC.n_features - 2)).astype(np.float32)
    lag = np.zeros((n, t), np.float32)
    for k in range(1, t):
        lag[:, k] = 0.8 * lag[:, k - 1] + 0.2 * track[:, k, 0]
    targets = np.stack([lag * (1 + params[:, :1]), 100 + 5 * lag], axis=2).astype(np.float32)
    return SeriesData(np.arange(n), params, track, targets, get_condition("straight"), np.arange(n))


def test_the_kind_is_a_causal_sequence_network_with_a_washout():
    assert default_window("cnn-gru-seq") == DEFAULT_WASHOUT == 100
    assert default_window("cnn-gru") == 20
    net = build_network(_small())
    assert isinstance(net, CNNSequence) and net.washout == 5
    assert all(not layer.bidirectional for layer in net.rnn)
    with pytest.raises(ValueError, match="bidirectional = True: .* accepted False only"):
        build_network(NetConfig(**{**_small().to_dict(), "bidirectional": True}))
    x = torch.randn(3, 30, SPEC.n_features)
    assert net.eval()(x).shape == (3, 25, 2)  # the washout is not a prediction


def test_an_input_change_at_step_k_changes_no_output_before_k():
    """Causality, pooling included: outputs before step k are bitwise unchanged, the output
    at step k changes (the input reaches the head at once)."""
    torch.manual_seed(0)
    net = build_network(_small()).eval()
    x = torch.randn(2, 40, SPEC.n_features)
    base = net.predict_series(x)
    for k in (0, 1, 17, 39):
        y = x.clone()
        y[:, k, 2:] += 3.0  # the track input at step k
        out = net.predict_series(y)
        assert torch.equal(out[:, :k], base[:, :k])
        assert (out[:, k] - base[:, k]).abs().max() > 1e-4


def test_a_series_run_in_stretches_with_the_state_carried_equals_one_run():
    torch.manual_seed(1)
    net = build_network(_small()).eval()
    x = torch.randn(3, 50, SPEC.n_features)
    whole = net.predict_series(x)
    with torch.inference_mode():
        a, state = net.steps(x[:, :23])
        b, _ = net.steps(x[:, 23:], state)
        fresh, _ = net.steps(x[:, 23:])  # without the state: another answer
    torch.testing.assert_close(torch.cat([a, b], 1), whole, rtol=1e-5, atol=1e-6)
    assert (fresh - whole[:, 23:]).abs().max() > 1e-3
    torch.testing.assert_close(net.predict_series(x, stepwise=True), whole, rtol=1e-5, atol=1e-6)
    # the autograd path (training) computes the same function in eval mode
    with torch.enable_grad():
        torch.testing.assert_close(net.steps(x)[0].detach(), whole, rtol=1e-5, atol=1e-6)
    # groups of series give the same rows as one batch
    torch.testing.assert_close(net.predict_series(x, group_steps=50), whole)
    with pytest.raises(RuntimeError, match="eval"):
        net.train().predict_series(x)


def test_chunks_are_slices_of_the_series_and_targets_skip_the_washout():
    data = _data(4, 0, t=60)
    norm = Normaliser.fit(data)
    smp = ChunkSampler(data, norm, washout=5, chunk_steps=20)
    assert smp.chunk == 20 and len(smp.index) == 4 * 41 and smp.targets_per_row == 15
    rows = np.array([0, 40, 41 * 3 + 7])
    x, y = smp.batch(rows)
    assert x.shape == (3, 20, SPEC.n_features) and y.shape == (3, 15, 2)
    for b, (i, s) in enumerate(smp.index[rows]):
        np.testing.assert_array_equal(x[b, :, 2:].numpy(), norm.track(data.track[i, s : s + 20]))
        np.testing.assert_array_equal(x[b, :, :2].numpy(), np.tile(data.params_unit[i], (20, 1)))
        np.testing.assert_array_equal(y[b].numpy(), norm.target(data.targets[i, s + 5 : s + 20]))
    # the network's training outputs line up with these targets: its outputs at the chunk's
    # steps washout .. C - 1
    torch.manual_seed(2)
    net = build_network(_small()).eval()
    with torch.no_grad():
        torch.testing.assert_close(net(x), net.steps(x)[0][:, 5:])
    assert smp.validation_rows(100) == 7  # ceil(100 / 15) chunks
    assert smp.rows_per_batch(512, 6) == 6
    # a shared track and chunks longer than the series
    shared = SeriesData(
        data.sample_ids, data.params_unit, data.track[:1], data.targets, data.condition, data.seeds
    )
    long = ChunkSampler(shared, norm, washout=5, chunk_steps=500)
    assert long.chunk == 60 and len(long.index) == 4
    with pytest.raises(ValueError, match=r"washout \(window\) = 60 steps: accepted fewer than"):
        ChunkSampler(data, norm, washout=60, chunk_steps=400)
    with pytest.raises(ValueError, match="chunk_steps = 20: accepted more than the washout of 30"):
        ChunkSampler(data, norm, washout=30, chunk_steps=20)


def test_the_sampler_follows_the_kind():
    data = _data(3, 0)
    norm = Normaliser.fit(data)
    tcfg = TrainConfig(chunk_steps=30)
    assert isinstance(sampler_for("cnn-gru-seq", data, norm, 5, tcfg), ChunkSampler)
    assert isinstance(sampler_for("cnn-gru", data, norm, 5, tcfg), WindowSampler)
    with pytest.raises(RailsuspInputError, match="chunk_steps = 1: accepted an integer from 2 to"):
        TrainConfig(chunk_steps=1)
    with pytest.raises(RailsuspInputError, match="chunks_per_batch = 0"):
        TrainConfig(chunks_per_batch=0)


def _train(
    epochs: int,
    checkpoint=None,
    seed: int = 3,
    batches: int = 4,
    net_cfg: NetConfig | None = None,
    batch_size: int = 512,
) -> tuple[dict, list]:
    train, val = _data(8, 0), _data(4, 1)
    norm = Normaliser.fit(train)
    tcfg = TrainConfig(
        epochs=epochs,
        batch_size=batch_size,
        batches_per_epoch=batches,
        chunk_steps=25,
        chunks_per_batch=8,
        val_windows=200,
        learning_rate=1e-2,
        patience=10,  # not the epochs: a resume under raised epochs keeps its key
        seed=seed,
    )
    torch.manual_seed(np.random.default_rng().integers(1000))  # the global state must not count
    net = build_network(_small() if net_cfg is None else net_cfg)
    hist = train_network(
        net,
        sampler_for("cnn-gru-seq", train, norm, 5, tcfg),
        sampler_for("cnn-gru-seq", val, norm, 5, tcfg),
        tcfg,
        checkpoint=checkpoint,
    )
    return {k: v.clone() for k, v in net.state_dict().items()}, hist


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_training_is_seeded_and_a_resumed_training_equals_an_uninterrupted_one(
    tmp_path, trained_epochs
):
    whole, h_whole = _train(4)
    ck = tmp_path / "checkpoint.pt"
    half, _ = _train(2, ck)
    before = torch.load(ck, weights_only=True)["history"]
    trained_epochs()
    resumed, h_res = _train(4, ck)
    # it resumed: two epochs trained, the first two the checkpoint's (their own seconds)
    assert trained_epochs() == 2 and h_res[:2] == before
    assert [h["val_loss"] for h in h_res] == [h["val_loss"] for h in h_whole]
    assert _same(resumed, whole) and not _same(half, whole)
    other, _ = _train(2, seed=4)
    assert not _same(other, half)


def test_the_window_count_batch_size_does_not_restart_a_chunk_training(tmp_path, trained_epochs):
    """cnn-gru-seq draws ``chunks_per_batch`` chunks per mini-batch and never reads
    ``batch_size``: another ``--batch-size`` retrained its checkpoint from epoch 1 (it was
    in the key; the surrogate options audit)."""
    ck = tmp_path / "checkpoint.pt"
    _train(2, ck)
    trained_epochs()
    _, h = _train(3, ck, batch_size=7)
    assert trained_epochs() == 1 and len(h) == 3


def test_a_short_training_learns_the_lagged_response():
    """The targets lag the track input by a 5-step time constant (x_k = 0.8 x_(k-1) + 0.2 u_k):
    the validation loss (standardised, 1 for a constant guess) falls below 0.35, under what
    the inputs of the current and previous step alone explain (0.41 for the best linear fit
    of u_k and u_(k-1), which is all the pooling sees): the recurrent state is used."""
    cfg = NetConfig(**{**_small(dropout=0.0).to_dict(), "rnn_hidden": (16, 8)})
    _, hist = _train(6, batches=8, net_cfg=cfg)
    assert hist[-1]["train_loss"] < 0.5 * hist[0]["train_loss"]
    assert min(h["val_loss"] for h in hist) < 0.35


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """cnn-gru-seq trained (briefly) on a tiny many-track campaign through train_surrogate."""
    out = tmp_path_factory.mktemp("seq") / "run"
    cond = get_condition("straight", duration_s=2.0, n_steps=100, lead_in_m=30.0)
    cfg = make_config([cond], 12, batch_size=6, seed=5, parameters=KEYS, independent_seeds=True)
    run_campaign(cfg, out)
    tcfg = TrainConfig(
        epochs=2, batches_per_epoch=2, chunk_steps=60, chunks_per_batch=4, val_windows=100
    )
    sur = train_surrogate(out, "straight", kind="cnn-gru-seq", window=30, train=tcfg)
    return out, sur


def test_predict_keeps_the_window_networks_contract(trained):
    """(n_sets, T, 2) in kN, NaN during the washout, finite after; one call for many sets
    gives each set's own series; a saved and loaded bundle predicts the same numbers."""
    run, sur = trained
    assert sur.kind == "cnn-gru-seq" and sur.spec.window == 30
    x = np.array([[14e6, 5e6, 150e6, 1e6, 1.5e6, 60e3], [17e6, 6e6, 120e6, 0.95e6, 2e6, 50e3]])
    x = x[:, : len(sur.spec.parameters)]
    out = sur.predict(x)
    assert out.shape == (2, 100, 2)
    assert np.isnan(out[:, :30]).all() and np.isfinite(out[:, 30:]).all()
    np.testing.assert_allclose(sur.predict(x[1:]), out[1:], rtol=1e-5)
    np.testing.assert_allclose(sur.predict(x, fast=False), out, rtol=1e-5, atol=1e-6)
    back = load(run / "surrogates" / "cnn-gru-seq" / "straight")
    assert isinstance(back.net, CNNSequence) and back.net_config == sur.net_config
    np.testing.assert_array_equal(back.predict(x), out)
    rows = evaluate(back, _test_data(back, run))
    assert {r["target"] for r in rows} == {"Y", "Q"}
    assert all(np.isfinite(r["relative_error_of_mean"]) for r in rows)


def test_runs_each_on_its_own_track_are_predicted_together_as_one_by_one(trained):
    """``predict(track=(n, T, n_track))``, one track per set, gives each set what it gets
    alone on its track (segments and record correction included), and predict_series scores
    a campaign's runs that way in batches; a window network refuses per-set tracks."""
    run, sur = trained
    data = _test_data(sur, run)
    x = np.array(
        [[14.2e6, 5.2e6, 130e6, 0.9e6, 1.6e6, 52e3], [14.8e6, 6.1e6, 150e6, 1.2e6, 1.9e6, 61e3]]
    )
    x = np.vstack([x, x])[:, : len(sur.spec.parameters)]
    rng = np.random.default_rng(1)
    n_track = sur.spec.n_features - len(sur.spec.parameters)
    tracks = rng.standard_normal((4, 150, n_track))
    together = sur.predict(x, track=tracks)
    for i in range(4):
        np.testing.assert_allclose(
            together[i], sur.predict(x[i : i + 1], track=tracks[i])[0], rtol=1e-5, atol=1e-5
        )
    assert np.abs(together[0, 30:] - together[2, 30:]).max() > 1e-3  # the tracks matter
    from railsusp.surrogate.evaluate import _si, predict_series

    one_by_one = np.concatenate(
        [
            sur.predict(_si(sur, data.params_unit[i : i + 1]), track=data.track[i])
            for i in range(data.n_samples)
        ]
    )
    np.testing.assert_allclose(predict_series(sur, data), one_by_one, rtol=1e-5, atol=1e-5)
    with pytest.raises(ValueError, match="one track per set .* with n = 4 sets"):
        sur.predict(x, track=tracks[:3])


def test_a_long_record_is_predicted_in_segments_of_the_training_chunk(trained):
    """The bundle predicts in segments of its training chunk (60 steps here): a track three
    records long gives each step the output of the segment that keeps it, and
    ``meta["segment_steps"] = None`` the one run with the state carried (another answer)."""
    _, sur = trained
    assert sur.segment_steps == sur.meta["train_config"]["chunk_steps"] == 60
    x = np.array([[14.5e6, 5.5e6, 140e6, 1.1e6, 1.7e6, 55e3]])[:, : len(sur.spec.parameters)]
    rng = np.random.default_rng(0)
    n_track = sur.spec.n_features - len(sur.spec.parameters)
    track = 20 * rng.standard_normal((300, n_track))  # (the state matters on a rough one)
    out = sur.predict(x, track=track, corrected=False)
    feats = torch.from_numpy(
        np.concatenate(
            [np.repeat(sur._unit(x)[:, None], 300, 1), sur.normaliser.track(track[None])], 2
        ).astype(np.float32)
    )
    ref = sur.normaliser.target_inverse(sur.net.predict_series(feats, segment=60).numpy())
    np.testing.assert_allclose(out[:, 30:], ref[:, 30:], rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(
        sur.predict(x, track=track[:60], corrected=False), out[:, :60], rtol=1e-5
    )
    sur.meta["segment_steps"] = None
    try:
        carried = sur.predict(x, track=track, corrected=False)
    finally:
        del sur.meta["segment_steps"]
    np.testing.assert_allclose(carried[:, :60], out[:, :60], rtol=1e-5)
    assert np.abs(carried[:, 60:] - out[:, 60:]).max() > 1e-3


def test_the_cli_trains_the_kind_and_refuses_a_washout_as_long_as_the_records(trained):
    from typer.testing import CliRunner

    from railsusp.cli import app

    run, _ = trained
    result = CliRunner().invoke(app, ["train", str(run), "--model", "cnn-gru-seq"])
    assert result.exit_code == 2, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert errors == [
        "error: --window 100 steps (the default of cnn-gru-seq): accepted 2 to 99, fewer than "
        "the 100 steps of the series of condition 'straight'"
    ]


def _test_data(sur, run):
    from railsusp.campaign import load_campaign
    from railsusp.surrogate.data import load_series

    data = load_series(load_campaign(run), "straight", sur.spec)
    return data.subset(np.flatnonzero(np.isin(data.sample_ids, sur.meta["test_ids"])))


def test_the_bench_scripts_train_score_and_time_the_kind(trained):
    from conftest import bench_script

    run, sur = trained
    tracks = bench_script("surrogate_tracks")
    tcfg = TrainConfig(**sur.meta["train_config"])  # the finished training is reloaded
    rows = tracks.network_rows(
        run, "straight", kind="cnn-gru-seq", window=30, label="cnn-gru-seq", train=tcfg
    )
    assert [r["target"] for r in rows] == ["Y", "Q"]
    assert all(r["n_samples"] == len(sur.meta["test_ids"]) for r in rows)
    assert all(
        np.isfinite(r["relative_error_of_mean"]) and r["model"] == "cnn-gru-seq" for r in rows
    )
    assert "cnn-gru-seq" in tracks.NETWORKS
    bench = bench_script("surrogate")
    rand = bench.random_surrogate("cnn-gru-seq")
    assert rand.spec.window == rand.net_config.window == DEFAULT_WASHOUT
    assert bench.generation_seconds(rand, n_sets=2, n_steps=300, repeats=1) > 0


def test_chunk_settings_do_not_restart_a_window_training(tmp_path):
    """A window network's checkpoint resumes whatever the chunk settings (it does not use
    them); the sequence network's restarts when they change."""
    train, val = _data(6, 0), _data(3, 1)
    norm = Normaliser.fit(train)
    cfg = NetConfig(**{**_small().to_dict(), "kind": "bp", "mlp_hidden": (8,)})

    def run(epochs: int, chunk_steps: int, kind: str, net_cfg: NetConfig) -> list:
        tcfg = TrainConfig(
            epochs=epochs,
            batches_per_epoch=2,
            batch_size=16,
            val_windows=50,
            chunk_steps=chunk_steps,
        )
        return train_network(
            build_network(net_cfg),
            sampler_for(kind, train, norm, 5, tcfg),
            sampler_for(kind, val, norm, 5, tcfg),
            tcfg,
            checkpoint=tmp_path / f"{kind}.pt",
        )

    first = run(1, 20, "bp", cfg)
    assert run(2, 30, "bp", cfg)[0] == first[0]  # resumed: its first epoch kept
    first = run(1, 20, "cnn-gru-seq", _small())
    again = run(2, 30, "cnn-gru-seq", _small())
    assert again[0]["val_loss"] != first[0]["val_loss"]  # afresh, on other chunks
    assert run(3, 30, "cnn-gru-seq", _small())[:2] == again  # resumed
