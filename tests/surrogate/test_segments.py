"""The sequence CNN-GRU on records longer than its training chunks: segments of the chunk's
length, each from the zero state a washout before the steps it keeps, stitched
(:func:`railsusp.surrogate.sequence.segment_plan`, ``predict_series(segment=...)``)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from railsusp.surrogate.models import NetConfig, build_network
from railsusp.surrogate.sequence import segment_plan

N_FEATURES = 4


def _net(washout: int, seed: int = 0):
    torch.manual_seed(seed)
    cfg = NetConfig(
        kind="cnn-gru-seq",
        n_features=N_FEATURES,
        window=washout,
        conv_channels=(N_FEATURES, 8),
        rnn_hidden=(8, 4),
        dense=(8,),
        dropout=0.2,
    )
    return build_network(cfg).eval()


@settings(max_examples=200, deadline=None)
@given(
    washout=st.integers(0, 50),
    extra=st.integers(1, 80),
    t_steps=st.integers(1, 700),
)
def test_the_plan_tiles_the_record_with_equal_segments_each_a_washout_ahead(
    washout, extra, t_steps
):
    """Kept stretches tile 0 .. T - 1 once, in order; every segment lies in the record and is
    ``segment`` steps long (or the whole record when shorter); each later one starts at least
    a washout before its first kept step and covers its kept stretch."""
    segment = washout + extra
    plan = segment_plan(t_steps, segment, washout)
    length = min(segment, t_steps)
    assert plan[0] == (0, 0)
    ends = [keep for _, keep in plan[1:]] + [t_steps]
    kept = np.concatenate([np.arange(k, e) for (_, k), e in zip(plan, ends, strict=True)])
    np.testing.assert_array_equal(kept, np.arange(t_steps))
    for (start, keep), end in zip(plan, ends, strict=True):
        assert 0 <= start and start + length <= t_steps
        assert start <= keep < end <= start + length
        if keep > 0:
            assert keep - start >= washout
    if t_steps > segment:  # stride segment - washout, all but the last exactly a washout ahead
        assert all(k - s == washout for s, k in plan[1:-1])
        assert np.all(np.diff([k for _, k in plan[1:]]) == segment - washout)


def test_the_plan_refuses_a_segment_no_longer_than_the_washout():
    with pytest.raises(ValueError, match="segment = 100 steps: accepted more than the washout of"):
        segment_plan(1000, 100, 100)
    assert segment_plan(400, 400, 100) == [(0, 0)]
    assert segment_plan(1000, 400, 100) == [(0, 0), (300, 400), (600, 700)]
    # the last moved back to end at the record's end
    assert segment_plan(1050, 400, 100) == [(0, 0), (300, 400), (600, 700), (650, 1000)]


def test_the_stitched_prediction_equals_each_segment_run_alone():
    net = _net(washout=5)
    x = torch.randn(3, 97, N_FEATURES)
    out = net.predict_series(x, segment=20)
    plan = segment_plan(97, 20, 5)
    ends = [keep for _, keep in plan[1:]] + [97]
    for (start, keep), end in zip(plan, ends, strict=True):
        alone = net.predict_series(x[:, start : start + 20])
        torch.testing.assert_close(
            out[:, keep:end], alone[:, keep - start : end - start], rtol=1e-6, atol=1e-7
        )
    # the one-step-at-a-time reference gives the same stitched numbers
    torch.testing.assert_close(
        net.predict_series(x, segment=20, stepwise=True), out, rtol=1e-5, atol=1e-6
    )
    # and groups of segments the same as one batch
    torch.testing.assert_close(net.predict_series(x, segment=20, group_steps=40), out)
    # the carried state gives another answer beyond the first segment
    assert (net.predict_series(x)[:, 20:] - out[:, 20:]).abs().max() > 1e-4


@pytest.mark.parametrize("t_steps", [1, 7, 20])
def test_a_record_no_longer_than_a_segment_gives_exactly_one_run(t_steps):
    net = _net(washout=5)
    x = torch.randn(2, t_steps, N_FEATURES)
    assert torch.equal(net.predict_series(x, segment=20), net.predict_series(x))


@settings(max_examples=25, deadline=None)
@given(step=st.integers(0, 139), seed=st.integers(0, 2**16))
def test_no_output_reads_more_than_a_segment_of_input(step, seed):
    """Bounded memory, whatever the record's length: the output at step k is unchanged by
    any input before step k - segment + 1 (bitwise up to float32 rounding of the batch)."""
    net = _net(washout=5)
    gen = torch.Generator().manual_seed(seed)
    x = torch.randn(1, 140, N_FEATURES, generator=gen)
    y = x.clone()
    first = max(0, step - 20 + 1)
    y[:, :first] = 10 * torch.randn(1, first, N_FEATURES, generator=gen)
    a = net.predict_series(x, segment=20)[:, step]
    b = net.predict_series(y, segment=20)[:, step]
    torch.testing.assert_close(a, b, rtol=0, atol=1e-6)


def test_a_record_of_three_identical_stretches_predicts_three_identical_stretches():
    """Drift bounded: three copies of one 40-step input give, after the first segment, the
    same output in each copy (segments of 20 steps, washout 10: the copies' segments read
    the same inputs)."""
    net = _net(washout=10, seed=3)
    one = torch.randn(2, 40, N_FEATURES)
    x = one.repeat(1, 3, 1)
    out = net.predict_series(x, segment=20)
    torch.testing.assert_close(out[:, 60:100], out[:, 20:60], rtol=0, atol=1e-6)
    torch.testing.assert_close(out[:, 80:120], out[:, 40:80], rtol=0, atol=1e-6)
