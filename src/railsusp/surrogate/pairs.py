"""Gradient-enhanced training of the sequence CNN-GRU on pairs of runs that differ in one
parameter (the campaign's perturbed twins, :mod:`railsusp.campaign.perturbed`).

A mini-batch holds B chunks of training runs and, on the same track and steps, B chunks of
their perturbed twins. The loss is the mean squared error of all 2B chunks (the twins are
runs like any other) plus ``pair_weight`` times the squared error of the **difference** of
each pair's two predictions against the difference of its two simulations, per target
divided by the mean square of that simulated difference over the training pairs::

    L = mean (f(θ) - y)² + λ · mean_pairs ((f(θ') - f(θ)) - (y' - y))² / mean (y' - y)²

so that λ = 1 weighs a network that does not move with the parameter at all (f(θ') = f(θ))
as much as one that predicts nothing. The forces' own loss never asks for the derivative:
a network fitting 95 % of the series can pass on half of a parameter's effect (bench/README.md,
"What limits the sequence network's gains"); this term asks for it directly, at the
refinement's 5 % step where the Jacobian check measures it. Both members of a pair get the
same dropout mask (:meth:`~railsusp.surrogate.sequence.CNNSequence.forward` with
``pairs=True``), or the masks' difference would swamp the parameter's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from railsusp.campaign import Campaign
from railsusp.surrogate.chunks import ChunkSampler
from railsusp.surrogate.data import Normaliser, SeriesData, params_to_unit, twin_channels
from railsusp.surrogate.features import FeatureSpec
from railsusp.vehicle.simulation_result import WHEEL_NAMES, measured_wheel_index


@dataclass
class TwinRuns:
    """The perturbed twins of a data set's samples: m twins per sample."""

    params_unit: np.ndarray  # (n, m, n_params): the twins' network parameters, unit
    targets: np.ndarray  # (n, m, T, n_targets), kN; NaN where the twin failed

    def subset(self, idx: np.ndarray) -> TwinRuns:
        return TwinRuns(self.params_unit[idx], self.targets[idx])

    @property
    def ok(self) -> np.ndarray:
        """(n, m) twins that ran."""
        return np.isfinite(self.targets).all(axis=(2, 3))


def load_twins(campaign: Campaign, data: SeriesData, spec: FeatureSpec) -> TwinRuns:
    """The perturbed twins (:mod:`railsusp.campaign.perturbed`) of ``data``'s samples, read
    at the wheel and in the units :func:`~railsusp.surrogate.data.load_series` reads the
    runs. One-line errors where they are missing or incomplete, or move a parameter the
    network does not read (its effect would be noise to it)."""
    from railsusp.campaign.perturbed import (
        perturbed_complete,
        perturbed_folder,
        perturbed_parameters,
        read_perturbations,
    )

    cond = data.condition
    if not perturbed_complete(campaign.path, cond.name):
        raise ValueError(
            f"{campaign.path}: the perturbed twins of {cond.name!r} are missing, incomplete or "
            "of another configuration; make them with "
            "`railsusp.campaign.perturbed.run_perturbed_twins` before training on pairs"
        )
    table = read_perturbations(campaign.path)
    unseen = sorted(set(table["parameter"]) - set(spec.parameters))
    if unseen:
        raise ValueError(
            f"perturbed twins move {', '.join(unseen)}, which the network does not read "
            f"(its parameters: {', '.join(spec.parameters)})"
        )
    cfg = campaign.config
    design = campaign.design()
    w = measured_wheel_index(cond, cfg.wheel)
    names = [f"{t}_{WHEEL_NAMES[w]}" for t in spec.targets]
    per_sample = int(table["twin"].max()) + 1
    ids = data.sample_ids
    sim = list(cfg.simulated_parameters)
    keep = [sim.index(p) for p in spec.parameters]
    params = np.empty((len(ids), per_sample, len(spec.parameters)), np.float32)
    targets = np.empty((len(ids), per_sample, data.n_steps, len(names)), np.float32)
    for j in range(per_sample):
        x = perturbed_parameters(cfg, design, table, j)[ids][:, keep]
        params[:, j] = params_to_unit(x, spec.parameters)
        targets[:, j] = twin_channels(perturbed_folder(campaign.path, j), cond.name, ids, names)
    return TwinRuns(params, targets)


