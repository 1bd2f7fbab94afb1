"""Several working conditions' surrogates predicted in step, for the same parameter sets.

NSGA-II asks every generation for the same parameter sets' forces in each recorded condition
(the study's three at 60 km/h). Where the conditions' surrogates are sequence CNN-GRUs of
one architecture and segment, on tracks of one length, :func:`predict_in_step` runs their
networks through one loop (:func:`~railsusp.surrogate.sequence_sets.predict_sets_in_step`)
and does each surrogate's own input checks, scaling, nominal forces and record correction as
:meth:`~railsusp.surrogate.bundle.Surrogate.predict` does: each condition's series are those
its surrogate predicts alone, to float32 rounding.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from railsusp.conditions import WorkingCondition
from railsusp.surrogate.bundle import Surrogate
from railsusp.surrogate.data import window_index
from railsusp.surrogate.sequence import CNNSequence
from railsusp.surrogate.sequence_sets import architecture, predict_sets_in_step


def in_step_key(surrogate: Surrogate, track: np.ndarray) -> tuple[Any, ...] | None:
    """What surrogates must share to be predicted in step on their raw track inputs
    ``track`` (T, n_track): the network's architecture, the prediction segment and the
    track's shape; None for a surrogate that cannot (not a sequence CNN-GRU, or one track
    per set)."""
    if not isinstance(surrogate.net, CNNSequence) or np.ndim(track) != 2:
        return None
    return (architecture(surrogate.net), surrogate.segment_steps, np.shape(track))


def predict_in_step(
    surrogates: Sequence[Surrogate],
    params: np.ndarray,
    conditions: Sequence[WorkingCondition],
    tracks: Sequence[np.ndarray],
    *,
    corrected: bool = True,
) -> list[np.ndarray]:
    """Each surrogate's ``predict(params, conditions[g], track=tracks[g])`` (n, T, n_targets),
    kN, the networks run in step. ``params``: (n, n_key) SI values of the key parameters,
    the same for every surrogate; ``tracks``: each condition's raw track input (T,
    n_track), as :meth:`~railsusp.estimate.forces.SurrogateForces.track_input` gives it.
    Refused in one line: surrogates of other key parameters, or that :func:`in_step_key`
    does not pair."""
    if not surrogates or not len(surrogates) == len(conditions) == len(tracks):
        raise ValueError(
            f"{len(surrogates)} surrogates, {len(conditions)} conditions and {len(tracks)} "
            "tracks: accepted one condition and one track per surrogate"
        )
    keys = [in_step_key(s, t) for s, t in zip(surrogates, tracks, strict=True)]
    if keys[0] is None or any(k != keys[0] for k in keys):
        raise ValueError(
            "these surrogates cannot be predicted in step: accepted sequence CNN-GRUs of one "
            "architecture and segment, each on one track (T, n_track) of one length"
        )
    if len({tuple(s.spec.parameters) for s in surrogates}) > 1:
        raise ValueError(
            "surrogates of different key parameters: "
            + " / ".join(", ".join(s.spec.parameters) for s in surrogates)
        )
    inputs = [
        s.inputs(params, c, track=t) for s, c, t in zip(surrogates, conditions, tracks, strict=True)
    ]
    unit = inputs[0][0]
    normalised = [
        torch.from_numpy(np.ascontiguousarray(s.normaliser.track(raw[None]), dtype=np.float32))
        for s, (_, raw) in zip(surrogates, inputs, strict=True)
    ]
    for s in surrogates:
        s.net.eval()
    full = predict_sets_in_step(
        [s.net for s in surrogates],
        torch.from_numpy(np.ascontiguousarray(unit, dtype=np.float32)),
        normalised,
        segment=surrogates[0].segment_steps,
    )
    out = []
    for s, (_, raw), series in zip(surrogates, inputs, full, strict=True):
        idx = window_index(unit.shape[0], raw.shape[0], s.spec.window)
        preds = series.numpy()[idx[:, 0], idx[:, 1]]
        out.append(s.outputs(preds, idx, unit, raw, corrected=corrected))
    return out
