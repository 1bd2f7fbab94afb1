"""Record-level correction of a window network's force series.

A network trained on the mean squared error of single window-end forces fits the series
well (R² about 0.93 on tangent) and still misses the record statistic that calibration
compares: the part of the force a window cannot explain is shrunk towards its conditional
mean, so the record mean of |Y| comes out low, by an amount that varies smoothly with the
suspension parameters (per-run errors of two trainings correlate at 0.84). A Gaussian
process per target from the key parameters to log(simulated / predicted record mean) over
the training runs (at most :data:`MAX_RUNS` of them) learns that part; the predicted series
are scaled by its exponential.
On tangent (1024-run campaign, 50-step windows) it took the CNN-GRU's lateral error of the
record mean from 2.55 % to 0.99 % per held-out run (bench/README.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from railsusp.vehicle.simulation_result import record_statistic

#: fewer training runs than this leave a network uncorrected (a GP of six inputs needs more)
MIN_RUNS = 8

#: the GP is fitted on at most this many training runs (a seeded draw where there are more).
#: Its cost grows as the cube of the runs: rebuilt from the saved hyperparameters it took
#: 0.19 s for 1434 runs, 0.63 s for 2048 and 8-18 s (and 1.9 GB at peak) for 5734, once in
#: every process that predicts; the uphill network of 5734 training runs read 1.878 % lateral
#: per held-out run corrected on all of them, 1.886 % on 2048 in a first fit and 1.900 % as
#: shipped (measured 2026-11-25, bench/README.md "Shipped: the uphill network of 8192 tracks").
MAX_RUNS = 2048


def record_means(series: np.ndarray, targets: Sequence[str], window: int) -> np.ndarray:
    """(n, n_targets) record mean of |Y| and of Q after the first ``window`` steps, kN."""
    x = np.asarray(series, dtype=float)[:, window:]
    return np.stack(
        [record_statistic(x[..., j], "mean", name == "Y") for j, name in enumerate(targets)],
        axis=1,
    )


@dataclass
class RecordCorrection:
    """Per-target factor exp(GP(parameters)) on a network's predicted series."""

    targets: tuple[str, ...]
    x_unit: np.ndarray  # (n, n_params) training runs' key parameters, unit cube
    log_ratio: np.ndarray  # (n, n_targets) log(simulated / predicted record mean)
    thetas: list[np.ndarray]  # fitted kernel hyperparameters per target (log scale)
    seed: int = 0
    _gps: list = field(default_factory=list, repr=False)

    @classmethod
    def fit(
        cls,
        params_unit: np.ndarray,
        simulated: np.ndarray,
        predicted: np.ndarray,
        targets: Sequence[str],
        window: int,
        seed: int = 0,
        max_runs: int | None = None,
    ) -> RecordCorrection:
        """Fit on runs' simulated and network-predicted series (n, T, n_targets), kN: on
        all runs with finite record means, or on ``max_runs`` (default :data:`MAX_RUNS`) of
        them drawn with ``seed``."""
        from railsusp.sensitivity_metamodel import fit_gp

        sim = record_means(simulated, targets, window)
        pred = record_means(predicted, targets, window)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.log(sim / pred)
        ok = np.isfinite(ratio).all(axis=1)
        if ok.sum() < MIN_RUNS:
            raise ValueError(
                f"record correction needs at least {MIN_RUNS} runs with finite record means, "
                f"got {int(ok.sum())}"
            )
        x, r = np.asarray(params_unit, float)[ok], ratio[ok]
        max_runs = MAX_RUNS if max_runs is None else max_runs
        if max_runs < MIN_RUNS:
            raise ValueError(f"max_runs: {max_runs}, accepted {MIN_RUNS} or more")
        if len(x) > max_runs:
            keep = np.sort(np.random.default_rng(seed).choice(len(x), max_runs, replace=False))
            x, r = x[keep], r[keep]
        gps = [fit_gp(x, r[:, j], seed) for j in range(r.shape[1])]
        # the fitted GPs are not kept: they are rebuilt from the hyperparameters as a loaded
        # correction's are (one BLAS thread), so that the trained network and its saved
        # bundle predict the same numbers bit for bit (the search's own Cholesky factor,
        # with the machine's BLAS threads, differed in the last digit)
        return cls(tuple(targets), x, r, [gp.kernel_.theta for gp in gps], seed)

    def _models(self) -> list:
        """The GPs rebuilt from the stored hyperparameters, once. One BLAS thread: the
        Cholesky factor of about 1400 training runs takes 0.08 s on one core, and 1.6 s
        with OpenBLAS's two threads on a two-core machine that is busy with other work
        (measured 2026-11-24), which made a network set's first prediction take 16 s."""
        if not self._gps:
            from threadpoolctl import threadpool_limits

            from railsusp.sensitivity_metamodel import fit_gp

            with threadpool_limits(1, user_api="blas"):
                self._gps = [
                    fit_gp(self.x_unit, self.log_ratio[:, j], self.seed, theta=th)
                    for j, th in enumerate(self.thetas)
                ]
        return self._gps

    def factors(self, params_unit: np.ndarray) -> np.ndarray:
        """(n, n_targets) factors on the predicted series of parameter sets (unit cube)."""
        x = np.atleast_2d(np.asarray(params_unit, float))
        return np.exp(np.stack([gp.predict(x) for gp in self._models()], axis=1))

    def apply(self, series: np.ndarray, params_unit: np.ndarray) -> np.ndarray:
        """Series (n, T, n_targets) scaled by each set's factors."""
        return series * self.factors(params_unit)[:, None, :]

    def to_dict(self) -> dict:
        """The training runs and hyperparameters: rebuilds the GPs exactly, no search."""
        return {
            "targets": list(self.targets),
            "x_unit": self.x_unit.tolist(),
            "log_ratio": self.log_ratio.tolist(),
            "thetas": [np.asarray(t).tolist() for t in self.thetas],
            "seed": self.seed,
        }

    @classmethod
    def from_dict(cls, doc: dict) -> RecordCorrection:
        return cls(
            tuple(doc["targets"]),
            np.asarray(doc["x_unit"], float),
            np.asarray(doc["log_ratio"], float),
            [np.asarray(t, float) for t in doc["thetas"]],
            int(doc.get("seed", 0)),
        )
