"""A training's checkpoint: what it is keyed by, when it resumes, and how it is read and
written (used by :func:`railsusp.surrogate.train.train_network`).

A checkpoint resumes only the same training: the settings (but for the epoch limits, which
may be raised to train on), the architecture and the data (windows, features, samples,
normalisation), so another window length or campaign starts afresh. Settings added after
checkpoints existed count only when changed (:data:`LATER_SETTINGS`), so older checkpoints
still resume. It is written atomically after every epoch and read with
``weights_only=True``: a crafted checkpoint cannot run code.
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path
from typing import Any

import numpy as np
import torch

from railsusp.integrity import TorchFileCutShort, read_torch_file
from railsusp.store import atomic_write_bytes, content_hash, remove_stale_temporaries
from railsusp.surrogate.chunks import ChunkSampler
from railsusp.surrogate.pairs import PairSampler

#: settings added after checkpoints existed: they count in a checkpoint's key only when
#: changed from these defaults, so older checkpoints still resume
LATER_SETTINGS = {
    "fine_tune_lr_factor": 0.1,
    "chunk_steps": 400,
    "chunks_per_batch": 32,
    "pair_weight": 0.0,
    "max_seconds": None,
}


def fingerprint(*samplers: Any) -> str:
    """SHA-256 of the samplers' windows or chunks, inputs and targets."""
    h = hashlib.sha256()
    for smp in samplers:
        h.update(str(smp.window).encode())
        if isinstance(smp, ChunkSampler):
            h.update(f"chunk {smp.chunk}".encode())
        arrays = [smp.params, smp.track, smp.targets, smp.index]
        if isinstance(smp, PairSampler):
            arrays += [smp.twin_params, smp.twin_targets]
        for arr in arrays:
            h.update(str(arr.shape).encode())
            h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()


