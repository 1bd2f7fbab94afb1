"""Statistics surrogates as a force model of the calibration: Gaussian processes per
condition straight to the statistics of the measured wheel's forces, no series
(:class:`StatisticsForces`); :func:`open_force_model` picks a folder's surrogate kind
(window or statistics) from its contents, :func:`force_statistics` the statistics any force
model predicts."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from railsusp.conditions import TRACK_AND_LENGTH_FIELDS, WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.estimate.forces import (
    ForceModel,
    SurrogateForces,
    check_force_laws,
    check_parameters,
)
from railsusp.estimate.statistics import recording_segments, series_statistics
from railsusp.measured import Recording


def check_served_condition(
    trained: WorkingCondition,
    condition: WorkingCondition,
    statistics: Sequence[str] = (),
    where: str = "",
) -> None:
    """Refuse, in one line, a recording's ``condition`` that statistics GPs trained on
    ``trained`` do not serve (:meth:`StatisticsForces.check_condition`): any field but the
    track's and the record length where they were trained on synthesised track (the seed
    and stated accuracy alone on a measured one), and for the rate-dependent ``statistics``
    another sampling rate. Also the configuration's check, before any stage runs."""
    from railsusp.estimate.statistics import check_rate

    # Trained on synthesised track, the GPs predict the average over track realisations,
    # whatever the recording's seed, length or measured track. Trained on a measured
    # track, they hold for that stretch of track only.
    ignore = (
        ("seed", "track_accuracy_mm")  # the accuracy changes the comparison only
        if trained.track_geometry is not None
        else TRACK_AND_LENGTH_FIELDS
    )
    diff = trained.differences(condition, ignore)
    if diff:
        ignored = (
            "the seed and the stated accuracy (trained on a measured track)"
            if trained.track_geometry is not None
            else "the track and the record length"
        )
        pairs = ", ".join(
            f"{f} {getattr(condition, f)!r} against {getattr(trained, f)!r}" for f in diff
        )
        raise RailsuspInputError(
            f"recording {condition.name!r}: the statistics surrogate of its condition is "
            f"trained on another one, which differs in {', '.join(diff)} ({pairs}); accepted "
            f"recordings that differ from it only in {ignored}"
        )
    check_rate(
        statistics,
        1.0 / trained.sample_interval,
        condition,
        f"the statistics surrogate{' in ' + where if where else ''} was trained",
        "the mean, a recording at the training's rate, or surrogates trained at the recording's",
    )


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
        check_force_laws(self.folder, {n: m.meta for n, m in self._models.items()})
        first = next(iter(self._models.values()))
        self.parameters = tuple(parameters) if parameters else first.parameters
        check_parameters(
            self.folder,
            {n: m.parameters for n, m in self._models.items()},
            self.parameters,
            given=bool(parameters),
        )

    @property
    def conditions(self) -> list[str]:
        return list(self._models)

    def surrogate(self, name: str) -> Any:
        """The :class:`~railsusp.surrogate.statistics.StatisticsSurrogate` of condition
        ``name`` (its ``meta["wheel"]``: the wheel whose forces it predicts,
        :func:`~railsusp.estimate.problem.model_wheel`)."""
        return self._models[name]

    @property
    def wagon(self) -> Any:
        """The wagon data the GPs' campaign simulated (their first bundle's), or None for
        bundles saved before they recorded it (then no wagon is checked, as before)."""
        return next(iter(self._models.values())).wagon

    def check_condition(self, condition: WorkingCondition, statistics: Sequence[str] = ()) -> None:
        """Refuse, in one line naming the recording and the field, a condition the GPs of
        its name were not trained for (any field but the track's and the record length
        where they were trained on synthesised track; the seed and stated accuracy alone on
        a measured one), and, for the ``statistics`` that depend on the band the forces
        are sampled in (:func:`~railsusp.estimate.statistics.rate_dependent`), another
        sampling rate than the training's: a 100 Hz recording compared with the p99 of
        50 Hz records, whose content stops at 20 Hz. Called before any optimisation."""
        model = self._models.get(condition.name)
        if model is None:
            raise RailsuspInputError(
                f"recording {condition.name!r}: no statistics surrogate of that condition in "
                f"{self.folder} (has {', '.join(self._models)})"
            )
        check_served_condition(model.condition, condition, statistics, str(self.folder))

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
        self.check_condition(condition)
        mean, std = self._models[condition.name].predict(x_si, statistics)
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