class PairSampler(ChunkSampler):
    """Chunks of training runs with the same chunk of one of their perturbed twins: a batch
    of B rows gives 2B chunks, the runs first, then their twins in the same order."""

    def __init__(
        self,
        data: SeriesData,
        twins: TwinRuns,
        norm: Normaliser,
        washout: int,
        chunk_steps: int,
        weight: float,
    ):
        super().__init__(data, norm, washout, chunk_steps)
        if twins.params_unit.shape[0] != data.n_samples:
            raise ValueError(
                f"twins of {twins.params_unit.shape[0]} samples for {data.n_samples} samples"
            )
        self.weight = float(weight)
        self.twin_params = twins.params_unit.astype(np.float32)
        baseline = data.track[..., data.track.shape[-1] - data.n_baseline :]
        learned = twins.targets - (baseline[:, None] if data.n_baseline else 0.0)
        self.twin_targets = norm.target(np.nan_to_num(learned)).astype(np.float32)
        ok = twins.ok
        if not ok.any():
            raise ValueError("no perturbed twin ran: nothing to train the pairs on")
        m = ok.shape[1]
        diff = (self.twin_targets - self.targets[:, None])[ok][:, self.window :]
        self.diff_scale = torch.from_numpy(
            np.maximum(np.mean(diff.astype(np.float64) ** 2, axis=(0, 1)), 1e-12).astype(np.float32)
        )
        # a twin that failed is replaced by another of its sample, or by the run itself (a
        # pair of equal runs, whose pair term is zero)
        for i, j in zip(*np.nonzero(~ok), strict=True):
            k = np.flatnonzero(ok[i])
            if len(k):
                self.twin_params[i, j] = self.twin_params[i, k[0]]
                self.twin_targets[i, j] = self.twin_targets[i, k[0]]
            else:
                self.twin_params[i, j], self.twin_targets[i, j] = self.params[i], self.targets[i]
        # row r * m + j: the runs' chunk r (ChunkSampler's rows, in its order) with twin j
        self.n_chunks, self.n_twins = len(self.index), m
        self.index = np.concatenate(
            [np.repeat(self.index, m, axis=0), np.tile(np.arange(m), len(self.index))[:, None]],
            axis=1,
        )

    def validation_rows(self, val_windows: int) -> int:
        """Validation chunks as :class:`ChunkSampler` counts them (runs, not pairs)."""
        return min(self.n_chunks, -(-val_windows // self.targets_per_row))

    def pick(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """The validation rows: the chunks :class:`ChunkSampler` draws from the same
        generator, each with its first twin, so that the runs' validation loss is taken on
        the same chunks as a network trained on the forces alone."""
        return rng.choice(self.n_chunks, count, replace=False) * self.n_twins

    def batch(self, rows: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        """Inputs (2B, C, F) and targets after the washout (2B, C - washout, n_targets):
        the B runs' chunks, then their twins' on the same track and steps."""
        x, y = super().batch(rows)
        idx = self.index[rows]
        i, j = idx[:, 0], idx[:, 2]
        steps = idx[:, 1:2] + np.arange(self.chunk)[None, :]
        xt = x.clone()
        xt[:, :, : self.params.shape[1]] = torch.from_numpy(self.twin_params[i, j])[:, None, :]
        yt = self.twin_targets[i[:, None], j[:, None], steps[:, self.window :]]
        return torch.cat([x, xt]), torch.cat([y, torch.from_numpy(yt)])

    def loss(self, pred: torch.Tensor, y: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(the training loss of the module docstring, its pair term) for a batch's
        predictions and targets as :meth:`batch` orders them."""
        b = pred.shape[0] // 2
        main = torch.mean((pred - y) ** 2)
        d = (pred[b:] - pred[:b]) - (y[b:] - y[:b])
        pair = torch.mean(d**2 / self.diff_scale.to(d.device))
        return main + self.weight * pair, pair
