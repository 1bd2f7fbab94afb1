"""Record statistics of recordings and predictions, and the names of the objectives.

The measured track is unknown in general, so records are compared through statistics (mean,
RMS, 99th percentile or standard deviation of |Y| and Q of the measured wheel, or a
combination such as ``mean+p99+std`` whose relative errors are averaged); ``p99.85`` is
EN 14363's estimated maximum (:data:`EN14363_MAX`); ``aligned`` names the time-aligned
comparison of the series (:mod:`railsusp.estimate.comparison`), possible only on recordings
that carry their measured track geometry.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.en14363 import FORCE_CUTOFF_HZ, WINDOW_M, full_window, lowpass, sliding_mean
from railsusp.measured import Recording
from railsusp.vehicle.simulation_result import (
    RECORD_STATISTICS,
    record_statistic,
    statistic_segments,
)

#: time-aligned comparison of the series (recordings with measured track geometry only)
ALIGNED = "aligned"

#: EN 14363's estimated maximum: the 99.85 % value of the force low-passed at 20 Hz and
#: averaged over 2 m of track (:mod:`railsusp.en14363`), of Y (signed, flange force +: the
#: guiding force of the measured wheel) and of Q. It needs the sampling rate and speed of
#: the record, which the plain record statistics do not, so it is computed here from the
#: recording or the condition; statistics GPs are not trained on it.
EN14363_MAX = "p99.85"

STATISTICS = (*RECORD_STATISTICS, EN14363_MAX, ALIGNED)


#: the record statistics whose value depends on the band a series is sampled in: the spread
#: of the forces (a simulation sampled at 100 Hz keeps content to 40 Hz, one at 50 Hz to
#: 20 Hz). The mean does not; EN 14363's maximum low-passes at 20 Hz first, so it does only
#: where a rate puts that filter lower (below 44.4 Hz: :func:`rate_dependent`)
SPREAD_STATISTICS = ("rms", "p99", "std")

#: sampling rates closer than this (relative) are one rate (a record cut to whole steps)
RATE_TOLERANCE = 1e-3


def rate_dependent(statistics: Sequence[str], rate_hz: float, other_hz: float) -> list[str]:
    """The statistics of ``statistics`` that differ between the same forces sampled at
    ``rate_hz`` and at ``other_hz`` (none where the rates agree to :data:`RATE_TOLERANCE`):
    the spread statistics (:data:`SPREAD_STATISTICS`), and :data:`EN14363_MAX` where its
    low-pass is not the same 20 Hz at both rates (at most 0.45 of a rate)."""
    if abs(rate_hz / other_hz - 1.0) <= RATE_TOLERANCE:
        return []
    out = [st for st in statistics if st in SPREAD_STATISTICS]
    cut_a, cut_b = (min(FORCE_CUTOFF_HZ, 0.45 * r) for r in (rate_hz, other_hz))
    if EN14363_MAX in statistics and abs(cut_a / cut_b - 1.0) > RATE_TOLERANCE:
        out.append(EN14363_MAX)
    return out


def check_rate(
    statistics: Sequence[str], trained_hz: float, condition: Any, trained: str, accepted: str
) -> None:
    """Refuse, in one line, a recording's ``condition`` sampled at another rate than the
    surrogate's ``trained_hz`` where ``statistics`` hold one that depends on it
    (:func:`rate_dependent`); ``trained`` says what was trained at that rate, ``accepted``
    what would do instead."""
    from railsusp.errors import RailsuspInputError

    theirs = 1.0 / condition.sample_interval
    bad = rate_dependent(statistics, trained_hz, theirs)
    if bad:
        raise RailsuspInputError(
            f"recording {condition.name!r}: statistic {'+'.join(bad)!r} depends on the "
            f"sampling rate; its condition samples at {theirs:.6g} Hz (n_steps "
            f"{condition.n_steps} over {condition.duration_s:g} s), {trained} at "
            f"{trained_hz:.6g} Hz: accepted {accepted}"
        )


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
    stats = tuple(t.strip() for t in str(text).split("+"))
    bad = [t for t in stats if t not in STATISTICS]  # an empty part too: 'mean+', 'mean++p99'
    if bad or len(set(stats)) != len(stats):
        raise ValueError(
            f"statistic {text!r}: give one of {', '.join(STATISTICS)} or a '+'-joined "
            "combination of different ones (e.g. mean+p99+std)"
        )
    return stats


def measured_statistics(rec: Recording, statistics: Sequence[str]) -> np.ndarray:
    """(2, n_statistics) statistics of |Y| and Q of a recording's first measured wheel, kN,
    averaged over the record's segments of about 20 s (:func:`record_statistic`)."""
    w = rec.wheels[0]
    return yq_statistics(
        rec.Y[w],
        rec.Q[w],
        statistics,
        recording_segments(rec),
        rate_hz=rec.sampling_rate,
        speed_ms=rec.condition.speed,
    )


