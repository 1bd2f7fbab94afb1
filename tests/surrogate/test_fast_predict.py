"""The whole-series fast path of the CNN-recurrent surrogates equals the per-window network."""

import numpy as np
import pytest
import torch

from railsusp.conditions import get_condition
from railsusp.surrogate import recurrence
from railsusp.surrogate.bundle import Surrogate, series_features
from railsusp.surrogate.data import Normaliser, gather_windows, window_index
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.models import NetConfig, build_network
from railsusp.vehicle.wagon import load_wagon

KEYS = ("X13", "X14", "X15", "X16", "X17", "X18")
SMALL = {"conv_channels": (8, 12), "rnn_hidden": (10, 6, 5), "dense": (8, 4)}
CASES = [
    ("cnn-gru", {}),
    ("cnn-lstm", {}),
    ("cnn-bilstm", {}),
    ("cnn-gru", {"bidirectional": True}),
    ("cnn-gru", SMALL),
    ("cnn-lstm", SMALL),
    ("cnn-bilstm", SMALL),
    ("cnn-gru", {**SMALL, "rnn_hidden": (7,), "window": 6}),
    ("cnn-bilstm", {**SMALL, "rnn_hidden": (7,), "window": 2}),
]


def _net(kind: str, opts: dict, seed: int = 0) -> torch.nn.Module:
    torch.manual_seed(seed)
    return build_network(NetConfig(kind=kind, **opts)).eval()


def _reference(net, feats: torch.Tensor, index: np.ndarray, window: int) -> torch.Tensor:
    steps = index[:, 1:2] + np.arange(-window + 1, 1)[None, :]
    with torch.inference_mode():
        return net(feats[index[:, 0:1], steps])


@pytest.mark.parametrize(("kind", "opts"), CASES)
def test_predict_series_equals_forward_on_every_window(kind, opts):
    """First and last windows of each series, random ones in between, several series in one
    call, out of order; chunks and series groups smaller than the call."""
    net = _net(kind, opts)
    window = net.window
    n, t_steps = 3, 45
    feats = torch.randn(n, t_steps, 21) * 2
    rng = np.random.default_rng(1)
    ends = np.r_[window - 1, window, t_steps - 1, rng.integers(window - 1, t_steps, 20)]
    index = np.stack([rng.integers(0, n, len(ends)), ends], 1)
    index = np.vstack([index, [[s, window - 1] for s in range(n)], [[2, t_steps - 1]]])
    ref = _reference(net, feats, index, window)
    fast = net.predict_series(feats, index, chunk=7, group_steps=2 * t_steps)
    assert fast.shape == ref.shape == (len(index), 2)
    assert torch.allclose(fast, ref, rtol=1e-4, atol=1e-5), (fast - ref).abs().max()
    # every window of every series, the 1-D form, one group and one chunk
    all_ends = np.arange(window - 1, t_steps)
    every = net.predict_series(feats, all_ends)
    assert every.shape == (n, len(all_ends), 2)
    pairs = window_index(n, t_steps, window - 1)
    ref_all = _reference(net, feats, pairs, window).reshape(every.shape)
    assert torch.allclose(every, ref_all, rtol=1e-4, atol=1e-5), (every - ref_all).abs().max()


@pytest.mark.parametrize("kind", ["cnn-gru", "cnn-bilstm"])
def test_predict_series_without_onednn(kind, monkeypatch):
    """The torch (MKL) matmuls taken where torch lacks oneDNN give the same outputs."""
    monkeypatch.setattr(recurrence, "ONEDNN", False)
    net = _net(kind, SMALL)
    feats = torch.randn(2, 40, 21)
    index = window_index(2, 40, 19)
    ref = _reference(net, feats, index, 20)
    assert torch.allclose(net.predict_series(feats, index), ref, rtol=1e-4, atol=1e-5)


def test_predict_series_rejects_bad_windows_and_training_mode():
    net = _net("cnn-gru", SMALL)
    feats = torch.zeros(2, 30, 21)
    assert net.predict_series(feats, np.zeros((0, 2), int)).shape == (0, 2)
    with pytest.raises(ValueError, match="window ends must lie in 19 .. 29"):
        net.predict_series(feats, np.array([[0, 18]]))
    with pytest.raises(ValueError, match="window ends"):
        net.predict_series(feats, np.array([[0, 30]]))
    with pytest.raises(ValueError, match="series index"):
        net.predict_series(feats, np.array([[2, 25]]))
    with pytest.raises(RuntimeError, match="eval"):
        net.train().predict_series(feats, np.array([[0, 25]]))


def test_series_features_hold_the_gathered_windows():
    rng = np.random.default_rng(0)
    params = rng.random((4, 6)).astype(np.float32)
    idx = window_index(4, 40, 20)
    for n_tracks in (1, 4):
        track = rng.random((n_tracks, 40, 15)).astype(np.float32)
        feats = series_features(params, track)
        assert feats.shape == (4, 40, 21)
        steps = idx[:, 1:2] + np.arange(-19, 1)[None, :]
        np.testing.assert_array_equal(
            feats[idx[:, 0:1], steps], gather_windows(params, track, idx, 20)
        )


