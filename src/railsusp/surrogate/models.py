"""Surrogate networks (PyTorch): the study's CNN-GRU and its recurrent and MLP baselines.

All take windows (batch, L, F) and return the standardised targets (batch, n_targets).

* :class:`CNNRecurrent` with ``cell="gru"``: the study's CNN-GRU (its Section 3): two 1x1
  convolutions over the features (F then 128 channels, ReLU then LeakyReLU), max pooling of
  width 2 and stride 1 along time, dropout 0.2, three stacked GRU layers (64, 32, 16 units,
  optionally bidirectional), dense layers 64 -> 8 -> 8 -> outputs. ``cell="lstm"`` is the
  CNN-LSTM baseline, ``cell="lstm", bidirectional=True`` the CNN-BiLSTM.
* :class:`WindowMLP`: the "BP" baseline, a multilayer perceptron on the flattened window.
* ``"cnn-gru-seq"``: the study's layers run causally over whole series with the state carried
  along (:class:`~railsusp.surrogate.sequence.CNNSequence`): it takes chunks (batch, C, F)
  and returns the targets at their steps after its washout (batch, C - washout, n_targets).

:meth:`CNNRecurrent.predict_series` gives the same outputs as ``forward`` for many
overlapping windows of whole series at a fraction of the cost (see its docstring).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np
import torch
from torch import nn

from railsusp.surrogate.recurrence import cell_params, gru_step, linear, lstm_step
from railsusp.surrogate.sequence import CNNSequence, conv_front, dense_head


@dataclass(frozen=True)
class NetConfig:
    """Architecture of a surrogate network (sizes configurable, study defaults)."""

    kind: str = "cnn-gru"
    n_features: int = 21
    #: steps of input before the first prediction: the window length, or for the sequence
    #: CNN-GRU its washout (:data:`DEFAULT_WASHOUT`)
    window: int = 20
    n_outputs: int = 2
    conv_channels: tuple[int, ...] = (21, 128)
    rnn_hidden: tuple[int, ...] = (64, 32, 16)
    bidirectional: bool = False
    dense: tuple[int, ...] = (64, 8, 8)
    dropout: float = 0.2
    mlp_hidden: tuple[int, ...] = field(default=(256, 128, 64))

    def to_dict(self) -> dict:
        return asdict(self)


KINDS = {
    "cnn-gru": {"cell": "gru", "bidirectional": False},
    "cnn-lstm": {"cell": "lstm", "bidirectional": False},
    "cnn-bilstm": {"cell": "lstm", "bidirectional": True},
    "bp": {},
    "cnn-gru-seq": {"cell": "gru", "bidirectional": False},
}
#: kinds that run over whole series (:mod:`.sequence`), trained on chunks (:mod:`.chunks`)
SEQUENCE_KINDS = ("cnn-gru-seq",)
#: the window networks' window and the sequence CNN-GRU's washout, steps: 2 s at 50 Hz, about
#: twice the period of the wheelset's kinematic oscillation on tangent at 60 km/h
DEFAULT_WINDOW = 20
DEFAULT_WASHOUT = 100


def default_window(kind: str) -> int:
    """The steps before a kind's first prediction when none is given."""
    return DEFAULT_WASHOUT if kind in SEQUENCE_KINDS else DEFAULT_WINDOW


