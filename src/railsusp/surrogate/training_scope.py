"""What a trained surrogate is and what it was trained on: its network, feature definition,
normalisation, working condition, wagon, track realisation(s) and track family
(:class:`TrainedNetwork`), and so which conditions, tracks and sampling intervals it serves
(:meth:`TrainedNetwork.untrained_fields`, :meth:`TrainedNetwork.reads_training_track`).

Apart from :mod:`railsusp.surrogate.bundle`, whose :class:`~railsusp.surrogate.bundle.Surrogate`
(a :class:`TrainedNetwork`) predicts force series and is saved and loaded: the questions of a
network's training scope read only its stored description, never run the network, and are
asked on their own (a recording's condition checked against a network set before any
prediction, :mod:`railsusp.surrogate.pretrained`, :mod:`railsusp.estimate.forces`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch

from railsusp.conditions import TRACK_AND_LENGTH_FIELDS, WorkingCondition
from railsusp.surrogate.correction import RecordCorrection
from railsusp.surrogate.data import Normaliser
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.models import NetConfig
from railsusp.surrogate.sequence import CNNSequence
from railsusp.vehicle.simulate import SolverSettings
from railsusp.vehicle.track_geometry import same_measured_track
from railsusp.vehicle.wagon import WagonData

#: condition fields a track-family campaign varies, and their names in the family
_FAMILY_FIELDS = {
    "irregularity_class": "irregularity_classes",
    "curve_radius_m": "curve_radius_m",
    "cant_mm": "cant_mm",
}


def family_of(ranges: dict[str, Any], condition: WorkingCondition) -> dict[str, list]:
    """A track family's ranges as one condition's runs drew them: a family campaign varies
    the curve radius and cant in its curves only, so a tangent condition's runs have
    neither (:func:`railsusp.variation.sample_tracks` draws them only where the condition
    has a ``curve_radius_m``)."""
    fam = {k: list(v) for k, v in ranges.items()}
    if condition.curve_radius_m is None:
        fam.pop("curve_radius_m", None)
        fam.pop("cant_mm", None)
    return fam


#: relative difference of sample intervals a network accepts (whole-step and whole-ms cuts)
SAMPLING_TOLERANCE = 1e-3


@dataclass
class TrainedNetwork:
    """A trained window (or sequence) network, its feature definition and normalisation,
    and what it was trained on: the base of :class:`~railsusp.surrogate.bundle.Surrogate`,
    which adds prediction and saving."""

    net: torch.nn.Module
    net_config: NetConfig
    spec: FeatureSpec
    normaliser: Normaliser
    condition: WorkingCondition
    wagon: WagonData
    track_seed: int
    meta: dict[str, Any] = field(default_factory=dict)
    #: record-level correction of the predicted series (None: the network's own output)
    correction: RecordCorrection | None = None

    @property
    def kind(self) -> str:
        return self.net_config.kind

    def solver_settings(self) -> SolverSettings:
        """The training campaign's solver settings (the defaults for surrogates saved before
        they were kept): a nominal response simulated at prediction must be simulated as the
        twins the network was trained on were."""
        return SolverSettings(**self.meta.get("solver", {}))

    @property
    def one_track(self) -> bool:
        """Trained on a single track realisation (a common-random-numbers campaign): it then
        predicts that track only. On other tracks such networks' series are uncorrelated
        with the simulator's (held-out R² about 0, bench/README.md): they learn the track's
        windows, not the wheel-rail dynamics. Unknown (False) for surrogates saved before
        the count was kept."""
        return self.meta.get("track_realisations") == 1

    @property
    def segment_steps(self) -> int | None:
        """The sequence CNN-GRU's prediction segment (steps; None: each series in one run
        with the state carried, and for window networks): ``meta["segment_steps"]`` when
        set, else the length of the chunks it was trained on (``train_config.chunk_steps``,
        at most its campaign's record length), so that no prediction runs its state longer
        than training did (:func:`~railsusp.surrogate.sequence.segment_plan`)."""
        if not isinstance(self.net, CNNSequence):
            return None
        if "segment_steps" in self.meta:
            seg = self.meta["segment_steps"]
            return None if seg is None else int(seg)
        chunk = (self.meta.get("train_config") or {}).get("chunk_steps")
        return None if chunk is None else min(int(chunk), self.condition.n_steps)

    def reads_training_track(
        self, condition: WorkingCondition | None = None, seed: int | None = None
    ) -> bool:
        """Whether ``predict(params, condition, seed=seed)`` runs on the training track."""
        on = self.condition if condition is None else condition
        if on.track_geometry is not None or self.condition.track_geometry is not None:
            # one file, or a copy of it (a synthetic recording's of its condition's track)
            return same_measured_track(on, self.condition)
        if seed is None:
            seed = self.track_seed if condition is None else condition.seed
        return seed == self.track_seed

    def track_family(self) -> dict[str, list]:
        """The ranges of the track family this network's own runs were drawn from: the
        campaign's family (``meta.track_family``), less the curve's radius and cant where
        the network's condition is tangent track (a family campaign varies them in its
        curves only, so a tangent network never saw a curve: until stop 62 its bundle
        claimed the campaign's radius and cant and accepted a curve, 40 % low on |Y|)."""
        return family_of(self.meta.get("track_family") or {}, self.condition)

    def in_track_family(self, field_name: str, value: Any) -> bool:
        """Whether a condition field's value lies in the track family the surrogate was
        trained on (its FRA class, curve radius or cant varied per sample, inclusive)."""
        rng = self.track_family().get(_FAMILY_FIELDS.get(field_name, ""))
        return rng is not None and value is not None and rng[0] <= value <= rng[1]

    def untrained_fields(self, condition: WorkingCondition) -> list[tuple[str, Any, str]]:
        """(field, value, what the network was trained on) for each field of ``condition``
        outside the surrogate's training: a field other than the track input (irregularity
        seed, measured geometry) and the record length that differs from its condition and
        is not in its track family, a sampling interval other than the training's (the
        record length may differ, not the time step of the network's series), and a
        family field (FRA class, curve radius, cant)
        outside the family's range even where it equals the surrogate's own condition: a
        family campaign draws those per sample, so the condition's nominal value (the
        study's 110 mm cant, say) need not lie in the family (0-100 mm) and would be an
        extrapolation."""
        fam = self.track_family()
        ignore = TRACK_AND_LENGTH_FIELDS
        names = list(self.condition.differences(condition, ignore))
        for name, key in _FAMILY_FIELDS.items():
            if key in fam and name not in names and getattr(condition, name) is not None:
                names.append(name)
        out = []
        # the record length may differ, its sampling may not: the network's steps are the
        # training's time step (a 100 Hz recording read as 50 Hz would halve every frequency)
        # (to 0.1 %: a record cut to whole milliseconds or whole steps keeps its rate)
        mine, theirs = self.condition.sample_interval, condition.sample_interval
        if abs(theirs - mine) > SAMPLING_TOLERANCE * mine:
            out.append(("sample_interval", float(f"{theirs:.6g}"), f"{mine:g} s only"))
        for name in names:
            value = getattr(condition, name)
            if self.in_track_family(name, value):
                continue
            rng = fam.get(_FAMILY_FIELDS.get(name, ""))
            if rng is not None:
                trained = f"the track family {rng[0]:g} to {rng[1]:g}"
            else:
                trained = f"{getattr(self.condition, name)!r} only"
            out.append((name, value, trained))
        return out
