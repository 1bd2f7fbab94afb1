"""Summary statistics of wheel-rail forces that need no track geometry, for the
simulation-based posterior (:mod:`railsusp.estimate.posterior`).

Per section of one working condition, for the measured wheel:

- EN 14363 quantities (:mod:`railsusp.en14363`): Y, Q and Y/Q low-passed (20 Hz), averaged
  over 2 m of track, described by their 0.15 %, 50 % and 99.85 % percentiles of the
  samples whose 2 m window lies wholly inside the section (as
  :func:`railsusp.en14363.section_statistics`); Y/Q only where the wheel is loaded
  (:func:`section_summary`); optionally the same for the wheelset's lateral force on the
  track, ``sumY`` (the track-shifting force, EN 14363's sum of Y: both wheels of the
  wheelset recorded), + towards the measured wheel's field side (:func:`wheelset_force`);
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

from functools import lru_cache

import numpy as np
from scipy.fft import rfftfreq
from scipy.signal import welch

from railsusp.en14363 import (
    FORCE_CUTOFF_HZ,
    full_window,
    lowpass,
    percentiles,
    section_statistics,
    sliding_mean,
)

#: version of the summary statistics' definitions, stamped with every posterior estimator's
#: cached simulations and checked with the force-law revision: a change of a definition
#: here makes a new version, so that statistics cached under the old ones are not mixed
#: with new ones (2026-11-30.2: sumY the track-shifting force Y - Y_partner, Y/Q without
#: unloaded samples, percentiles without the windows cut short at a section's ends)
STATISTICS_VERSION = "2026-11-30.2"
#: frequency bands of the band RMS, Hz (upper edges capped at 0.45 of the sampling rate)
BANDS_HZ: tuple[tuple[float, float], ...] = ((0.3, 1.5), (1.5, 4.0), (4.0, 8.0), (8.0, 15.0))
#: floor under a band RMS before its logarithm, kN
BAND_FLOOR_KN = 1e-4
PERCENTILE_NAMES = ("p0.15", "p50", "p99.85")
#: vertical force below which a wheel counts as unloaded, kN: its Y/Q is not defined
UNLOADED_KN = 1.0
#: share of a 2 m window that must be loaded wheel for its mean of Y/Q to count
#: (a window of unloaded samples only has no quotient; the floor keeps rounding out)
MIN_LOADED_SHARE = 1e-6


def summary_names(sum_y: bool = False) -> list[str]:
    """Names of the entries of :func:`section_summary`, in order."""
    channels = ["Y", "Q", "YQ", *(["sumY"] if sum_y else [])]
    names = [f"{c}_{p}" for c in channels for p in PERCENTILE_NAMES]
    names += [f"{c}_band_{lo:g}-{hi:g}Hz" for c in ("Y", "Q") for lo, hi in BANDS_HZ]
    return names


def en14363_percentiles(
    x: np.ndarray, fs: float, speed_ms: float, defined: np.ndarray | None = None
) -> np.ndarray:
    """0.15/50/99.85 % percentiles of ``x`` low-passed (20 Hz, capped at 0.45 fs) and
    averaged over 2 m of track at constant speed ``speed_ms``, of the samples whose window
    lies wholly inside the section (:func:`railsusp.en14363.full_window`, as
    :func:`railsusp.en14363.section_statistics`): near either end the window is cut short,
    averages less and would put the ends among the extremes (a section shorter than 2 m of
    track keeps all its samples).

    ``defined`` (boolean, as ``x``): where ``x`` is defined (Y/Q: where the wheel is
    loaded). The filter needs a whole series, so the gaps are bridged by linear
    interpolation for it; the 2 m mean is then the mean over the window's defined samples
    only (trapezoidal weights, as :func:`~railsusp.en14363.sliding_mean`), and a sample
    whose window holds none is left out. No defined sample at all: NaN (the statistic does
    not exist; a training case with it is left out as a failed run is)."""
    x = np.asarray(x, dtype=float)
    if defined is None or np.all(defined):
        p = section_statistics(x, fs, speed_ms)
        return np.array([p.p0_15, p.p50, p.p99_85])
    defined = np.asarray(defined, dtype=bool)
    if not defined.any():
        return np.full(len(PERCENTILE_NAMES), np.nan)
    position = np.arange(x.size) * speed_ms / fs
    bridged = np.interp(position, position[defined], x[defined])
    weight = defined.astype(float)
    share = sliding_mean(weight, position)
    covered = share > MIN_LOADED_SHARE
    filtered = lowpass(bridged, fs, min(FORCE_CUTOFF_HZ, 0.45 * fs))
    smooth = sliding_mean(filtered * weight, position) / np.where(covered, share, 1.0)
    keep = full_window(position) & covered
    return percentiles(smooth[keep] if keep.any() else smooth[covered])


def wheelset_force(Y: np.ndarray, Y_partner: np.ndarray) -> np.ndarray:
    """The wheelset's lateral force on the track (kN), + towards the measured wheel's field
    side: ``Y - Y_partner``. Each wheel's Y is + towards its own field side (docs/data-
    format.md), so the wheelset's force on the track is the difference of the two, not
    their sum (:attr:`railsusp.vehicle.simulation_result.SimulationResult.H`, + to the left, is
    Y_L - Y_R). Towards the measured wheel's field side: outward in a curve, where the
    measured wheel is the outer one, and + to the left on tangent, where the simulations
    measure the leading wheelset's left wheel (H itself; a recording of the right wheel
    there, which the statistics of tangent track take alike, gives -H, its mirror image)."""
    return np.asarray(Y, dtype=float) - np.asarray(Y_partner, dtype=float)


def narrowest_band_hz(fs: float, bands=BANDS_HZ) -> float:
    """The width (Hz) of the narrowest of ``bands`` at the sampling rate ``fs``, each band's
    upper edge capped at 0.45 ``fs`` as :func:`band_rms` caps it (0 or less: a band lies
    wholly above the cap and holds nothing at this rate)."""
    return min(min(hi, 0.45 * fs) - lo for lo, hi in bands)


def band_segment(n: int, fs: float, bands=BANDS_HZ) -> int | None:
    """The Welch segment (samples) of :func:`band_rms` for a record of ``n`` samples at
    ``fs``: a quarter of the record, at least 32 samples, and at least as long as makes the
    frequency step ``fs / segment`` no wider than the narrowest band
    (:func:`narrowest_band_hz`), so that every band holds a line of the spectrum and a
    tone's power lies in its own band. None where the record is shorter than that segment
    (or a band lies above the rate's cap): its bands cannot be resolved.

    The quarter alone left the frequency step above the lowest band's 1.2 Hz in sections
    under 2.8 s at 50 Hz: 0.3-1.5 Hz then held no line (log10 of the floor in every case, a
    constant the flows cannot learn from) and a 1 Hz tone went to 1.5-4 Hz. Where the
    quarter resolves the bands (every section of 3.36 s or more at 50 Hz, the 20 s default
    among them) the segment is the quarter, as before."""
    width = narrowest_band_hz(fs, bands)
    if width <= 0:
        return None
    need = int(np.ceil(fs / width - 1e-9))
    nper = max(quarter_segment(n), need)
    return nper if nper <= n else None


def quarter_segment(n: int) -> int:
    """The Welch segment of :func:`band_rms` before it followed the band edges: a quarter
    of the record, at least 32 samples (the whole record if shorter)."""
    return int(min(n, max(32, n // 4)))


def bands_widened(n: int, fs: float) -> bool:
    """Whether sections of ``n`` samples at ``fs`` take a longer segment
    (:func:`band_segment`) than the quarter of the record they took before it followed the
    band edges: their band statistics changed."""
    return band_segment(n, fs) not in (None, quarter_segment(n))


def check_band_resolution(cond, section_s: float) -> None:
    """A one-line error naming ``section_s`` and the shortest section whose band RMS
    resolves every band of :data:`BANDS_HZ` (:func:`band_segment`) at the sampling rate of
    the condition ``cond`` (a :class:`~railsusp.working_condition.WorkingCondition`), unless
    its sections of ``section_s`` do; at a rate at which a band lies wholly above 0.45 of
    it, naming the rate instead. Sections that resolved no line in the lowest band gave its
    statistic one constant value in every case (sbi warned of constant dimensions, and the
    synthetic likelihood's scatter factor of their sections reached 1e21, its posterior
    the prior reported calibrated). At 50 Hz every section of 1 s or more resolves them."""
    check_sections_resolve(
        cond,
        section_s,
        lambda n, fs: band_segment(n, fs) is not None,
        BANDS_HZ,
        "the band RMS from {top:g} Hz lies above 0.45 times the rate",
        "the frequency bands of the summary ({width:.3g} Hz the narrowest) are resolved by "
        "sections",
    )


def check_sections_resolve(
    cond,
    section_s: float,
    resolves,
    bands,
    above: str,
    needs: str,
    other: str = "",
    step_bound: bool = True,
) -> None:
    """The one-line refusal of :func:`check_band_resolution` and of the third-octave
    family's (:mod:`railsusp.estimate.posterior_band_resolution`), for bands ``bands`` that
    sections of ``n`` samples at ``fs`` resolve where ``resolves(n, fs)``: nothing where
    sections of ``section_s`` of ``cond`` do; where a band lies wholly above 0.45 of the
    rate, the rate named (``above``: its words, with ``{top}`` the band's lower edge, and
    ``other`` what else is accepted); else ``section_s`` and the shortest section that does
    (``needs``: the words before "of at least", with ``{width}`` the narrowest band;
    ``step_bound``: no section shorter than one over that width resolves them, where the
    rule is a frequency step at most the band, the search's start)."""
    from railsusp.errors import RailsuspInputError

    def resolved(seconds: float) -> bool:
        c = cond.with_duration(seconds)  # its samples, at the rate they round to
        return resolves(c.n_steps, 1.0 / c.sample_interval)

    if resolved(section_s):
        return
    fs = 1.0 / cond.sample_interval
    width = narrowest_band_hz(fs, bands)
    if width <= 0:
        top = max(lo for lo, _ in bands)
        raise RailsuspInputError(
            f"condition {cond.name!r}: sampled at {fs:.4g} Hz, {above.format(top=top)}; "
            f"accepted conditions sampled at more than {top / 0.45:.4g} Hz (n_steps / "
            f"duration_s){other}"
        )
    least = max(section_s, np.ceil(fs / width - 1e-9) / fs) if step_bound else section_s
    least = float(np.ceil(least * 100 - 1e-6) / 100)  # in steps of 0.01 s
    while least < 600.0 and not resolved(least):  # the rate moves as the samples round
        least = round(least + 0.01, 2)
    raise RailsuspInputError(
        f"section_s = {section_s:g}: at the {fs:.4g} Hz of condition {cond.name!r} "
        f"{needs.format(width=width)} of at least {least:g} s; accepted {least:g} to 600"
    )


def half_segment(n: int, segment_fraction: float = 0.5) -> int:
    """The Welch segment of :func:`~railsusp.estimate.statistic_families.log_band_rms`
    before it followed the band edges: ``segment_fraction`` of the record, at least 32
    samples (the whole record if shorter)."""
    return int(min(n, max(32, round(segment_fraction * n))))


def holds_a_line(nper: int, fs: float, bands) -> bool:
    """Whether a Welch spectrum of ``nper``-sample segments at ``fs`` has a line (as
    :func:`scipy.signal.welch` places them) in every one of ``bands``, each band's upper
    edge capped at 0.45 ``fs`` as :func:`~railsusp.estimate.statistic_families.
    log_band_rms` caps it."""
    f = rfftfreq(nper, 1.0 / fs)
    return all(np.any((f >= lo) & (f < min(hi, 0.45 * fs))) for lo, hi in bands)


@lru_cache(maxsize=4096)
def line_segment(n: int, fs: float, bands, segment_fraction: float = 0.5) -> int | None:
    """The Welch segment (samples) of :func:`~railsusp.estimate.statistic_families.
    log_band_rms` for a record of ``n`` samples at ``fs`` in ``bands`` (a tuple of (low,
    high) pairs, Hz): ``segment_fraction`` of the record (:func:`half_segment`) where every
    band holds a line of its spectrum (:func:`holds_a_line`), else the shortest longer
    segment, up to the whole record, at which every band does. None where none does: the
    record is too short (or a band lies above the rate's cap) to resolve the bands.

    Half the record alone left the narrowest third-octave bands (0.3-0.38 Hz is 0.078 Hz
    wide) without a line in many sections: at 50 Hz all 18 were resolved only from 16.78 to
    20.02 s and from 21.18 s on (the 20 s default by luck), and a band without a line read
    the floor in every case. Where half the record resolves them the segment is that half,
    as before; at 50 Hz sections of 8.4 s (420 samples) or more are resolved."""
    start = half_segment(n, segment_fraction)
    for nper in range(start, n + 1):
        if holds_a_line(nper, fs, bands):
            return nper
    return None


def band_rms(x: np.ndarray, fs: float, bands=BANDS_HZ) -> np.ndarray:
    """RMS (units of ``x``) of the de-meaned ``x`` in each band, from the integral of its
    one-sided Welch power spectral density over the band (Parseval: the sum over all bands
    of the squares is the variance). Segments of :func:`band_segment`: a quarter of the
    record, longer where the bands need it; a record too short to resolve them (whose
    sections the posterior's settings refuse, :func:`check_band_resolution`) is read with
    the quarter, as before."""
    x = np.asarray(x, dtype=float)
    nper = band_segment(x.size, fs, bands) or quarter_segment(x.size)
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
    ``Y_partner``: the other wheel of the same wheelset, for the wheelset's lateral force
    ``sumY`` (:func:`wheelset_force`); None leaves it out.

    Y/Q is the quotient of the instantaneous forces, low-passed and averaged over 2 m as
    the forces are (EN 14363's (Y/Q)2m), but only where Q exceeds :data:`UNLOADED_KN`: an
    unloaded wheel has no quotient (as :attr:`railsusp.vehicle.simulation_result.SimulationResult.
    derailment_quotient`), and Y over a floor of 1 kN there gave tens of units that set
    the 99.85 % value of any section in which a wheel lifted. Its unloaded samples are
    left out of the 2 m means (:func:`en14363_percentiles`)."""
    Y = np.asarray(Y, dtype=float)
    Q = np.asarray(Q, dtype=float)
    loaded = Q > UNLOADED_KN
    yq = np.where(loaded, Y / np.where(loaded, Q, 1.0), np.nan)
    parts = [en14363_percentiles(c, fs, speed_ms) for c in (Y, Q)]
    parts.append(en14363_percentiles(yq, fs, speed_ms, defined=loaded))
    if Y_partner is not None:
        parts.append(en14363_percentiles(wheelset_force(Y, Y_partner), fs, speed_ms))
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
