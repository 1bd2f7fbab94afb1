"""Non-network surrogates: the study's RBF baseline and a parameters -> statistics GP.

* :class:`RBFWindowModel`: radial-basis-function interpolation (scipy ``RBFInterpolator``,
  multiquadric, local neighbourhoods) from the features of a window's last step (key
  parameters and the track input at that step) to the forces at that step, fitted on a random
  subset of the training windows. The study's "RBF" row.
* :class:`StatisticsGP`: beyond the study, a Gaussian process per target and statistic from
  the key parameters straight to a statistic of a record (mean, RMS, p99 or std of |Y| and Q
  of the measured wheel), with predictive standard deviation: calibration compares
  statistics, so this is the cheapest surrogate that can serve it. Trained on a campaign
  with independent track seeds it predicts the track-averaged statistic.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.interpolate import RBFInterpolator

from railsusp.params import bounds
from railsusp.surrogate.data import Normaliser, SeriesData, window_index
from railsusp.surrogate.features import FeatureSpec
from railsusp.vehicle.simulation_result import (
    RECORD_STATISTICS,
    record_statistic,
    statistic_segments,
)


class RBFWindowModel:
    """RBF interpolation of the forces from the last step of each window."""

    kind = "rbf"

    def __init__(
        self,
        spec: FeatureSpec,
        norm: Normaliser,
        n_centres: int = 4000,
        neighbors: int = 64,
        seed: int = 0,
    ):
        self.spec, self.normaliser = spec, norm
        self.n_centres, self.neighbors, self.seed = n_centres, neighbors, seed
        self._rbf: RBFInterpolator | None = None
        self._keep: np.ndarray | None = None  # features that vary (curvature is 0 on tangent)

    def _features(
        self, params_unit: np.ndarray, track_norm: np.ndarray, idx: np.ndarray
    ) -> np.ndarray:
        ti = np.zeros(len(idx), dtype=int) if track_norm.shape[0] == 1 else idx[:, 0]
        x = np.hstack([params_unit[idx[:, 0]], track_norm[ti, idx[:, 1]]])
        return x if self._keep is None else x[:, self._keep]

    def fit(self, train: SeriesData) -> RBFWindowModel:
        idx = window_index(train.n_samples, train.n_steps, self.spec.window)
        rng = np.random.default_rng(self.seed)
        pick = rng.choice(len(idx), min(self.n_centres, len(idx)), replace=False)
        idx = idx[pick]
        self._keep = None
        x = self._features(train.params_unit, self.normaliser.track(train.track), idx)
        self._keep = np.flatnonzero(x.std(axis=0) > 1e-9)
        x = x[:, self._keep]
        y = self.normaliser.target(train.targets[idx[:, 0], idx[:, 1]])
        self._rbf = RBFInterpolator(
            x,
            y,
            kernel="multiquadric",
            epsilon=1.0,
            degree=0,
            smoothing=1e-3,
            neighbors=min(self.neighbors, len(x)),
        )
        return self

    def predict(self, params: np.ndarray, *, track: np.ndarray, **_) -> np.ndarray:
        """Force series (n, T, n_targets) in kN for SI key parameters on a track (T, n)."""
        if self._rbf is None:
            raise RuntimeError("RBF model not fitted")
        lo, hi = bounds(self.spec.parameters)
        unit = (np.atleast_2d(params) - lo) / (hi - lo)
        tr = self.normaliser.track(np.asarray(track)[None])
        idx = window_index(unit.shape[0], tr.shape[1], self.spec.window)
        out = np.full((unit.shape[0], tr.shape[1], len(self.spec.targets)), np.nan)
        out[idx[:, 0], idx[:, 1]] = self.normaliser.target_inverse(
            self._rbf(self._features(unit, tr, idx))
        )
        return out


class StatisticsGP:
    """Gaussian process per target and statistic: key parameters (unit cube) -> a record
    statistic of the measured wheel's force (mean, RMS, p99 or std of |Y| and Q)."""

    kind = "gp-stats"

    def __init__(self, spec: FeatureSpec, seed: int = 0, statistics: Sequence[str] = ("mean",)):
        bad = [s for s in statistics if s not in RECORD_STATISTICS]
        if bad or not statistics:
            raise ValueError(
                f"statistics {list(statistics)}: accepted {', '.join(RECORD_STATISTICS)}"
            )
        self.spec, self.seed, self.stats = spec, seed, tuple(statistics)
        self._gps: list = []

    @property
    def columns(self) -> list[tuple[str, str]]:
        """(target, statistic) of each GP, target-major."""
        return [(t, s) for t in self.spec.targets for s in self.stats]

    @staticmethod
    def statistics(
        data: SeriesData, spec: FeatureSpec, stats: Sequence[str] = ("mean",)
    ) -> np.ndarray:
        """Per-sample statistics of |Y| and Q over the record after the first window (kN),
        averaged over its segments of about 20 s, columns target-major."""
        x = data.targets[:, spec.window :]
        segments = statistic_segments(x.shape[1], data.condition.sample_interval)
        cols = []
        for j, name in enumerate(spec.targets):
            cols += [record_statistic(x[..., j], st, name == "Y", segments) for st in stats]
        return np.stack(cols, axis=1)

    def fit(self, train: SeriesData) -> StatisticsGP:
        from railsusp.sensitivity_metamodel import fit_gp

        stats = self.statistics(train, self.spec, self.stats)
        ok = np.isfinite(stats).all(axis=1)
        self._gps = [
            fit_gp(train.params_unit[ok], stats[ok, j], self.seed) for j in range(stats.shape[1])
        ]
        return self

    def predict_statistics(self, params_unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(mean, standard deviation) of each column of :attr:`columns`, (n, n_cols), kN."""
        if not self._gps:
            raise RuntimeError("statistics GP not fitted")
        res = [gp.predict(params_unit, return_std=True) for gp in self._gps]
        return np.stack([m for m, _ in res], axis=1), np.stack([s for _, s in res], axis=1)

    def noise_std(self) -> np.ndarray:
        """(n_cols,) standard deviation of the white-noise term of each GP, kN: the scatter
        of the training records' statistic that the parameters do not explain (mostly the
        track realisation of each record)."""
        if not self._gps:
            raise RuntimeError("statistics GP not fitted")
        return np.array(
            [
                np.sqrt(gp.kernel_.k2.noise_level) * float(np.atleast_1d(gp._y_train_std)[0])
                for gp in self._gps
            ]
        )

    def to_dict(self) -> dict:
        """Everything needed to rebuild the fitted GPs exactly: training data and the
        optimised kernel hyperparameters (log scale), per column."""
        return {
            "features": self.spec.to_dict(),
            "statistics": list(self.stats),
            "seed": self.seed,
            "gps": [
                {
                    "target": t,
                    "statistic": st,
                    "theta": gp.kernel_.theta.tolist(),
                    "x_unit": gp.X_train_.tolist(),
                    "y": (gp.y_train_ * gp._y_train_std + gp._y_train_mean).tolist(),
                }
                for (t, st), gp in zip(self.columns, self._gps, strict=True)
            ],
        }

    @classmethod
    def from_dict(cls, doc: dict) -> StatisticsGP:
        """Rebuild from :meth:`to_dict` (refits with the stored hyperparameters, no search)."""
        from railsusp.sensitivity_metamodel import fit_gp

        model = cls(FeatureSpec.from_dict(doc["features"]), doc["seed"], doc["statistics"])
        for g in doc["gps"]:
            x, y = np.asarray(g["x_unit"]), np.asarray(g["y"])
            model._gps.append(fit_gp(x, y, model.seed, theta=np.asarray(g["theta"])))
        return model
