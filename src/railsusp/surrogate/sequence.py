"""The sequence CNN-GRU ("cnn-gru-seq"): the study's layers run causally over a whole series.

The study's CNN-GRU reads 20-step windows (0.4 s at 50 Hz, 6.7 m of track at 60 km/h) and
restarts its recurrences from the zero state in every window. The wheelset and bogie lateral
motion on tangent has a kinematic wavelength of about 15-20 m and the lateral forces remember
3-5 s of irregularities, far beyond such a window; and predicting a T-step series costs
T x L recurrent steps. This network keeps the study's layers (two 1x1 convolutions over the
features, F then 128 channels, ReLU then LeakyReLU; max pooling of width 2 along time;
dropout; three stacked GRUs of 64, 32 and 16 units; dense layers 64 -> 8 -> 8 -> outputs at
every step) but runs them once over the series with the recurrent state carried along:
T recurrent steps per series, and a memory as long as the dynamics need.

The pooling is kept, made causal: step t pools the convolution outputs of steps t - 1 and t
(step 0 pools with itself), so the output at step k reads inputs 0 .. k only. It keeps the
layer stack, and its weights, the study's; at 50 Hz it costs nothing measurable.

Its first ``washout`` outputs (``NetConfig.window`` of this kind) are not predictions: the
state has not yet forgotten its zero start. Training (:mod:`.chunks`) leaves them out of the
loss and :meth:`~railsusp.surrogate.bundle.Surrogate.predict` returns NaN there, as the window
networks do in their first ``window`` steps. Only unidirectional layers: a backward direction
would read the future.

**Segments.** Trained on chunks of C steps, each from the zero state, the network has never
run its state longer than C steps; run over a record many times longer, nothing in training
bounds where its state goes. (A residual of 1.2-1.5 standard deviations on 60 s records,
first read as such a drift, was the washout counted as zero force by the comparison; run
once over three copies of a 20 s input, the network repeats its output.)
:meth:`CNNSequence.predict_series` with ``segment`` = C therefore predicts a long record as
overlapping segments of C steps (:func:`segment_plan`), each run from the zero state as in
training and started at least a washout before the first step it keeps, and stitches the
kept outputs: no output reads more than C steps of input, whatever the record's length, and
a record of at most C steps gives one run over it as before.
"""

from __future__ import annotations

from typing import Protocol

import torch
from torch import nn

from railsusp.surrogate.sequence_sets import (
    BLOCK_STEPS,
    GROUP_ROWS,
    predict_sets_in_step,
    segment_plan,
)


class Sizes(Protocol):
    """What the network reads of :class:`~railsusp.surrogate.models.NetConfig` (declared
    here so that the two modules do not import each other)."""

    n_features: int
    window: int
    n_outputs: int
    conv_channels: tuple[int, ...]
    rnn_hidden: tuple[int, ...]
    bidirectional: bool
    dense: tuple[int, ...]
    dropout: float


#: what the network carries from one stretch of a series to the next: the last convolution
#: output (for the pooling) and each GRU layer's hidden state
SequenceState = tuple[torch.Tensor, list[torch.Tensor]]


def dense_head(n_in: int, hidden: tuple[int, ...], n_outputs: int) -> nn.Sequential:
    """The study's dense layers after the recurrences: Linear + ReLU per hidden size, then a
    linear output layer (shared by the window and the sequence networks)."""
    layers: list[nn.Module] = []
    prev = n_in
    for h in hidden:
        layers += [nn.Linear(prev, h), nn.ReLU()]
        prev = h
    layers.append(nn.Linear(prev, n_outputs))
    return nn.Sequential(*layers)


def conv_front(cfg: Sizes) -> list[nn.Module]:
    """The study's two 1x1 convolutions (ReLU, then leaky ReLU) over the input features,
    shared by the window and the sequence networks; both keep them as the first four
    modules of their ``conv`` (weights and fast paths index them there)."""
    c1, c2 = cfg.conv_channels
    return [
        nn.Conv1d(cfg.n_features, c1, kernel_size=1),
        nn.ReLU(),
        nn.Conv1d(c1, c2, kernel_size=1),
        nn.LeakyReLU(),
    ]


