"""Non-network surrogates: the study's RBF baseline and a parameters -> statistics GP.

* :class:`RBFWindowModel`: radial-basis-function interpolation (scipy ``RBFInterpolator``,
  multiquadric, local neighbourhoods) from the features of a window's last step (key
  parameters and the track input at that step) to the forces at that step, fitted on a random
  subset of the training windows. The study's "RBF" row.
* :class:`StatisticsGP`: beyond the study, a Gaussian process per target from the key
  parameters straight to the mean force of a record (|Y| and Q of the measured wheel), with
  predictive standard deviation: calibration compares statistics, so this is the cheapest
  surrogate that can serve it.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RBFInterpolator

from railsusp.params import bounds
from railsusp.surrogate.data import FeatureSpec, Normaliser, SeriesData, window_index
from railsusp.vehicle.simulate import record_statistic


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
    """Gaussian process per target: key parameters (unit cube) -> mean force of a record."""

    kind = "gp-stats"

    def __init__(self, spec: FeatureSpec, seed: int = 0):
        self.spec, self.seed = spec, seed
        self._gps: list = []

    @staticmethod
    def statistics(targets: np.ndarray, spec: FeatureSpec) -> np.ndarray:
        """Per-sample mean of |Y| and Q over the record after the first window (kN)."""
        cols = []
        for j, name in enumerate(spec.targets):
            x = targets[:, spec.window :, j]
            cols.append(record_statistic(x, "mean", name == "Y"))
        return np.stack(cols, axis=1)

    def fit(self, train: SeriesData) -> StatisticsGP:
        from railsusp.sensitivity import fit_gp

        stats = self.statistics(train.targets, self.spec)
        self._gps = [
            fit_gp(train.params_unit, stats[:, j], self.seed) for j in range(stats.shape[1])
        ]
        return self

    def predict_statistics(self, params_unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(mean, standard deviation) of each target's record mean, (n, n_targets), kN."""
        res = [gp.predict(params_unit, return_std=True) for gp in self._gps]
        return np.stack([m for m, _ in res], axis=1), np.stack([s for _, s in res], axis=1)
