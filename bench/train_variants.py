"""Training variants of the sequence CNN-GRU tried against issue 19's parameter gains, run
through bench/surrogate_tracks.py (bench/README.md, "What raises the gains").

Each variant changes one thing of the training or the network for this process only, then
runs ``surrogate_tracks.py`` with the arguments that follow it; bench/jacobian_check.py (and
any other script) runs through ``--variant film`` the same way, so that a saved FiLM network
loads. None of them is part of railsusp. Measured: ``band``, ``film`` and larger batches moved
the lateral gains by at most 0.07; ``widen`` raised every one (bench/README.md).

* ``band``: the loss is the mean square of the error low-passed along time (a windowed-sinc
  FIR of ``--band-taps`` taps at ``--band-hz``, 'valid' part), i.e. only the band that the
  time-aligned comparison on measured track sees (estimate/comparison.py: 2.9-4.7 Hz at 0.5 mm
  geometry error and 60 km/h).
* ``film``: feature-wise linear modulation by the parameters: the GRU input and each GRU
  layer's output are scaled by 1 + g(θ) and shifted by b(θ), g and b linear in the
  parameters and zero at the start (a warm start begins at the network it starts from).
  Predictions take the reference path (:meth:`CNNSequence.predict_series`), not the fast one.
* ``widen``: ``--init-from`` a narrower network of the same kind, copied into the wider one
  of ``--rnn-hidden``/``--dense`` so that the outputs are unchanged at the start: the new
  units' weights into the old units and into the outputs are zero, their own inputs random.

::

    python bench/train_variants.py --variant band --band-hz 5 -- bench/surrogate_tracks.py \\
        --run runs/tracks-8192-up --samples 8192 --conditions uphill --seed 1 --models "" \\
        --nominal --nominal-kinds cnn-gru-seq --init-from cnn-gru-seq-nominal-8k --init-inputs \\
        --tag=-band5 --epochs 12 --patience 20 --learning-rate 2.5e-4 --train-threads 2 \\
        --train-conditions uphill
"""

from __future__ import annotations

import argparse
import runpy
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from torch import nn

import railsusp.surrogate.fit as surrogate_fit
import railsusp.surrogate.in_step as in_step
import railsusp.surrogate.sequence as sequence
import railsusp.surrogate.train as train
from _cli import parser
from railsusp.surrogate.bundle import series_features
from railsusp.surrogate.models import build_network
from railsusp.surrogate.pairs import PairSampler

#: the campaigns' sampling rate, Hz (20 s records of 1000 steps)
SAMPLING_HZ = 50.0


