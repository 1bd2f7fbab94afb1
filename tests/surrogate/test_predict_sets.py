"""The sequence CNN-GRU's fast path for many parameter sets on one track
(:meth:`railsusp.surrogate.sequence.CNNSequence.predict_sets`): the numbers of the reference
path (:meth:`~railsusp.surrogate.sequence.CNNSequence.predict_series` on the per-step inputs
of :func:`~railsusp.surrogate.bundle.series_features`) to float32 rounding, whatever its
blocks, groups and segments, with and without oneDNN."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from railsusp.surrogate import recurrence
from railsusp.surrogate.bundle import series_features
from railsusp.surrogate.models import NetConfig, build_network
from railsusp.surrogate.sequence import CNNSequence

N_PAR, N_TRACK = 3, 4


def _net(washout: int = 6, seed: int = 0, layers: tuple[int, ...] = (8, 4, 3)) -> CNNSequence:
    """A small network of the e30 network's shape: three GRUs, head 8 -> 5 -> outputs."""
    torch.manual_seed(seed)
    cfg = NetConfig(
        kind="cnn-gru-seq",
        n_features=N_PAR + N_TRACK,
        window=washout,
        conv_channels=(N_PAR + N_TRACK, 12),
        rnn_hidden=layers,
        dense=(8, 5),
        dropout=0.2,
    )
    net = build_network(cfg).eval()
    with torch.no_grad():  # biases of a trained network's size, so that every term counts
        for p in net.parameters():
            p.mul_(2.0)
    return net


def _inputs(n: int, t_steps: int, n_tracks: int = 1, seed: int = 1):
    g = torch.Generator().manual_seed(seed)
    return torch.rand(n, N_PAR, generator=g), torch.randn(n_tracks, t_steps, N_TRACK, generator=g)


def _reference(net: CNNSequence, params, track, segment=None, stepwise=False) -> torch.Tensor:
    feats = series_features(params.numpy(), track.numpy()).astype(np.float32)
    return net.predict_series(torch.from_numpy(feats), segment=segment, stepwise=stepwise)


@pytest.mark.parametrize(
    ("t_steps", "segment", "block_steps", "group_rows"),
    [
        (50, None, 16, 512),  # one run over the series, blocks of 16 (the last shorter)
        (50, None, 1, 512),  # one step per block: the state carried across every step
        (50, None, 64, 3),  # one block; groups of 3 sets
        (130, 40, 16, 512),  # segments, all sets' segments one batch
        (130, 40, 7, 9),  # segments, blocks that do not divide the segment, groups of 2 sets
        (130, 40, 40, 1),  # one block per segment, one set per group
        (40, 40, 5, 512),  # a record as long as a segment: one run
    ],
)
def test_the_fast_path_gives_the_reference_numbers(t_steps, segment, block_steps, group_rows):
    net = _net()
    params, track = _inputs(7, t_steps)
    ref = _reference(net, params, track, segment)
    out = net.predict_sets(
        params, track, segment=segment, block_steps=block_steps, group_rows=group_rows
    )
    assert out.shape == ref.shape == (7, t_steps, 2)
    torch.testing.assert_close(out, ref, rtol=1e-5, atol=1e-5)
    # the one-step-at-a-time reference (torch's GRU, state carried within each segment)
    torch.testing.assert_close(
        out, _reference(net, params, track, segment, stepwise=True), rtol=1e-5, atol=1e-5
    )


def test_a_track_per_set_gives_each_set_its_own_track():
    net = _net()
    params, track = _inputs(4, 90, n_tracks=4)
    out = net.predict_sets(params, track, segment=30, group_rows=10)
    torch.testing.assert_close(out, _reference(net, params, track, 30), rtol=1e-5, atol=1e-5)
    alone = net.predict_sets(params[2:3], track[2:3], segment=30)
    torch.testing.assert_close(out[2:3], alone, rtol=1e-5, atol=1e-5)
    # and the track matters: set 2 on set 0's track is another series
    assert (net.predict_sets(params[2:3], track[:1], segment=30) - alone).abs().max() > 1e-3


def test_the_parameters_and_each_step_of_the_track_reach_the_output():
    """The split first convolution keeps both parts: changing one set's parameters changes
    its series only; changing the shared track at step k changes every set from k on and
    nothing before k (causal), within the segment that reads it."""
    net = _net()
    params, track = _inputs(3, 60)
    base = net.predict_sets(params, track)
    moved = params.clone()
    moved[1, 0] += 0.5
    out = net.predict_sets(moved, track)
    assert torch.equal(out[[0, 2]], base[[0, 2]])
    assert (out[1] - base[1]).abs().max() > 1e-3
    bumped = track.clone()
    bumped[0, 25] += 2.0
    out = net.predict_sets(params, bumped)
    assert torch.equal(out[:, :25], base[:, :25])
    assert (out[:, 25] - base[:, 25]).abs().min() > 0.0


def test_the_torch_matmuls_without_onednn_give_the_same_numbers(monkeypatch):
    net = _net()
    params, track = _inputs(5, 100)
    fast = net.predict_sets(params, track, segment=35)
    monkeypatch.setattr(recurrence, "ONEDNN", False)
    torch.testing.assert_close(net.predict_sets(params, track, segment=35), fast)
    torch.testing.assert_close(fast, _reference(net, params, track, 35), rtol=1e-5, atol=1e-5)


def test_bad_inputs_and_training_mode_are_refused_in_one_line():
    net = _net()
    params, track = _inputs(3, 20)
    with pytest.raises(ValueError, match=r"params \(3, 3\) and track \(2, 20, 4\): accepted"):
        net.predict_sets(params, track.expand(2, -1, -1))
    with pytest.raises(ValueError, match="n_par \\+ n_track = 7"):
        net.predict_sets(params[:, :2], track)
    with pytest.raises(RuntimeError, match="eval"):
        net.train().predict_sets(params, track)
    assert net.eval().predict_sets(params[:0], track).shape == (0, 20, 2)


def test_a_float64_network_keeps_float64_through_its_gates():
    """The compiled gate pass is float32's; a float64 network takes torch's steps and keeps
    its precision (the reference path to 1e-12, far below float32's 1e-7)."""
    net = _net().double()
    params, track = _inputs(5, 60)
    feats = series_features(params.numpy(), track.numpy())
    ref = net.predict_series(torch.from_numpy(feats), segment=40)
    out = net.predict_sets(params.double(), track.double(), segment=40)
    assert out.dtype == torch.float64
    torch.testing.assert_close(out, ref, rtol=1e-12, atol=1e-12)
