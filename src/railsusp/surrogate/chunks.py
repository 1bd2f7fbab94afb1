"""Training data of the sequence CNN-GRU (:mod:`.sequence`): random stretches of whole series.

A mini-batch is ``chunks_per_batch`` chunks of ``chunk_steps`` consecutive steps (the series
length if shorter), each from a random training sample and start step. The network runs a
chunk from the zero state, as it runs a series from its start; its first ``washout`` outputs
are left out of the loss, so a chunk of C steps gives C - washout targets. An epoch draws
its chunks at random (seeded) like the window sampler's windows, and the validation loss is
taken on a fixed random set of validation chunks holding about ``val_windows`` targets. The
inputs and targets are normalised as the window networks' are.
"""

from __future__ import annotations

import numpy as np
import torch

from railsusp.surrogate.data import Normaliser, SeriesData


class ChunkSampler:
    """Chunks (sample, start step) of one data set's series, normalised, as tensors."""

    def __init__(self, data: SeriesData, norm: Normaliser, washout: int, chunk_steps: int):
        if data.n_steps <= washout:
            raise ValueError(
                f"washout (window) = {washout} steps: accepted fewer than the series' "
                f"{data.n_steps}"
            )
        if chunk_steps <= washout:
            raise ValueError(
                f"chunk_steps = {chunk_steps}: accepted more than the washout of {washout} steps"
            )
        self.chunk = min(chunk_steps, data.n_steps)
        self.params = data.params_unit.astype(np.float32)
        self.track = norm.track(data.track)
        self.targets = norm.target(data.learned)
        self.window = washout
        starts = np.arange(data.n_steps - self.chunk + 1)
        self.index = np.stack(
            np.meshgrid(np.arange(data.n_samples), starts, indexing="ij"), axis=-1
        ).reshape(-1, 2)

    @property
    def targets_per_row(self) -> int:
        """Targets in the loss per chunk (its steps after the washout)."""
        return self.chunk - self.window

    def rows_per_batch(self, batch_size: int, chunks_per_batch: int) -> int:
        """Chunks per training mini-batch: ``chunks_per_batch`` (``batch_size`` counts
        windows, for the window networks)."""
        return chunks_per_batch

    def validation_rows(self, val_windows: int) -> int:
        """Validation chunks: enough for about ``val_windows`` targets, at most all."""
        return min(len(self.index), -(-val_windows // self.targets_per_row))

    def pick(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """``count`` distinct rows drawn from ``rng`` (the validation chunks)."""
        return rng.choice(len(self.index), count, replace=False)

    def batch(self, rows: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        """Inputs (B, C, F) of the chunks and their targets after the washout
        (B, C - washout, n_targets)."""
        idx = self.index[rows]
        i = idx[:, 0]
        steps = idx[:, 1:2] + np.arange(self.chunk)[None, :]
        ti = np.zeros_like(i) if self.track.shape[0] == 1 else i
        tr = self.track[ti[:, None], steps]
        p = np.broadcast_to(self.params[i][:, None, :], (len(i), self.chunk, self.params.shape[1]))
        x = np.concatenate([p, tr], axis=2)
        y = self.targets[i[:, None], steps[:, self.window :]]
        return torch.from_numpy(np.ascontiguousarray(x)), torch.from_numpy(y)
