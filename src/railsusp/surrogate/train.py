"""One training loop for every PyTorch surrogate: Adam, early stopping, checkpoints, resume.

An "epoch" is a fixed number of mini-batches of windows drawn at random (seeded) from the
training samples, so that its cost does not grow with the campaign; validation uses a fixed
random subset of the validation samples' windows. The sequence CNN-GRU trains in the same loop
on chunks of whole series instead of windows (:class:`~railsusp.surrogate.chunks.ChunkSampler`,
chosen by :func:`sampler_for`). The state is checkpointed atomically after
every epoch and a killed training resumes from the last checkpoint with the same result.

On the CPU a training is bitwise reproducible for a given seed: the initial weights are drawn
from the seed (whatever the global random state was when the network was built), mini-batches
and dropout come from seeded generators whose states the checkpoint carries, and PyTorch runs
its deterministic algorithms. What a checkpoint is keyed by, when it resumes, and how it is
read (``weights_only=True``: a crafted checkpoint cannot run code) and written:
:mod:`railsusp.surrogate.checkpoint`.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from railsusp.errors import RailsuspInputError
from railsusp.interrupts import stop_if_interrupted
from railsusp.surrogate.checkpoint import identity_keys, resume_state, save_checkpoint
from railsusp.surrogate.chunks import ChunkSampler
from railsusp.surrogate.data import Normaliser, SeriesData, gather_windows, window_index
from railsusp.surrogate.models import SEQUENCE_KINDS
from railsusp.surrogate.pairs import PairSampler, TwinRuns

#: one debug line per epoch (``railsusp --verbose`` shows it)
log = logging.getLogger("railsusp.surrogate.train")


@dataclass(frozen=True)
class TrainConfig:
    """Training settings (seeded; CPU by default, CUDA when asked and available)."""

    epochs: int = 40
    batches_per_epoch: int = 200
    batch_size: int = 512
    learning_rate: float = 1e-3
    patience: int = 6
    #: after the main phase, this many epochs more from its best state at the learning rate
    #: times ``fine_tune_lr_factor`` (a step decay; same early stopping)
    fine_tune_epochs: int = 0
    fine_tune_lr_factor: float = 0.1
    val_windows: int = 20_000
    seed: int = 0
    device: str = "cpu"
    #: the sequence CNN-GRU only: steps per training chunk (washout included) and chunks per
    #: mini-batch (it ignores ``batch_size``, which counts windows)
    chunk_steps: int = 400
    chunks_per_batch: int = 32
    #: the sequence CNN-GRU only: weight of the pair term of gradient-enhanced training on
    #: the campaign's perturbed twins (:mod:`.pairs`); 0 trains on the forces alone
    pair_weight: float = 0.0
    #: wall-clock budget of the whole training, s (None: the epoch limits alone). The main
    #: phase stops starting epochs after its share, ``epochs / (epochs + fine_tune_epochs)``
    #: of it, the fine-tune phase after the rest (the training's first epoch always runs);
    #: the best state is kept as always. A training resumed under another budget goes on in
    #: the phase it was in: once the fine-tune phase has begun, the main phase's cut-short
    #: epochs are not made up. For a training on a lent machine whose time is fixed
    #: (bench/README.md, "Trained on a GPU").
    max_seconds: float | None = None

    def __post_init__(self) -> None:
        """Refuse settings that would train nothing or fail later (one-line errors)."""
        # the upper bounds are those of a run's [surrogate] section (pipeline_config): a
        # mini-batch of 1e8 windows asked numpy for 112 GiB instead of being refused
        for name, lo, hi in (
            ("epochs", 1, 10_000),
            ("batches_per_epoch", 1, 100_000),
            ("batch_size", 1, 65_536),
            ("patience", 1, 10_000),
            ("fine_tune_epochs", 0, 10_000),
            ("val_windows", 1, 10_000_000),
            ("seed", 0, 2**32 - 1),
            ("chunk_steps", 2, 1_000_000),
            ("chunks_per_batch", 1, 65_536),
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise RailsuspInputError(
                    f"training {name} = {v!r}: accepted an integer from {lo} to {hi}"
                )
        pw = self.pair_weight
        if isinstance(pw, bool) or not isinstance(pw, int | float) or not 0 <= pw <= 100:
            raise RailsuspInputError(f"training pair_weight = {pw!r}: accepted [0, 100]")
        ms = self.max_seconds
        if ms is not None and (
            isinstance(ms, bool) or not isinstance(ms, int | float) or not 0 < ms < math.inf
        ):
            raise RailsuspInputError(
                f"training max_seconds = {ms!r}: accepted a number of seconds > 0, or None"
            )
        for name, lo, hi in (("learning_rate", 0.0, 1.0), ("fine_tune_lr_factor", 0.0, 1.0)):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and lo < v <= hi):
                raise RailsuspInputError(f"training {name} = {v!r}: accepted ({lo:g}, {hi:g}]")
        if self.device not in DEVICES:
            raise RailsuspInputError(f"device {self.device!r}: accepted {', '.join(DEVICES)}")

    def to_dict(self) -> dict:
        return asdict(self)


#: the devices a training accepts
DEVICES = ("cpu", "cuda", "auto")


def resolve_device(name: str) -> torch.device:
    """'cpu', 'cuda' or 'auto' (CUDA when available)."""
    if name not in DEVICES:
        raise RailsuspInputError(f"device {name!r}: accepted {', '.join(DEVICES)}")
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda" and not torch.cuda.is_available():
        raise RailsuspInputError("device 'cuda' asked for but no CUDA device is available")
    return torch.device(name)


def seed_weights(net: nn.Module, seed: int) -> None:
    """Draw ``net``'s initial weights again from ``seed`` (every layer's own initialiser),
    so that they do not depend on the global random state when it was built."""
    gen_state = torch.get_rng_state()
    torch.manual_seed(seed)
    for module in net.modules():
        reset = getattr(module, "reset_parameters", None)
        if callable(reset):
            reset()
    torch.set_rng_state(gen_state)


class WindowSampler:
    """Windows of one data set, normalised, as tensors."""

    def __init__(self, data: SeriesData, norm: Normaliser, window: int):
        self.params = data.params_unit.astype(np.float32)
        self.track = norm.track(data.track)
        self.targets = norm.target(data.learned)
        self.window = window
        self.index = window_index(data.n_samples, data.n_steps, window)

    def rows_per_batch(self, batch_size: int, chunks_per_batch: int) -> int:
        """Windows per training mini-batch: ``batch_size`` (``chunks_per_batch`` is the
        sequence network's)."""
        return batch_size

    def validation_rows(self, val_windows: int) -> int:
        """Validation windows: ``val_windows``, at most all."""
        return min(val_windows, len(self.index))

    def pick(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """``count`` distinct rows drawn from ``rng`` (the validation windows)."""
        return rng.choice(len(self.index), count, replace=False)

    def batch(self, rows: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        idx = self.index[rows]
        x = gather_windows(self.params, self.track, idx, self.window)
        y = self.targets[idx[:, 0], idx[:, 1]]
        return torch.from_numpy(np.ascontiguousarray(x)), torch.from_numpy(y)


Sampler = WindowSampler | ChunkSampler | PairSampler


def sampler_for(
    kind: str,
    data: SeriesData,
    norm: Normaliser,
    window: int,
    cfg: TrainConfig,
    twins: TwinRuns | None = None,
) -> Sampler:
    """The training data of a network kind: windows of ``window`` steps, or for the
    sequence CNN-GRU chunks of ``cfg.chunk_steps`` steps whose first ``window`` (its
    washout) are not in the loss, paired with the perturbed ``twins``' chunks when
    ``cfg.pair_weight`` > 0 (:mod:`.pairs`)."""
    if cfg.pair_weight > 0:
        if kind not in SEQUENCE_KINDS:
            raise RailsuspInputError(
                f"training pair_weight = {cfg.pair_weight}: accepted 0 for {kind!r} (pairs "
                f"train the sequence networks only: {', '.join(SEQUENCE_KINDS)})"
            )
        if twins is None:
            raise RailsuspInputError(
                f"training pair_weight = {cfg.pair_weight}: needs the campaign's perturbed twins"
            )
        return PairSampler(data, twins, norm, window, cfg.chunk_steps, cfg.pair_weight)
    if kind in SEQUENCE_KINDS:
        return ChunkSampler(data, norm, window, cfg.chunk_steps)
    return WindowSampler(data, norm, window)


def batch_loss(
    net: nn.Module, sampler: Sampler, xb: torch.Tensor, yb: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor | None]:
    """(the loss of a batch as ``sampler`` asks for it, its pair term or None): mean squared
    error, or on pairs :meth:`PairSampler.loss` with pair-shared dropout."""
    if isinstance(sampler, PairSampler):
        return sampler.loss(net(xb, pairs=True), yb)
    return nn.functional.mse_loss(net(xb), yb), None


def _train_epoch(
    net: nn.Module,
    opt: torch.optim.Optimizer,
    train: Sampler,
    rng: np.random.Generator,
    cfg: TrainConfig,
    device: torch.device,
) -> tuple[float, float | None]:
    """One epoch of ``cfg.batches_per_epoch`` random mini-batches; the mean training loss
    and, on pairs, the mean of its pair term."""
    net.train()
    total, total_pair = 0.0, 0.0
    n_rows = train.rows_per_batch(cfg.batch_size, cfg.chunks_per_batch)
    for _ in range(cfg.batches_per_epoch):
        xb, yb = train.batch(rng.integers(0, len(train.index), n_rows))
        xb, yb = xb.to(device), yb.to(device)
        opt.zero_grad()
        loss, pair = batch_loss(net, train, xb, yb)
        loss.backward()
        opt.step()
        total += loss.item()
        total_pair += 0.0 if pair is None else pair.item()
    n = cfg.batches_per_epoch
    return total / n, (total_pair / n if isinstance(train, PairSampler) else None)


def share_pair_scale(train: Sampler, val: Sampler) -> None:
    """Give the validation pairs the training pairs' normalisation of the pair term (the
    mean square of the simulated differences over the **training** pairs, as docs/
    surrogates.md says), so that the early-stopping criterion weighs the two terms as the
    training loss does; each sampler normalised by its own pairs until stop 62 (audit)."""
    if isinstance(train, PairSampler) and isinstance(val, PairSampler):
        val.diff_scale = train.diff_scale


def validation_loss(
    net: nn.Module, val: Sampler, xv: torch.Tensor, yv: torch.Tensor
) -> tuple[float, float | None, float]:
    """(mean squared error of the validation runs, the pair term or None, the early-stopping
    criterion). On pairs the first is taken on the runs alone (the twins' half left out), so
    that it compares with a network trained on the forces alone, and the criterion is the
    training loss's: that error plus ``pair_weight`` times the pair term."""
    with torch.no_grad():
        pred = net(xv)
        if not isinstance(val, PairSampler):
            v = float(nn.functional.mse_loss(pred, yv))
            return v, None, v
        b = pred.shape[0] // 2
        v = float(nn.functional.mse_loss(pred[:b], yv[:b]))
        pair = float(val.loss(pred, yv)[1])
        return v, pair, v + val.weight * pair


def train_network(
    net: nn.Module,
    train: Sampler,
    val: Sampler,
    cfg: TrainConfig,
    checkpoint: Path | None = None,
    progress: Callable[[int, float, float], None] | None = None,
    initial: dict[str, torch.Tensor] | None = None,
) -> list[dict]:
    """Train ``net`` in place; returns the history (epoch, phase, learning rate, train and
    validation loss, time; on pairs their pair terms and the stopping criterion).
    ``initial``: weights to start from instead of the seed's (a warm start, e.g. a network
    trained on the forces alone, trained on on pairs); they count in the checkpoint's key.

    The best validation state is restored at the end (early stopping). With
    ``cfg.fine_tune_epochs`` a second phase restarts Adam from the main phase's best state at
    a tenth of the learning rate (a step decay: on tangent it lowered the CNN-GRU's
    validation loss by 12-15 %, bench/README.md).
    """
    device = resolve_device(cfg.device)
    if device.type == "cpu":
        torch.use_deterministic_algorithms(True, warn_only=True)
    seed_weights(net, cfg.seed)
    torch.manual_seed(cfg.seed)
    net.to(device)
    if initial is not None:  # a warm start: the training begins from these weights
        net.load_state_dict(initial)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.learning_rate)
    rng = np.random.default_rng(cfg.seed)
    share_pair_scale(train, val)
    val_rows = val.pick(np.random.default_rng(cfg.seed + 1), val.validation_rows(cfg.val_windows))
    xv, yv = val.batch(val_rows)
    xv, yv = xv.to(device), yv.to(device)
    history: list[dict] = []
    best, best_state, stale = float("inf"), None, 0
    # a checkpoint resumes only the same training (railsusp.surrogate.checkpoint); the
    # device as resolved (``auto`` on a machine without CUDA trains as ``cpu`` does)
    ident, key, legacy = identity_keys(cfg.to_dict(), device, net, train, val, initial)
    if checkpoint is not None:
        state, why = resume_state(checkpoint, key, legacy, ident, cfg.epochs, cfg.fine_tune_epochs)
        if why:
            log.warning("%s", why)
        if state is not None:
            net.load_state_dict(state["model"])
            opt.load_state_dict(state["optim"])
            history, best, stale = state["history"], state["best"], state["stale"]
            best_state = state["best_state"]
            rng.bit_generator.state = state["rng"]
            torch.set_rng_state(state["torch_rng"])
    phases = [("main", cfg.epochs, cfg.learning_rate)]
    if cfg.fine_tune_epochs > 0:
        lr = cfg.learning_rate * cfg.fine_tune_lr_factor
        phases.append(("fine-tune", cfg.fine_tune_epochs, lr))
    started = time.perf_counter()
    deadlines = _phase_deadlines(cfg, started)
    for n, (phase, n_epochs, lr) in enumerate(phases):
        done = sum(h.get("phase", "main") == phase for h in history)
        if n == 0 and any(h.get("phase", "main") != "main" for h in history):
            continue  # the main phase is over: a later one has begun
        if n > 0 and done == 0:  # a new phase starts from the best state, at its own rate
            if best_state is not None:
                net.load_state_dict(best_state)
            opt = torch.optim.Adam(net.parameters(), lr=lr)
            stale = 0
        for _ in range(done, n_epochs):
            if stale >= cfg.patience or (history and time.perf_counter() >= deadlines[n]):
                break  # (a budget never leaves a training without its first epoch)
            t0 = time.perf_counter()
            train_loss, train_pair = _train_epoch(net, opt, train, rng, cfg, device)
            net.eval()
            vloss, val_pair, criterion = validation_loss(net, val, xv, yv)
            entry = {
                "epoch": len(history) + 1,
                "phase": phase,
                "learning_rate": lr,
                "train_loss": train_loss,
                "val_loss": vloss,
                "seconds": time.perf_counter() - t0,
            }
            if val_pair is not None:
                entry |= {"train_pair_loss": train_pair, "val_pair_loss": val_pair}
                entry["val_criterion"] = criterion
            history.append(entry)
            if criterion < best:
                best, stale = criterion, 0
                best_state = {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}
            else:
                stale += 1
            if checkpoint is not None:
                state = {
                    "key": key,
                    "ident": ident,  # what a resume under other settings names as changed
                    "epochs": cfg.epochs,
                    "fine_tune_epochs": cfg.fine_tune_epochs,
                    "model": net.state_dict(),
                    "optim": opt.state_dict(),
                    "history": history,
                    "best": best,
                    "stale": stale,
                    "best_state": best_state,
                    "rng": rng.bit_generator.state,
                    "torch_rng": torch.get_rng_state(),
                }
                save_checkpoint(checkpoint, state)
            log.debug(
                "training %s (%s): epoch %d/%d, train loss %.3g, validation loss %.3g",
                type(net).__name__,
                phase,
                len(history),
                sum(p[1] for p in phases),
                train_loss,
                vloss,
            )
            if progress is not None:
                progress(len(history), train_loss, vloss)
            if checkpoint is not None:  # a swallowed Ctrl-C: stop after the epoch's checkpoint
                stop_if_interrupted()
    if best_state is not None:
        net.load_state_dict(best_state)
    net.to("cpu").eval()
    return history


def _phase_deadlines(cfg: TrainConfig, started: float) -> list[float]:
    """The clock reading after which each phase (main, fine-tune) starts no new epoch: its
    share of ``cfg.max_seconds`` by epochs, the fine-tune phase's deadline the whole
    budget's end (infinite without a budget)."""
    if cfg.max_seconds is None:
        return [float("inf"), float("inf")]
    main_share = cfg.epochs / (cfg.epochs + cfg.fine_tune_epochs)
    return [started + main_share * cfg.max_seconds, started + cfg.max_seconds]
