"""A run's speed from its distance channel alone (no speed channel): the odometer's
staircase drawn through its steps, then differenced over a centred window.

Apart from :mod:`railsusp.measured.run` (which reads the recording and calls these where it
has a distance channel and no speed) because this is signal processing of one channel, not
reading.
"""

from __future__ import annotations

import numpy as np


def distance_through_steps(time: np.ndarray, x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The distance ``x`` (sampled at ``time``) on the times ``t``, drawn through the
    samples at which it changes: an odometer that counts whole metres holds its value
    between steps, and the times of its steps are where the wagon passed each metre. A
    staircase differenced over 1 s read 8 or 9 m a second at 30 km/h, a 12 % spread that
    broke every section by speed; through its steps the spread is the sampling's, 0.02 s in
    a second at 50 Hz. A distance that changes at every sample is unchanged."""
    keep = np.ones(x.size, dtype=bool)
    keep[1:-1] = x[1:-1] != x[:-2]
    return np.interp(t, time[keep], x[keep])


def smoothed_gradient(x: np.ndarray, t: np.ndarray, window_s: float = 1.0) -> np.ndarray:
    """dx/dt over a centred window of about ``window_s`` (position channels step)."""
    dt = float(np.median(np.diff(t)))
    k = max(1, round(window_s / dt / 2))
    idx = np.arange(x.size)
    lo, hi = np.clip(idx - k, 0, x.size - 1), np.clip(idx + k, 0, x.size - 1)
    return (x[hi] - x[lo]) / (t[hi] - t[lo])
