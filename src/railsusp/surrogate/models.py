"""Surrogate networks (PyTorch): the study's CNN-GRU and its recurrent and MLP baselines.

All take windows (batch, L, F) and return the standardised targets (batch, n_targets).

* :class:`CNNRecurrent` with ``cell="gru"``: the study's CNN-GRU (its Section 3): two 1x1
  convolutions over the features (F then 128 channels, ReLU then LeakyReLU), max pooling of
  width 2 and stride 1 along time, dropout 0.2, three stacked GRU layers (64, 32, 16 units,
  optionally bidirectional), dense layers 64 -> 8 -> 8 -> outputs. ``cell="lstm"`` is the
  CNN-LSTM baseline, ``cell="lstm", bidirectional=True`` the CNN-BiLSTM.
* :class:`WindowMLP`: the "BP" baseline, a multilayer perceptron on the flattened window.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import torch
from torch import nn


@dataclass(frozen=True)
class NetConfig:
    """Architecture of a surrogate network (sizes configurable, study defaults)."""

    kind: str = "cnn-gru"
    n_features: int = 21
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
}


class CNNRecurrent(nn.Module):
    """1x1 convolutions -> max pool -> dropout -> stacked GRU/LSTM -> dense layers."""

    def __init__(self, cfg: NetConfig, cell: str = "gru"):
        super().__init__()
        c1, c2 = cfg.conv_channels
        self.conv = nn.Sequential(
            nn.Conv1d(cfg.n_features, c1, kernel_size=1),
            nn.ReLU(),
            nn.Conv1d(c1, c2, kernel_size=1),
            nn.LeakyReLU(),
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
        dense, prev = [], size
        for h in cfg.dense:
            dense += [nn.Linear(prev, h), nn.ReLU()]
            prev = h
        dense.append(nn.Linear(prev, cfg.n_outputs))
        self.head = nn.Sequential(*dense)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.conv(x.transpose(1, 2)).transpose(1, 2)  # (B, L-1, C)
        for layer in self.rnn:
            h, _ = layer(h)
        return self.head(h[:, -1, :])


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


def build_network(cfg: NetConfig) -> nn.Module:
    """The network for ``cfg.kind`` (cnn-gru, cnn-lstm, cnn-bilstm, bp)."""
    if cfg.kind not in KINDS:
        raise ValueError(f"unknown surrogate kind {cfg.kind!r}; accepted {', '.join(KINDS)}")
    if cfg.kind == "bp":
        return WindowMLP(cfg)
    opts = KINDS[cfg.kind]
    if opts["bidirectional"] != cfg.bidirectional and cfg.kind != "cnn-gru":
        cfg = NetConfig(**{**cfg.to_dict(), "bidirectional": opts["bidirectional"]})
    return CNNRecurrent(cfg, cell=opts["cell"])