def state_hash(state: dict[str, torch.Tensor]) -> str:
    """SHA-256 of a state dict's names and values."""
    h = hashlib.sha256()
    for name in sorted(state):
        h.update(name.encode())
        h.update(state[name].detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


def identity(
    settings: dict[str, Any],
    device: torch.device,
    net: torch.nn.Module,
    train: Any,
    val: Any,
    initial: dict[str, torch.Tensor] | None,
    legacy: bool = False,
) -> dict:
    """What a checkpoint's key is the hash of: the training ``settings`` (a
    :class:`~railsusp.surrogate.train.TrainConfig` as a dict) the training depends on, the
    architecture and the samplers' data (``legacy``: as keyed before, the device as typed
    and ``batch_size`` for the chunk networks too)."""
    unused: tuple[str, ...] = ("epochs", "fine_tune_epochs", "max_seconds")
    if not isinstance(train, ChunkSampler):
        unused += ("chunk_steps", "chunks_per_batch")
    elif not legacy:  # chunks per mini-batch: ``chunks_per_batch``, not ``batch_size``
        unused += ("batch_size",)
    values = dict(settings)
    if not legacy:
        values["device"] = device.type
    kept = {
        k: v for k, v in values.items() if k not in unused and LATER_SETTINGS.get(k, object()) != v
    }
    ident = {"cfg": kept, "arch": repr(net), "data": fingerprint(train, val)}
    if initial is not None:
        ident["initial"] = state_hash(initial)
    return ident


def what_differs(before: object, now: dict) -> str:
    """The settings (``batch_size 512 -> 256``), architecture, data or initial weights in
    which a checkpoint's identity ``before`` differs from ``now``, for one line; a checkpoint
    from before identities were kept says only that something does."""
    if not isinstance(before, dict):
        return "settings, architecture or data"
    parts = []
    old_cfg, new_cfg = before.get("cfg") or {}, now["cfg"]
    for k in sorted(set(old_cfg) | set(new_cfg)):
        a = old_cfg.get(k, LATER_SETTINGS.get(k, "-"))
        b = new_cfg.get(k, LATER_SETTINGS.get(k, "-"))
        if a != b:
            parts.append(f"{k} {a} -> {b}")
    if before.get("arch") != now["arch"]:
        parts.append("architecture")
    if before.get("data") != now["data"]:
        parts.append("data: window, features, samples or normalisation")
    if before.get("initial") != now.get("initial"):
        parts.append("initial weights")
    return ", ".join(parts) or "settings, architecture or data"


def resumable(state: dict, epochs: int, fine_tune_epochs: int) -> bool:
    """Whether training on from checkpoint ``state`` reaches what a fresh training with the
    epoch limits ``epochs`` and ``fine_tune_epochs`` reaches (the limits are not in the
    checkpoint's key, so that a main phase may be trained on with a raised ``epochs``).
    Still in the main phase: when it has not run past ``epochs``. Past it: when the main
    phase ended where this training's would, at ``epochs`` or stopped early below both
    limits (by patience), and the fine-tune phase has not run past ``fine_tune_epochs``.
    Before this check a pipeline whose ``[surrogate] epochs`` changed kept the network of
    the old limits."""
    history = state.get("history") or []
    main = sum(h.get("phase", "main") == "main" for h in history)
    fine = len(history) - main
    if fine == 0:
        return main <= epochs
    old = state.get("epochs")  # None: a checkpoint from before the limits were kept
    stopped_early = old is not None and main < min(old, epochs)
    return (main == epochs or stopped_early) and 0 < fine <= fine_tune_epochs


def read_checkpoint(path: Path) -> dict | None:
    """A checkpoint's state, read with ``weights_only=True`` (tensors, numbers, strings and
    containers only: no code runs), or None for one cut short (its zip does not read: a
    copy interrupted, a full disk), which holds nothing to trust and is trained past from
    the start. One that holds anything else, or is not a checkpoint, is refused with a
    one-line error rather than trusted or silently overwritten."""
    # read onto the CPU whatever device trains: load_state_dict moves the network's and the
    # optimiser's tensors to their parameters' device, and torch.set_rng_state takes a CPU
    # tensor only (a checkpoint of a GPU training read onto the GPU could not resume)
    try:
        state = read_torch_file(path, "checkpoint", "delete it to train afresh")
    except TorchFileCutShort:
        return None
    return state if isinstance(state, dict) else None


def resume_state(
    path: Path, key: str, legacy: str, ident: dict, epochs: int, fine_tune_epochs: int
) -> tuple[dict | None, str]:
    """(the state to resume from, or None; why a checkpoint there is not resumed, or "").
    ``key``: the hash of this training's :func:`identity`, ``legacy`` that of its legacy
    identity (a checkpoint keyed so resumes where these settings match it). A training
    killed while saving its checkpoint left the temporary (a network's size, hidden) for
    good: it is removed first (the audit of stop 64)."""
    remove_stale_temporaries(path.parent, targets=(path.name,))
    if not path.exists():
        return None, ""
    state = read_checkpoint(path)
    if state is None:
        return None, f"checkpoint {path} is cut short or damaged; training starts afresh"
    if state.get("key") == legacy != key:
        state["key"] = key
    if state.get("key") != key:
        why = what_differs(state.get("ident"), ident)
        return None, f"checkpoint {path} of other settings ({why}); training starts afresh"
    if not resumable(state, epochs, fine_tune_epochs):
        return None, (
            f"checkpoint {path}: trained with other epoch limits past where these resume "
            f"(epochs {state.get('epochs', '?')}, fine-tune "
            f"{state.get('fine_tune_epochs', '?')}); training starts afresh"
        )
    return state, ""


def save_checkpoint(path: Path, state: dict) -> None:
    """Write a training's state to ``path`` atomically (a kill leaves the last one whole)."""
    buf = io.BytesIO()
    torch.save(state, buf)
    atomic_write_bytes(path, buf.getvalue())


def identity_keys(
    settings: dict[str, Any],
    device: torch.device,
    net: torch.nn.Module,
    train: Any,
    val: Any,
    initial: dict[str, torch.Tensor] | None,
) -> tuple[dict, str, str]:
    """(this training's identity, its key, its legacy key): :func:`identity` hashed."""
    ident = identity(settings, device, net, train, val, initial)
    legacy = identity(settings, device, net, train, val, initial, legacy=True)
    return ident, content_hash(ident), content_hash(legacy)
