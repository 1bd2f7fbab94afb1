"""Record statistics of recordings and predictions, and the names of the objectives.

The measured track is unknown in general, so records are compared through statistics (mean,
RMS, 99th percentile or standard deviation of |Y| and Q of the measured wheel, or a
combination such as ``mean+p99+std`` whose relative errors are averaged); ``aligned`` names
the time-aligned comparison of the series (:mod:`railsusp.estimate.comparison`), possible
only on recordings that carry their measured track geometry.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.measured import Recording
from railsusp.vehicle.simulate import RECORD_STATISTICS, record_statistic, statistic_segments

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


def measured_statistics(rec: Recording, statistics: Sequence[str]) -> np.ndarray:
    """(2, n_statistics) statistics of |Y| and Q of a recording's first measured wheel, kN,
    averaged over the record's segments of about 20 s (:func:`record_statistic`)."""
    w = rec.wheels[0]
    return yq_statistics(rec.Y[w], rec.Q[w], statistics, recording_segments(rec))


def recording_segments(rec: Recording) -> int:
    """How many statistic segments a recording holds (:func:`statistic_segments`)."""
    return statistic_segments(rec.time.size, 1.0 / rec.sampling_rate)


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
