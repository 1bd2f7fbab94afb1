"""The GRU and LSTM equations one step at a time, on oneDNN matmuls: the fast prediction
paths of the window CNN-recurrent networks (:meth:`CNNRecurrent.predict_series
<railsusp.surrogate.models.CNNRecurrent.predict_series>`) and the hidden-side products of
the sequence CNN-GRU's (:meth:`CNNSequence.predict_sets
<railsusp.surrogate.sequence.CNNSequence.predict_sets>`, whose float32 gates are one compiled
pass: :mod:`.gru_kernel`; these steps are its path for other precisions).

torch's own ``nn.GRU`` runs the same equations in a C++ loop, but with MKL's matmuls (on the
bench machine, an AMD EPYC, MKL seems to run its AVX2 kernels) and its CPU tanh, several
times slower than its sigmoid. These steps take the weights of a torch module
(:func:`cell_params`) and give its outputs to float32 rounding.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import torch
from torch import nn

#: torch has oneDNN's fused linear op (private to torch, pinned to 2.13); else MKL is used
ONEDNN = torch.backends.mkldnn.is_available() and hasattr(torch.ops.mkldnn, "_linear_pointwise")


def linear(x: torch.Tensor, w: torch.Tensor, b: torch.Tensor | None = None) -> torch.Tensor:
    """x W^T + b for 2-D float32 ``x``, through oneDNN where torch has it (the op torch's
    Inductor compiles CPU linear layers to), else torch.nn.functional.linear (MKL). For these
    thin matrices oneDNN measured about twice MKL's FLOP rate on the bench machine (AMD EPYC,
    where MKL seems to run its AVX2 kernels). The op is private to torch (pinned to 2.13): where it
    is missing, :data:`ONEDNN` is false and the torch path is taken."""
    if ONEDNN and x.dtype == torch.float32:
        return torch.ops.mkldnn._linear_pointwise(x, w, b, "none", [], "")
    return nn.functional.linear(x, w, b)


def linear_add(x: torch.Tensor, w: torch.Tensor, other: torch.Tensor) -> torch.Tensor:
    """other + x W^T (a new tensor), fused by oneDNN where available (see :func:`linear`)."""
    if ONEDNN and x.dtype == torch.float32:
        return torch.ops.mkldnn._linear_pointwise.binary(x, other, w, None, "add")
    return torch.addmm(other, x, w.t())


def cell_params(layer: nn.GRU | nn.LSTM, cell: str) -> list[tuple[torch.Tensor, ...]]:
    """Of a one-layer torch GRU or LSTM (``cell`` "gru" or "lstm"), per direction: (W_ih,
    input-side bias, W_hh, hidden-side bias or None), for :func:`gru_step` and
    :func:`lstm_step`.

    The biases that torch's equations add to the input projection are folded into it: for
    the LSTM b_ih + b_hh, for the GRU b_ih plus the r and z parts of b_hh; the GRU's
    hidden-side bias is (0, 0, b_hn), since the reset gate multiplies W_hn h + b_hn. The
    rows of the gate that goes through tanh (GRU n, LSTM g) are doubled, an exact scaling:
    the steps take tanh(y) = 2 sigmoid(2y) - 1, as torch's CPU tanh is several times
    slower than its sigmoid."""
    hs, dirs = layer.hidden_size, []
    scale = torch.ones(layer.weight_hh_l0.shape[0], 1)
    scale[2 * hs : 3 * hs] = 2.0
    for sfx in ("", "_reverse")[: 2 if layer.bidirectional else 1]:
        w_ih = getattr(layer, f"weight_ih_l0{sfx}") * scale
        w_hh = getattr(layer, f"weight_hh_l0{sfx}") * scale
        b_ih = getattr(layer, f"bias_ih_l0{sfx}")
        b_hh = getattr(layer, f"bias_hh_l0{sfx}")
        if cell == "lstm":
            dirs.append((w_ih, (b_ih + b_hh) * scale[:, 0], w_hh, None))
        else:
            b_in = torch.cat([b_ih[: 2 * hs] + b_hh[: 2 * hs], 2.0 * b_ih[2 * hs :]])
            b_h = torch.cat([torch.zeros(2 * hs), 2.0 * b_hh[2 * hs :]])
            dirs.append((w_ih, b_in, w_hh, b_h))
    return dirs


def tanh_from_doubled_(x: torch.Tensor) -> torch.Tensor:
    """tanh(y) from x = 2y, in place: 2 sigmoid(x) - 1 (to float32 rounding)."""
    return x.sigmoid_().mul_(2.0).sub_(1.0)


def gru_step(
    gi: torch.Tensor,
    h: torch.Tensor | None,
    w_hh: torch.Tensor,
    b_h: torch.Tensor,
    hidden_side: torch.Tensor | None = None,
) -> torch.Tensor:
    """One torch.nn.GRU step (its documented equations):
    r = sigmoid(W_ir x + b_ir + W_hr h + b_hr), z = sigmoid(W_iz x + b_iz + W_hz h + b_hz),
    n = tanh(W_in x + b_in + r * (W_hn h + b_hn)), h' = (1 - z) * n + z * h.

    ``gi``: the input terms (..., 3H) (b_hr, b_hz folded in, n rows doubled, see
    :func:`cell_params`), overwritten; ``h=None``: the zero state, whose hidden terms are just
    the biases ``b_h``. ``hidden_side``: W_hh h + b_h when the caller has computed it (several
    networks' in one batched product, :mod:`.sequence_sets`); otherwise it is
    ``linear(h, w_hh, b_h)``."""
    hs = gi.shape[-1] // 3
    if h is None:
        rz = gi[..., : 2 * hs].sigmoid_()
        n = tanh_from_doubled_(gi[..., 2 * hs :].addcmul_(rz[..., :hs], b_h[..., 2 * hs :]))
        return torch.addcmul(n, rz[..., hs:], n, value=-1.0)
    gh = linear(h, w_hh, b_h) if hidden_side is None else hidden_side
    rz = gi[..., : 2 * hs].add_(gh[..., : 2 * hs]).sigmoid_()
    n = tanh_from_doubled_(gi[..., 2 * hs :].addcmul_(rz[..., :hs], gh[..., 2 * hs :]))
    return torch.lerp(n, h, rz[..., hs:])


def lstm_step(
    gi: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor] | None, w_hh: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """One torch.nn.LSTM step (its documented equations): i, f, g, o = sigmoid, sigmoid,
    tanh, sigmoid of W_ih x + b_ih + W_hh h + b_hh; c' = f * c + i * g, h' = o * tanh(c').

    ``gi``: the input terms (both biases folded in, g rows doubled), may be overwritten;
    ``state=None``: the zero (h, c)."""
    hs = w_hh.shape[1]
    gates = gi if state is None else linear_add(state[0], w_hh, gi)
    gates.sigmoid_()
    i, f, o = gates[:, :hs], gates[:, hs : 2 * hs], gates[:, 3 * hs :]
    g = gates[:, 2 * hs : 3 * hs].mul_(2.0).sub_(1.0)  # tanh from the doubled rows
    c = i * g if state is None else torch.addcmul(f * state[1], i, g)
    return o * tanh_from_doubled_(c * 2.0), c


@contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """torch's intra-op thread count (and MKL's) at ``n`` inside, the count before restored
    after: the prediction's workers each run torch's products on one thread, so that no
    product waits for a thread that another process holds (issue 19's estimate under load,
    bench/README.md, "Predictions under outside load"); the posterior's small flows too."""
    before = torch.get_num_threads()
    if before != n:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        if torch.get_num_threads() != before:
            torch.set_num_threads(before)