def band_mse(cut_hz: float, taps: int):
    """The mean square of the error (B, S, C) low-passed along its S steps at ``cut_hz``
    (Hamming-windowed sinc of ``taps`` taps, unit gain at 0 Hz, its 'valid' part)."""
    n = np.arange(taps) - (taps - 1) / 2
    h = 2 * cut_hz / SAMPLING_HZ * np.sinc(2 * cut_hz / SAMPLING_HZ * n) * np.hamming(taps)
    kernel = torch.tensor(h / h.sum(), dtype=torch.float32).view(1, 1, -1)

    def mse(pred: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        e = pred - y
        b, s, c = e.shape
        flat = e.transpose(1, 2).reshape(b * c, 1, s)
        return nn.functional.conv1d(flat, kernel.to(e)).pow(2).mean()

    return mse


def band_loss(cut_hz: float, taps: int) -> None:
    """Train on :func:`band_mse` instead of the mean square error."""
    mse = band_mse(cut_hz, taps)

    def batch_loss(net, sampler, xb, yb):
        if isinstance(sampler, PairSampler):
            raise SystemExit("--variant band: accepted without pairs (pair_weight 0)")
        return mse(net(xb), yb), None

    def validation_loss(net, val, xv, yv):
        with torch.no_grad():
            v = float(mse(net(xv), yv))
        return v, None, v

    train.batch_loss = batch_loss
    train.validation_loss = validation_loss


class _Zero(nn.Linear):
    """A linear layer that starts (and restarts: the training's seeding resets every
    module) at zero."""

    def reset_parameters(self) -> None:
        nn.init.zeros_(self.weight)
        nn.init.zeros_(self.bias)


def film(n_par: int) -> None:
    """FiLM of the GRU input and of every GRU layer's output by the ``n_par`` parameters (the
    first ``n_par`` features: give the network's own count, nothing can check it)."""
    init, plain_steps = sequence.CNNSequence.__init__, sequence.CNNSequence.steps

    def __init__(self, cfg):
        init(self, cfg)
        if not 0 < n_par < cfg.n_features:
            raise SystemExit(f"--film-parameters {n_par}: accepted 1 to {cfg.n_features - 1}")
        self.film = nn.ModuleList(
            _Zero(n_par, 2 * s) for s in (cfg.conv_channels[1], *cfg.rnn_hidden)
        )
        hooks(self)

    def modulate(self, h, k):
        g, b = self.film[k](self.film_theta).chunk(2, -1)
        return h * (1 + g) + b

    def steps(self, x, state=None, pairs=False):
        if pairs:
            raise SystemExit("--variant film: accepted without pairs (pair_weight 0)")
        self.film_theta = x[:, 0, :n_par]  # (B, n_par): the parameters, the same every step
        return plain_steps(self, x, state, pairs)

    def hooks(self):
        """The GRU input is modulated where it enters the dropout (after the pooling), each
        GRU layer's output where it leaves the layer (its state is carried unmodulated)."""
        self.dropout.register_forward_pre_hook(lambda m, args: (modulate(self, args[0], 0),))
        for i, layer in enumerate(self.rnn):
            layer.register_forward_hook(
                lambda m, args, out, k=i + 1: (modulate(self, out[0], k), out[1])
            )

    def load_state_dict(self, state, strict=True, assign=False):
        """A network saved without modulation loads with zero modulation; nothing else may
        be missing or left over."""
        own = self.state_dict()
        missing = [k for k in own if k not in state and not k.startswith("film.")]
        extra = [k for k in state if k not in own]
        if strict and (missing or extra):
            raise KeyError(f"weights missing {missing}, unexpected {extra}")
        return nn.Module.load_state_dict(self, state, strict=False)

    @torch.inference_mode()
    def reference(nets, params, tracks, *, segment=None, block_steps=None, group_rows=None):
        params = np.asarray(params, dtype=np.float32)
        return [
            net.predict_series(
                torch.from_numpy(series_features(params, np.asarray(track, dtype=np.float32))),
                segment=segment,
            )
            for net, track in zip(nets, tracks, strict=True)
        ]

    sequence.CNNSequence.__init__ = __init__
    sequence.CNNSequence.steps = steps
    sequence.CNNSequence.load_state_dict = load_state_dict
    sequence.predict_sets_in_step = reference
    in_step.predict_sets_in_step = reference


def _widen_gru(old, new, prefix, h_old, h_new, in_old) -> None:
    """Copy a GRU layer of ``h_old`` units (``in_old`` inputs) into one of ``h_new``."""
    for kind in ("weight_ih", "weight_hh", "bias_ih", "bias_hh"):
        key = f"{prefix}.{kind}_l0"
        w, cols = new[key].clone(), in_old if kind == "weight_ih" else h_old
        for g in range(3):  # gates r, z, n
            rows, rows_old = slice(g * h_new, g * h_new + h_old), slice(g * h_old, (g + 1) * h_old)
            if kind.startswith("bias"):
                w[rows] = old[key][rows_old]
            else:
                w[rows, :cols] = old[key][rows_old]
                w[rows, cols:] = 0.0  # the new units' outputs do not reach the old units
        new[key] = w


def widened(src_net: nn.Module, src_cfg, cfg) -> dict[str, torch.Tensor]:
    """The weights of a network of ``cfg`` whose outputs are those of ``src_net`` (of
    ``src_cfg``: the same kind and convolutions, GRU layers and dense layers no wider)."""
    old, (ho, hn) = src_net.state_dict(), (src_cfg.rnn_hidden, cfg.rnn_hidden)
    do, dn = src_cfg.dense, cfg.dense
    if (
        len(ho) != len(hn)
        or len(do) != len(dn)
        or any(a > b for a, b in zip((*ho, *do), (*hn, *dn), strict=True))
    ):
        raise ValueError(f"GRUs {ho} and dense {do}: accepted at most {hn} and {dn}, as many")
    net = build_network(cfg)
    train.seed_weights(net, 0)  # the new units' weights, the same in every run
    new = {k: v.detach().clone() for k, v in net.state_dict().items()}
    for k in ("conv.0.weight", "conv.0.bias", "conv.2.weight", "conv.2.bias"):
        new[k] = old[k].clone()
    inputs = [src_cfg.conv_channels[1], *ho[:-1]]
    for i in range(len(ho)):
        _widen_gru(old, new, f"rnn.{i}", ho[i], hn[i], inputs[i])
    sizes = [ho[-1], *do, src_cfg.n_outputs]
    for j in range(len(sizes) - 1):  # the head's Linear layers (ReLU between)
        w, b = new[f"head.{2 * j}.weight"].clone(), new[f"head.{2 * j}.bias"].clone()
        w[: sizes[j + 1], : sizes[j]] = old[f"head.{2 * j}.weight"]
        w[: sizes[j + 1], sizes[j] :] = 0.0
        b[: sizes[j + 1]] = old[f"head.{2 * j}.bias"]
        new[f"head.{2 * j}.weight"], new[f"head.{2 * j}.bias"] = w, b
    return new


def widen() -> None:
    """Warm starts from a narrower network of the same kind (:func:`widened`), after the
    warm start's own checks of everything but the widths (features, normalisation, the rest
    of the network's configuration)."""
    checked = surrogate_fit.warm_start

    def warm_start(src, path, cfg, spec, norm):
        narrow = replace(cfg, rnn_hidden=src.net_config.rnn_hidden, dense=src.net_config.dense)
        checked(src, path, narrow, spec, norm)
        try:
            return widened(src.net, src.net_config, cfg)
        except ValueError as exc:
            raise SystemExit(f"--variant widen: {path}: {exc}") from None

    surrogate_fit.warm_start = warm_start


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--variant", choices=("band", "film", "widen"), required=True)
    ap.add_argument("--band-hz", type=float, default=5.0, help="band: the loss's cut-off, Hz")
    ap.add_argument("--band-taps", type=int, default=101, help="band: FIR taps (odd)")
    ap.add_argument("--film-parameters", type=int, default=5, help="film: parameter inputs")
    ap.add_argument("script", help="the script to run, e.g. bench/surrogate_tracks.py")
    ap.add_argument("args", nargs=argparse.REMAINDER, help="its arguments")
    args = ap.parse_args()
    if args.variant == "band":
        if not 0.0 < args.band_hz < SAMPLING_HZ / 2 or args.band_taps % 2 == 0:
            ap.error(f"--band-hz {args.band_hz}, --band-taps {args.band_taps}: accepted "
                     f"(0, {SAMPLING_HZ / 2:g}) Hz and an odd number of taps")  # fmt: skip
        band_loss(args.band_hz, args.band_taps)
    elif args.variant == "film":
        film(args.film_parameters)
    else:
        widen()
    sys.argv = [args.script, *args.args]
    sys.path.insert(0, str(Path(args.script).parent))  # its sibling modules
    runpy.run_path(args.script, run_name="__main__")


if __name__ == "__main__":
    main()