def recording_segments(rec: Recording) -> int:
    """How many statistic segments a recording holds (:func:`statistic_segments`)."""
    return statistic_segments(rec.time.size, 1.0 / rec.sampling_rate)


def series_statistics(
    series: np.ndarray, condition: WorkingCondition, statistics: Sequence[str]
) -> np.ndarray:
    """(n, 2, n_statistics) statistics of predicted (n, T, 2) |Y|, Q series of a condition,
    averaged over the record's segments like a recording's."""
    segments = statistic_segments(series.shape[1], condition.sample_interval)
    return yq_statistics(
        series[:, :, 0],
        series[:, :, 1],
        statistics,
        segments,
        rate_hz=1.0 / condition.sample_interval,
        speed_ms=condition.speed,
    )


def yq_statistics(
    y: np.ndarray,
    q: np.ndarray,
    statistics: Sequence[str],
    segments: int = 1,
    *,
    rate_hz: float | None = None,
    speed_ms: float | None = None,
) -> np.ndarray:
    """(..., 2, n_statistics) statistics of |Y| and Q series (time along the last axis),
    averaged over ``segments`` consecutive parts (:func:`record_statistic`); ``p99.85``
    needs the sampling rate (Hz) and speed (m/s) of the series."""
    if not statistics:
        return np.empty((*np.shape(y)[:-1], 2, 0))

    def one(x: np.ndarray, lateral: bool) -> np.ndarray:
        return np.stack(
            [
                force_statistic(x, st, lateral, segments, rate_hz=rate_hz, speed_ms=speed_ms)
                for st in statistics
            ],
            axis=-1,
        )

    return np.stack([one(y, True), one(q, False)], axis=-2)


def force_statistic(
    x: np.ndarray,
    statistic: str,
    lateral: bool,
    segments: int = 1,
    *,
    rate_hz: float | None = None,
    speed_ms: float | None = None,
) -> np.ndarray:
    """One statistic of force series (time along the last axis), averaged over ``segments``
    consecutive parts: a record statistic (:func:`record_statistic`), or
    :data:`EN14363_MAX`, which needs ``rate_hz`` and ``speed_ms``."""
    if statistic != EN14363_MAX:
        return record_statistic(x, statistic, lateral, segments)
    if rate_hz is None or speed_ms is None or not rate_hz > 0 or not speed_ms > 0:
        raise ValueError(
            f"statistic {EN14363_MAX!r} needs the sampling rate and a running speed above 0 "
            f"(given {rate_hz} Hz, {speed_ms} m/s)"
        )
    parts = np.array_split(np.asarray(x, dtype=float), max(1, segments), axis=-1)
    return np.mean([en14363_maximum(p, rate_hz, speed_ms) for p in parts], axis=0)


def en14363_maximum(
    x: np.ndarray,
    rate_hz: float,
    speed_ms: float,
    cutoff_hz: float = FORCE_CUTOFF_HZ,
    window_m: float = WINDOW_M,
) -> np.ndarray:
    """EN 14363's estimated maximum of force series at constant speed (time along the last
    axis): low-pass at ``cutoff_hz`` (at most 0.45 of the rate), sliding mean over
    ``window_m`` of track, 99.85 % value of the samples whose window lies inside the
    record (:func:`~railsusp.en14363.full_window`). Samples undefined in every series (a window
    surrogate's first window) are left out; a series with other gaps gives NaN, as does a
    record shorter than the filter can take."""
    x = np.asarray(x, dtype=float)
    flat = x.reshape(-1, x.shape[-1])
    defined = np.flatnonzero(np.isfinite(flat).any(axis=0))
    out = np.full(flat.shape[0], np.nan)
    if defined.size < 16:
        return out.reshape(x.shape[:-1])
    part = flat[:, defined[0] : defined[-1] + 1]
    position = np.arange(part.shape[1]) * (speed_ms / rate_hz)
    inside = full_window(position, window_m)
    if not inside.any():
        return out.reshape(x.shape[:-1])
    for i, row in enumerate(part):
        if np.isfinite(row).all():
            smooth = sliding_mean(
                lowpass(row, rate_hz, min(cutoff_hz, 0.45 * rate_hz)), position, window_m
            )
            out[i] = np.percentile(smooth[inside], 99.85)
    return out.reshape(x.shape[:-1])