@pytest.mark.parametrize("kind", ["cnn-gru", "cnn-bilstm", "bp"])
def test_bundle_predict_is_unchanged_by_the_fast_path(kind):
    """A surrogate bundle (random weights, no campaign needed) predicts the same force series
    through the fast path as through the per-window reference, and the same windows in any
    order and batch size."""
    cfg = NetConfig(kind=kind, **SMALL, mlp_hidden=(16,))
    torch.manual_seed(0)
    t_steps = 120
    sur = Surrogate(
        build_network(cfg),
        cfg,
        FeatureSpec(parameters=KEYS),
        Normaliser([0.0] * 15, [2.0] * 15, [10.0, 120.0], [5.0, 20.0]),
        get_condition("straight", duration_s=2.4, n_steps=t_steps, lead_in_m=30.0),
        load_wagon(),
        0,
    )
    from railsusp.params import bounds

    lo, hi = bounds(KEYS)
    x = lo + (hi - lo) * np.random.default_rng(3).random((5, len(KEYS)))
    track = np.random.default_rng(4).normal(size=(t_steps, 15))
    fast = sur.predict(x, track=track, batch_size=100)
    ref = sur.predict(x, track=track, fast=False)
    assert fast.shape == (5, t_steps, 2)
    assert np.isnan(fast[:, :20]).all() and np.isfinite(fast[:, 20:]).all()
    np.testing.assert_allclose(fast[:, 20:], ref[:, 20:], rtol=1e-5, atol=1e-4)
    # windows asked in a shuffled order, per-sample tracks
    unit = sur._unit(x)
    tr = sur.normaliser.track(np.stack([track * (1 + 0.1 * i) for i in range(5)]))
    idx = window_index(5, t_steps, 20)[np.random.default_rng(5).permutation(5 * 100)]
    a = sur.predict_windows(unit, tr, idx, batch_size=64)
    b = sur.predict_windows(unit, tr, idx, fast=False)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize(("window", "hidden", "n_tracks"), [(20, (256, 128, 64), 1), (5, (9,), 3)])
def test_bp_predict_series_equals_forward_on_every_window(window, hidden, n_tracks):
    """The BP network's split first layer (track convolution + summed parameter weights)
    gives what the network gives on each gathered window: first and last windows, random
    ones out of order, one shared track or one per sample, chunks smaller than the call."""
    torch.manual_seed(2)
    net = build_network(NetConfig(kind="bp", window=window, mlp_hidden=hidden)).eval()
    rng = np.random.default_rng(6)
    n, t_steps = 3, 50
    params = rng.random((n, 6)).astype(np.float32)
    track = rng.normal(size=(n_tracks, t_steps, 15)).astype(np.float32) * 2
    ends = np.r_[window - 1, t_steps - 1, rng.integers(window - 1, t_steps, 30)]
    index = np.stack([rng.integers(0, n, len(ends)), ends], 1)
    with torch.inference_mode():
        ref = net(torch.from_numpy(gather_windows(params, track, index, window)))
        fast = net.predict_series(torch.from_numpy(params), torch.from_numpy(track), index, chunk=7)
    assert fast.shape == ref.shape == (len(index), 2)
    assert torch.allclose(fast, ref, rtol=1e-5, atol=1e-5), (fast - ref).abs().max()
    # a parameter change moves only the parameter part: the track's convolution is shared
    params2 = params.copy()
    params2[0] += 0.5
    with torch.inference_mode():
        ref2 = net(torch.from_numpy(gather_windows(params2, track, index, window)))
        fast2 = net.predict_series(torch.from_numpy(params2), torch.from_numpy(track), index)
    assert torch.allclose(fast2, ref2, rtol=1e-5, atol=1e-5)
    assert not torch.allclose(fast2[index[:, 0] == 0], fast[index[:, 0] == 0])


def test_a_surrogate_of_an_older_wagon_description_is_refused_in_one_line(tmp_path):
    import json

    from railsusp.errors import RailsuspInputError
    from railsusp.surrogate.bundle import load

    cfg = NetConfig(kind="bp", mlp_hidden=(4,))
    sur = Surrogate(
        build_network(cfg),
        cfg,
        FeatureSpec(parameters=KEYS),
        Normaliser([0.0] * 15, [2.0] * 15, [10.0, 120.0], [5.0, 20.0]),
        get_condition("straight"),
        load_wagon(),
        0,
    )
    sur.save(tmp_path / "s")
    assert load(tmp_path / "s").wagon == load_wagon()
    meta = tmp_path / "s" / "surrogate.json"
    doc = json.loads(meta.read_text())
    del doc["wagon"]["centre_plate"]["rocking_stiffness"]  # as saved before 2026-11-24
    meta.write_text(json.dumps(doc))
    with pytest.raises(RailsuspInputError, match="centre_plate.rocking_stiffness.*train it again"):
        load(tmp_path / "s")
