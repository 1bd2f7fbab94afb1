"""The sequence CNN-GRU's prediction for many parameter sets: one network, or the networks of
several working conditions in step.

NSGA-II asks, every generation, for the forces of the same parameter sets in each recorded
condition, and each condition has its own network of one architecture (the study's layers;
bench/networks_c80_k6.txt). The fast path (:meth:`CNNSequence.predict_sets
<railsusp.surrogate.sequence.CNNSequence.predict_sets>`) runs the segments of all sets a few
steps at a time; its GRU recurrences are one small matrix product and the gate equations
per layer and step, which at the 200 rows of a demo generation cost torch's dispatch more
than their arithmetic (bench/README.md, "The recorded conditions' networks in step").
:func:`predict_sets_in_step` therefore runs G networks through the same loop at once:

* the recurrences' hidden-side products of all G networks are one batched product
  (``torch.baddbmm``), their gates one compiled pass over the (G, rows, ...) stack
  (:func:`~railsusp.surrogate.gru_kernel.gru_gates`), and every pooling and activation one
  call on the stack;
* the per-block input products (the second convolution, each GRU's input projection, the
  dense head: thousands of rows) stay one product per network, written into one buffer.

Each network's outputs are those it gives alone to float32 rounding, not bit for bit: one
network alone takes oneDNN's product where torch has it
(:func:`~railsusp.surrogate.recurrence.linear`, its numbers unchanged), several in step
MKL's ``addmm`` and ``baddbmm``, which sum in another order (on the shipped networks at
most 1.6e-5 kN apart; the tests check 1e-5 relative). One network through
:func:`predict_sets_in_step` is the one-network path.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from itertools import pairwise

import torch
from torch import nn

from railsusp.surrogate.gru_kernel import gru_gates
from railsusp.surrogate.recurrence import cell_params, gru_step, linear, torch_threads

#: time steps of all segments run through the layers together, so that a block's activations
#: stay in the processor's cache between the layers (16 until stop 35; 8 measured 4-7 % faster
#: at 500 segments on a Zen 4, the same at 200, the outputs bit for bit the same)
BLOCK_STEPS = 8
#: segments (parameter sets x segments of each) run as one batch, per network
GROUP_ROWS = 512
#: parameter sets a prediction's worker takes at least (:func:`set_chunks`)
MIN_SETS_PER_WORKER = 8


def segment_plan(t_steps: int, segment: int, washout: int) -> list[tuple[int, int]]:
    """How a series of ``t_steps`` steps is predicted as segments of ``segment`` steps, each
    run from the zero state: (first input step, first kept output step) per segment. Segment
    j reads steps start .. start + segment - 1 and gives the outputs from its kept step to the
    next segment's kept step (the last: to the series' end). The first segment starts and
    keeps at step 0 (its washout is the series', masked by the caller); every later one
    starts at least ``washout`` steps before the first step it keeps (exactly that many, but
    the last, which is moved back to end at the series' end so that all segments have the
    same length). Successive kept stretches are ``segment - washout`` steps long."""
    if segment <= washout:
        raise ValueError(
            f"segment = {segment} steps: accepted more than the washout of {washout} steps"
        )
    if t_steps <= segment:
        return [(0, 0)]
    plan = [(0, 0)]
    keep = segment
    while keep < t_steps:
        plan.append((min(keep - washout, t_steps - segment), keep))
        keep += segment - washout
    return plan


def architecture(net: nn.Module) -> tuple:
    """What networks must share to run in step: every weight's shape and type, the washout
    and the leaky ReLU's slope."""
    return (
        tuple((tuple(p.shape), p.dtype) for p in net.parameters()),
        net.washout,
        net.conv[3].negative_slope,
    )


@dataclass(frozen=True)
class _Weights:
    """The G networks' weights as the loop uses them: per network for the block products,
    stacked for the recurrences' hidden side."""

    conv2: list[tuple[torch.Tensor, torch.Tensor]]
    slope: float
    cells: list[tuple[list[tuple[torch.Tensor, torch.Tensor]], torch.Tensor, torch.Tensor]]
    head: list[list[tuple[torch.Tensor, torch.Tensor]] | nn.Module]
    n_out: int

    @classmethod
    def of(cls, nets: Sequence[nn.Module]) -> _Weights:
        first = nets[0]
        conv2 = [(n.conv[2].weight[:, :, 0], n.conv[2].bias) for n in nets]
        cells = []
        for i in range(len(first.rnn)):
            per_net = [cell_params(n.rnn[i], "gru")[0] for n in nets]
            inputs = [(w_ih, b_in) for w_ih, b_in, _, _ in per_net]
            if len(nets) == 1:  # the hidden side as one network alone computes it
                w_hh, b_h = per_net[0][2][None], per_net[0][3][None]
            else:  # (G, H, 3H) and (G, 1, 3H) for one batched product
                w_hh = torch.stack([c[2].t() for c in per_net]).contiguous()
                b_h = torch.stack([c[3] for c in per_net])[:, None]
            cells.append((inputs, w_hh, b_h))
        head: list = []
        for j, layer in enumerate(first.head):
            if isinstance(layer, nn.Linear):
                head.append([(n.head[j].weight, n.head[j].bias) for n in nets])
            else:
                head.append(layer)
        return cls(conv2, first.conv[3].negative_slope, cells, head, first.head[-1].out_features)


def _each(x: torch.Tensor, weights: list[tuple[torch.Tensor, torch.Tensor]]) -> torch.Tensor:
    """x_g W_g^T + b_g for each network g of (G, rows, F) ``x`` -> (G, rows, out)."""
    if len(weights) == 1:
        return linear(x[0], *weights[0])[None]
    out = torch.empty(x.shape[0], x.shape[1], weights[0][0].shape[0], dtype=x.dtype)
    for g, (w, b) in enumerate(weights):
        torch.addmm(b, x[g], w.t(), out=out[g])
    return out


def _hidden_side(h: torch.Tensor, w_hh: torch.Tensor, b_h: torch.Tensor) -> torch.Tensor:
    """W_hh h + b_h of each network for the (G, rows, H) hidden states: one network's as
    :func:`~railsusp.surrogate.recurrence.gru_step` computes it, several as one batched
    product."""
    if h.shape[0] == 1:
        return linear(h[0], w_hh[0], b_h[0])[None]
    return torch.baddbmm(b_h, h, w_hh)


def gru_steps(
    gates: torch.Tensor, state: torch.Tensor | None, w_hh: torch.Tensor, b_h: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """k steps of G GRUs over ``rows`` rows each: (every step's hidden states (G, k, rows, H),
    the state after the last). ``gates``: (G, k, rows, 3H) contiguous, the input side
    (:func:`~railsusp.surrogate.recurrence.cell_params`'s folding and doubling; may be
    overwritten); ``state``: (G, rows, H), or None for the zero state; ``w_hh``, ``b_h`` as
    :class:`_Weights` keeps them. Per step the hidden side's product is torch's
    (:func:`_hidden_side`); in float32 the gates are one compiled pass
    (:func:`~railsusp.surrogate.gru_kernel.gru_gates`, which updates the state in place),
    in other precisions torch's steps (:func:`~railsusp.surrogate.recurrence.gru_step`)."""
    n_nets, k, rows, h3 = gates.shape
    seq = torch.empty(n_nets, k, rows, h3 // 3, dtype=gates.dtype)
    if gates.dtype != torch.float32:
        for t in range(k):
            side = None if state is None else _hidden_side(state, w_hh, b_h)
            state = gru_step(gates[:, t], state, w_hh, b_h, hidden_side=side)
            seq[:, t] = state
        return seq, state
    if state is None:  # the zero state: its hidden side is b_h exactly
        state = torch.zeros(n_nets, rows, h3 // 3, dtype=gates.dtype)
    state_np, gates_np, seq_np = state.numpy(), gates.numpy(), seq.numpy()
    for t in range(k):
        side = _hidden_side(state, w_hh, b_h)
        gru_gates(gates_np, t, side.contiguous().numpy(), state_np, seq_np)
    return seq, state


@torch.inference_mode()
def predict_sets_in_step(
    nets: Sequence[nn.Module],
    params: torch.Tensor,
    tracks: Sequence[torch.Tensor],
    *,
    segment: int | None = None,
    block_steps: int = BLOCK_STEPS,
    group_rows: int = GROUP_ROWS,
) -> list[torch.Tensor]:
    """Each network's :meth:`CNNSequence.predict_sets
    <railsusp.surrogate.sequence.CNNSequence.predict_sets>` outputs (n, T, n_outputs) for
    the parameter sets ``params`` (n, n_par, the same sets for every network: their unit
    values) on its own track features ``tracks[g]`` (1 or n, T, n_track; all of one shape),
    the networks run in step (see the module's docstring). The networks must be of one
    architecture (:func:`architecture`) and in eval mode; ``segment``, ``block_steps`` and
    ``group_rows`` as ``predict_sets``."""
    if not nets or len(tracks) != len(nets):
        raise ValueError(f"{len(nets)} networks and {len(tracks)} tracks: accepted one per network")
    if any(n.training for n in nets):
        raise RuntimeError("predict_sets computes eval-mode outputs; call .eval() first")
    if len({architecture(n) for n in nets}) > 1:
        raise ValueError(
            "networks of different architectures cannot run in step: accepted networks whose "
            "weights, washout and slope all have one shape"
        )
    w = next(nets[0].parameters())
    params = torch.as_tensor(params).to(w.dtype)
    tracks = [torch.as_tensor(t).to(w.dtype) for t in tracks]
    c1 = nets[0].conv[0]
    n, n_par = params.shape
    for track in tracks:
        if (
            track.ndim != 3
            or track.shape != tracks[0].shape
            or track.shape[0] not in (1, n)
            or n_par + track.shape[2] != c1.in_channels
        ):
            raise ValueError(
                f"params {tuple(params.shape)} and track {tuple(track.shape)}: accepted "
                f"(n, n_par) and (1 or n, T, n_track) with n_par + n_track = {c1.in_channels}"
                + ("" if len(tracks) == 1 else ", one shape for every network")
            )
    t_steps = tracks[0].shape[1]
    plan = [(0, 0)]
    if segment is not None and t_steps > segment:
        plan = segment_plan(t_steps, segment, nets[0].washout)
    length = t_steps if len(plan) == 1 else segment
    track_parts, param_parts = [], []
    for net, track in zip(nets, tracks, strict=True):
        w1 = net.conv[0].weight[:, :, 0]
        part = linear(track.flatten(0, 1), w1[:, n_par:].contiguous(), net.conv[0].bias)
        track_parts.append(part.view(*track.shape[:2], -1))
        param_parts.append(linear(params, w1[:, :n_par].contiguous()))
    track_part, param_part = torch.stack(track_parts), torch.stack(param_parts)
    weights = _Weights.of(nets)
    out = torch.empty(len(nets), n, t_steps, weights.n_out, dtype=w.dtype)
    starts = torch.tensor([s for s, _ in plan])
    ends = [keep for _, keep in plan[1:]] + [t_steps]

    @torch.inference_mode()  # (per thread: the workers' too)
    def run(lo: int, hi: int) -> None:
        sets = torch.arange(lo, hi)
        part = track_part[:, :1] if tracks[0].shape[0] == 1 else track_part[:, sets]
        seg = _segments(weights, part, param_part[:, sets], starts, length, block_steps)
        for j, ((start, keep), end) in enumerate(zip(plan, ends, strict=True)):
            kept = seg[:, keep - start : end - start, j]  # (G, steps, sets, n_outputs)
            out[:, lo:hi, keep:end] = kept.transpose(1, 2)

    chunks, workers = set_chunks(n, max(1, group_rows // len(plan)), torch.get_num_threads())
    with torch_threads(1):
        if workers == 1:
            for lo, hi in chunks:
                run(lo, hi)
        else:
            with ThreadPoolExecutor(workers) as pool:
                for done in [pool.submit(run, lo, hi) for lo, hi in chunks]:
                    done.result()  # (an error in a worker raised here)
    return list(out)


def set_chunks(n: int, most: int, threads: int) -> tuple[list[tuple[int, int]], int]:
    """How the prediction shares ``threads`` cores: (the (first, end) sets of each chunk, the
    workers). Each worker runs whole chunks of at most ``most`` sets (one batch of segments,
    GROUP_ROWS) on one thread, so that no product or gate pass waits for another thread:
    thousands of parallel passes a generation, each of them waiting for a thread that
    another process held, made an NSGA-II generation 10-40 times slower on a 2-core machine
    with one other busy process (bench/README.md, "Predictions under outside load"). At
    least MIN_SETS_PER_WORKER sets a worker (smaller products cost more than they share);
    the chunks as equal as their count allows. Each set's outputs do not depend on the
    chunks (tests/surrogate/test_sequence_sets.py)."""
    workers = max(1, min(threads, n // MIN_SETS_PER_WORKER))
    count = -(-max(-(-n // most), workers) // workers) * workers  # whole rounds of workers
    count = min(count, n)
    ends = [k * n // count for k in range(count + 1)] if n else [0]
    return list(pairwise(ends)), workers


def _segments(
    w: _Weights,
    track_part: torch.Tensor,
    param_part: torch.Tensor,
    starts: torch.Tensor,
    length: int,
    block_steps: int,
) -> torch.Tensor:
    """Outputs (G, length, J, n, n_outputs) of the segments of ``length`` steps starting at
    ``starts`` (J) of n sets, each from the zero state, for G networks: ``track_part`` (G, 1
    or n, T, C) and ``param_part`` (G, n, C) are the two parts of the first convolution's
    input. All segments go through all layers ``block_steps`` steps at a time, the state
    carried between the blocks."""
    n_nets, n = param_part.shape[:2]
    n_seg = len(starts)
    rows = n_seg * n
    out = torch.empty(n_nets, length, n_seg, n, w.n_out, dtype=param_part.dtype)
    last, hidden = None, [None] * len(w.cells)
    for lo in range(0, length, block_steps):
        k = min(block_steps, length - lo)
        steps = starts[None, :] + torch.arange(lo, lo + k)[:, None]  # (k, J)
        if track_part.shape[1] == 1:
            shared = track_part[:, 0][:, steps][:, :, :, None]  # (G, k, J, 1, C)
        else:
            shared = track_part[:, torch.arange(n)[None, None, :], steps[:, :, None]]
        h = torch.relu_(shared + param_part[:, None, None]).view(n_nets, k * rows, -1)
        conv = nn.functional.leaky_relu_(_each(h, w.conv2), w.slope).view(n_nets, k, rows, -1)
        before = conv[:, :1] if last is None else last  # a segment's step 0 pools with itself
        seq = torch.empty_like(conv)  # max pool of width 2 (dropout: identity)
        torch.maximum(conv[:, 1:], conv[:, :-1], out=seq[:, 1:])
        torch.maximum(conv[:, :1], before, out=seq[:, :1])
        last = conv[:, -1:]
        for i, (inputs, w_hh, b_h) in enumerate(w.cells):
            gates = _each(seq.view(n_nets, k * rows, -1), inputs).view(n_nets, k, rows, -1)
            seq, hidden[i] = gru_steps(gates, hidden[i], w_hh, b_h)
        h = seq.view(n_nets, k * rows, -1)
        for layer in w.head:
            h = _each(h, layer) if isinstance(layer, list) else layer(h)
        out[:, lo : lo + k] = h.view(n_nets, k, n_seg, n, -1)
    return out
