"""Surrogate training data: sliding windows of track input and parameters -> wheel forces.

The study feeds its CNN-GRU 20 x 21 windows (20 time steps, 21 features, stride 1, 980 windows
per 1000-step series) and predicts the lateral and vertical wheel-rail force at the window's
end. What a window holds (:class:`~railsusp.surrogate.features.FeatureSpec`) and the track
input each axle sees are :mod:`railsusp.surrogate.features`; this module reads a campaign's
series of one condition into arrays (:func:`load_series`, with the nominal twins' response
where the features carry it), splits them by sample, fits the normalisation and cuts the
windows.

The window ending at step k covers steps k - L + 1 .. k and predicts Y and Q of the measured
wheel at step k, for k = L .. T - 1 (T - L windows: 980 for the study's 1000 and 20).
Training, validation and test sets are split by simulation sample, never by window (by track
and parameter set: :mod:`railsusp.surrogate.split`), and the normalisation is fitted on the
training samples only. Each sample's track input is rebuilt from its own condition: its
irregularity seed and, in a track-family campaign, its FRA class, radius and cant.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from railsusp.campaign import CHANNELS, Campaign
from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.params import bounds, spec
from railsusp.surrogate.features import FeatureSpec as FeatureSpec  # public here too
from railsusp.surrogate.features import track_features
from railsusp.variation import layout_key, sample_condition
from railsusp.vehicle.simulation_result import WHEEL_NAMES, measured_wheel_index


@dataclass
class SeriesData:
    """Per-sample arrays of one condition: parameters (unit), track features, targets."""

    sample_ids: np.ndarray  # (n,)
    params_unit: np.ndarray  # (n, n_params)
    track: np.ndarray  # (n, T, n_track) or (1, T, n_track) when every sample shares it
    targets: np.ndarray  # (n, T, n_targets), kN
    condition: WorkingCondition
    seeds: np.ndarray  # (n,)
    #: parameters varied in the campaign but not network inputs: names and SI values (n, k)
    other_names: tuple[str, ...] = ()
    others: np.ndarray | None = None
    #: trailing track columns holding the nominal response (FeatureSpec.n_baseline)
    n_baseline: int = 0

    @property
    def learned(self) -> np.ndarray:
        """What a network learns (n, T, n_targets): the targets, less the nominal response
        where the inputs carry it (:mod:`.nominal`)."""
        if not self.n_baseline:
            return self.targets
        return self.targets - self.track[..., -self.n_baseline :]

    @property
    def n_samples(self) -> int:
        return len(self.sample_ids)

    @property
    def n_steps(self) -> int:
        return self.targets.shape[1]

    def subset(self, idx: np.ndarray) -> SeriesData:
        track = self.track if self.track.shape[0] == 1 else self.track[idx]
        return SeriesData(
            self.sample_ids[idx],
            self.params_unit[idx],
            track,
            self.targets[idx],
            self.condition,
            self.seeds[idx],
            self.other_names,
            None if self.others is None else self.others[idx],
            self.n_baseline,
        )


def params_to_unit(x_si: np.ndarray, parameters: Sequence[str]) -> np.ndarray:
    """SI parameter values -> [0, 1] by their Table 2 ranges."""
    lo, hi = bounds(parameters)
    return (np.asarray(x_si, float) - lo) / (hi - lo)


#: how far past a range end (share of the range) a value is still taken as at the end: the
#: round-off of SI values converted back from fractions of the range (1e-16 of the value),
#: and of float32 ones (6e-8 of the value, up to 2e-7 of a range); the network reads its
#: input in float32, which resolves no finer than 6e-8 of the range at its upper end
RANGE_TOLERANCE = 1e-6


def check_trained_range(x_si: np.ndarray, unit: np.ndarray, parameters: Sequence[str]) -> None:
    """Refuse, in one line naming the parameter, the row, the value (SI, with its unit)
    and the range, a parameter value that is not finite or lies outside the range the
    network was trained over (the sampling range its input is the fraction of; past it by
    more than :data:`RANGE_TOLERANCE` of it). ``x_si`` (n, k): the values as given;
    ``unit``: their fractions of the ranges. A network extrapolates without a word:
    display units for SI (MN/m for N/m), a sign slip or ten times a value gave plausible
    forces, and NaN an error from deep in the record correction's GPs."""
    bad = ~np.isfinite(unit) | (unit < -RANGE_TOLERANCE) | (unit > 1.0 + RANGE_TOLERANCE)
    if not bad.any():
        return
    i, j = (int(k) for k in np.argwhere(bad)[0])
    s = spec(parameters[j])
    lo, hi = s.bounds  # type: ignore[misc]  # (a key parameter is a sampled one)
    value = float(x_si[i, j])
    where = f" (row {i} of {len(x_si)})" if len(x_si) > 1 else ""
    trained = f"[{lo:g}, {hi:g}] {s.si_unit}" + (
        f" ({s.range_text()})" if s.display_unit != s.si_unit else ""
    )
    head = f"params: {s.symbol} ({s.description}) = "
    if not np.isfinite(value):
        raise RailsuspInputError(
            f"{head}{value}{where} is not finite; accepted SI values in the range this "
            f"surrogate was trained over, {trained}"
        )
    raise RailsuspInputError(
        f"{head}{value:g} {s.si_unit}{where} is outside the range this surrogate was trained "
        f"over, {trained}; accepted SI values in that range"
    )


