"""Summary statistics of wheel-rail forces that need no track geometry, for the
simulation-based posterior (:mod:`railsusp.estimate.posterior`).

Per section of one working condition, for the measured wheel:

- EN 14363 quantities (:mod:`railsusp.en14363`): Y, Q and Y/Q low-passed (20 Hz), averaged
  over 2 m of track, described by their 0.15 %, 50 % and 99.85 % percentiles; optionally
  the same for the wheelset sum of Y (the track-shifting force, both wheels of the
  wheelset recorded);
- the RMS of Y and of Q in frequency bands (:data:`BANDS_HZ`, log10 of kN), from a Welch
  spectrum of the de-meaned section: the suspension sets the frequencies at which the
  track's excitation comes through, the percentiles set its levels.

None of these depends on where along the track a force was measured, so a recording on
track that nobody has measured has them, and the simulator gives their distribution over
track realisations. Forces in kN, positions in m, rates in Hz.

A record is cut into sections of one length (the estimator's training section); each
section gives one summary vector (:func:`cut_sections`).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import welch

from railsusp.en14363 import FORCE_CUTOFF_HZ, lowpass, percentiles, sliding_mean

#: frequency bands of the band RMS, Hz (upper edges capped at 0.45 of the sampling rate)
BANDS_HZ: tuple[tuple[float, float], ...] = ((0.3, 1.5), (1.5, 4.0), (4.0, 8.0), (8.0, 15.0))
#: floor under a band RMS before its logarithm, kN
BAND_FLOOR_KN = 1e-4
PERCENTILE_NAMES = ("p0.15", "p50", "p99.85")


def summary_names(sum_y: bool = False) -> list[str]:
    """Names of the entries of :func:`section_summary`, in order."""
    channels = ["Y", "Q", "YQ", *(["sumY"] if sum_y else [])]
    names = [f"{c}_{p}" for c in channels for p in PERCENTILE_NAMES]
    names += [f"{c}_band_{lo:g}-{hi:g}Hz" for c in ("Y", "Q") for lo, hi in BANDS_HZ]
    return names


def en14363_percentiles(x: np.ndarray, fs: float, speed_ms: float) -> np.ndarray:
    """0.15/50/99.85 % percentiles of ``x`` low-passed (20 Hz, capped at 0.45 fs) and
    averaged over 2 m of track at constant speed ``speed_ms``."""
    x = np.asarray(x, dtype=float)
    position = np.arange(x.size) * speed_ms / fs
    filtered = lowpass(x, fs, min(FORCE_CUTOFF_HZ, 0.45 * fs))
    return percentiles(sliding_mean(filtered, position))


def band_rms(x: np.ndarray, fs: float, bands=BANDS_HZ) -> np.ndarray:
    """RMS (units of ``x``) of the de-meaned ``x`` in each band, from the integral of its
    one-sided Welch power spectral density over the band (Parseval: the sum over all bands
    of the squares is the variance). Segments of a quarter of the record, at least 32
    samples, so a short section still resolves the lowest band roughly."""
    x = np.asarray(x, dtype=float)
    nper = int(min(x.size, max(32, x.size // 4)))
    f, pxx = welch(x - x.mean(), fs=fs, nperseg=nper, detrend="constant")
    df = f[1] - f[0]
    out = []
    for lo, hi in bands:
        hi = min(hi, 0.45 * fs)
        sel = (f >= lo) & (f < hi)
        out.append(np.sqrt(np.sum(pxx[sel]) * df) if sel.any() else 0.0)
    return np.array(out)


def section_summary(
    Y: np.ndarray,
    Q: np.ndarray,
    fs: float,
    speed_ms: float,
    Y_partner: np.ndarray | None = None,
) -> np.ndarray:
    """Summary vector (:func:`summary_names`) of one section of the measured wheel's lateral
    force ``Y`` and vertical force ``Q`` (kN) sampled at ``fs`` Hz at ``speed_ms``.
    ``Y_partner``: the other wheel of the same wheelset, for the sum of Y; None leaves it
    out. Y/Q is taken where Q exceeds 1 kN (an unloaded wheel gives no quotient)."""
    Y = np.asarray(Y, dtype=float)
    Q = np.asarray(Q, dtype=float)
    yq = Y / np.maximum(Q, 1.0)
    parts = [en14363_percentiles(c, fs, speed_ms) for c in (Y, Q, yq)]
    if Y_partner is not None:
        parts.append(en14363_percentiles(Y + np.asarray(Y_partner, float), fs, speed_ms))
    bands = [np.log10(np.maximum(band_rms(c, fs), BAND_FLOOR_KN)) for c in (Y, Q)]
    return np.concatenate(parts + bands)


def cut_sections(n_samples: int, section_samples: int) -> list[slice]:
    """Consecutive, non-overlapping sections of ``section_samples`` each in a record of
    ``n_samples``; the remainder shorter than a section is left out (a short piece would
    have statistics of another distribution than the training sections')."""
    if section_samples < 1:
        raise ValueError(f"section of {section_samples} samples: accepted at least 1")
    n = n_samples // section_samples
    return [slice(i * section_samples, (i + 1) * section_samples) for i in range(n)]