class CNNSequence(nn.Module):
    """1x1 convolutions -> causal max pool -> dropout -> stacked GRUs -> dense head, per step."""

    def __init__(self, cfg: Sizes):
        super().__init__()
        if cfg.bidirectional:
            raise ValueError(
                "bidirectional = True: the sequence CNN-GRU is causal, accepted False only"
            )
        if cfg.window < 0:
            raise ValueError(f"washout (window) = {cfg.window}: accepted an integer >= 0")
        c2 = cfg.conv_channels[1]
        self.conv = nn.Sequential(*conv_front(cfg))
        self.dropout = nn.Dropout(cfg.dropout)
        layers, size = [], c2
        for h in cfg.rnn_hidden:
            layers.append(nn.GRU(size, h))  # time-major: each step's batch is contiguous
            size = h
        self.rnn = nn.ModuleList(layers)
        self.head = dense_head(size, cfg.dense, cfg.n_outputs)
        self.washout = cfg.window

    def steps(
        self, x: torch.Tensor, state: SequenceState | None = None, pairs: bool = False
    ) -> tuple[torch.Tensor, SequenceState]:
        """Outputs at every step of ``x`` (B, T, F) -> (B, T, n_outputs), and the state at
        its end. ``state``: the one a previous call returned for the steps just before (a
        series run in stretches gives the outputs of one run over it), ``None`` for the start
        of a series (zero recurrent state). ``pairs``: rows b and B/2 + b are a pair
        (:mod:`.pairs`) and get the same dropout mask in training."""
        c1, c2 = self.conv[0], self.conv[2]
        h = torch.relu(_dense(x.transpose(0, 1), c1.weight[:, :, 0], c1.bias))  # (T, B, C)
        conv = nn.functional.leaky_relu(
            _dense(h, c2.weight[:, :, 0], c2.bias), self.conv[3].negative_slope
        )
        before = conv[:1] if state is None else state[0]
        h = torch.maximum(conv, torch.cat([before, conv[:-1]]))
        if pairs and self.training and self.dropout.p > 0:
            half = h.shape[1] // 2
            mask = self.dropout(torch.ones_like(h[:, :half]))
            h = h * torch.cat([mask, mask], dim=1)
        else:
            h = self.dropout(h)
        hidden = []
        for i, layer in enumerate(self.rnn):
            h, hn = layer(h, None if state is None else state[1][i])
            hidden.append(hn)
        return self.head(h).transpose(0, 1), (conv[-1:], hidden)

    def forward(self, x: torch.Tensor, pairs: bool = False) -> torch.Tensor:
        """Training and validation: the outputs of chunks ``x`` (B, C, F) after the washout,
        (B, C - washout, n_outputs), each chunk from the zero state; ``pairs`` as
        :meth:`steps`."""
        return self.steps(x, pairs=pairs)[0][:, self.washout :]

    @torch.inference_mode()
    def predict_series(
        self,
        features: torch.Tensor,
        *,
        group_steps: int = 1 << 18,
        stepwise: bool = False,
        segment: int | None = None,
    ) -> torch.Tensor:
        """Eval-mode outputs (n, T, n_outputs) at every step of whole series (n, T, F), each
        from its start; the washout steps are left in (the caller masks them). The reference
        of :meth:`predict_sets`, which ``Surrogate.predict`` uses.

        ``segment``: None runs each series once from its start with the state carried to its
        end; an integer (the training chunk's length, greater than the washout) predicts a
        series longer than that as overlapping segments of ``segment`` steps
        (:func:`segment_plan`), each from the zero state, stitched: the output at step k then
        reads at most ``segment`` steps of input, ending at k. A series of at most
        ``segment`` steps is one segment, i.e. the same as ``None``.

        Series (or segments) go through torch's GRU (its C++ loop over time) in groups of
        about ``group_steps`` steps in all; the 1x1 convolutions as the dense layers they
        are, on contiguous time-major rows.
        ``stepwise=True`` is the reference: one step at a time with the state carried, as the
        network would run online; it gives the same numbers to float32 rounding."""
        if self.training:
            raise RuntimeError("predict_series computes eval-mode outputs; call .eval() first")
        w = next(self.parameters())
        features = torch.as_tensor(features).to(w.dtype)
        n, t_steps, n_feat = features.shape
        n_out = self.head[-1].out_features
        if segment is not None and t_steps > segment:
            plan = segment_plan(t_steps, segment, self.washout)
            starts = torch.tensor([s for s, _ in plan])
            rows = features[:, starts[:, None] + torch.arange(segment)]  # (n, J, S, F)
            seg_out = self.predict_series(
                rows.reshape(-1, segment, n_feat), group_steps=group_steps, stepwise=stepwise
            ).view(n, len(plan), segment, n_out)
            out = torch.empty(n, t_steps, n_out, dtype=w.dtype)
            ends = [keep for _, keep in plan[1:]] + [t_steps]
            for j, ((start, keep), end) in enumerate(zip(plan, ends, strict=True)):
                out[:, keep:end] = seg_out[:, j, keep - start : end - start]
            return out
        out = torch.empty(n, t_steps, n_out, dtype=w.dtype)
        per_group = max(1, group_steps // max(t_steps, 1))
        for lo in range(0, n, per_group):
            x = features[lo : lo + per_group]
            if not stepwise:
                out[lo : lo + per_group] = self.steps(x)[0]
                continue
            state = None
            for k in range(t_steps):
                out[lo : lo + per_group, k : k + 1], state = self.steps(x[:, k : k + 1], state)
        return out

    @torch.inference_mode()
    def predict_sets(
        self,
        params: torch.Tensor,
        track: torch.Tensor,
        *,
        segment: int | None = None,
        block_steps: int = BLOCK_STEPS,
        group_rows: int = GROUP_ROWS,
    ) -> torch.Tensor:
        """:meth:`predict_series` of the per-step inputs that
        :func:`~railsusp.surrogate.bundle.series_features` builds from parameter sets
        ``params`` (n, n_par) and track features ``track`` (1 or n, T, n_track), the same
        numbers to float32 rounding, three to four times faster (an NSGA-II generation of 50
        sets on a 3000-step record: bench/README.md), without building those inputs.

        * The first convolution is linear and 1x1: its track part is computed once per
          track step, its parameter part once per set (the parameters are the same at
          every step), and they are added per step and set, as
          :meth:`WindowMLP.predict_series <railsusp.surrogate.models.WindowMLP.predict_series>`
          splits its first layer.
        * The segments of all sets (``segment``, :func:`segment_plan`) are one batch, in
          groups of about ``group_rows``, and go through all the layers ``block_steps``
          steps at a time with the state carried (as :meth:`steps` in stretches), so that
          the activations between the layers stay in the cache instead of whole series of
          128 channels going to memory and back after every layer.
        * The GRUs run torch's equations one step at a time: the hidden side's product on
          oneDNN (:mod:`.recurrence`), about twice the speed of ``nn.GRU`` on the bench
          machine, the gates in one compiled pass per row (:mod:`.gru_kernel`).

        The recurrences themselves (one small matmul per layer and step) are what is left;
        a segment's washout is recomputed as the method asks (each from the zero state).
        Several conditions' networks run in step: :mod:`.sequence_sets`."""
        return predict_sets_in_step(
            [self],
            params,
            [track],
            segment=segment,
            block_steps=block_steps,
            group_rows=group_rows,
        )[0]


def _dense(x: torch.Tensor, w: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """x W^T + b over the last axis of (T, B, F) ``x``: a 1x1 convolution along time, as one
    matrix product over the contiguous (T * B, F) rows."""
    return nn.functional.linear(x.reshape(-1, x.shape[-1]), w, b).view(*x.shape[:-1], -1)
