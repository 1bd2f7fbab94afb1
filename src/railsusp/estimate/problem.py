"""NSGA-II calibration of the key suspension parameters against measured wheel-rail forces.

Problem, algorithm, termination, one entry point (pymoo style): :class:`CalibrationProblem`
holds the objectives (lateral and vertical mismatch between a force model and the
recordings, as relative errors of a record statistic, joint over the conditions by default),
:class:`NSGAConfig` the algorithm settings (the study's: population 50, crossover 0.9,
mutation 0.05, 100 generations), and :func:`estimate` returns a :class:`CalibrationResult`
that saves and plots itself.

The measured track is unknown, so records are compared through statistics (mean, RMS,
99th percentile or standard deviation of |Y| and Q of the measured wheel, or a combination
such as ``mean+p99+std`` whose relative errors are averaged), never sample by sample.

Force models: a trained window surrogate per condition (:class:`SurrogateForces`, the
study's route), statistics surrogates per condition (:class:`StatisticsForces`, Gaussian
processes straight to the statistics) or the batched simulator itself
(:class:`SimulatorForces`, slow, the reference). :func:`open_force_model` picks the surrogate
kind from a folder's contents.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import pandas as pd
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.core.callback import Callback
from pymoo.core.problem import Problem
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.sampling.rnd import FloatRandomSampling
from pymoo.optimize import minimize
from pymoo.util.display.multi import MultiObjectiveOutput

from railsusp.conditions import TRACK_INPUT_FIELDS, WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.identifiability import cramer_rao_pct_range
from railsusp.measured import Recording, bandwidth_filter
from railsusp.params import ParameterSet, bounds, spec
from railsusp.store import write_json, write_parquet
from railsusp.vehicle.simulate import RECORD_STATISTICS, record_statistic, statistic_segments
from railsusp.vehicle.track import CHANNEL_COMPONENTS, accurate_wavelength_m, read_track_geometry

if TYPE_CHECKING:  # the refinement builds on this module
    from railsusp.refine import Refinement

#: time-aligned comparison of the series (recordings with measured track geometry only)
ALIGNED = "aligned"
STATISTICS = (*RECORD_STATISTICS, ALIGNED)
#: how a statistic's mismatch enters an objective: relative error (the study's), or the
#: mismatch in units of the statistics surrogate's predictive standard deviation (GP
#: uncertainty plus track-realisation scatter), which weights precise features more
WEIGHTINGS = ("relative", "noise")


def check_weighting(weighting: str) -> str:
    """``weighting`` if it is one of :data:`WEIGHTINGS`, else a ValueError naming them."""
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting {weighting!r}: accepted {', '.join(WEIGHTINGS)}")
    return weighting


def parse_statistics(text: str) -> tuple[str, ...]:
    """``"mean"`` or a ``+``-joined combination such as ``"mean+p99+std"``, validated.

    ``aligned`` is not a record statistic but the time-aligned mismatch of the series (see
    :func:`aligned_error`)."""
    stats = tuple(t.strip() for t in str(text).split("+") if t.strip())
    bad = [t for t in stats if t not in STATISTICS]
    if bad or not stats or len(set(stats)) != len(stats):
        raise ValueError(
            f"statistic {text!r}: give one of {', '.join(STATISTICS)} or a '+'-joined "
            "combination of different ones (e.g. mean+p99+std)"
        )
    return stats


def measurement_filter(series: np.ndarray, rec: Recording) -> np.ndarray:
    """Predicted series (n, T, channels) passed through the recording's documented filter
    (``filter_bandwidth_hz`` in its metadata), so that a model is compared with what the
    instrument could see; unchanged when the recording gives no bandwidth. Undefined leading
    steps (window surrogates) stay undefined, and so does the whole of a set whose series
    breaks off (a simulation flagged as failed)."""
    bw = rec.meta.get("filter_bandwidth_hz")
    if not bw:
        return series
    return _lowpass_defined(series, rec.sampling_rate, np.full(series.shape[-1], float(bw)))


def _lowpass_defined(series: np.ndarray, fs: float, bandwidths: np.ndarray) -> np.ndarray:
    """Series (n, T, channels) low-passed along time, channel c at ``bandwidths[c]`` Hz
    (:func:`~railsusp.measured.bandwidth_filter`); leading undefined steps stay undefined,
    and a set whose series breaks off becomes wholly undefined."""

    def lowpass(x: np.ndarray) -> np.ndarray:  # (T, channels) or (n, T, channels)
        out = np.empty_like(x)
        for c, bw in enumerate(bandwidths):
            out[..., c] = bandwidth_filter(x[..., c], fs, float(bw), axis=-1)
        return out

    if np.isfinite(series).all():
        return lowpass(series)
    out = np.full_like(series, np.nan)
    for i, one in enumerate(series):
        ok = np.isfinite(one).all(axis=1)
        first = int(np.argmax(ok))
        if ok.any() and ok[first:].all() and ok.size - first > 30:
            out[i, first:] = lowpass(one[first:])
    return out


def comparison_band_hz(rec: Recording) -> np.ndarray | None:
    """(2,) upper frequency (Hz) of the time-aligned comparison of lateral and vertical
    force: the speed over the shortest wavelength down to which the recording's track
    geometry is accurate (:func:`~railsusp.vehicle.track.accurate_wavelength_m`, from the
    condition's ``track_accuracy_mm``; the components that drive each channel). None where
    the geometry is exact (accuracy 0): the whole instrument band is compared.

    Below that wavelength the geometry error outweighs the geometry, and a fit there would
    absorb the error into the parameters (an errors-in-variables bias)."""
    cond = rec.condition
    if cond.track_geometry is None or not cond.track_accuracy_mm:
        return None
    path = Path(cond.track_geometry)
    return np.array(
        _comparison_band(
            str(path.resolve()),
            path.stat().st_mtime_ns,
            cond.track_accuracy_mm,
            cond.wavelength_min_m,
            cond.speed,
        )
    )


@lru_cache(maxsize=32)
def _comparison_band(
    path: str, _mtime_ns: int, accuracy_mm: float, wavelength_min_m: float, speed: float
) -> tuple[float, float]:
    """:func:`comparison_band_hz` of one geometry file, cached: every time-aligned
    comparison asks for it, and the geometry's PSD need not be estimated each time."""
    lam = accurate_wavelength_m(read_track_geometry(path), accuracy_mm * 1e-3, wavelength_min_m)
    y, q = (speed / max(lam[c] for c in CHANNEL_COMPONENTS[ch]) for ch in ("Y", "Q"))
    return (y, q)


def comparison_filter(series: np.ndarray, rec: Recording) -> np.ndarray:
    """Predicted series (n, T, 2) as the time-aligned comparison sees them: through the
    recording's filter (:func:`measurement_filter`) and limited to its comparison band
    (:func:`comparison_band_hz`)."""
    series = measurement_filter(series, rec)
    band = comparison_band_hz(rec)
    return series if band is None else _lowpass_defined(series, rec.sampling_rate, band)


def compared_measurement(rec: Recording) -> np.ndarray:
    """(T, 2) the recording's lateral and vertical force limited to its comparison band."""
    meas = rec.forces()
    band = comparison_band_hz(rec)
    return meas if band is None else _lowpass_defined(meas[None], rec.sampling_rate, band)[0]


def comparison_samples(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """Per channel (Y, Q), the samples of a recording the time-aligned comparison uses: all
    of them without a comparison band; with one, four per period of the band's upper
    frequency (residuals closer than that are not independent), leaving out one period at
    each end, where the zero-phase filter's start and end transients lie."""
    n = rec.forces().shape[0]
    band = comparison_band_hz(rec)
    if band is None:
        return (np.arange(n), np.arange(n))
    fs = rec.sampling_rate
    edge = min(int(np.ceil(fs / band.min())), n // 4)
    y, q = (np.arange(edge, n - edge, max(1, int(fs / (4.0 * f)))) for f in band)
    return (y, q)


#: time-aligned error given to a prediction that is undefined (a failed simulation)
FAILED_ALIGNED_ERROR = 1e3


def aligned_error(pred: np.ndarray, rec: Recording) -> np.ndarray:
    """(n, 2) time-aligned mismatch of predicted lateral and vertical series (n, T, 2) with a
    recording made on measured track: RMS of the sample-by-sample difference over the
    standard deviation of the measured series (its dynamic part), after the recording's
    filter is applied to the prediction and both are limited to the band where the track
    geometry is accurate (:func:`comparison_band_hz`). Zero for a perfect model and
    noise-free data;
    :data:`FAILED_ALIGNED_ERROR` for a set without a defined prediction."""
    meas = rec.forces()
    if pred.shape[-2] != meas.shape[0]:
        raise ValueError(
            f"recording {rec.condition.name!r} has {meas.shape[0]} samples, the model "
            f"predicts {pred.shape[-2]}: time-aligned comparison needs the same time base"
        )
    ok = np.isfinite(pred).all(axis=-1)  # (n, T)
    first = np.argmax(ok, axis=1)
    after_first = np.arange(ok.shape[1])[None, :] >= first[:, None]
    defined = ok.any(axis=1) & np.all(ok | ~after_first, axis=1)  # only leading gaps
    meas = compared_measurement(rec)
    diff = comparison_filter(pred, rec) - meas
    err = np.empty(diff.shape[::2])
    for c, used in enumerate(comparison_samples(rec)):
        d = diff[:, used, c]
        sq = np.where(np.isfinite(d), d**2, 0.0).sum(axis=1)
        count = np.isfinite(d).sum(axis=1)
        err[:, c] = np.where(count > 0, np.sqrt(sq / np.maximum(count, 1)), np.inf)
    err /= meas.std(axis=0)
    return np.where(defined[:, None] & np.isfinite(err), err, FAILED_ALIGNED_ERROR)


class ForceModel(Protocol):
    """Predicts the measured wheel's force series for parameter sets in a condition."""

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        """(n, T, 2) lateral and vertical force (kN), NaN where undefined."""
        ...


class SurrogateForces:
    """Window surrogates, one per condition name (a folder of ``<condition>/`` bundles)."""

    def __init__(self, folder: str | Path, parameters: Sequence[str] | None = None):
        from railsusp.surrogate import load

        self.folder = Path(folder)
        self._models: dict[str, Any] = {}
        self._warned: set[str] = set()
        for sub in sorted(self.folder.iterdir()) if self.folder.is_dir() else []:
            if (sub / "surrogate.json").exists():
                self._models[sub.name] = load(sub)
        if not self._models:
            raise FileNotFoundError(f"{self.folder}: no surrogate bundles (<condition>/)")
        first = next(iter(self._models.values()))
        self.parameters = tuple(parameters) if parameters else tuple(first.spec.parameters)
        for name, m in self._models.items():
            if tuple(m.spec.parameters) != self.parameters:
                raise ValueError(
                    f"surrogate {name} uses {m.spec.parameters}, the calibration {self.parameters}"
                )

    @property
    def conditions(self) -> list[str]:
        return list(self._models)

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        if condition.name not in self._models:
            raise ValueError(
                f"no surrogate for condition {condition.name!r} in {self.folder} "
                f"(has {', '.join(self._models)})"
            )
        # on a measured track the network reads that track, if it can; otherwise it predicts
        # its training track, whose statistics the recording's are compared with
        on = condition if self.reads_track(condition) else None
        unread = on is None and condition.track_geometry is not None
        if unread and condition.name not in self._warned:
            from railsusp.surrogate.bundle import OneTrackWarning

            self._warned.add(condition.name)  # once per condition, not per generation
            warnings.warn(
                f"the surrogate of {condition.name!r} was trained on one track realisation: "
                "its statistics on that track are compared with the recording's, whose "
                "measured track it cannot read",
                OneTrackWarning,
                stacklevel=2,
            )
        return self._models[condition.name].predict(x_si, condition=on)

    def reads_track(self, condition: WorkingCondition) -> bool:
        """Whether the network of ``condition`` predicts on its measured track: not when it
        was trained on one other track realisation (it learns that track's windows, not the
        dynamics: :attr:`~railsusp.surrogate.bundle.Surrogate.one_track`)."""
        if condition.track_geometry is None:
            return False
        model = self._models[condition.name]
        return not model.one_track or model.reads_training_track(condition)


class StatisticsForces:
    """Statistics surrogates, one per condition name (a folder of ``<condition>/`` bundles
    with ``statistics.json``): predict the statistics directly, no series."""

    def __init__(self, folder: str | Path, parameters: Sequence[str] | None = None):
        from railsusp.surrogate.statistics import is_statistics_bundle, load_statistics

        self.folder = Path(folder)
        subs = sorted(self.folder.iterdir()) if self.folder.is_dir() else []
        self._models = {p.name: load_statistics(p) for p in subs if is_statistics_bundle(p)}
        if not self._models:
            raise FileNotFoundError(f"{self.folder}: no statistics surrogates (<condition>/)")
        first = next(iter(self._models.values()))
        self.parameters = tuple(parameters) if parameters else first.parameters
        for name, m in self._models.items():
            if m.parameters != self.parameters:
                raise ValueError(
                    f"statistics surrogate {name} uses {m.parameters}, the calibration "
                    f"{self.parameters}"
                )

    @property
    def conditions(self) -> list[str]:
        return list(self._models)

    def predict_statistics(
        self,
        x_si: np.ndarray,
        condition: WorkingCondition,
        statistics: Sequence[str],
        with_std: bool = False,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n, 2, n_statistics) lateral and vertical statistics, kN; with ``with_std`` also
        their predictive standard deviation (GP uncertainty and the scatter between track
        realisations of a record of the training length)."""
        if condition.name not in self._models:
            raise ValueError(
                f"no statistics surrogate for condition {condition.name!r} in {self.folder} "
                f"(has {', '.join(self._models)})"
            )
        model = self._models[condition.name]
        # Trained on synthesised track, the GPs predict the average over track realisations,
        # whatever the recording's seed, length or measured track. Trained on a measured
        # track, they hold for that stretch of track only.
        ignore = (
            ("seed", "track_accuracy_mm")  # the accuracy changes the comparison only
            if model.condition.track_geometry is not None
            else (*TRACK_INPUT_FIELDS, "duration_s", "n_steps")
        )
        diff = model.condition.differences(condition, ignore)
        if diff:
            raise ValueError(
                f"the statistics surrogate for {condition.name!r} was trained for another "
                f"condition: it differs in {', '.join(diff)}"
            )
        mean, std = model.predict(x_si, statistics)
        return (mean, std) if with_std else mean

    def measurement_std(
        self, x_si: np.ndarray, rec: Recording, statistics: Sequence[str]
    ) -> np.ndarray:
        """(n, 2, n_statistics) standard deviation of a recording's statistics about the GP
        mean, kN: the GP's own uncertainty plus the realisation scatter of its training
        records, scaled to the recording's length (scatter variance ~ 1 / segments)."""
        _, sd = self.predict_statistics(x_si, rec.condition, statistics, with_std=True)
        model = self._models[rec.condition.name]
        noise = model.noise_std(statistics) ** 2
        posterior = np.maximum(sd**2 - noise, 0.0)
        scale = model.training_segments / recording_segments(rec)
        return np.sqrt(posterior + noise * scale)


def open_force_model(
    folder: str | Path, parameters: Sequence[str] | None = None
) -> tuple[SurrogateForces | StatisticsForces, tuple[str, ...]]:
    """The surrogate force model in ``folder`` (window or statistics bundles per condition)
    and its key parameters (``parameters`` if given)."""
    from railsusp.surrogate.statistics import is_statistics_bundle

    folder = Path(folder)
    subs = sorted(folder.iterdir()) if folder.is_dir() else []
    kind = StatisticsForces if any(is_statistics_bundle(p) for p in subs) else SurrogateForces
    model = kind(folder, parameters)
    return model, model.parameters


def force_statistics(
    model: ForceModel | StatisticsForces,
    x_si: np.ndarray,
    condition: WorkingCondition,
    statistics: Sequence[str],
) -> np.ndarray:
    """(n, 2, n_statistics) statistics of |Y| and Q predicted by any force model, kN."""
    if isinstance(model, StatisticsForces):
        return model.predict_statistics(x_si, condition, statistics)
    return series_statistics(model.series(x_si, condition), condition, statistics)


def series_statistics(
    series: np.ndarray, condition: WorkingCondition, statistics: Sequence[str]
) -> np.ndarray:
    """(n, 2, n_statistics) statistics of predicted (n, T, 2) |Y|, Q series of a condition,
    averaged over the record's segments like a recording's."""
    segments = statistic_segments(series.shape[1], condition.sample_interval)
    return yq_statistics(series[:, :, 0], series[:, :, 1], statistics, segments)


def yq_statistics(
    y: np.ndarray, q: np.ndarray, statistics: Sequence[str], segments: int = 1
) -> np.ndarray:
    """(..., 2, n_statistics) statistics of |Y| and Q series (time along the last axis),
    averaged over ``segments`` consecutive parts (:func:`record_statistic`)."""
    if not statistics:
        return np.empty((*np.shape(y)[:-1], 2, 0))
    return np.stack(
        [
            np.stack([record_statistic(y, st, True, segments) for st in statistics], axis=-1),
            np.stack([record_statistic(q, st, False, segments) for st in statistics], axis=-1),
        ],
        axis=-2,
    )


class SimulatorForces:
    """The batched simulator on the design track of each condition (slow reference)."""

    def __init__(self, parameters: Sequence[str], wheel: str = "auto"):
        self.parameters = tuple(parameters)
        self.wheel = wheel

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        from railsusp.vehicle.simulate import simulate_batch

        r = simulate_batch(x_si, condition, symbols=self.parameters)
        j = r.measured_wheel(self.wheel)
        return np.stack([r.Y[:, j], r.Q[:, j]], axis=2) / 1e3


@dataclass(frozen=True)
class NSGAConfig:
    """NSGA-II settings (the study's defaults) and the objective definition."""

    pop_size: int = 50
    n_gen: int = 100
    crossover_prob: float = 0.9
    mutation_prob: float = 0.05
    seed: int = 0
    statistic: str = "mean"
    per_condition: bool = False
    weighting: str = "relative"

    def __post_init__(self):
        parse_statistics(self.statistic)  # fail early with the accepted values
        check_weighting(self.weighting)

    def to_dict(self) -> dict:
        return asdict(self)


def measured_statistics(rec: Recording, statistics: Sequence[str]) -> np.ndarray:
    """(2, n_statistics) statistics of |Y| and Q of a recording's first measured wheel, kN,
    averaged over the record's segments of about 20 s (:func:`record_statistic`)."""
    w = rec.wheels[0]
    return yq_statistics(rec.Y[w], rec.Q[w], statistics, recording_segments(rec))


def recording_segments(rec: Recording) -> int:
    """How many statistic segments a recording holds (:func:`statistic_segments`)."""
    return statistic_segments(rec.time.size, 1.0 / rec.sampling_rate)


class CalibrationProblem(Problem):
    """Two objectives over the key parameters (decision variables scaled to [0, 1]):
    relative error of the lateral and of the vertical force statistic against the
    recordings (averaged over the statistics of a combination such as ``mean+p99+std``),
    averaged over the conditions (or one pair per condition)."""

    def __init__(
        self,
        model: ForceModel,
        recordings: Sequence[Recording],
        parameters: Sequence[str],
        statistic: str = "mean",
        per_condition: bool = False,
        weighting: str = "relative",
    ):
        self.model, self.recordings = model, list(recordings)
        self.parameters = tuple(parameters)
        self.statistic, self.per_condition = statistic, per_condition
        if check_weighting(weighting) == "noise" and not isinstance(model, StatisticsForces):
            raise ValueError(
                "weighting 'noise' needs the predictive standard deviation of a statistics "
                "surrogate (gp-stats force model)"
            )
        self.weighting = weighting
        self.lo, self.hi = bounds(self.parameters)
        combination = parse_statistics(statistic)
        self.aligned = ALIGNED in combination
        self.stats = tuple(st for st in combination if st != ALIGNED)
        if self.aligned:
            check_aligned(model, self.recordings)
        self.measured = [measured_statistics(rec, self.stats) for rec in self.recordings]
        n_obj = 2 * len(self.recordings) if per_condition else 2
        super().__init__(n_var=len(self.parameters), n_obj=n_obj, xl=0.0, xu=1.0)

    def to_si(self, unit: np.ndarray) -> np.ndarray:
        return self.lo + np.asarray(unit) * (self.hi - self.lo)

    def errors(self, x_si: np.ndarray) -> np.ndarray:
        """(n, n_conditions, 2) mismatch of the lateral and vertical statistic, averaged over
        the statistics of a combination: relative error, or with ``weighting="noise"`` the
        absolute error over the predictive standard deviation."""
        errs = []
        for rec, meas in zip(self.recordings, self.measured, strict=True):
            parts = []
            if self.aligned:
                series = self.model.series(x_si, rec.condition)
                parts.append(aligned_error(series, rec)[:, :, None])
                if self.stats:
                    pred = series_statistics(series, rec.condition, self.stats)
                    parts.append(np.abs(pred - meas) / np.abs(meas))
            elif self.weighting == "noise":
                pred, sd = self.model.predict_statistics(
                    x_si, rec.condition, self.stats, with_std=True
                )
                parts.append(np.abs(pred - meas) / np.maximum(sd, 1e-9))
            else:
                pred = force_statistics(self.model, x_si, rec.condition, self.stats)
                parts.append(np.abs(pred - meas) / np.abs(meas))
            errs.append(np.concatenate(parts, axis=2).mean(axis=2))
        return np.stack(errs, axis=1)

    def _evaluate(self, x, out, *args, **kwargs):
        e = self.errors(self.to_si(x))
        out["F"] = e.reshape(len(x), -1) if self.per_condition else e.mean(axis=1)


def check_aligned(model: Any, recordings: Sequence[Recording]) -> None:
    """Time-aligned comparison needs series from a model and recordings on measured track."""
    if isinstance(model, StatisticsForces):
        raise ValueError(
            "statistic 'aligned' compares series: use a window surrogate or the simulator, "
            "not a statistics surrogate"
        )
    if isinstance(model, SimulatorForces):
        from railsusp.vehicle.simulate import WHEEL_NAMES, measured_wheel_index

        for r in recordings:
            sim_wheel = WHEEL_NAMES[measured_wheel_index(r.condition, model.wheel)]
            if r.wheels[0] != sim_wheel:
                raise ValueError(
                    f"recording {r.condition.name!r} measures {r.wheels[0]}, the simulator "
                    f"force model wheel {model.wheel!r} gives {sim_wheel}"
                )
    if isinstance(model, SurrogateForces):
        other = [
            r.condition.name
            for r in recordings
            if r.condition.track_geometry is not None and not model.reads_track(r.condition)
        ]
        if other:
            raise RailsuspInputError(
                f"statistic 'aligned': the surrogates of {', '.join(other)} in {model.folder} "
                "were trained on one track realisation and cannot predict the recordings' "
                "measured track: train them on a campaign over the recordings (railsusp "
                "campaign --conditions FIELD), or use --simulator"
            )
    blind = [r.condition.name for r in recordings if r.condition.track_geometry is None]
    if blind:
        raise ValueError(
            "statistic 'aligned' compares time-aligned samples, which needs recordings that "
            f"carry measured track geometry; {', '.join(blind)} do not (the field recordings "
            "need condition.track_geometry, docs/data-format.md)"
        )


class _Log(Callback):
    """Records pymoo's n_gen, n_eval, n_nds, eps, indicator (the study's Tables 3/4) and
    each generation's population, for the convergence history."""

    def __init__(self):
        super().__init__()
        self.rows: list[dict] = []
        self.front_x: list[np.ndarray] = []
        self.front_f: list[np.ndarray] = []
        self._out = MultiObjectiveOutput()
        self._ready = False

    def notify(self, algorithm):
        if not self._ready:
            self._out.initialize(algorithm)
            self._ready = True
        self._out.update(algorithm)
        row = {c.name: c.value for c in self._out.columns}
        row["eps"] = None if row.get("eps") is None else float(row["eps"])
        self.rows.append(row)
        self.front_x.append(algorithm.opt.get("X").copy())
        self.front_f.append(algorithm.opt.get("F").copy())


def choose(front: np.ndarray) -> int:
    """Index of the Pareto point closest to the ideal point after normalising each objective
    to [0, 1] over the front (the documented choice rule)."""
    lo, hi = front.min(axis=0), front.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    return int(np.argmin(np.linalg.norm((front - lo) / span, axis=1)))


def display_values(parameters: Sequence[str], x_si: np.ndarray) -> dict[str, float]:
    """Parameter values (SI) in their display units, by symbol."""
    return {p: spec(p).to_display(v) for p, v in zip(parameters, x_si, strict=True)}


@dataclass
class CalibrationResult:
    """Pareto set/front, chosen estimate, convergence history and log of one NSGA-II run."""

    parameters: tuple[str, ...]
    pareto_x: np.ndarray  # (n_pareto, k) SI
    pareto_f: np.ndarray  # (n_pareto, n_obj)
    chosen: int
    log: pd.DataFrame
    history: np.ndarray  # (n_gen, k) SI: per generation, the choice rule on its front
    config: NSGAConfig
    seeds_spread: dict[str, float] = field(default_factory=dict)
    refinement: Refinement | None = None
    #: Cramér-Rao bound of each parameter at NSGA-II's choice, % of range (statistics GPs)
    cramer_rao: dict[str, float] = field(default_factory=dict)

    @property
    def chosen_x(self) -> np.ndarray:
        """The estimate, SI: the refined one when refined, else NSGA-II's choice."""
        return self.refinement.estimate_si if self.refinement else self.pareto_x[self.chosen]

    @property
    def estimate(self) -> dict[str, float]:
        """The estimate, display units."""
        return display_values(self.parameters, self.chosen_x)

    def pareto_spread(self) -> dict[str, float]:
        """Spread (max - min) of each parameter over the Pareto set, in % of its range."""
        lo, hi = bounds(self.parameters)
        span = self.pareto_x.max(axis=0) - self.pareto_x.min(axis=0)
        return {
            p: float(100 * s / (h - low))
            for p, s, low, h in zip(self.parameters, span, lo, hi, strict=True)
        }

    def table(self) -> pd.DataFrame:
        """The study's Table 5 layout: initial (nominal) and estimated value, display units,
        with the Pareto and seed spreads."""
        ps = self.pareto_spread()
        nsga = display_values(self.parameters, self.pareto_x[self.chosen])
        refined = self.refinement.to_dict() if self.refinement else {}
        rows = []
        for p, v in self.estimate.items():
            row = {
                "parameter": p,
                "unit": spec(p).display_unit,
                "initial": spec(p).nominal_display,
                "estimated": v,
                "pareto_spread_pct_range": ps[p],
                "seed_spread_pct_range": self.seeds_spread.get(p, float("nan")),
            }
            if self.refinement:
                row["nsga_estimate"] = nsga[p]
                row["standard_error_pct_range"] = refined["standard_error_pct_range"][p]
                if refined["geometry_draws"]:
                    row["geometry_error_pct_range"] = refined["geometry_error_pct_range"][p]
            if self.cramer_rao:
                row["cramer_rao_pct_range"] = self.cramer_rao[p]
            rows.append(row)
        return pd.DataFrame(rows)

    def save(self, out: str | Path, extra: dict | None = None) -> Path:
        """Write the log, the Table 5 layout, the JSON record (with ``extra`` provenance such
        as the recordings folder) and the Pareto and convergence figures."""
        out = Path(out)
        write_parquet(out / "nsga_log.parquet", self.log)
        self.log.to_csv(out / "nsga_log.csv", index=False)
        self.table().to_csv(out / "estimate.csv", index=False)
        write_json(
            out / "estimate.json",
            {
                "parameters": list(self.parameters),
                "estimate_display": self.estimate,
                "pareto_x_si": self.pareto_x,
                "pareto_f": self.pareto_f,
                "chosen": self.chosen,
                "history_si": self.history,
                "config": self.config.to_dict(),
                "pareto_spread_pct_range": self.pareto_spread(),
                "seed_spread_pct_range": self.seeds_spread,
                "choice_rule": "closest to the ideal point of the front normalised to [0, 1]"
                + (", then refined by output-error least squares" if self.refinement else ""),
                "nsga_estimate_display": display_values(
                    self.parameters, self.pareto_x[self.chosen]
                ),
                "refinement": self.refinement.to_dict() if self.refinement else None,
                "cramer_rao_pct_range": self.cramer_rao,
                **(extra or {}),
            },
        )
        from railsusp.report import plot_convergence, plot_pareto

        plot_pareto(self, out / "pareto.png")
        plot_convergence(self, out / "convergence.png")
        return out

    def estimate_set(self, base: ParameterSet | None = None) -> ParameterSet:
        """The chosen estimate as a full ParameterSet (others from ``base`` or nominal)."""
        base = base or ParameterSet.nominal()
        return base.replace(dict(zip(self.parameters, self.chosen_x, strict=True)))


def estimate(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    config: NSGAConfig | None = None,
    initial_si: np.ndarray | None = None,
) -> CalibrationResult:
    """Run NSGA-II and pick the estimate; deterministic for a given seed.

    ``initial_si``: parameter sets (n, k), SI, to start the population from (e.g. the Pareto
    set of a cheaper estimate), topped up with random sets to the population size."""
    cfg = NSGAConfig() if config is None else config
    problem = CalibrationProblem(
        model, recordings, parameters, cfg.statistic, cfg.per_condition, cfg.weighting
    )
    sampling: Any = FloatRandomSampling()
    if initial_si is not None:
        start = np.clip((np.atleast_2d(initial_si) - problem.lo) / (problem.hi - problem.lo), 0, 1)
        start = start[: cfg.pop_size]
        fill = np.random.default_rng(cfg.seed).random((cfg.pop_size - len(start), problem.n_var))
        sampling = np.vstack([start, fill])
    algo = NSGA2(
        pop_size=cfg.pop_size,
        sampling=sampling,
        crossover=SBX(prob=cfg.crossover_prob, eta=15),
        mutation=PM(prob_var=cfg.mutation_prob, eta=20),
        eliminate_duplicates=True,
    )
    log = _Log()
    res = minimize(problem, algo, ("n_gen", cfg.n_gen), seed=cfg.seed, verbose=False, callback=log)
    x = np.atleast_2d(res.X)
    f = np.atleast_2d(res.F)
    order = np.argsort(f[:, 0])
    x, f = x[order], f[order]
    history = np.array(
        [problem.to_si(fx[choose(ff)]) for fx, ff in zip(log.front_x, log.front_f, strict=True)]
    )
    result = CalibrationResult(
        tuple(parameters), problem.to_si(x), f, choose(f), pd.DataFrame(log.rows), history, cfg
    )
    if isinstance(model, StatisticsForces) and problem.stats:
        result.cramer_rao = cramer_rao_pct_range(
            model, problem.recordings, result.parameters, result.chosen_x, problem.stats
        )
    return result


def estimate_with_seeds(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    config: NSGAConfig | None = None,
    n_seeds: int = 3,
) -> CalibrationResult:
    """The estimate of the first seed, with the spread of the chosen estimate over
    ``n_seeds`` independent runs (in % of each parameter's range)."""
    cfg = NSGAConfig() if config is None else config
    runs = [
        estimate(
            model, recordings, parameters, NSGAConfig(**{**cfg.to_dict(), "seed": cfg.seed + k})
        )
        for k in range(n_seeds)
    ]
    lo, hi = bounds(parameters)
    chosen = np.array([r.pareto_x[r.chosen] for r in runs])
    spread = (chosen.max(axis=0) - chosen.min(axis=0)) / (hi - lo) * 100
    first = runs[0]
    first.seeds_spread = {p: float(s) for p, s in zip(parameters, spread, strict=True)}
    return first
