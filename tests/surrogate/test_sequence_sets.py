"""Several sequence CNN-GRUs run in step
(:func:`railsusp.surrogate.sequence_sets.predict_sets_in_step`): each network's outputs are
those it gives alone through :meth:`CNNSequence.predict_sets
<railsusp.surrogate.sequence.CNNSequence.predict_sets>` to float32 rounding, whatever the
record length, segments, blocks and groups; each network keeps its own weights and track;
networks that cannot share the loop are refused in one line."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_predict_sets import N_PAR, N_TRACK, _net  # a small network of the e30 network's shape

from railsusp.surrogate.bundle import series_features
from railsusp.surrogate.sequence import CNNSequence
from railsusp.surrogate.sequence_sets import architecture, predict_sets_in_step


def _params(n: int, seed: int = 1) -> torch.Tensor:
    return torch.rand(n, N_PAR, generator=torch.Generator().manual_seed(seed))


def _track(t_steps: int, n_tracks: int = 1, seed: int = 2) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.randn(n_tracks, t_steps, N_TRACK, generator=g)


def _reference(net: CNNSequence, params, track, segment=None) -> torch.Tensor:
    """The reference path: torch's GRU over the per-step inputs of whole series."""
    feats = series_features(params.numpy(), track.numpy()).astype(np.float32)
    return net.predict_series(torch.from_numpy(feats), segment=segment)


@pytest.mark.parametrize("n_nets", [2, 3])
@pytest.mark.parametrize(
    ("t_steps", "segment", "block_steps", "group_rows", "n_tracks"),
    [
        (50, None, 16, 512, 1),  # one run over the series, the last block shorter
        (50, None, 1, 3, 1),  # one step per block, groups of 3 sets
        (25, 40, 16, 512, 1),  # a record shorter than a segment: one run
        (40, 40, 7, 512, 1),  # a record as long as a segment: one run
        (130, 40, 16, 512, 1),  # segments, all sets' segments one batch
        (130, 40, 7, 9, 1),  # segments, blocks that do not divide them, groups of 2 sets
        (130, 40, 40, 1, 1),  # one block per segment, one set per group
        (90, 30, 16, 10, 7),  # one track per set, in groups
    ],
)
def test_networks_in_step_give_each_networks_own_outputs(
    n_nets, t_steps, segment, block_steps, group_rows, n_tracks
):
    nets = [_net(seed=g) for g in range(n_nets)]
    params = _params(7)
    tracks = [_track(t_steps, n_tracks, seed=10 + g) for g in range(n_nets)]
    out = predict_sets_in_step(
        nets, params, tracks, segment=segment, block_steps=block_steps, group_rows=group_rows
    )
    assert len(out) == n_nets
    for net, track, mine in zip(nets, tracks, out, strict=True):
        alone = net.predict_sets(
            params, track, segment=segment, block_steps=block_steps, group_rows=group_rows
        )
        assert mine.shape == alone.shape == (7, t_steps, 2)
        torch.testing.assert_close(mine, alone, rtol=1e-5, atol=1e-6)
        # and the reference path's numbers, which share no code with the fast one
        ref = _reference(net, params, track, segment)
        torch.testing.assert_close(mine, ref, rtol=1e-5, atol=1e-5)
    # the networks differ: each output is its own network's, not a copy of the first's
    assert (out[1] - out[0]).abs().max() > 1e-2


