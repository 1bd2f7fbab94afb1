"""Statistics surrogate: key parameters -> record statistics of one condition, saved and loaded.

A :class:`~railsusp.surrogate.baselines.StatisticsGP` (one Gaussian process per force and
statistic) with the condition it serves and the provenance of its training campaign. It
predicts what calibration compares (mean, RMS, p99, std of |Y| and Q of the measured wheel)
without predicting series. Trained on a campaign with independent track seeds, it predicts
the statistic averaged over track realisations, with the realisation scatter in the GP's
noise term, which is what a recording on an unknown track should be compared with.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.params import bounds
from railsusp.provenance import provenance
from railsusp.store import read_json, write_json
from railsusp.surrogate.baselines import StatisticsGP
from railsusp.surrogate.data import check_trained_range, load_series
from railsusp.surrogate.features import FeatureSpec
from railsusp.vehicle.simulation_result import RECORD_STATISTICS, statistic_segments

FORMAT = "railsusp-statistics-surrogate-1"
FILE = "statistics.json"


@dataclass
class StatisticsSurrogate:
    """A fitted statistics GP for one working condition."""

    gp: StatisticsGP
    condition: WorkingCondition
    meta: dict = field(default_factory=dict)

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(self.gp.spec.parameters)

    @property
    def statistics(self) -> tuple[str, ...]:
        return self.gp.stats

    def predict(
        self, params_si: np.ndarray, statistics: Sequence[str] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(mean, std) of the statistics, each (n, n_targets, n_statistics), kN.

        ``params_si``: (n, n_key) SI values of the key parameters, inside their ranges (a
        value outside them, or not finite, is refused in one line:
        :func:`~railsusp.surrogate.data.check_trained_range`; the GPs extrapolated it)."""
        stats = tuple(statistics) if statistics else self.statistics
        missing = [s for s in stats if s not in self.statistics]
        if missing:
            raise ValueError(
                f"statistics {missing} not in this surrogate (has {', '.join(self.statistics)})"
            )
        lo, hi = bounds(self.parameters)
        x = np.atleast_2d(np.asarray(params_si, dtype=float))
        unit = (x - lo) / (hi - lo)
        check_trained_range(x, unit, self.parameters)
        mean, std = self.gp.predict_statistics(unit)
        n_t, n_s = len(self.gp.spec.targets), len(self.statistics)
        pick = [self.statistics.index(s) for s in stats]
        mean = mean.reshape(len(unit), n_t, n_s)[:, :, pick]
        std = std.reshape(len(unit), n_t, n_s)[:, :, pick]
        return mean, std

    def noise_std(self, statistics: Sequence[str] | None = None) -> np.ndarray:
        """(n_targets, n_statistics) white-noise standard deviation of the GPs, kN: the
        realisation scatter of a statistic of one training record."""
        stats = tuple(statistics) if statistics else self.statistics
        n_t, n_s = len(self.gp.spec.targets), len(self.statistics)
        sd = self.gp.noise_std().reshape(n_t, n_s)
        return sd[:, [self.statistics.index(s) for s in stats]]

    @property
    def wagon(self):
        """The wagon data its campaign simulated (``meta["wagon"]``, saved since the
        estimate's audit of stop 63), or None for a bundle saved before (no wagon is checked
        against it, as before); one that this railsusp cannot read is refused in one line."""
        from railsusp.vehicle.wagon import WagonData

        fields = (self.meta or {}).get("wagon")
        if fields is None:
            return None
        try:
            return WagonData.model_validate(fields)
        except ValueError:
            raise ValueError(
                f"statistics surrogate of {self.condition.name!r}: its wagon description is "
                "not one this railsusp reads: train it again on its campaign"
            ) from None

    @property
    def training_segments(self) -> int:
        """Statistic segments in one training record (after the first window)."""
        n = self.condition.n_steps - self.gp.spec.window
        return statistic_segments(n, self.condition.sample_interval)

    def save(self, path: str | Path) -> Path:
        """Write ``statistics.json`` (training data, hyperparameters, condition, provenance)."""
        doc = {
            "format": FORMAT,
            "model": self.gp.to_dict(),
            "condition": self.condition.model_dump(),
            "meta": self.meta,
            "saved": provenance(),
        }
        return write_json(Path(path) / FILE, doc)


def is_statistics_bundle(path: str | Path) -> bool:
    return (Path(path) / FILE).exists()


def load_statistics(path: str | Path) -> StatisticsSurrogate:
    """Load a saved statistics surrogate (its folder, or the folder's ``statistics.json``);
    predictions equal the saved model's."""
    path = Path(path)
    p = path if path.name == FILE and path.is_file() else path / FILE
    if not p.exists():
        raise FileNotFoundError(f"{path} holds no statistics surrogate (no {FILE})")
    doc = read_json(p)  # a damaged file is one line naming it
    fmt = doc.get("format") if isinstance(doc, dict) else None
    if fmt != FORMAT:
        raise ValueError(f"{p}: unknown statistics-surrogate format {fmt!r}")
    return StatisticsSurrogate(
        StatisticsGP.from_dict(doc["model"]),
        WorkingCondition(**doc["condition"]),
        doc.get("meta", {}),
    )


def train_statistics_surrogate(
    run: str | Path,
    condition: str,
    *,
    parameters: Sequence[str] | None = None,
    statistics: Sequence[str] = RECORD_STATISTICS,
    max_train: int = 500,
    seed: int = 0,
    out: str | Path | None = None,
) -> StatisticsSurrogate:
    """Fit the statistics GPs of one condition on the samples of a complete campaign (at most
    ``max_train``, chosen at random; an unfinished campaign is refused) and save them under
    ``RUN/surrogates/gp-stats/<cond>/``."""
    from railsusp.campaign import load_campaign, require_complete
    from railsusp.surrogate.keys import key_parameters
    from railsusp.variation import assumed_parameters

    camp = require_complete(load_campaign(run))  # never train on part of a campaign
    params = tuple(parameters) if parameters else key_parameters(run)
    spec = FeatureSpec(parameters=params)
    data = load_series(camp, condition, spec)
    if data.n_samples > max_train:
        rng = np.random.default_rng(seed)
        data = data.subset(np.sort(rng.choice(data.n_samples, max_train, replace=False)))
    gp = StatisticsGP(spec, seed, statistics).fit(data)
    model = StatisticsSurrogate(
        gp,
        data.condition,
        {
            "campaign": str(camp.path.resolve()),
            "campaign_hash": camp.config.hash(),
            "model_revision": camp.model_revision,  # the force laws it learnt
            # the wheel whose forces it predicts and the wagon simulated, checked against
            # the recordings and the estimate's wagon as a window surrogate's are
            "wheel": camp.config.wheel,
            "wagon": camp.config.wagon.model_dump(mode="json"),
            "n_train": int(data.n_samples),
            "independent_seeds": bool(len(np.unique(data.seeds)) > 1),
            "assumed_parameters": assumed_parameters(
                spec.parameters, camp.config.other_parameters, camp.config.parameters
            ),
        },
    )
    model.save(Path(out) if out else camp.path / "surrogates" / "gp-stats" / condition)
    return model
