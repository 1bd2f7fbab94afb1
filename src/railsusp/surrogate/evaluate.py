"""Surrogate accuracy on held-out simulations (the study's Table 7 and more).

For each target (lateral Y, vertical Q of the measured wheel) over the test samples: the
simulated and predicted mean force (|Y| for the lateral force, whose sign alternates on
tangent track) and the relative error of the mean, |predicted - simulated| / simulated
(the study's formula (2)), for each sample and averaged over the samples (the stricter
reading, railsusp's headline figure), and of the mean over all samples (the pooled reading:
one simulated and one predicted value per condition, the form of the study's Table 7); plus
the time-series NRMSE (RMSE / standard deviation of the simulated series) and the
coefficient of determination R², both pooled over the held-out runs' samples.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from railsusp.surrogate.bundle import Surrogate
from railsusp.surrogate.data import SeriesData
from railsusp.surrogate.models import SEQUENCE_KINDS
from railsusp.vehicle.simulation_result import record_statistic

#: runs per call when the sequence CNN-GRU predicts a campaign's runs, each on its own track
RUNS_PER_CALL = 64


def predict_series(sur: Surrogate, data: SeriesData, corrected: bool = True) -> np.ndarray:
    """Predictions (n, T, n_targets) for data samples, each on its own track
    (``corrected=False``: without the surrogate's record correction). The sequence CNN-GRU
    takes :data:`RUNS_PER_CALL` runs per call, each with its own track (one batch through
    its layers: a campaign's 1434 training runs in minutes, not half an hour one by one);
    the window networks one run per call."""
    if data.track.shape[0] == 1:
        x = np.column_stack([data.params_unit])
        return sur.predict(_si(sur, x), track=data.track[0], corrected=corrected)
    if sur.kind in SEQUENCE_KINDS:
        return np.concatenate(
            [
                sur.predict(
                    _si(sur, data.params_unit[lo : lo + RUNS_PER_CALL]),
                    track=data.track[lo : lo + RUNS_PER_CALL],
                    corrected=corrected,
                )
                for lo in range(0, data.n_samples, RUNS_PER_CALL)
            ]
        )
    return np.concatenate(
        [
            sur.predict(
                _si(sur, data.params_unit[i : i + 1]), track=data.track[i], corrected=corrected
            )
            for i in range(data.n_samples)
        ]
    )


def _si(sur: Surrogate, unit: np.ndarray) -> np.ndarray:
    from railsusp.params import bounds

    lo, hi = bounds(sur.spec.parameters)
    return lo + unit * (hi - lo)


def accuracy(
    sim: np.ndarray, pred: np.ndarray, targets: tuple[str, ...], window: int
) -> list[dict[str, Any]]:
    """Table-7 metrics per target from simulated and predicted series (n, T, n_targets)."""
    rows = []
    for j, name in enumerate(targets):
        s = sim[:, window:, j]
        p = pred[:, window:, j]
        s_stat = record_statistic(s, "mean", name == "Y")
        p_stat = record_statistic(p, "mean", name == "Y")
        rel = np.abs(p_stat - s_stat) / np.abs(s_stat)
        resid = (p - s).ravel()
        var = np.var(s.ravel())
        rows.append(
            {
                "target": name,
                "simulated_mean_kN": float(s_stat.mean()),
                "predicted_mean_kN": float(p_stat.mean()),
                "relative_error_of_mean": float(rel.mean()),
                "relative_error_of_mean_max": float(rel.max()),
                "relative_error_of_pooled_mean": pooled_error(s_stat, p_stat),
                "nrmse": float(np.sqrt(np.mean(resid**2) / var)) if var > 0 else float("nan"),
                "r2": float(1.0 - np.mean(resid**2) / var) if var > 0 else float("nan"),
                "n_samples": int(s.shape[0]),
            }
        )
    return rows


def pooled_error(simulated: np.ndarray, predicted: np.ndarray) -> float:
    """Relative error of the mean over all samples of a per-sample statistic."""
    return float(abs(predicted.mean() - simulated.mean()) / abs(simulated.mean()))


def predict_with_alone(sur: Surrogate, data: SeriesData) -> tuple[np.ndarray, np.ndarray | None]:
    """(corrected predictions, the network's own or None without a record correction) from
    one pass of the network over ``data``: the correction only scales its output."""
    raw = predict_series(sur, data, corrected=False)
    if sur.correction is None:
        return raw, None
    return sur.correction.apply(raw, data.params_unit), raw


def evaluate(sur: Surrogate, data: SeriesData) -> list[dict[str, Any]]:
    """Accuracy of ``sur`` on the samples of ``data`` (normally its held-out test samples)."""
    pred = predict_series(sur, data)
    return accuracy(data.targets.astype(float), pred, sur.spec.targets, sur.spec.window)
