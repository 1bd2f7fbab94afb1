"""Families of geometry-free statistics of one section of an instrumented wheelset's
forces, beyond the EN 14363 summary (:mod:`railsusp.estimate.summaries`), for the
simulation-based posterior (``PosteriorSettings.statistics``).

One instrumented wheelset gives four channels: the measured wheel's lateral force Y and
vertical force Q, and the same of the other wheel of the wheelset (the partner, ``Yp``,
``Qp``). Each family is a function of one section of them (kN, sampled at ``fs`` Hz, the
wagon at ``speed_ms``):

- ``en14363`` (always first): the measured wheel's EN 14363 percentiles of Y, Q, Y/Q and
  log10 band RMS of Y and Q in four bands (17 statistics; :func:`~railsusp.estimate.
  summaries.section_summary`);
- ``third-octave``: log10 RMS of the measured wheel's Y and Q in 18 third-octave bands
  from 0.3 to 19.2 Hz (a finer spectrum: where the suspension's modes let the track's
  excitation through);
- ``wheelset``: the partner wheel's own 17, and the percentiles and four band RMS of the
  wheelset's lateral force on the track ``sumY`` (the track-shifting force, EN 14363's sum
  of Y: Y - Yp, + towards the measured wheel's field side, :func:`~railsusp.estimate.
  summaries.wheelset_force`) and of the difference of Q, ``dQ`` = Q - Qp;
- ``coherence``: band coherency (real and imaginary parts of the band-integrated cross
  spectrum over the geometric mean of the two band powers: magnitude and phase without a
  wrap) of Y with Q on the measured wheel, of the two wheels' Y and of their Q, in six
  bands; lagged auto-correlations of Y and Q and cross-correlations of Y with Q;
- ``cross-spectra``: the four channels' whole cross-spectral matrix in 1 Hz bands from
  0.2 to 15 Hz (:data:`SPECTRAL_BANDS_HZ`): per band the log10 RMS of each channel and the
  coherency of each of the six pairs (16 numbers, one to one with the band's Hermitian
  4 x 4 matrix).

Why these (bench/statistics_information.py, measured from common-random-number
simulations at 600 s per condition, all ten parameters unknown): the Cramer-Rao 90 % width
of X13 falls from 17.7 % of range with the EN 14363 17 to 7.5 % with all four families,
X11 from 33 to 13 %, X14 from 39 to 13 %; bench/spectral_information.py measures what
the means and the whole cross-spectral matrix of the four channels carry, which
``cross-spectra`` reads in 1 Hz bands. None depends on where along the track a section was
taken, so a recording on unmeasured track has them.

Names are ``CHANNEL_KIND``: the channel says which instrument gains the statistic depends
on (:func:`gain_dependence`); coherencies and correlations depend on none.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import csd, welch

from railsusp.errors import RailsuspInputError
from railsusp.estimate.summaries import (
    BAND_FLOOR_KN,
    BANDS_HZ,
    PERCENTILE_NAMES,
    band_rms,
    en14363_percentiles,
    half_segment,
    line_segment,
    section_summary,
    summary_names,
    wheelset_force,
)

#: the families, in the order their statistics follow one another
FAMILIES = ("en14363", "third-octave", "wheelset", "coherence", "cross-spectra")
#: what ``all`` selects: the families whose posterior bench/README.md has checked
#: ("Richer statistics in the posterior"); ``cross-spectra`` (its information measured by
#: bench/spectral_information.py and statistics_information.py; a posterior on it with 8000
#: training cases was not calibrated at 600 s and no narrower than the four families')
#: only by name
ALL_FAMILIES = ("en14363", "third-octave", "wheelset", "coherence")
#: the families that need the partner wheel's channels
PARTNER_FAMILIES = ("wheelset", "coherence", "cross-spectra")
#: third-octave bands from 0.3 Hz, Hz (18 of them, to 19.2 Hz)
THIRD_OCTAVE_HZ: tuple[tuple[float, float], ...] = tuple(
    (0.3 * 2 ** (k / 3), 0.3 * 2 ** ((k + 1) / 3)) for k in range(18)
)
#: bands of the coherencies, Hz
CROSS_BANDS_HZ: tuple[tuple[float, float], ...] = (
    (0.3, 0.8), (0.8, 1.5), (1.5, 3.0), (3.0, 5.0), (5.0, 8.0), (8.0, 15.0)
)  # fmt: skip
#: bands of the cross-spectral matrix (``cross-spectra``), Hz: 0.2-1, then 1 Hz wide to 15
SPECTRAL_BANDS_HZ: tuple[tuple[float, float], ...] = (
    (0.2, 1.0),
    *((float(k), float(k + 1)) for k in range(1, 15)),
)
#: the channels of the cross-spectral matrix and its pairs, in the order of the statistics
SPECTRAL_CHANNELS = ("Y", "Q", "Yp", "Qp")
SPECTRAL_PAIRS = tuple(
    (a, b) for i, a in enumerate(SPECTRAL_CHANNELS) for b in SPECTRAL_CHANNELS[i + 1 :]
)
#: lags of the auto-correlations of Y and Q, s
AUTO_LAGS_S = (0.04, 0.1, 0.2, 0.5, 1.0)
#: lags of the cross-correlation of Y with Q (Q later than Y for a positive lag), s
CROSS_LAGS_S = (-0.5, -0.1, 0.0, 0.1, 0.5)


def parse_families(text) -> tuple[str, ...]:
    """The families of ``text`` (a comma-separated string or a sequence of names; ``all``
    for :data:`ALL_FAMILIES`) in :data:`FAMILIES` order, ``en14363`` always included; a
    one-line error naming the accepted ones."""
    if isinstance(text, str):
        items = text.split(",")
    elif isinstance(text, (tuple, list)) and all(isinstance(t, str) for t in text):
        items = list(text)
    else:
        items = [repr(text)]
    items = [t.strip() for t in items if t.strip()]
    if "all" in items:
        items = [t for t in items if t != "all"] + list(ALL_FAMILIES)
    wrong = [t for t in items if t not in FAMILIES]
    if wrong or not items:
        raise RailsuspInputError(
            f"statistics = {','.join(items) or '(none)'}: accepted 'all' "
            f"({', '.join(ALL_FAMILIES)}) or a comma-separated choice of {', '.join(FAMILIES)}"
        )
    return tuple(f for f in FAMILIES if f in items or f == "en14363")


def needs_partner(families: tuple[str, ...], sum_y: bool = False) -> bool:
    """Whether the families (or the EN 14363 summary's wheelset sum) read the partner
    wheel's Y."""
    return sum_y or any(f in PARTNER_FAMILIES for f in families)


def needs_partner_q(families: tuple[str, ...]) -> bool:
    """Whether the families read the partner wheel's Q too (the EN 14363 summary's
    wheelset sum reads only its Y)."""
    return any(f in PARTNER_FAMILIES for f in families)


def family_names(family: str, sum_y: bool = False) -> list[str]:
    """Names of the statistics of ``family``, in the order of :func:`section_statistics`."""
    bands4 = [f"band_{lo:g}-{hi:g}Hz" for lo, hi in BANDS_HZ]
    if family == "en14363":
        return summary_names(sum_y)
    if family == "third-octave":
        return [f"{c}_3oct_{lo:.3g}-{hi:.3g}Hz" for c in "YQ" for lo, hi in THIRD_OCTAVE_HZ]
    if family == "wheelset":
        partner = ["{}p_{}".format(*n.split("_", 1)) for n in summary_names()]
        level = [*PERCENTILE_NAMES, *bands4]
        return partner + [f"{c}_{n}" for c in ("sumY", "dQ") for n in level]
    if family == "coherence":
        coh = [
            f"coh{pair}_{part}_{lo:g}-{hi:g}Hz"
            for pair in ("YQ", "YY", "QQ")
            for part in ("re", "im")
            for lo, hi in CROSS_BANDS_HZ
        ]
        auto = [f"acorr{c}_{lag:g}s" for c in "YQ" for lag in AUTO_LAGS_S]
        return coh + auto + [f"xcorrYQ_{lag:g}s" for lag in CROSS_LAGS_S]
    if family == "cross-spectra":
        out = []
        for lo, hi in SPECTRAL_BANDS_HZ:
            out += [f"{c}_xs_{lo:g}-{hi:g}Hz" for c in SPECTRAL_CHANNELS]
            out += [f"xcoh{a}{b}_{part}_{lo:g}-{hi:g}Hz"
                    for part in ("re", "im") for a, b in SPECTRAL_PAIRS]  # fmt: skip
        return out
    raise RailsuspInputError(f"statistics family {family!r}: accepted {', '.join(FAMILIES)}")


def statistic_names(families: tuple[str, ...], sum_y: bool = False) -> list[str]:
    """Names of the whole summary vector of ``families``."""
    return [n for f in families for n in family_names(f, sum_y)]


def log_band_rms(x: np.ndarray, fs: float, bands, segment_fraction: float = 0.5) -> np.ndarray:
    """log10 of the RMS (units of ``x``, floored at :data:`BAND_FLOOR_KN`) of the de-meaned
    ``x`` in each band: the integral of its one-sided Welch spectral density (Hann,
    half-overlapping segments of :func:`~railsusp.estimate.summaries.line_segment`:
    ``segment_fraction`` of the record, longer where a band would otherwise hold no line)
    over the band. A record too short to
    resolve the bands (whose sections the posterior's settings refuse,
    :func:`railsusp.estimate.posterior_band_resolution.check_third_octave_resolution`) is
    read with ``segment_fraction`` of it, as before."""
    x = np.asarray(x, dtype=float)
    bands = tuple(tuple(map(float, b)) for b in bands)
    nper = line_segment(x.size, float(fs), bands, segment_fraction)
    nper = nper or half_segment(x.size, segment_fraction)
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
    (-2 pi f tau for y delayed by tau). Independent of either channel's gain."""
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


def band_cross_spectra(channels: np.ndarray, fs: float, bands=SPECTRAL_BANDS_HZ) -> np.ndarray:
    """The cross-spectral matrix of ``channels`` (C, T), band by band: per band the log10
    RMS of each channel (de-meaned, floored at :data:`BAND_FLOOR_KN`), then the coherency
    of each pair i < j (the band's cross spectrum conj(X_i) X_j summed over the band over
    the geometric mean of the two band powers), real parts then imaginary parts. Welch
    estimates, Hann segments of a quarter of the record overlapping by half (a 20 s
    section: 0.2 Hz lines, seven segments; half-overlapping segments keep nearly all of
    the section's information, where one tapered periodogram keeps about half of it:
    tests/test_bench_spectral_information.py). The log RMS moves with its channel's gain
    by gain / ln 10; the coherencies do not depend on the gains."""
    x = np.asarray(channels, dtype=float)
    nper = int(min(x.shape[1], max(32, x.shape[1] // 4)))
    f, sxy = csd(x[:, None, :], x[None, :, :], fs=fs, nperseg=nper, detrend="constant")
    df = f[1] - f[0]
    iu = np.triu_indices(len(x), 1)
    out = []
    for lo, hi in bands:
        sel = (f >= lo) & (f < min(hi, 0.45 * fs))
        band = np.sum(sxy[:, :, sel], axis=-1)
        power = np.real(np.diagonal(band)).copy()
        rms = np.sqrt(np.maximum(power, 0.0) * df)
        den = np.sqrt(np.outer(power, power))[iu]
        coh = np.where(den > 0, band[iu] / np.where(den > 0, den, 1.0), 0.0)
        out.append(np.concatenate([np.log10(np.maximum(rms, BAND_FLOOR_KN)), coh.real, coh.imag]))
    return np.concatenate(out)


def lagged_correlation(x: np.ndarray, y: np.ndarray, fs: float, lags_s) -> np.ndarray:
    """Correlation of x(t) with y(t + lag) for each lag (s, rounded to samples), over the
    samples the two overlap in, of the de-meaned series scaled by their whole-record
    standard deviations (1 at lag 0 for y = x; -1 at half a period for a sine).
    Independent of either channel's gain."""
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


def family_statistics(
    family: str,
    Y: np.ndarray,
    Q: np.ndarray,
    fs: float,
    speed_ms: float,
    Yp: np.ndarray | None = None,
    Qp: np.ndarray | None = None,
    sum_y: bool = False,
) -> np.ndarray:
    """One family's statistics (:func:`family_names`) of one section; Q and Qp are
    floored at 0 (a lifted wheel carries no load). ``Yp``/``Qp``: the partner wheel, needed
    by :data:`PARTNER_FAMILIES` and by ``sum_y``."""
    Q = np.maximum(np.asarray(Q, float), 0.0)
    if family in PARTNER_FAMILIES or (family == "en14363" and sum_y):
        if Yp is None or (family != "en14363" and Qp is None):
            raise RailsuspInputError(
                f"statistics family {family!r} needs the partner wheel's Y and Q"
            )
    if family == "en14363":
        return section_summary(Y, Q, fs, speed_ms, Yp if sum_y else None)
    if family == "third-octave":
        return np.concatenate([log_band_rms(c, fs, THIRD_OCTAVE_HZ) for c in (Y, Q)])
    Yp = np.asarray(Yp, float)
    Qp = np.maximum(np.asarray(Qp, float), 0.0)
    if family == "wheelset":
        parts = [section_summary(Yp, Qp, fs, speed_ms)]
        parts += [
            _level_and_bands(wheelset_force(Y, Yp), fs, speed_ms),
            _level_and_bands(Q - Qp, fs, speed_ms),
        ]
        return np.concatenate(parts)
    if family == "coherence":
        parts = [band_coherency(Y, Q, fs), band_coherency(Y, Yp, fs), band_coherency(Q, Qp, fs)]
        parts += [lagged_correlation(c, c, fs, AUTO_LAGS_S) for c in (Y, Q)]
        parts.append(lagged_correlation(Y, Q, fs, CROSS_LAGS_S))
        return np.concatenate(parts)
    if family == "cross-spectra":
        return band_cross_spectra(np.stack([Y, Q, Yp, Qp]), fs)
    raise RailsuspInputError(f"statistics family {family!r}: accepted {', '.join(FAMILIES)}")


def section_statistics(
    families: tuple[str, ...],
    Y: np.ndarray,
    Q: np.ndarray,
    fs: float,
    speed_ms: float,
    Yp: np.ndarray | None = None,
    Qp: np.ndarray | None = None,
    sum_y: bool = False,
) -> np.ndarray:
    """The summary vector (:func:`statistic_names`) of one section: the families one after
    the other."""
    return np.concatenate(
        [family_statistics(f, Y, Q, fs, speed_ms, Yp, Qp, sum_y) for f in families]
    )


#: per channel of a statistic's name: (instrument channel, weight) of its gain dependence
_GAIN_SOURCES: dict[str, tuple[tuple[str, float], ...]] = {
    "Y": (("Y", 1.0),),
    "Q": (("Q", 1.0),),
    "YQ": (("Y", 1.0), ("Q", -1.0)),
    "Yp": (("Yp", 1.0),),
    "Qp": (("Qp", 1.0),),
    "YQp": (("Yp", 1.0), ("Qp", -1.0)),
}
#: a channel's level, as a combination of medians of the same condition's statistics (the
#: partner's: the measured wheel's less the median of the wheelset's difference, sumY =
#: Y - Yp and dQ = Q - Qp; the EN 14363 summary with ``sum_y`` has no Yp_p50 of its own)
_LEVEL = {
    "Y": (("Y_p50", 1.0),),
    "Q": (("Q_p50", 1.0),),
    "Yp": (("Y_p50", 1.0), ("sumY_p50", -1.0)),
    "Qp": (("Q_p50", 1.0), ("dQ_p50", -1.0)),
}

GainTerm = tuple[str, float, tuple[tuple[str, float], ...]]


def gain_dependence(name: str) -> list[GainTerm]:
    """How the statistic ``name`` (``CHANNEL_KIND``, without the condition) moves with
    small relative gain errors of the instrument's channels: a list of (channel, factor,
    scale): d statistic / d gain = factor times the sum of weight x mean of the statistics
    of ``scale`` ((name, weight) pairs of the same condition; none: times 1).

    - a percentile scales with its channel's gain (scale: itself); Y/Q with the
      difference of the two gains;
    - a percentile d_p of the wheelset's lateral force sumY = Y - Yp (each wheel's Y is
      + towards its own field side, so the wheelset's force is their difference) moves
      with the measured wheel's gain by that wheel's force where the difference is at
      d_p, E[Y | D = d_p] = level + share (d_p - median of D) (regression on the
      difference, Gaussian forces), and with the partner's gain by minus the partner's,
      E[Yp | D = d_p] = level - share (d_p - median of D); the level is the wheel's
      median (the partner's: the measured wheel's less the difference's median) and the
      share 1/2 (equal wheels). The two wheels' terms add up to d_p, exact for equal
      gains. The difference of Q, dQ = Q - Qp, alike. Why not half the percentile per
      wheel (the model before the levels): the wheels' levels can be far larger than their
      difference;
    - a log10 band RMS shifts by its channel's gain / ln 10; of a wheelset difference,
      by half of each wheel's gain / ln 10 (exact for uncorrelated wheels of equal
      fluctuation; otherwise the calibration records' model error takes the rest);
    - coherencies and correlations do not depend on the gains.
    """
    channel, kind = name.split("_", 1)
    if channel.startswith(("coh", "xcoh", "acorr", "xcorr")):
        return []
    log_kind = kind.startswith(("band", "3oct", "xs_"))
    if channel in ("sumY", "dQ"):  # Y - Yp and Q - Qp
        own, partner = ("Y", "Yp") if channel == "sumY" else ("Q", "Qp")
        if log_kind:
            return [(own, 0.5 / np.log(10.0), ()), (partner, 0.5 / np.log(10.0), ())]
        spread = ((name, 0.5), (f"{channel}_p50", -0.5))  # (d_p - median) / 2
        partner_spread = tuple((n, -w) for n, w in spread)
        return [(own, 1.0, _LEVEL[own] + spread), (partner, -1.0, _LEVEL[partner] + partner_spread)]
    if channel not in _GAIN_SOURCES:
        raise ValueError(f"statistic {name!r}: no gain model for channel {channel!r}")
    if log_kind:
        return [(src, w / np.log(10.0), ()) for src, w in _GAIN_SOURCES[channel]]
    return [(src, w, ((name, 1.0),)) for src, w in _GAIN_SOURCES[channel]]
