"""Candidate geometry-free statistics of one section of an instrumented wheelset's forces,
for bench/statistics_information.py (issue 20: do richer statistics than today's 17 carry
more about X13, X11 and X14?).

One instrumented wheelset gives four channels: the measured wheel's lateral force Y and
vertical force Q, and the same of the other wheel of the wheelset (the partner). Groups of
statistics, each a function of one section of those four channels (kN, sampled at ``fs``
Hz, the wagon at ``speed_ms``):

- ``today``: the 17 of the posterior (:func:`railsusp.estimate.summaries.section_summary`,
  the measured wheel only): EN 14363 percentiles of Y, Q, Y/Q and log10 band RMS of Y, Q in
  four bands;
- ``third_octave``: log10 RMS of the measured wheel's Y and Q in 18 third-octave bands from
  0.3 to 19.2 Hz (a finer spectrum);
- ``both_wheels``: the partner wheel's own 17, and the percentiles and four band RMS of the
  wheelset sum of Y (the track-shifting force) and of the left-right difference of Q;
- ``cross``: the band coherency (real and imaginary parts of the band-integrated cross
  spectrum over the geometric mean of the two band powers: magnitude and phase without a
  wrap) of Y with Q on the measured wheel, of the two wheels' Y and of their Q, in six
  bands; lagged auto-correlations of Y and Q and cross-correlations of Y with Q.

None depends on where along the track a section was taken. Pure functions on arrays.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import csd, welch

from railsusp.estimate.summaries import (
    BAND_FLOOR_KN,
    BANDS_HZ,
    PERCENTILE_NAMES,
    band_rms,
    en14363_percentiles,
    section_summary,
    summary_names,
)

#: third-octave bands from 0.3 Hz, Hz (18 of them, to 19.2 Hz)
THIRD_OCTAVE_HZ: tuple[tuple[float, float], ...] = tuple(
    (0.3 * 2 ** (k / 3), 0.3 * 2 ** ((k + 1) / 3)) for k in range(18)
)
#: bands of the coherencies, Hz
CROSS_BANDS_HZ: tuple[tuple[float, float], ...] = (
    (0.3, 0.8), (0.8, 1.5), (1.5, 3.0), (3.0, 5.0), (5.0, 8.0), (8.0, 15.0)
)  # fmt: skip
#: lags of the auto-correlations of Y and Q, s
AUTO_LAGS_S = (0.04, 0.1, 0.2, 0.5, 1.0)
#: lags of the cross-correlation of Y with Q (Q later than Y for a positive lag), s
CROSS_LAGS_S = (-0.5, -0.1, 0.0, 0.1, 0.5)
#: the channels of one section, in this order: measured wheel Y, Q, partner Y, Q
CHANNELS = ("Y", "Q", "Y_partner", "Q_partner")
GROUPS = ("today", "third_octave", "both_wheels", "cross")


def log_band_rms(x: np.ndarray, fs: float, bands, segment_fraction: float = 0.5) -> np.ndarray:
    """log10 of the RMS (units of ``x``, floored at :data:`BAND_FLOOR_KN`) of the de-meaned
    ``x`` in each band: the integral of its one-sided Welch spectral density (Hann,
    segments of ``segment_fraction`` of the record, half overlapping) over the band. Half
    the record resolves 0.1 Hz in a 20 s section, so the narrowest third-octave band
    (0.3-0.38 Hz) holds a line."""
    x = np.asarray(x, dtype=float)
    nper = int(min(x.size, max(32, round(segment_fraction * x.size))))
    f, pxx = welch(x - x.mean(), fs=fs, nperseg=nper, detrend="constant")
    df = f[1] - f[0]
    out = np.empty(len(bands))
    for i, (lo, hi) in enumerate(bands):
        sel = (f >= lo) & (f < min(hi, 0.45 * fs))
        out[i] = np.sqrt(np.sum(pxx[sel]) * df) if sel.any() else 0.0
    return np.log10(np.maximum(out, BAND_FLOOR_KN))


def band_coherency(x: np.ndarray, y: np.ndarray, fs: float, bands=CROSS_BANDS_HZ) -> np.ndarray:
    """Band coherency of ``x`` and ``y``: per band, sum of the cross spectrum
    conj(X) Y over the band divided by sqrt(sum |X|^2 sum |Y|^2) (Welch, segments of a
    quarter of the record), as the real parts of all bands then the imaginary parts. Its
    magnitude is at most 1 (1 for y a multiple of x), its angle is y's phase lead on x
    (-2 pi f tau for y delayed by tau)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    nper = int(min(x.size, max(32, x.size // 4)))
    kw = {"fs": fs, "nperseg": nper, "detrend": "constant"}
    f, sxy = csd(x, y, **kw)
    _, sxx = welch(x, **kw)
    _, syy = welch(y, **kw)
    out = np.zeros(len(bands), dtype=complex)
    for i, (lo, hi) in enumerate(bands):
        sel = (f >= lo) & (f < min(hi, 0.45 * fs))
        den = np.sqrt(np.sum(sxx[sel]) * np.sum(syy[sel]))
        if sel.any() and den > 0:
            out[i] = np.sum(sxy[sel]) / den
    return np.concatenate([out.real, out.imag])


def lagged_correlation(x: np.ndarray, y: np.ndarray, fs: float, lags_s) -> np.ndarray:
    """Correlation of x(t) with y(t + lag) for each lag (s, rounded to samples), over the
    samples the two overlap in, of the de-meaned series scaled by their whole-record
    standard deviations (1 at lag 0 for y = x; -1 at half a period for a sine)."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    y = np.asarray(y, dtype=float) - np.mean(y)
    scale = np.std(x) * np.std(y)
    out = np.empty(len(lags_s))
    for i, lag in enumerate(lags_s):
        k = round(lag * fs)
        a, b = (x[: x.size - k], y[k:]) if k >= 0 else (x[-k:], y[: y.size + k])
        out[i] = np.mean(a * b) / scale if scale > 0 else 0.0
    return out


def _level_and_bands(x: np.ndarray, fs: float, speed_ms: float) -> np.ndarray:
    """Percentiles (EN 14363) and log10 band RMS (:data:`BANDS_HZ`) of one series."""
    bands = np.log10(np.maximum(band_rms(x, fs), BAND_FLOOR_KN))
    return np.concatenate([en14363_percentiles(x, fs, speed_ms), bands])


def group_names(group: str) -> list[str]:
    """Names of the entries of ``group`` (:data:`GROUPS`), in the order of
    :func:`section_statistics`."""
    bands4 = [f"band_{lo:g}-{hi:g}Hz" for lo, hi in BANDS_HZ]
    if group == "today":
        return summary_names()
    if group == "third_octave":
        return [f"{c}_3oct_{lo:.3g}-{hi:.3g}Hz" for c in "YQ" for lo, hi in THIRD_OCTAVE_HZ]
    if group == "both_wheels":
        level = [*PERCENTILE_NAMES, *bands4]
        return [f"partner_{n}" for n in summary_names()] + [
            f"{c}_{n}" for c in ("sumY", "dQ") for n in level
        ]
    if group == "cross":
        coh = [
            f"coh_{pair}_{part}_{lo:g}-{hi:g}Hz"
            for pair in ("YQ", "YY", "QQ")
            for part in ("re", "im")
            for lo, hi in CROSS_BANDS_HZ
        ]
        auto = [f"acorr_{c}_{lag:g}s" for c in "YQ" for lag in AUTO_LAGS_S]
        return coh + auto + [f"xcorr_YQ_{lag:g}s" for lag in CROSS_LAGS_S]
    raise ValueError(f"group {group!r}: accepted {', '.join(GROUPS)}")


def section_statistics(signals: np.ndarray, fs: float, speed_ms: float) -> dict[str, np.ndarray]:
    """Every group's statistics (:func:`group_names`) of one section, ``signals`` (4, T) the
    channels of :data:`CHANNELS` in kN. Q is floored at 0 as in the posterior (a lifted
    wheel carries no load)."""
    Y, Q, Yp, Qp = (np.asarray(s, dtype=float) for s in signals)
    Q, Qp = np.maximum(Q, 0.0), np.maximum(Qp, 0.0)
    both = [section_summary(Yp, Qp, fs, speed_ms)]
    both += [_level_and_bands(Y + Yp, fs, speed_ms), _level_and_bands(Q - Qp, fs, speed_ms)]
    cross = [band_coherency(Y, Q, fs), band_coherency(Y, Yp, fs), band_coherency(Q, Qp, fs)]
    cross += [lagged_correlation(c, c, fs, AUTO_LAGS_S) for c in (Y, Q)]
    cross.append(lagged_correlation(Y, Q, fs, CROSS_LAGS_S))
    return {
        "today": section_summary(Y, Q, fs, speed_ms),
        "third_octave": np.concatenate([log_band_rms(c, fs, THIRD_OCTAVE_HZ) for c in (Y, Q)]),
        "both_wheels": np.concatenate(both),
        "cross": np.concatenate(cross),
    }
