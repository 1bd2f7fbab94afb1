"""The sequence CNN-GRU's compiled gate pass (:mod:`railsusp.surrogate.gru_kernel`): torch's
GRU equations to float32 rounding over many steps, from the zero state and from a carried
one, for several networks at once; its logistic function against the exact one; NaN kept."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numba as nb
import numpy as np
import pytest
import torch
from torch import nn

from railsusp.surrogate.gru_kernel import _sigmoid, gru_gates
from railsusp.surrogate.recurrence import cell_params, linear
from railsusp.vehicle.kernel_cache import FASTMATH


@nb.njit(cache=False, fastmath=FASTMATH, error_model="numpy")  # (as the kernel compiles it)
def _sigmoids(x):
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        out[i] = _sigmoid(x[i])
    return out


def test_logistic_function_is_exact_to_well_below_float32():
    x = np.concatenate([np.linspace(-40.0, 40.0, 200_001), [0.0, -0.0, 1e-300, -1e-300]])
    e = np.exp(-np.abs(x))
    exact = np.where(x >= 0.0, 1.0 / (1.0 + e), e / (1.0 + e))  # no overflow or cancellation
    got = _sigmoids(x)
    # beyond |x| = 24 the function is clamped: e^-24 = 3.8e-11 from 0 or 1 at most, far
    # below float32's 6e-8 at the gates' sums
    assert np.max(np.abs(got - exact)) < 4e-11
    inside = np.abs(x) <= 24.0
    assert np.max(np.abs(got - exact)[inside]) < 1e-13
    # and relative, where the values are small: float32's resolution there is 6e-8
    assert np.max(np.abs(got[inside] / exact[inside] - 1.0)) < 1e-7
    assert np.all(np.diff(got[:200_001]) >= 0.0)  # monotone over the sorted part


def test_logistic_function_keeps_nan_and_saturates_at_infinity():
    got = _sigmoids(np.array([np.nan, np.inf, -np.inf]))
    assert np.isnan(got[0])
    assert got[1] == pytest.approx(1.0, abs=1e-10)
    assert got[2] == pytest.approx(0.0, abs=1e-10)


def _steps_torch(gates, w_hh, b_h, h0):
    """torch's nn.GRU recurrence (its equations, as CNNSequence.steps runs them) over k steps."""
    hs = w_hh.shape[1]
    h, out = h0.clone(), []
    for t in range(gates.shape[0]):
        gh = h @ w_hh.t() + b_h
        r = torch.sigmoid(gates[t, :, :hs] + gh[:, :hs])
        z = torch.sigmoid(gates[t, :, hs : 2 * hs] + gh[:, hs : 2 * hs])
        n = torch.tanh(0.5 * (gates[t, :, 2 * hs :] + r * gh[:, 2 * hs :]))  # rows doubled
        h = (1.0 - z) * n + z * h
        out.append(h)
    return torch.stack(out)


@pytest.mark.parametrize("hidden", [16, 7])
def test_gate_pass_gives_torch_gru_outputs_for_several_networks(hidden):
    torch.manual_seed(3)
    n_net, k, rows, n_in = 3, 40, 70, 5  # rows not a multiple of the chunk
    grus = [nn.GRU(n_in, hidden) for _ in range(n_net)]
    for g in grus:  # weights of a trained network's size, so that the gates saturate too
        with torch.no_grad():
            for p in g.parameters():
                p.mul_(4.0)
    x = torch.randn(k, rows, n_in)
    h0 = torch.randn(n_net, rows, hidden) * 0.5
    with torch.inference_mode():
        cells = [cell_params(g, "gru")[0] for g in grus]
        flat = x.reshape(-1, n_in)
        gates = torch.stack(
            [linear(flat, w_ih, b_in).view(k, rows, -1) for w_ih, b_in, _, _ in cells]
        ).contiguous()
        for start in ("zero", "carried"):
            state = np.zeros((n_net, rows, hidden), np.float32)
            if start == "carried":
                state[:] = h0.numpy()
            before = torch.from_numpy(state.copy())
            seq = np.empty((n_net, k, rows, hidden), np.float32)
            h = torch.from_numpy(state)  # the kernel updates it in place
            for t in range(k):
                side = torch.stack([linear(h[g], c[2], c[3]) for g, c in enumerate(cells)])
                gru_gates(gates.numpy(), t, side.contiguous().numpy(), state, seq)
            for g, (_, _, w_hh, b_h) in enumerate(cells):
                ref = _steps_torch(gates[g], w_hh, b_h, before[g])
                np.testing.assert_allclose(seq[g], ref.numpy(), rtol=0, atol=5e-6)
                # the same as torch's own nn.GRU on the inputs
                own, _ = grus[g](x, before[g][None])
                np.testing.assert_allclose(seq[g], own.numpy(), rtol=0, atol=5e-6)
            np.testing.assert_array_equal(state, seq[:, -1])  # the last step's states


def test_gate_pass_propagates_a_nan_row_only():
    hs, rows = 4, 40
    gates = np.zeros((1, 1, rows, 3 * hs), np.float32)
    gates[0, 0, 5, 0] = np.nan
    state = np.zeros((1, rows, hs), np.float32)
    seq = np.empty((1, 1, rows, hs), np.float32)
    gru_gates(gates, 0, np.zeros((1, rows, 3 * hs), np.float32), state, seq)
    assert np.isnan(seq[0, 0, 5, 0])
    assert np.isfinite(np.delete(seq[0, 0], 5, axis=0)).all()


def test_a_prediction_leaves_torch_thread_count_alone():
    """The first use of Numba's thread pool in a process sets OpenMP's thread count, which
    torch shares: a process told to use one thread must keep predicting on one (a fresh
    process, since the pool starts once per process)."""
    script = textwrap.dedent(
        """
        import torch
        from railsusp.surrogate.models import NetConfig, build_network
        cfg = NetConfig(kind="cnn-gru-seq", n_features=5, window=4, conv_channels=(5, 6),
                        rnn_hidden=(4, 3), dense=(4,), dropout=0.0)
        net = build_network(cfg).eval()
        before = torch.get_num_threads()
        net.predict_sets(torch.rand(3, 2), torch.randn(1, 30, 3), segment=20)
        print(before, torch.get_num_threads())
        """
    )
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "2"}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.split() == ["1", "1"]
