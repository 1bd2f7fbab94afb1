"""What a surrogate's input window holds, and the track input each axle sees.

The study feeds its CNN-GRU 20 x 21 windows but does not say what the 21 features are.
railsusp's default feature set (:class:`FeatureSpec`, configurable):

* the key suspension parameters, scaled to [0, 1] by their Table 2 ranges, constant along
  the window (6 with the study's choice);
* the track input at three axles (the measured leading wheelset w1, the trailing wheelset of
  the same bogie w2 and the leading wheelset of the rear bogie w3), five channels each:
  vertical and lateral irregularity of both rails (mm) and the design curvature (1/km):
  3 x 5 = 15;
* optionally the cant angle at each axle (``"cant"``, in mm of superelevation over the
  1.5 m base): added by training when the campaign varies the cant (a track family), since
  the curvature channel alone cannot tell two cants apart;
* optionally the nominal wagon's response on the same track (:mod:`.nominal`): more of its
  channels as context (``nominal_context``), then its forces at the measured wheel, which
  the network's output is added to (``nominal_response``).

:func:`track_features` rebuilds a sample's track channels at the chosen axles from its own
condition (irregularity seed and, in a track-family campaign, FRA class, radius and cant).
This is apart from :mod:`railsusp.surrogate.data`, which reads a campaign's series into
training arrays and windows, because what a network reads is one question and how a
campaign's runs become training windows another: an estimate rebuilds the features of a
recording's track with no campaign at all (:mod:`railsusp.estimate.forces`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from railsusp.conditions import CANT_BASE_M, WorkingCondition
from railsusp.surrogate.nominal import check_context, nominal_forces
from railsusp.vehicle import layout as L
from railsusp.vehicle.simulate import SolverSettings
from railsusp.vehicle.track_grid import track_arrays
from railsusp.vehicle.wagon import WagonData

TRACK_CHANNELS = {
    "zL": L.TR_ZL,
    "zR": L.TR_ZR,
    "yL": L.TR_YL,
    "yR": L.TR_YR,
    "curvature": L.TR_KAPPA,
    "cant": L.TR_CANT,
}
#: display scaling of the track channels: irregularities in mm, curvature in 1/km, cant
#: angle as mm of superelevation (small-angle, over the 1.5 m base)
_CHANNEL_SCALE = {
    "zL": 1e3,
    "zR": 1e3,
    "yL": 1e3,
    "yR": 1e3,
    "curvature": 1e3,
    "cant": 1e3 * CANT_BASE_M,
}
#: the default track channels (the study's 21 features with six parameters)
DEFAULT_TRACK_CHANNELS = ("zL", "zR", "yL", "yR", "curvature")


@dataclass(frozen=True)
class FeatureSpec:
    """What a window holds: parameters, track channels at which axles, window length."""

    parameters: tuple[str, ...]
    track_channels: tuple[str, ...] = DEFAULT_TRACK_CHANNELS
    axles: tuple[int, ...] = (0, 1, 2)  # wheelset indices: 0 = w1 (leading) ...
    window: int = 20
    targets: tuple[str, ...] = ("Y", "Q")
    #: the nominal wagon's forces on the same track as inputs, after the track channels
    #: (:mod:`.nominal`); the network then learns the force minus the nominal force
    nominal_response: bool = False
    #: more channels of the nominal wagon's response (:data:`.nominal.CONTEXT_CHANNELS`)
    #: as inputs, between the track channels and the nominal forces (needs
    #: ``nominal_response``)
    nominal_context: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        check_context(self.nominal_context)
        if self.nominal_context and not self.nominal_response:
            raise ValueError("nominal_context: accepted only with nominal_response = true")

    @property
    def n_baseline(self) -> int:
        """Trailing track-input columns that are the nominal response (one per target)."""
        return len(self.targets) if self.nominal_response else 0

    @property
    def n_features(self) -> int:
        return (
            len(self.parameters)
            + len(self.track_channels) * len(self.axles)
            + len(self.nominal_context)
            + self.n_baseline
        )

    def names(self) -> list[str]:
        """Feature names in input order."""
        return [
            *(f"{p}_unit" for p in self.parameters),
            *(f"{c}@w{a + 1}" for a in self.axles for c in self.track_channels),
            *(f"{c}_nominal" for c in self.nominal_context),
            *(f"{t}_nominal" for t in self.targets[: self.n_baseline]),
        ]

    def to_dict(self) -> dict:
        doc = asdict(self)
        if not self.nominal_response:  # surrogates saved before the option read the same
            del doc["nominal_response"]
        if not self.nominal_context:  # nor before this one
            del doc["nominal_context"]
        return doc

    @classmethod
    def from_dict(cls, doc: dict) -> FeatureSpec:
        """Inverse of :meth:`to_dict` (JSON lists back to tuples)."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in doc.items()})


def axle_offsets(wagon: WagonData) -> np.ndarray:
    """Distance of each wheelset behind the leading one, m."""
    a = wagon.bogie.half_wheelbase
    lc = wagon.car_body.bogie_half_spacing
    return np.array([0.0, 2 * a, 2 * lc, 2 * lc + 2 * a])


def track_features(
    condition: WorkingCondition,
    seed: int,
    spec: FeatureSpec,
    wagon: WagonData,
    settings: SolverSettings | None = None,
    nominal: np.ndarray | None = None,
) -> np.ndarray:
    """Track input seen by the chosen axles at every output step: (T, channels x axles),
    then, with ``spec.nominal_response``, the nominal wagon's response on that track: its
    ``spec.nominal_context`` channels and its forces (kN, one column per target):
    ``nominal`` (T, n_context + n_targets) when already simulated (a campaign's nominal
    twin), else simulated here (:func:`.nominal.nominal_forces`)."""
    settings = SolverSettings() if settings is None else settings
    if spec.nominal_response:
        if nominal is None:
            nominal = nominal_forces(
                condition, seed, wagon, spec.targets, settings, spec.nominal_context
            )
        plain = track_features(
            condition,
            seed,
            replace(spec, nominal_response=False, nominal_context=()),
            wagon,
            settings,
        )
        return np.concatenate([plain, np.asarray(nominal, dtype=plain.dtype)], axis=1)
    tr, s0, ds = track_arrays(condition.with_changes(seed=seed), [seed], wagon, settings)
    grid = s0 + ds * np.arange(tr.shape[2])
    t = np.arange(condition.n_steps) * condition.sample_interval
    s_front = condition.lead_in_m + condition.speed * t
    offs = axle_offsets(wagon)
    cols = []
    for a in spec.axles:
        s = s_front - offs[a]
        for ch in spec.track_channels:
            cols.append(np.interp(s, grid, tr[0, TRACK_CHANNELS[ch]]) * _CHANNEL_SCALE[ch])
    return np.stack(cols, axis=1)
