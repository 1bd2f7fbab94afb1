"""A trained surrogate: network weights + architecture + feature definition + normalisation +
condition, wagon and training provenance, saved to and loaded from one folder.

``Surrogate.predict(params, ...)`` returns force series (kN) of the measured wheel for any
batch of parameter sets in its condition, on the campaign's track or another realisation.
CNN-recurrent networks predict whole series at once (:meth:`CNNRecurrent.predict_series`,
about 4x the windows per second of running the network on every gathered window); the
sequence CNN-GRU runs once over each series, or each segment of it
(:meth:`CNNSequence.predict_sets`).

What a surrogate was trained on, and so which conditions and tracks it serves (its fields,
:meth:`~railsusp.surrogate.training_scope.TrainedNetwork.untrained_fields` and the other
questions that read its description only), is its base class's, in
:mod:`railsusp.surrogate.training_scope`; this module predicts, saves and loads.
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from pydantic import ValidationError

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.integrity import read_torch_file
from railsusp.params import ParameterSet, spec
from railsusp.provenance import provenance
from railsusp.store import atomic_folder, atomic_write_bytes, read_json, write_json
from railsusp.surrogate.correction import RecordCorrection
from railsusp.surrogate.data import (
    Normaliser,
    check_trained_range,
    gather_windows,
    params_to_unit,
    window_index,
)
from railsusp.surrogate.features import FeatureSpec, track_features
from railsusp.surrogate.models import CNNRecurrent, NetConfig, WindowMLP, build_network
from railsusp.surrogate.sequence import CNNSequence
from railsusp.surrogate.training_scope import TrainedNetwork
from railsusp.vehicle.wagon import WagonData

FORMAT = "railsusp-surrogate/1"


class OneTrackWarning(UserWarning):
    """A surrogate trained on one track realisation was asked to predict on another."""


def series_features(params: np.ndarray, track: np.ndarray) -> np.ndarray:
    """Per-step inputs (n, T, F) of whole series: the parameters repeated along time, then the
    track features (shared when ``track`` is (1, T, n_track)). The window (i, k) of
    :func:`gather_windows` is rows k - L + 1 .. k of series i."""
    n, t_steps = params.shape[0], track.shape[1]
    p = np.broadcast_to(params[:, None, :], (n, t_steps, params.shape[1]))
    tr = np.broadcast_to(track, (n, *track.shape[1:]))
    return np.concatenate([p, tr], axis=2)


@dataclass
class Surrogate(TrainedNetwork):
    """A trained window (or sequence) network for one working condition."""

    def _unit(self, params: np.ndarray | list[ParameterSet]) -> np.ndarray:
        """The parameters' fractions of their ranges (n, n_key), float32, the network's
        input; values outside the ranges the network was trained over refused
        (:func:`check_trained_range`)."""
        if isinstance(params, np.ndarray):
            x = np.atleast_2d(params)
            if x.shape[1] != len(self.spec.parameters):
                raise ValueError(
                    f"params must have {len(self.spec.parameters)} columns "
                    f"({', '.join(self.spec.parameters)}), got {x.shape[1]}"
                )
        else:
            x = np.array([[p[s] for s in self.spec.parameters] for p in params])
        unit = params_to_unit(x, self.spec.parameters)
        check_trained_range(np.asarray(x, dtype=float), unit, self.spec.parameters)
        return unit.astype(np.float32)

    def predict(
        self,
        params: np.ndarray | list[ParameterSet],
        condition: WorkingCondition | None = None,
        *,
        seed: int | None = None,
        track: np.ndarray | None = None,
        batch_size: int = 2048,
        fast: bool = True,
        corrected: bool = True,
    ) -> np.ndarray:
        """Force series (n_sets, T, n_targets) in kN; the first ``window`` steps are NaN (for
        the sequence CNN-GRU, its washout).

        ``params``: (n, n_key) SI values of the key parameters, or ParameterSets. The track
        is the training track (``track_seed``) unless ``condition`` (the surrogate's own
        condition, possibly with another irregularity seed, a measured ``track_geometry`` or
        another record length), ``seed`` or raw ``track`` features (T, n_track) say
        otherwise; for the sequence CNN-GRU ``track`` may also hold one track per set (n, T,
        n_track), all of one length (a campaign's runs scored together). With
        ``spec.nominal_response`` the track input ends with the nominal
        wagon's forces on that track (simulated here unless ``track`` is given), which are
        added to the network's output. A surrogate serves one condition only, or, trained
        on a track family, that condition with its FRA class, radius and cant anywhere in
        the family.
        ``fast=False`` takes the per-window reference path (see :meth:`predict_windows`);
        ``corrected=False`` leaves out the record correction (:mod:`.correction`), when the
        surrogate has one. A parameter value that is not finite or lies outside the range
        the network was trained over is refused in one line
        (:class:`~railsusp.errors.RailsuspInputError`, :func:`check_trained_range`): the
        network would extrapolate without a word.
        """
        unit, raw = self.inputs(params, condition, seed=seed, track=track)
        tr = self.normaliser.track(raw if raw.ndim == 3 else raw[None])
        idx = window_index(unit.shape[0], tr.shape[1], self.spec.window)
        preds = self.predict_windows(unit, tr, idx, batch_size, fast=fast)
        return self.outputs(preds, idx, unit, raw, corrected=corrected)

    def inputs(
        self,
        params: np.ndarray | list[ParameterSet],
        condition: WorkingCondition | None = None,
        *,
        seed: int | None = None,
        track: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """What :meth:`predict` feeds the network, checked: the parameters' unit values (n,
        n_key) and the raw track input, (T, n_track) or one per set (n, T, n_track).
        Arguments and refusals as :meth:`predict`."""
        unit = self._unit(params)
        on = self.condition
        if condition is not None:
            # the network reads the track, so another realisation, a measured track or
            # another record length is new input, not another condition
            diff = self.untrained_fields(condition)
            if diff:
                raise ValueError(
                    f"this surrogate was trained for condition {self.condition.name!r}; the "
                    "given condition differs in "
                    + ", ".join(f"{n} = {v!r} (trained on {t})" for n, v, t in diff)
                )
            seed = condition.seed if seed is None else seed
            on = condition
        if track is None and self.one_track and not self.reads_training_track(condition, seed):
            warnings.warn(
                f"this {self.kind} surrogate of {self.condition.name!r} was trained on one track "
                f"realisation (seed {self.track_seed}) and does not predict another: train it "
                "on a campaign with --independent-seeds, or on the recordings' measured track",
                OneTrackWarning,
                stacklevel=3,
            )
        if track is None:
            s = self.track_seed if seed is None else seed
            track = track_features(on, s, self.spec, self.wagon, self.solver_settings())
        raw = np.asarray(track)
        if raw.ndim == 3 and (raw.shape[0] != len(unit) or not isinstance(self.net, CNNSequence)):
            raise ValueError(
                f"track input {raw.shape}: one track per set (n, T, n_track) is accepted for "
                f"the sequence CNN-GRU only, with n = {len(unit)} sets"
            )
        if raw.shape[-1] != self.spec.n_features - len(self.spec.parameters):
            raise ValueError(
                f"track input has {raw.shape[-1]} columns, this surrogate reads "
                f"{self.spec.n_features - len(self.spec.parameters)} "
                f"({', '.join(self.spec.names()[len(self.spec.parameters) :])})"
            )
        return unit, raw

    def outputs(
        self,
        preds: np.ndarray,
        idx: np.ndarray,
        unit: np.ndarray,
        raw: np.ndarray,
        *,
        corrected: bool = True,
    ) -> np.ndarray:
        """Force series (n, T, n_targets), kN, from the network's standardised outputs
        ``preds`` at the (set, step) pairs ``idx`` (:func:`window_index`; NaN elsewhere):
        in physical units, the nominal wagon's forces added where the network predicts the
        change from them, and the record correction applied (``corrected``)."""
        out = np.full((unit.shape[0], raw.shape[-2], len(self.spec.targets)), np.nan)
        out[idx[:, 0], idx[:, 1]] = self.normaliser.target_inverse(preds)
        if self.spec.n_baseline:  # the network's part is the change from the nominal wagon
            out += (raw if raw.ndim == 3 else raw[None])[..., -self.spec.n_baseline :]
        if corrected and self.correction is not None:
            out = self.correction.apply(out, unit)
        return out

    def predict_windows(
        self,
        unit: np.ndarray,
        track_norm: np.ndarray,
        idx: np.ndarray,
        batch_size: int = 2048,
        *,
        fast: bool = True,
    ) -> np.ndarray:
        """Standardised predictions for (sample, end step) pairs, ``batch_size`` windows at a
        time.

        CNN-recurrent networks go through :meth:`CNNRecurrent.predict_series` on the per-step
        inputs of the whole series (built once), which computes the convolutions, pooling and
        first input projection once per series step instead of once per window step; the BP
        network through :meth:`WindowMLP.predict_series` (its first layer split into a
        convolution of the track and the parameters' part); the others, or ``fast=False``
        (the reference), run the network on every gathered window.
        Both give the same numbers to float32 rounding. The sequence CNN-GRU runs over each
        whole series from its start, in segments of :attr:`segment_steps` when the series is
        longer, through :meth:`CNNSequence.predict_sets` (the first convolution split into
        the track's part, once per step, and the parameters', once per set; all segments
        one batch, a few steps at a time; ``fast=False``: one step at a time through torch's
        GRU, the state carried within a segment), and its outputs at the asked steps are
        returned."""
        self.net.eval()
        if isinstance(self.net, CNNSequence):
            if fast:
                full = self.net.predict_sets(
                    torch.from_numpy(np.ascontiguousarray(unit, dtype=np.float32)),
                    torch.from_numpy(np.ascontiguousarray(track_norm, dtype=np.float32)),
                    segment=self.segment_steps,
                ).numpy()
            else:
                feats = series_features(unit, track_norm).astype(np.float32, copy=False)
                full = self.net.predict_series(
                    torch.from_numpy(feats), stepwise=True, segment=self.segment_steps
                ).numpy()
            return full[idx[:, 0], idx[:, 1]]
        if fast and isinstance(self.net, CNNRecurrent):
            feats = series_features(unit, track_norm).astype(np.float32, copy=False)
            with torch.inference_mode():
                pred = self.net.predict_series(torch.from_numpy(feats), idx, chunk=batch_size)
            return pred.numpy()
        if fast and isinstance(self.net, WindowMLP):
            with torch.inference_mode():
                pred = self.net.predict_series(
                    torch.from_numpy(np.ascontiguousarray(unit, dtype=np.float32)),
                    torch.from_numpy(np.ascontiguousarray(track_norm, dtype=np.float32)),
                    idx,
                    chunk=batch_size,
                )
            return pred.numpy()
        res = []
        with torch.inference_mode():
            for lo in range(0, len(idx), batch_size):
                x = gather_windows(unit, track_norm, idx[lo : lo + batch_size], self.spec.window)
                res.append(self.net(torch.from_numpy(np.ascontiguousarray(x))).numpy())
        return np.concatenate(res) if res else np.zeros((0, len(self.spec.targets)))

    def save(self, path: str | Path) -> Path:
        """Write ``model.pt`` (weights) and ``surrogate.json`` (everything else) into a folder,
        as one: both go into a temporary folder that then replaces ``path`` (other files
        there, such as the training checkpoint, are kept), so a crash never leaves new
        weights beside an old description."""
        path = Path(path)
        with atomic_folder(path) as tmp:
            self._write(tmp)
        return path

    def _write(self, path: Path) -> None:
        buf = io.BytesIO()
        torch.save(self.net.state_dict(), buf)
        atomic_write_bytes(path / "model.pt", buf.getvalue())
        write_json(
            path / "surrogate.json",
            {
                "format": FORMAT,
                "net": self.net_config.to_dict(),
                "features": self.spec.to_dict(),
                "normaliser": self.normaliser.__dict__,
                "condition": self.condition.model_dump(),
                "wagon": self.wagon.model_dump(mode="json"),
                "track_seed": self.track_seed,
                "meta": self.meta,
                "record_correction": None if self.correction is None else self.correction.to_dict(),
                "saved": provenance(),
            },
        )


def load(path: str | Path, remedy: str = "train the surrogate again") -> Surrogate:
    """Load a surrogate saved by :meth:`Surrogate.save`. A description or weights that do
    not read (damaged, of another railsusp, crafted) are one line naming the file and the
    ``remedy`` (a shipped network set's is not "train it again")."""
    path = Path(path)
    meta_path = path / "surrogate.json"
    if not meta_path.exists():
        raise FileNotFoundError(f"{path} holds no surrogate (no surrogate.json)")
    doc = read_json(meta_path)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise RailsuspInputError(f"{meta_path}: unknown surrogate format {found!r}")
    try:  # the description whole before the weights
        net_cfg = NetConfig(
            **{k: tuple(v) if isinstance(v, list) else v for k, v in doc["net"].items()}
        )
        feats = FeatureSpec.from_dict(doc["features"])
        for p in feats.parameters:
            spec(p)  # validates the stored parameter names
        wagon = _stored_wagon(doc["wagon"], meta_path)
        corr = doc.get("record_correction")  # absent in files saved before it existed
        parts = (
            Normaliser(**doc["normaliser"]),
            WorkingCondition(**doc["condition"]),
            wagon,
            int(doc["track_seed"]),
            doc.get("meta", {}),
            None if corr is None else RecordCorrection.from_dict(corr),
        )
        net = build_network(net_cfg)
    except RailsuspInputError:
        raise
    except (KeyError, TypeError, AttributeError, ValueError) as exc:
        raise RailsuspInputError(f"{meta_path}: {_unread(exc)}; {remedy}") from None
    state = read_torch_file(path / "model.pt", "surrogate weights", remedy)
    try:
        net.load_state_dict(state)
    except (RuntimeError, KeyError, TypeError, AttributeError) as exc:
        first = str(exc).strip().splitlines()[0]
        raise RailsuspInputError(
            f"surrogate weights {path / 'model.pt'} refused: not the network surrogate.json "
            f"describes ({first}); {remedy}"
        ) from None
    net.eval()
    return Surrogate(net, net_cfg, feats, *parts)


def _stored_wagon(fields: object, meta_path: Path) -> WagonData:
    """The wagon a surrogate was trained on; one of an older model is refused in one line
    (the surrogate has to be trained again, whatever its files' state)."""
    try:
        return WagonData(**fields)  # type: ignore[arg-type]
    except ValidationError as exc:
        names = ", ".join(".".join(map(str, e["loc"])) for e in exc.errors())
        raise RailsuspInputError(
            f"{meta_path}: its wagon description ({names}) is not one this railsusp reads: the "
            "surrogate was trained on an older model; train it again"
        ) from None


def _unread(exc: Exception) -> str:
    """Why a surrogate.json does not describe a surrogate, in a few words."""
    if isinstance(exc, KeyError):
        return f"not a surrogate description this railsusp reads (no {exc.args[0]!r})"
    first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    return f"not a surrogate description this railsusp reads ({first})"