def test_one_network_twice_on_two_tracks_gives_its_output_on_each():
    net = _net()
    params = _params(5)
    a, b = _track(100, seed=3), _track(100, seed=4)
    out_a, out_b = predict_sets_in_step([net, net], params, [a, b], segment=35)
    torch.testing.assert_close(out_a, net.predict_sets(params, a, segment=35), rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(out_b, net.predict_sets(params, b, segment=35), rtol=1e-5, atol=1e-6)
    assert (out_a - out_b).abs().max() > 1e-2  # each track reached its own output


def test_one_network_alone_gives_the_same_bits_whatever_the_blocks():
    """The blocks only group the steps (each step's arithmetic is the same), so the
    one-network path's numbers do not depend on them: BLOCK_STEPS went from 16 to 8 at stop
    35 without moving a bit."""
    net = _net(washout=5, seed=4)
    params, track = _params(6), _track(110)
    outs = [net.predict_sets(params, track, segment=30, block_steps=b) for b in (1, 8, 16, 30)]
    assert all(torch.equal(outs[0], o) for o in outs[1:])
    torch.testing.assert_close(outs[0], _reference(net, params, track, 30), rtol=1e-5, atol=1e-5)


def test_each_network_keeps_its_own_weights_in_the_stack():
    """Mixed-up weights (a layer of one network in the other's place) would show: swapping
    the networks swaps the outputs, and each output is far from the other network's alone."""
    one, two = _net(seed=1), _net(seed=2)
    params, track = _params(5), _track(120, seed=5)
    kw = {"segment": 40, "block_steps": 9}
    first = predict_sets_in_step([one, two], params, [track, track], **kw)
    swapped = predict_sets_in_step([two, one], params, [track, track], **kw)
    torch.testing.assert_close(swapped[0], first[1], rtol=1e-6, atol=1e-7)
    torch.testing.assert_close(swapped[1], first[0], rtol=1e-6, atol=1e-7)
    alone = [one.predict_sets(params, track, **kw), two.predict_sets(params, track, **kw)]
    for g in range(2):
        torch.testing.assert_close(first[g], alone[g], rtol=1e-5, atol=1e-6)
        assert (first[g] - alone[1 - g]).abs().max() > 1e-2
    # a network whose last GRU only differs from the first's still gets its own outputs
    three = _net(seed=1)
    with torch.no_grad():
        three.rnn[2].weight_hh_l0.mul_(-1.5)
    mine = predict_sets_in_step([one, three], params, [track, track], **kw)[1]
    torch.testing.assert_close(mine, three.predict_sets(params, track, **kw), rtol=1e-5, atol=1e-6)
    assert (mine - alone[0]).abs().max() > 1e-3


def test_the_architecture_is_the_weights_shapes_the_washout_and_the_slope():
    assert architecture(_net(seed=0)) == architecture(_net(seed=1))
    assert architecture(_net()) != architecture(_net(layers=(8, 4, 2)))
    assert architecture(_net(washout=6)) != architecture(_net(washout=5))
    steeper = _net()
    steeper.conv[3].negative_slope = 0.1
    assert architecture(steeper) != architecture(_net())


def _steeper() -> CNNSequence:
    net = _net(seed=1)
    net.conv[3].negative_slope = 0.1
    return net


@pytest.mark.parametrize(
    ("other", "message"),
    [
        (lambda: _net(seed=1, layers=(8, 4, 2)), "networks of different architectures"),
        (lambda: _net(seed=1, washout=5), "networks of different architectures"),
        (_steeper, "weights, washout and slope all have one shape"),
    ],
)
def test_networks_of_different_architectures_are_refused_in_one_line(other, message):
    params, track = _params(3), _track(30)
    with pytest.raises(ValueError, match=message) as err:
        predict_sets_in_step([_net(), other()], params, [track, track])
    assert "\n" not in str(err.value)


def test_bad_tracks_counts_and_training_mode_are_refused_in_one_line():
    nets = [_net(seed=0), _net(seed=1)]
    params, track = _params(3), _track(30)
    cases = [
        ([track, _track(31)], r"track \(1, 31, 4\): accepted .*one shape for every network"),
        ([track, track.expand(3, -1, -1)], "one shape for every network"),
        ([track], "2 networks and 1 tracks: accepted one per network"),
        ([track, track, track], "2 networks and 3 tracks"),
    ]
    for tracks, message in cases:
        with pytest.raises(ValueError, match=message) as err:
            predict_sets_in_step(nets, params, tracks)
        assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match="0 networks and 0 tracks"):
        predict_sets_in_step([], params, [])
    nets[1].train()
    with pytest.raises(RuntimeError, match=r"call \.eval\(\) first"):
        predict_sets_in_step(nets, params, [track, track])
    nets[1].eval()
    out = predict_sets_in_step(nets, params[:0], [track, track])
    assert [o.shape for o in out] == [(0, 30, 2), (0, 30, 2)]