def load_series(
    campaign: Campaign, condition: str, spec: FeatureSpec, wheel: str = "auto"
) -> SeriesData:
    """Build the surrogate arrays of one condition of a campaign (finished batches only)."""
    cfg = campaign.config
    cond = next((c for c in cfg.conditions if c.name == condition), None)
    if cond is None:
        raise ValueError(
            f"condition {condition!r} not in the campaign "
            f"({', '.join(c.name for c in cfg.conditions)})"
        )
    missing = [p for p in spec.parameters if p not in cfg.simulated_parameters]
    if missing:
        raise ValueError(f"parameters {missing} were not sampled in this campaign")
    ids, series = campaign.series(condition)
    design = campaign.design().set_index("sample_id").loc[ids]
    w = measured_wheel_index(cond, wheel if wheel != "auto" else cfg.wheel)
    targets = []
    for t in spec.targets:
        ch = CHANNELS.index(f"{t}_{WHEEL_NAMES[w]}")
        targets.append(series[:, ch, :] / 1e3)
    if spec.nominal_response:  # before the tracks' features, which take minutes
        check_nominal(campaign, cond, w)
    y = np.stack(targets, axis=2).astype(np.float32)
    ok = np.isfinite(y).all(axis=(1, 2))
    tracks = campaign.tracks(condition).set_index("sample_id").loc[ids].reset_index()
    rows = tracks.to_dict("records")
    seeds = tracks["seed"].to_numpy()
    keys = [(int(r["seed"]), layout_key(r)) for r in rows]
    plain = replace(spec, nominal_response=False, nominal_context=())
    per_key = {
        k: track_features(sample_condition(cond, r), k[0], plain, cfg.wagon, cfg.settings())
        for k, r in dict(zip(keys, rows, strict=True)).items()
    }
    if len(per_key) == 1 and not spec.nominal_response:
        track = next(iter(per_key.values()))[None]
    else:
        track = np.stack([per_key[k] for k in keys])
    if spec.nominal_response:
        track = np.concatenate([track, twin_forces(campaign, condition, ids, w, spec)], axis=2)
    other_names = tuple(p for p in cfg.simulated_parameters if p not in spec.parameters)
    data = SeriesData(
        ids,
        params_to_unit(design[list(spec.parameters)].to_numpy(), spec.parameters).astype(
            np.float32
        ),
        track.astype(np.float32),
        y,
        cond,
        seeds,
        other_names,
        design[list(other_names)].to_numpy(float),
        spec.n_baseline,
    )
    if spec.nominal_response:  # a twin that failed leaves its sample without an input
        ok &= np.isfinite(data.track).all(axis=(1, 2))
    return data.subset(np.flatnonzero(ok))


def check_nominal(campaign: Campaign, cond: WorkingCondition, wheel: int) -> None:
    """Refuse, in one line, what the nominal response cannot be read from: a campaign on one
    common track, a wheel other than the automatically chosen one (the wheel a prediction
    simulates), or twins missing, incomplete or of another configuration."""
    from railsusp.campaign.twins import check_twins_possible, twins_complete

    check_twins_possible(campaign.config, campaign.path)
    auto = measured_wheel_index(cond, "auto")
    if wheel != auto:
        raise ValueError(
            f"wheel {WHEEL_NAMES[wheel]}: the nominal response is read at the automatically "
            f"chosen measured wheel ({WHEEL_NAMES[auto]})"
        )
    if not twins_complete(campaign.path, cond.name):
        raise ValueError(
            f"{campaign.path}: the nominal twins of {cond.name!r} are missing, incomplete or "
            "of another configuration; make them with "
            "`railsusp.campaign.twins.run_nominal_twins` before training with the nominal response"
        )


