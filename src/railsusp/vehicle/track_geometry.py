"""Measured track geometry and the irregularities a simulation runs on.

A track-geometry file (docs/data-format.md) holds the four irregularity components a
track-recording car measured, against the distance from the leading wheelset's position at
the recording start: :func:`read_track_geometry` checks it (every problem at once, naming
file, column and row) and :func:`write_track_geometry` writes one atomically.
:func:`measured_irregularities` fades a file's geometry in where it starts inside the
simulated span; :func:`irregularities_for` gives a condition's section its irregularities,
synthesised from its FRA class and seed (:mod:`railsusp.vehicle.track`) or measured;
:func:`with_measurement_error` and :func:`accurate_wavelength_m` model what a recording car
gets wrong: the synthetic recordings' geometry error (:mod:`railsusp.measured.synthetic`),
the refinement's geometry-error draws (:mod:`railsusp.estimate.output_error`) and the
time-aligned comparison's band (:mod:`railsusp.estimate.comparison`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from functools import lru_cache
from itertools import pairwise
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError, did_you_mean
from railsusp.store import file_hash_cached
from railsusp.vehicle.track import COMPONENTS, Irregularities, smoothstep, synthesise

#: Columns of a track-geometry file (docs/data-format.md): distance from the leading
#: wheelset's position at the recording start, then the four irregularity components.
TRACK_COLUMNS: tuple[str, ...] = (
    "distance_m",
    "vertical_mm",
    "alignment_mm",
    "crosslevel_mm",
    "gauge_mm",
)
#: largest accepted |irregularity|, mm (Class 1 track stays well inside)
MAX_IRREGULARITY_MM = 100.0
#: largest accepted sample spacing, m (half the shortest 1 m wavelength)
MAX_TRACK_SPACING_M = 0.5
#: measured geometry is faded in over this length where it starts inside the simulated span, m
TRACK_TAPER_M = 10.0
#: a condition on measured geometry needs a lead-in of the axle spread plus this, m: the
#: simulator's fade-in from rest (vehicle.track_grid.MIN_FADE_IN_M) ends before the record
MIN_LEAD_IN_BEYOND_SPREAD_M = 5.0


def write_track_geometry(path: str | Path, irr: Irregularities, origin_m: float = 0.0) -> Path:
    """Write the first realisation of ``irr`` as a track-geometry file (CSV or Parquet,
    atomically), distances shifted by ``-origin_m`` (section -> recording coordinates)."""
    from railsusp.store import atomic_write_bytes, write_parquet

    path = Path(path)
    table = pd.DataFrame(
        {
            "distance_m": irr.s - origin_m,
            **{f"{c}_mm": irr.component(c)[0] * 1e3 for c in COMPONENTS},
        }
    )
    if path.suffix.lower() == ".parquet":
        return write_parquet(path, table)
    if path.suffix.lower() != ".csv":
        raise ValueError(f"track geometry file {path}: accepted suffixes .csv, .parquet")
    atomic_write_bytes(path, table.to_csv(index=False, float_format="%.9g").encode())
    return path


def read_track_geometry(path: str | Path) -> Irregularities:
    """Read and check a track-geometry file; distances as in the file (recording frame).

    Every problem is reported at once, naming the file, column and row: missing columns,
    non-numeric or missing cells, distances not strictly increasing or spaced over
    :data:`MAX_TRACK_SPACING_M`, magnitudes over :data:`MAX_IRREGULARITY_MM` and values that
    look like metres rather than millimetres.
    """
    p = Path(path)
    if not p.is_file():
        raise RailsuspInputError(f"track geometry file {p} not found")
    stat = p.stat()
    return _read_track_geometry(str(p.resolve()), stat.st_mtime_ns, stat.st_size)


def geometry_digests(conditions: Sequence[WorkingCondition]) -> dict[str, str]:
    """The content hash (SHA-256) of each measured track-geometry file the ``conditions``
    name, by path as named ("missing" for a file not there): what a campaign's and a run's
    stage hashes hold beside the path, so that a file edited in place is simulated again
    instead of its old results being reused (the interrupt/resume audit of stop 60). Empty
    without measured geometry (the hashes of such campaigns and runs are as before)."""
    out = {}
    for c in conditions:
        if c.track_geometry is None or c.track_geometry in out:
            continue
        p = Path(c.track_geometry)
        out[c.track_geometry] = file_hash_cached(p) if p.is_file() else "missing"
    return out


@lru_cache(maxsize=16)
def _read_track_geometry(path: str, _mtime_ns: int, _size: int) -> Irregularities:
    problems: list[str] = []
    try:
        table = pd.read_parquet(path) if path.lower().endswith(".parquet") else pd.read_csv(path)
    except Exception as exc:  # any parser failure is a bad file
        raise RailsuspInputError(f"track geometry file {path}: cannot be read ({exc})") from None
    missing = [c for c in TRACK_COLUMNS if c not in table.columns]
    for c in missing:
        problems.append(f"missing column {c!r}" + did_you_mean(c, list(map(str, table.columns))))
    if missing:
        raise RailsuspInputError(f"track geometry file {path}: " + "; ".join(problems))
    if len(table) < 2:
        raise RailsuspInputError(f"track geometry file {path}: fewer than 2 rows")
    cols: dict[str, np.ndarray] = {}
    for c in TRACK_COLUMNS:
        x = pd.to_numeric(table[c], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            problems.append(
                f"column {c!r}: {bad.size} missing or non-numeric cell(s), first at row "
                f"{int(bad[0]) + 2}"
            )
        cols[c] = x
    dist = cols["distance_m"]
    step = np.diff(dist)
    if np.any(~(step > 0)):
        row = int(np.flatnonzero(~(step > 0))[0]) + 3
        problems.append(f"column 'distance_m' is not strictly increasing (row {row})")
    elif step.max() > MAX_TRACK_SPACING_M * (1.0 + 1e-9) + 1e-9 * np.max(np.abs(dist)):
        # (the rounding of distances written to a few decimals: 0.5 m as 0.50000000001)
        row = int(np.argmax(step)) + 3
        problems.append(
            f"column 'distance_m': spacing {step.max():.3g} m at row {row} exceeds "
            f"{MAX_TRACK_SPACING_M} m (short wavelengths would be lost)"
        )
    values = np.stack([cols[f"{c}_mm"] for c in COMPONENTS])
    for c in COMPONENTS:
        x = cols[f"{c}_mm"]
        over = np.flatnonzero(np.abs(x) > MAX_IRREGULARITY_MM)
        if over.size:
            problems.append(
                f"column '{c}_mm': |value| {np.nanmax(np.abs(x)):.4g} mm at row "
                f"{int(over[0]) + 2} exceeds {MAX_IRREGULARITY_MM:g} mm"
            )
    if np.all(np.isfinite(values)) and np.max(np.abs(values)) < 0.1:
        problems.append(
            "all irregularities are below 0.1 mm: the values look like metres, give millimetres"
        )
    else:  # one component in metres among millimetres (a column left unconverted)
        for c in COMPONENTS:
            x = np.abs(cols[f"{c}_mm"])
            if np.all(np.isfinite(x)) and 0.0 < np.max(x) < 0.1:
                problems.append(
                    f"column '{c}_mm': every value below 0.1 mm while other components reach "
                    f"{np.nanmax(np.abs(values)):.3g} mm: it looks like metres, give millimetres "
                    "(a component not measured is all zeros)"
                )
    if problems:
        raise RailsuspInputError(f"track geometry file {path}: " + "; ".join(problems))
    return Irregularities(
        s=dist,
        **{c: cols[f"{c}_mm"][None, :] * 1e-3 for c in COMPONENTS},
        track_class=None,
        wavelength_min=float(2.0 * np.median(step)),
        wavelength_max=float(dist[-1] - dist[0]),
        seeds=(),
        source=path,
    )


def same_measured_track(a: WorkingCondition, b: WorkingCondition) -> bool:
    """Whether two conditions name the same measured track: one file, or two files whose rows
    agree once each condition's ``track_offset_m`` is applied (distances to 1 um,
    irregularities to 1e-6 mm: a file written back at nine significant digits is the same
    track). A recording's copy of its condition's file (the synthetic field's) is that
    track; an unreadable file is no match."""
    if a.track_geometry is None or b.track_geometry is None:
        return False
    if Path(a.track_geometry).resolve() == Path(b.track_geometry).resolve():
        return a.track_offset_m == b.track_offset_m
    try:
        ia, ib = read_track_geometry(a.track_geometry), read_track_geometry(b.track_geometry)
    except (RailsuspInputError, OSError, ValueError):
        return False
    if ia.s.shape != ib.s.shape:
        return False
    if not np.allclose(ia.s + a.track_offset_m, ib.s + b.track_offset_m, rtol=0.0, atol=1e-6):
        return False
    return all(
        np.allclose(ia.component(c), ib.component(c), rtol=0.0, atol=1e-9) for c in COMPONENTS
    )


def check_coverage(irr: Irregularities, condition: WorkingCondition, axle_spread_m: float) -> None:
    """Refuse (one line) measured irregularities ``irr`` of ``condition``'s
    ``track_geometry`` that do not cover the recorded stretch under every axle: from
    ``axle_spread_m`` plus the fade-in length behind the recording start (the file's
    distances shifted by ``track_offset_m``) to the end of the record."""
    least = axle_spread_m + MIN_LEAD_IN_BEYOND_SPREAD_M
    if condition.lead_in_m < least - 1e-9:
        raise RailsuspInputError(
            f"condition {condition.name!r}: lead_in_m = {condition.lead_in_m:g} m with measured "
            f"track geometry; accepted at least {least:.4g} m (the wagon's axle spread "
            f"{axle_spread_m:.4g} m plus the {MIN_LEAD_IN_BEYOND_SPREAD_M:g} m over which the "
            "simulator fades the track in from rest: with less, the record's first metres "
            "run on faded geometry)"
        )
    shift = condition.track_offset_m
    first, last = float(irr.s[0]) + shift, float(irr.s[-1]) + shift
    need_from = -(axle_spread_m + TRACK_TAPER_M)
    need_to = condition.record_length_m
    if first > need_from + 1e-9 or last < need_to - 1e-9:
        raise RailsuspInputError(
            f"track geometry file {condition.track_geometry} covers distance_m {first:g} to "
            f"{last:g} m (with track_offset_m {shift:g}); condition {condition.name!r} needs "
            f"at least {need_from:g} to {need_to:g} m (the wagon's axles over the "
            f"{condition.duration_s:g} s record)"
        )


def measured_irregularities(condition: WorkingCondition, axle_spread_m: float) -> Irregularities:
    """A condition's measured irregularities in section coordinates (recording start at
    ``lead_in_m``; the file's distances shifted by ``track_offset_m``), faded in over
    :data:`TRACK_TAPER_M` from the file's first point.

    The file must cover the recorded stretch under every axle: from ``axle_spread_m`` plus the
    fade-in length behind the recording start to the end of the record.
    """
    assert condition.track_geometry is not None
    irr = read_track_geometry(condition.track_geometry)
    check_coverage(irr, condition, axle_spread_m)
    shift = condition.track_offset_m
    fade = smoothstep((irr.s - irr.s[0]) / TRACK_TAPER_M)
    return Irregularities(
        s=irr.s + shift + condition.lead_in_m,
        **{c: irr.component(c) * fade for c in COMPONENTS},
        track_class=condition.irregularity_class,
        wavelength_min=irr.wavelength_min,
        wavelength_max=irr.wavelength_max,
        seeds=(),
        source=irr.source,
    )


#: Welch segment of a geometry record's PSD estimate, m (:func:`welch_segment`)
WELCH_SEGMENT_M = 128.0
#: power ratio of measured geometry to its measurement error above which a wavelength of the
#: geometry counts as accurate: an error amplitude below about 30 % of the geometry's
GEOMETRY_SNR_MIN = 10.0
#: components that drive each force channel: lateral (alignment, gauge, and cross-level
#: through the roll and gravity terms) and vertical (profile and cross-level)
CHANNEL_COMPONENTS: dict[str, tuple[str, ...]] = {
    "Y": ("alignment", "gauge", "crosslevel"),
    "Q": ("vertical", "crosslevel"),
}


def accurate_wavelength_m(
    irr: Irregularities,
    accuracy_m: float,
    wavelength_min_m: float,
    snr_min: float | None = None,
) -> dict[str, float]:
    """Per component, the shortest wavelength (m) down to which measured track geometry is
    accurate, given the RMS measurement error ``accuracy_m`` of each component.

    The error is taken as white within the measured band, wavelengths from
    ``wavelength_min_m`` up (one-sided PSD σ² λ_min), as the error of a track recording
    system lies within its band (EN 13848-2 states its accuracy per wavelength band). The
    geometry's PSD is a Welch estimate over 128 m segments, averaged in sixth-octave bands
    from the longest wavelength down; the first band whose geometry-to-error power ratio
    falls below ``snr_min`` (default :data:`GEOMETRY_SNR_MIN`) ends the accurate band, at its
    long-wavelength edge.
    Irregularity PSDs fall as Ω^-2 to Ω^-4, so short wavelengths are the first lost.
    """
    from scipy.signal import welch

    if not accuracy_m > 0.0:
        raise ValueError(f"accuracy_m = {accuracy_m:g}: give a positive RMS error")
    dx = float(np.median(np.diff(irr.s)))
    n = irr.s.size
    nperseg = welch_segment(n, dx)
    error_psd = accuracy_m**2 * wavelength_min_m
    snr_min = GEOMETRY_SNR_MIN if snr_min is None else snr_min
    out = {}
    for c in COMPONENTS:
        k, psd = welch(irr.component(c)[0], 1.0 / dx, nperseg=nperseg)
        edges = 2.0 ** np.arange(np.log2(k[1]), np.log2(1.0 / wavelength_min_m), 1.0 / 6.0)
        lam = wavelength_min_m
        for a, b in pairwise(edges):
            inside = (k >= a) & (k < b)
            if inside.any() and psd[inside].mean() / error_psd - 1.0 < snr_min:
                lam = 1.0 / a
                break
        out[c] = float(lam)
    return out


def welch_segment(n: int, dx: float) -> int:
    """Samples per Welch segment of a geometry record's PSD estimate (``n`` samples at
    spacing ``dx``): the power of two covering :data:`WELCH_SEGMENT_M`, at most the record."""
    return int(min(n, 2 ** np.ceil(np.log2(WELCH_SEGMENT_M / dx))))


def measurement_error_filter(wavelength_min_m: float, dx: float) -> np.ndarray:
    """Second-order sections of the low-pass that shapes a geometry car's measurement error
    (:func:`with_measurement_error`): 4th-order Butterworth at 1 / ``wavelength_min_m``, at
    most 0.45 of the sampling rate of spacing ``dx``. One design, so that the error's PSD
    the geometry posterior assumes is the error's (:mod:`railsusp.vehicle.geometry_posterior`)."""
    from scipy.signal import butter

    return butter(4, min(1.0 / wavelength_min_m, 0.45 / dx), fs=1.0 / dx, output="sos")