def test_networks_in_step_without_onednn_give_each_networks_own_outputs(monkeypatch):
    """Where torch lacks oneDNN's product, one network alone takes torch's; in step the
    products are torch's batched ones either way, and the outputs still agree."""
    from railsusp.surrogate import recurrence

    monkeypatch.setattr(recurrence, "ONEDNN", False)
    nets = [_net(seed=g) for g in range(3)]
    params, tracks = _params(5), [_track(100, seed=10 + g) for g in range(3)]
    together = predict_sets_in_step(nets, params, tracks, segment=35)
    for net, track, out in zip(nets, tracks, together, strict=True):
        alone = net.predict_sets(params, track, segment=35)
        torch.testing.assert_close(out, alone, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(out, _reference(net, params, track, 35), rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize(
    ("n", "most", "threads", "workers"),
    [(50, 64, 2, 2), (6, 64, 2, 1), (16, 64, 2, 2), (384, 64, 2, 2), (50, 64, 16, 6),
     (130, 64, 2, 2), (50, 64, 1, 1), (200, 25, 3, 3), (0, 64, 2, 1)],
)  # fmt: skip
def test_the_sets_are_shared_in_whole_rounds_of_chunks(n, most, threads, workers):
    from railsusp.surrogate.sequence_sets import MIN_SETS_PER_WORKER, set_chunks

    chunks, got = set_chunks(n, most, threads)
    assert got == workers
    edges = [0, *(hi for _, hi in chunks)]
    assert [lo for lo, _ in chunks] == edges[:-1] and edges[-1] == n  # contiguous, 0 to n
    sizes = [hi - lo for lo, hi in chunks]
    assert sum(sizes) == n and all(0 < s <= most for s in sizes)
    assert not sizes or max(sizes) - min(sizes) <= 1  # as equal as their count allows
    assert len(chunks) % workers == 0 or len(chunks) == n  # whole rounds of the workers
    assert workers == 1 or n // workers >= MIN_SETS_PER_WORKER  # no worker of a few sets


def test_the_workers_each_take_their_sets_on_one_thread(monkeypatch):
    """Each worker runs its sets with torch on one thread and the gate pass on the calling
    thread: a parallel pass per step (thousands a generation) waited for a thread that
    another process held, and an NSGA-II generation took 10-40 times longer on a 2-core
    machine with one other busy process (bench/README.md, "Predictions under outside
    load"). The outputs are those of one worker, bit for bit, and torch's thread count is
    restored after."""
    import threading

    from railsusp.surrogate import sequence_sets

    seen, chunks = [], []
    gates, segments = sequence_sets.gru_gates, sequence_sets._segments

    def spy(*args):
        seen.append((threading.get_ident(), torch.get_num_threads()))
        return gates(*args)

    def spy_segments(w, track_part, param_part, *args):
        chunks.append(param_part.shape[1])  # the sets of one worker's chunk
        return segments(w, track_part, param_part, *args)

    nets = [_net(seed=g) for g in range(2)]
    params, tracks = _params(32), [_track(90, seed=10 + g) for g in range(2)]
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        one = predict_sets_in_step(nets, params, tracks, segment=30)
        torch.set_num_threads(4)
        monkeypatch.setattr(sequence_sets, "gru_gates", spy)
        monkeypatch.setattr(sequence_sets, "_segments", spy_segments)
        four = predict_sets_in_step(nets, params, tracks, segment=30)
        assert torch.get_num_threads() == 4
    finally:
        torch.set_num_threads(before)
    assert {n for _, n in seen} == {1}  # every gate pass with torch on one thread
    assert chunks == [8, 8, 8, 8]  # four workers' chunks of 8 sets each
    assert threading.get_ident() not in {ident for ident, _ in seen}  # all in the workers
    for a, b in zip(one, four, strict=True):
        assert torch.equal(a, b)
