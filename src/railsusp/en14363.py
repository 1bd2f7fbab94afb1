"""Processing of measured wheel-rail forces as EN 14363 (running behaviour of railway
vehicles) evaluates them: a low-pass filter, sliding means over 2 m of track, and the
percentiles 0.15 %, 50 % and 99.85 % of the processed signal in a section.

Pure functions on arrays: forces in any one unit, positions in m, rates in Hz. The
standard's quantities are built from them: Y and Q low-passed (20 Hz), then averaged over
2 m of track (the mean over a window of distance, not of time, so that it is the same at
every speed), and a section is described by the percentiles of that; the 99.85 % value is
the section's estimated maximum and the 0.15 % value its minimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, sosfiltfilt

from railsusp.errors import RailsuspInputError

#: low-pass cut-off for wheel-rail forces, Hz
FORCE_CUTOFF_HZ = 20.0
#: length of the sliding mean, m
WINDOW_M = 2.0
#: percentiles that describe a section, %
PERCENTILES = (0.15, 50.0, 99.85)


def lowpass(x: np.ndarray, fs: float, cutoff_hz: float = FORCE_CUTOFF_HZ, order: int = 4):
    """Butterworth low-pass of ``order`` at ``cutoff_hz``, run forwards and backwards
    (zero phase, so that peaks stay where the track put them; the amplitude response is
    the filter's squared: 1/(1 + (f/fc)^(2 order)), for the default order 4 an 8th-order
    roll-off, 48 dB per octave, with -6 dB (half amplitude) at the cut-off, not the -3 dB
    of one pass). Along the last axis."""
    if not 0.0 < cutoff_hz < 0.5 * fs:
        raise ValueError(f"cut-off {cutoff_hz:g} Hz: accepted above 0, below half of {fs:g} Hz")
    sos = butter(order, cutoff_hz, fs=fs, output="sos")
    x = np.asarray(x, dtype=float)
    # scipy's default edge padding (3 (2 n_sections + 1) samples) needs a longer series; a
    # short one (a section of a few samples cut from a user's table) is padded less
    pad = min(3 * (2 * len(sos) + 1), max(0, x.shape[-1] - 1))
    return sosfiltfilt(sos, x, axis=-1, padlen=pad)


def sliding_mean(x: np.ndarray, position_m: np.ndarray, window_m: float = WINDOW_M):
    """Mean of ``x`` over the samples within ``window_m`` of track centred on each sample
    (positions strictly increasing; the speed may vary, the window is one of distance).
    Each sample weighs the track length it stands for (trapezoidal rule on the distance),
    so that a linear function of position is returned unchanged and a sine of wavelength
    L is scaled by sin(pi w / L) / (pi w / L). Near the ends the window is cut short.
    One channel (1-D)."""
    x = np.asarray(x, dtype=float)
    s = np.asarray(position_m, dtype=float)
    if x.ndim != 1 or s.shape != x.shape:
        raise ValueError(f"{s.size} positions for {x.shape[-1]} samples")
    if s.size < 2 or not np.all(np.diff(s) > 0):
        raise ValueError("positions must be strictly increasing (at least two)")
    if not window_m > 0:
        raise ValueError(f"window {window_m:g} m: must be positive")
    # integral of x over distance, as a piecewise-linear function of position
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(s))])
    lo = np.clip(s - 0.5 * window_m, s[0], s[-1])
    hi = np.clip(s + 0.5 * window_m, s[0], s[-1])

    def integral(at):
        xa = np.interp(at, s, x)
        k = np.clip(np.searchsorted(s, at, side="right") - 1, 0, s.size - 2)
        # integral up to s[k], plus the trapezoid from s[k] to ``at``
        return cum[k] + 0.5 * (x[k] + xa) * (at - s[k])

    return (integral(hi) - integral(lo)) / (hi - lo)


def full_window(position_m: np.ndarray, window_m: float = WINDOW_M) -> np.ndarray:
    """Mask of the samples whose sliding window lies wholly inside the record: within
    ``window_m`` / 2 of either end the window is cut short, averages less and would put
    the ends' samples among the extremes."""
    s = np.asarray(position_m, dtype=float)
    return (s >= s[0] + 0.5 * window_m) & (s <= s[-1] - 0.5 * window_m)


def percentiles(x: np.ndarray, levels: tuple[float, ...] = PERCENTILES) -> np.ndarray:
    """Percentiles (%) of ``x`` along the last axis (linear interpolation between order
    statistics)."""
    return np.percentile(np.asarray(x, dtype=float), levels, axis=-1)


@dataclass(frozen=True)
class SectionStatistics:
    """EN 14363 description of one force channel in one section."""

    p0_15: float
    p50: float
    p99_85: float

    def to_dict(self) -> dict[str, float]:
        return {"p0.15": self.p0_15, "p50": self.p50, "p99.85": self.p99_85}


def section_statistics(
    x: np.ndarray,
    fs: float,
    speed_ms: float | np.ndarray,
    cutoff_hz: float = FORCE_CUTOFF_HZ,
    window_m: float = WINDOW_M,
) -> SectionStatistics:
    """Low-pass, 2 m sliding mean and percentiles of one channel of a section recorded at
    ``fs`` Hz and ``speed_ms`` (m/s; one value or one per sample); the percentiles are of
    the samples whose window lies inside the section (:func:`full_window`)."""
    x = np.asarray(x, dtype=float)
    v = np.broadcast_to(np.asarray(speed_ms, dtype=float), x.shape)
    if not np.all(v > 0.0):  # the window is one of distance: standing, it has no samples
        raise RailsuspInputError(
            f"speed {float(np.min(v)):g} m/s in the section: the 2 m sliding mean runs over "
            "distance; accepted sections running at a positive speed throughout (cut stops "
            "out: railsusp sections)"
        )
    position = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / fs)])
    filtered = lowpass(x, fs, min(cutoff_hz, 0.45 * fs))
    smooth = sliding_mean(filtered, position, window_m)
    inside = full_window(position, window_m)
    p = percentiles(smooth[inside] if inside.any() else smooth)
    return SectionStatistics(*(float(q) for q in p))