def with_measurement_error(
    irr: Irregularities, rms_m: float, wavelength_min_m: float, rng: np.random.Generator
) -> Irregularities:
    """``irr`` (its first realisation) plus the measurement error that
    :func:`accurate_wavelength_m` assumes: on each component, white noise of RMS ``rms_m``
    low-passed at the shortest measured wavelength (4th-order Butterworth, zero phase), as a
    track recording system's error lies within its band. Unfiltered noise on a fine grid
    would be rail roughness, which no geometry car reports."""
    from scipy.signal import sosfiltfilt

    dx = float(np.median(np.diff(irr.s)))
    sos = measurement_error_filter(wavelength_min_m, dx)
    noisy = {}
    for c in COMPONENTS:
        e = sosfiltfilt(sos, rng.standard_normal(irr.s.size))
        noisy[c] = irr.component(c)[:1] + rms_m * e / np.std(e)
    return replace(irr, **noisy)


def irregularities_for(
    condition: WorkingCondition,
    seeds: int | Sequence[int] | None = None,
    behind: float = 30.0,
    axle_spread_m: float = 0.0,
) -> Irregularities | None:
    """Irregularities covering a condition's section, from ``-behind`` m (trailing axles).

    Synthesised from the condition's class and seed, or, when the condition names a
    ``track_geometry`` file, the measured ones (one realisation whatever the seeds; the file
    must cover the recorded stretch under every axle, ``axle_spread_m`` behind the leading
    one). Returns None for perfect track.
    """
    if condition.track_geometry is not None:
        return measured_irregularities(condition, axle_spread_m)
    if condition.irregularity_class is None:
        return None
    return synthesise(
        condition.section_length_m + behind + 10.0,
        condition.irregularity_class,
        condition.seed if seeds is None else seeds,
        wavelength_min=condition.wavelength_min_m,
        wavelength_max=condition.wavelength_max_m,
        start=-behind,
    )