def twin_forces(
    campaign: Campaign, condition: str, ids: np.ndarray, wheel: int, spec: FeatureSpec
) -> np.ndarray:
    """(n, T, n_context + n_targets): the ``spec.nominal_context`` channels (kN, m/s²), then
    the forces (kN) of wheel ``wheel``, of the nominal twins of samples ``ids``
    (:mod:`railsusp.campaign.twins`, checked by :func:`check_nominal`); NaN for a twin that
    failed."""
    from railsusp.campaign.twins import nominal_folder

    names = [*spec.nominal_context, *(f"{t}_{WHEEL_NAMES[wheel]}" for t in spec.targets)]
    return twin_channels(nominal_folder(campaign.path), condition, ids, names)


def twin_channels(root: Path, condition: str, ids: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """(n, T, len(names)): channels ``names`` of the runs stored under ``root`` (a campaign's
    twins, in its batch layout) of samples ``ids``, forces in kN, accelerations in m/s²; NaN
    for a sample with no stored run."""
    from railsusp.campaign.results import read_series

    twin_ids, series = read_series(root, condition)
    pos = {int(s): i for i, s in enumerate(twin_ids)}
    rows = np.array([pos.get(int(s), -1) for s in ids], dtype=int)
    found = rows >= 0
    per_unit = [1.0 if n.startswith("car_acc") else 1e3 for n in names]  # N -> kN
    cols = [CHANNELS.index(n) for n in names]
    out = np.full((len(ids), series.shape[2], len(names)), np.nan, dtype=series.dtype)
    for k, (c, d) in enumerate(zip(cols, per_unit, strict=True)):
        out[found, :, k] = series[rows[found], c, :] / d
    return out


def split_samples(
    sample_ids: np.ndarray, fractions: tuple[float, float, float] = (0.7, 0.15, 0.15), seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions of train / validation / test samples: a split by sample, never by window."""
    n = len(sample_ids)
    if n < 3:
        raise ValueError(f"need at least 3 samples to split, got {n}")
    perm = np.random.default_rng(seed).permutation(n)
    n_val = max(1, round(fractions[1] * n))
    n_test = max(1, round(fractions[2] * n))
    n_train = n - n_val - n_test
    if n_train < 1:
        raise ValueError(f"{n} samples leave no training sample with fractions {fractions}")
    return (
        np.sort(perm[:n_train]),
        np.sort(perm[n_train : n_train + n_val]),
        np.sort(perm[n_train + n_val :]),
    )


@dataclass
class Normaliser:
    """Standardisation of track features and targets, fitted on training data only."""

    track_mean: list[float] = field(default_factory=list)
    track_std: list[float] = field(default_factory=list)
    target_mean: list[float] = field(default_factory=list)
    target_std: list[float] = field(default_factory=list)

    @classmethod
    def fit(cls, data: SeriesData) -> Normaliser:
        tr = data.track.reshape(-1, data.track.shape[-1]).astype(np.float64)
        y = data.learned.reshape(-1, data.targets.shape[-1]).astype(np.float64)
        ts = tr.std(axis=0)
        ys = y.std(axis=0)
        return cls(
            tr.mean(axis=0).tolist(),
            np.where(ts > 0, ts, 1.0).tolist(),
            y.mean(axis=0).tolist(),
            np.where(ys > 0, ys, 1.0).tolist(),
        )

    def track(self, x: np.ndarray) -> np.ndarray:
        return ((x - np.asarray(self.track_mean)) / np.asarray(self.track_std)).astype(np.float32)

    def target(self, y: np.ndarray) -> np.ndarray:
        return ((y - np.asarray(self.target_mean)) / np.asarray(self.target_std)).astype(np.float32)

    def target_inverse(self, y: np.ndarray) -> np.ndarray:
        return y * np.asarray(self.target_std) + np.asarray(self.target_mean)


def window_index(n_samples: int, n_steps: int, window: int) -> np.ndarray:
    """All (sample, end step) pairs: (n_samples * (T - L), 2), end steps L .. T - 1."""
    ends = np.arange(window, n_steps)
    return np.stack(np.meshgrid(np.arange(n_samples), ends, indexing="ij"), axis=-1).reshape(-1, 2)


def gather_windows(
    params: np.ndarray, track: np.ndarray, index: np.ndarray, window: int
) -> np.ndarray:
    """Windows (B, L, F) for (sample, end) pairs: the parameters repeated along the window,
    then the track features of steps end - L + 1 .. end."""
    i, k = index[:, 0], index[:, 1]
    steps = k[:, None] + np.arange(-window + 1, 1)[None, :]
    ti = np.zeros_like(i) if track.shape[0] == 1 else i
    tr = track[ti[:, None], steps]  # (B, L, n_track)
    p = np.broadcast_to(params[i][:, None, :], (len(i), window, params.shape[1]))
    return np.concatenate([p, tr], axis=2)