class CNNRecurrent(nn.Module):
    """1x1 convolutions -> max pool -> dropout -> stacked GRU/LSTM -> dense layers."""

    def __init__(self, cfg: NetConfig, cell: str = "gru"):
        super().__init__()
        c2 = cfg.conv_channels[1]
        self.conv = nn.Sequential(
            *conv_front(cfg),
            nn.MaxPool1d(kernel_size=2, stride=1),
            nn.Dropout(cfg.dropout),
        )
        rnn_cls = nn.GRU if cell == "gru" else nn.LSTM
        layers, size = [], c2
        mult = 2 if cfg.bidirectional else 1
        for h in cfg.rnn_hidden:
            layers.append(rnn_cls(size, h, batch_first=True, bidirectional=cfg.bidirectional))
            size = h * mult
        self.rnn = nn.ModuleList(layers)
        self.head = dense_head(size, cfg.dense, cfg.n_outputs)
        self.cell = cell
        self.window = cfg.window

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.conv(x.transpose(1, 2)).transpose(1, 2)  # (B, L-1, C)
        for layer in self.rnn:
            h, _ = layer(h)
        return self.head(h[:, -1, :])

    @torch.inference_mode()
    def predict_series(
        self,
        features: torch.Tensor,
        index: torch.Tensor | np.ndarray,
        *,
        chunk: int = 2048,
        group_steps: int = 4096,
    ) -> torch.Tensor:
        """``forward`` (eval mode) of many windows of whole series, without recomputing what
        overlapping windows share.

        ``features``: (n_series, T, F) per-step inputs; ``index``: (B, 2) pairs (series, end
        step) as :func:`~railsusp.surrogate.data.window_index` gives them, the window ending at
        ``end`` covering steps end - L + 1 .. end, returns (B, n_outputs); or a 1-D array of end
        steps taken in every series, returns (n_series, len(index), n_outputs).

        Why it is exact: both convolutions are 1x1 (per step) and the max pool has width 2,
        stride 1, so a window's pooled step j is max(conv[t], conv[t + 1]) of the whole series
        at t = end - L + 1 + j, whichever window it lies in; so are the first recurrent layer's
        input projections (W_ih x + b_ih, the largest matmul). They are computed once per
        series step (series in groups of about ``group_steps`` steps). Only the recurrences,
        which start from the zero state in every window, are run per window, batched over
        ``chunk`` windows with torch's GRU/LSTM equations on the module's own weights. For a
        bidirectional last layer only its output at the window's last step reaches the head,
        so its backward direction runs one step. The matmuls go through oneDNN where torch has
        it and tanh is taken as 2 sigmoid(2y) - 1 (:mod:`.recurrence`), for speed on CPU.
        Matches ``forward`` to float32 rounding.
        """
        if self.training:
            raise RuntimeError("predict_series computes eval-mode outputs; call .eval() first")
        w = next(self.parameters())
        features = torch.as_tensor(features).to(w.dtype)
        idx = torch.as_tensor(np.asarray(index), dtype=torch.long)
        n_series, n_steps, _ = features.shape
        if idx.ndim == 1:
            pairs = torch.cartesian_prod(torch.arange(n_series), idx).reshape(-1, 2)
            return self.predict_series(
                features, pairs, chunk=chunk, group_steps=group_steps
            ).reshape(n_series, len(idx), -1)
        n_out = self.head[-1].out_features
        out = torch.empty(len(idx), n_out, dtype=w.dtype)
        if len(idx) == 0:
            return out
        series, ends = idx[:, 0], idx[:, 1]
        span = self.window - 1  # pooled steps per window
        if ends.min() < span or ends.max() >= n_steps:
            raise ValueError(
                f"window ends must lie in {span} .. {n_steps - 1} (window {self.window})"
            )
        if series.min() < 0 or series.max() >= n_series:
            raise ValueError(f"series index out of range 0 .. {n_series - 1}")
        uniq, inv = torch.unique(series, return_inverse=True)
        order = torch.argsort(inv, stable=True)
        inv_sorted = inv[order]
        prm = self._cell_params()
        per_group = max(1, group_steps // n_steps)
        for g0 in range(0, len(uniq), per_group):
            lo, hi = torch.searchsorted(inv_sorted, torch.tensor([g0, g0 + per_group])).tolist()
            gates = self._first_gates(features[uniq[g0 : g0 + per_group]], prm[0])
            rows = order[lo:hi]
            # first pooled step of each window, as a row of the (series x step) gate tables
            first = (inv[rows] - g0) * (n_steps - 1) + ends[rows] - span
            for c0 in range(0, len(rows), chunk):
                f = first[c0 : c0 + chunk]
                fns = [lambda j, g=g, f=f: g.index_select(0, f + j) for g in gates]
                out[rows[c0 : c0 + chunk]] = self._windows(fns, span, prm)
        return out

    def _cell_params(self) -> list[list[tuple[torch.Tensor, ...]]]:
        """Per layer, per direction: (W_ih, input-side bias, W_hh, hidden-side bias or None),
        biases folded, tanh rows doubled (:func:`~railsusp.surrogate.recurrence.cell_params`)."""
        return [cell_params(layer, self.cell) for layer in self.rnn]

    def _first_gates(
        self, x: torch.Tensor, prm: list[tuple[torch.Tensor, ...]]
    ) -> list[torch.Tensor]:
        """Input gates of the first recurrent layer at every pooled step of whole series
        (n, T, F): per direction a (n * (T - 1), gates) table, row s * (T - 1) + t."""
        c1, c2 = self.conv[0], self.conv[2]
        h = torch.relu(linear(x.flatten(0, 1), c1.weight[:, :, 0], c1.bias))
        h = linear(h, c2.weight[:, :, 0], c2.bias)
        h = nn.functional.leaky_relu(h, self.conv[3].negative_slope).view(*x.shape[:2], -1)
        pooled = torch.maximum(h[:, :-1], h[:, 1:])  # MaxPool1d(2, stride=1); dropout: identity
        return [linear(pooled.flatten(0, 1), w_ih, b) for w_ih, b, _, _ in prm]

    def _windows(
        self,
        first: list[Callable[[int], torch.Tensor]],
        n: int,
        prm: list[list[tuple[torch.Tensor, ...]]],
    ) -> torch.Tensor:
        """Head outputs of a chunk of windows: ``first[d](j)`` gives the first layer's input
        gates of direction d at pooled step j (0 .. n - 1) for every window of the chunk."""
        fns, seq = first, torch.empty(0)  # seq: the previous layer's outputs (B, n, size)
        for li, dirs in enumerate(prm):
            last = li == len(prm) - 1
            if li > 0:
                fns = []
                for d, (w_ih, b, _, _) in enumerate(dirs):
                    if last and d == 1:  # only the input at the last step is needed
                        g = linear(seq[:, -1].contiguous(), w_ih, b)
                        fns.append(lambda j, g=g: g)
                    else:
                        g = linear(seq.flatten(0, 1), w_ih, b).view(*seq.shape[:2], -1)
                        fns.append(lambda j, g=g: g[:, j])
            fwd = self._direction(fns[0], range(n), dirs[0], keep=not last)
            if len(dirs) == 1:
                seq = fwd
            elif last:
                seq = torch.cat([fwd, self._direction(fns[1], [n - 1], dirs[1], keep=False)], 1)
            else:
                bwd = self._direction(fns[1], range(n - 1, -1, -1), dirs[1], keep=True)
                seq = torch.cat([fwd, bwd], 2)
        return self.head(seq)

    def _direction(
        self,
        gates: Callable[[int], torch.Tensor],
        steps: range | list[int],
        prm: tuple[torch.Tensor, ...],
        keep: bool,
    ) -> torch.Tensor:
        """One direction of one layer from the zero state over ``steps``: the outputs
        (B, len(steps), H) in time order when ``keep``, else the last output (B, H).
        ``gates(j)`` is the input-side gate buffer of step j, which the step overwrites."""
        _, _, w_hh, b_h = prm
        state, outs = None, []
        for j in steps:
            if self.cell == "lstm":
                state = lstm_step(gates(j), state, w_hh)
                h = state[0]
            else:
                state = h = gru_step(gates(j), state, w_hh, b_h)
            if keep:
                outs.append(h)
        if not keep:
            return h
        if steps[0] > steps[-1]:
            outs.reverse()
        return torch.stack(outs, 1)


class WindowMLP(nn.Module):
    """ "BP" network: the flattened window through fully connected ReLU layers."""

    def __init__(self, cfg: NetConfig):
        super().__init__()
        layers, prev = [nn.Flatten()], cfg.window * cfg.n_features
        for h in cfg.mlp_hidden:
            layers += [nn.Linear(prev, h), nn.ReLU()]
            prev = h
        layers.append(nn.Linear(prev, cfg.n_outputs))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)

    def predict_series(
        self, params: torch.Tensor, track: torch.Tensor, index: np.ndarray, chunk: int = 4096
    ) -> torch.Tensor:
        """The outputs at the (sample, end step) pairs ``index`` of windows built as
        :func:`~railsusp.surrogate.data.gather_windows` builds them (the parameters
        ``params`` (n, n_p) repeated along the window, then the track features ``track``
        (n or 1, T, n_track) of the window's steps), without building the windows.

        The first layer is linear, so it splits: its track part is a convolution of the
        track series, computed once per series step instead of once per window and sample,
        and its parameter part, the parameters being the same at every step of a window,
        is one small matrix (the window's parameter weights summed) times the parameters.
        For the NSGA-II of the demo (50 parameter sets on one track per condition) that
        removes most of the work: the first layer carries 72 % of the network's
        multiply-adds and the gathered windows are never built. Same numbers as ``forward``
        on gathered windows to float32 rounding."""
        first = self.net[1]
        n_par = params.shape[1]
        window = first.in_features // (n_par + track.shape[2])
        w = first.weight.view(first.out_features, window, -1)
        w_par = w[:, :, :n_par].sum(dim=1)  # (H, n_par)
        w_track = w[:, :, n_par:].permute(0, 2, 1).contiguous()  # (H, n_track, L)
        # output j of the convolution is the window of steps j .. j + L - 1 (end j + L - 1)
        conv = torch.nn.functional.conv1d(track.permute(0, 2, 1), w_track)  # (S, H, T - L + 1)
        conv = conv.permute(0, 2, 1).contiguous()  # (S, T - L + 1, H): a window's row is gathered
        par = params @ w_par.T + first.bias  # (n, H)
        rest = self.net[2:]
        i = torch.from_numpy(np.ascontiguousarray(index[:, 0]))
        j = torch.from_numpy(np.ascontiguousarray(index[:, 1] - window + 1))
        ti = torch.zeros_like(i) if track.shape[0] == 1 else i
        out = []
        for lo in range(0, len(index), chunk):
            sl = slice(lo, lo + chunk)
            out.append(rest(conv[ti[sl], j[sl]] + par[i[sl]]))
        return torch.cat(out) if out else torch.zeros((0, self.net[-1].out_features))


def build_network(cfg: NetConfig) -> nn.Module:
    """The network for ``cfg.kind`` (cnn-gru, cnn-lstm, cnn-bilstm, bp, cnn-gru-seq)."""
    if cfg.kind not in KINDS:
        raise ValueError(f"unknown surrogate kind {cfg.kind!r}; accepted {', '.join(KINDS)}")
    if cfg.kind in SEQUENCE_KINDS:
        return CNNSequence(cfg)
    if cfg.kind == "bp":
        return WindowMLP(cfg)
    opts = KINDS[cfg.kind]
    if opts["bidirectional"] != cfg.bidirectional and cfg.kind != "cnn-gru":
        cfg = NetConfig(**{**cfg.to_dict(), "bidirectional": opts["bidirectional"]})
    return CNNRecurrent(cfg, cell=opts["cell"])
