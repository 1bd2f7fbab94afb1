"""Measured wheel-rail force recordings: the documented file format, a validating reader,
resampling to the pipeline's rate, and synthetic "field" recordings from hidden parameters.

Format (docs/data-format.md): a table (``NAME.csv`` or ``NAME.parquet``) with a ``time_s``
column (or ``distance_m`` with a ``speed_kmh`` column or metadata speed) and, per measured
wheel, ``Y_<wheel>_kN`` and ``Q_<wheel>_kN`` (wheels w1L .. w4R); optional
``curvature_1_per_km``, ``cant_mm``, ``grade_permille``. Metadata in a JSON sidecar
``NAME.json``: format tag, wagon, wheels, sampling rate, working condition, filter bandwidth.

The reader reports every problem of a file at once, naming file, column and row, in a
:class:`RecordingError`; short NaN gaps are interpolated with a warning.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.signal import butter, resample_poly, sosfiltfilt

from railsusp.conditions import WorkingCondition, get_condition, make_condition
from railsusp.errors import RailsuspInputError, did_you_mean
from railsusp.store import write_json, write_parquet
from railsusp.vehicle.layout import WHEEL_NAMES
from railsusp.vehicle.track import (
    read_track_geometry,
    with_measurement_error,
    write_track_geometry,
)

FORMAT = "railsusp-recording/1"
#: physical bounds for a loaded 25 t axle-load wagon (kN)
MAX_LATERAL_KN = 300.0
MAX_VERTICAL_KN = 600.0
#: NaN gaps up to this many samples are interpolated (with a warning); longer are rejected
MAX_GAP_SAMPLES = 5


class RecordingError(RailsuspInputError):
    """A recording that cannot be used; ``problems`` lists every issue found."""

    def __init__(self, path: str | Path, problems: list[str]):
        self.path = str(path)
        self.problems = problems
        super().__init__(f"{path}: {len(problems)} problem(s): " + "; ".join(problems))


class SimulationFailedError(RailsuspInputError):
    """A simulation that a recording was to be made of stopped (see its reason)."""


@dataclass
class Recording:
    """One instrumented-wheelset recording in one working condition (SI time, kN forces)."""

    time: np.ndarray
    Y: dict[str, np.ndarray]
    Q: dict[str, np.ndarray]
    condition: WorkingCondition
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def wheels(self) -> tuple[str, ...]:
        return tuple(self.Y)

    @property
    def sampling_rate(self) -> float:
        return 1.0 / float(np.median(np.diff(self.time)))

    def forces(self) -> np.ndarray:
        """(T, 2) lateral and vertical force of the first measured wheel, kN."""
        w = self.wheels[0]
        return np.stack([self.Y[w], self.Q[w]], axis=1)

    def to_dataframe(self) -> pd.DataFrame:
        cols = {"time_s": self.time}
        for w in self.wheels:
            cols[f"Y_{w}_kN"] = self.Y[w]
            cols[f"Q_{w}_kN"] = self.Q[w]
        return pd.DataFrame(cols)

    def write(self, path: str | Path, fmt: str = "csv") -> Path:
        """Write ``NAME.csv`` (or ``.parquet``) and the ``NAME.json`` sidecar atomically."""
        path = Path(path)
        stem = path.with_suffix("")
        meta = {
            "format": FORMAT,
            "wheels": list(self.wheels),
            "sampling_rate_hz": self.sampling_rate,
            "condition": self.condition.model_dump(),
            **self.meta,
        }
        if fmt == "parquet":
            table_path = write_parquet(stem.with_suffix(".parquet"), self.to_dataframe())
        elif fmt == "csv":
            table_path = stem.with_suffix(".csv")
            from railsusp.store import atomic_write_bytes

            atomic_write_bytes(
                table_path, self.to_dataframe().to_csv(index=False, float_format="%.6g").encode()
            )
        else:
            raise ValueError(f"format {fmt!r}: accepted csv or parquet")
        write_json(stem.with_suffix(".json"), meta)
        return table_path

    def resampled(self, rate_hz: float) -> Recording:
        """The recording at another rate: zero-phase anti-alias filter, polyphase resampling
        (scipy ``resample_poly``) on a uniform time base."""
        from fractions import Fraction

        src = self.sampling_rate
        frac = Fraction(rate_hz / src).limit_denominator(1000)
        up, down = frac.numerator, frac.denominator

        def conv(x):
            return resample_poly(x, up, down)

        n = len(conv(self.time * 0.0))
        t = self.time[0] + np.arange(n) / rate_hz
        return Recording(
            t,
            {w: conv(v) for w, v in self.Y.items()},
            {w: conv(v) for w, v in self.Q.items()},
            self.condition,
            {**self.meta, "resampled_from_hz": src},
        )


def read_recording(path: str | Path, *, min_rate_hz: float = 50.0) -> Recording:
    """Read and validate a recording; raise :class:`RecordingError` listing every problem.

    Checks: sidecar present and of this format; time column present, numeric, strictly
    increasing, sampling rate at least ``min_rate_hz`` (the pipeline's output rate); force
    columns named as documented (close misspellings are pointed out), numeric; NaN gaps up to
    MAX_GAP_SAMPLES interpolated with a warning, longer ones rejected; Q not negative; forces
    within physical bounds; forces that look like newtons instead of kilonewtons.
    """
    path = Path(path)
    problems: list[str] = []
    notes: list[str] = []  # warnings, given only for a usable file
    table_path = next(
        (
            p
            for p in (path, path.with_suffix(".csv"), path.with_suffix(".parquet"))
            if p.is_file() and p.suffix in (".csv", ".parquet")
        ),
        None,
    )
    if table_path is None:
        raise RecordingError(path, ["no .csv or .parquet table found"])
    side = table_path.with_suffix(".json")
    meta: dict[str, Any] = {}
    if not side.is_file():
        problems.append(f"metadata sidecar {side.name} missing")
    else:
        try:
            meta = json.loads(side.read_text("utf-8"))
        except json.JSONDecodeError as exc:
            problems.append(f"{side.name}: not valid JSON ({exc.msg}, line {exc.lineno})")
        if meta and meta.get("format") != FORMAT:
            problems.append(f"{side.name}: format {meta.get('format')!r}, expected {FORMAT!r}")
    try:
        df = (
            pd.read_parquet(table_path)
            if table_path.suffix == ".parquet"
            else pd.read_csv(table_path, dtype=str, keep_default_na=False)
        )
    except Exception as exc:
        raise RecordingError(table_path, [f"cannot read the table ({exc})"]) from None
    cols = list(df.columns)
    known = [
        "time_s",
        "distance_m",
        "speed_kmh",
        "curvature_1_per_km",
        "cant_mm",
        "grade_permille",
        *(f"{f}_{w}_kN" for w in WHEEL_NAMES for f in ("Y", "Q")),
    ]
    for c in cols:
        if c not in known:
            problems.append(f"column {c!r} not recognised{did_you_mean(c, known)}")

    def numeric(col: str) -> np.ndarray:
        raw = df[col]
        vals = pd.to_numeric(raw.replace("", np.nan), errors="coerce")
        bad = vals.isna() & ~(
            raw.isna()
            | (raw.astype(str).str.strip() == "")
            | (raw.astype(str).str.lower() == "nan")
        )
        for i in np.flatnonzero(bad.to_numpy())[:5]:
            problems.append(f"column {col!r}, row {i + 2}: {raw.iloc[i]!r} is not a number")
        return vals.to_numpy(dtype=float)

    time = None
    if "time_s" in cols:
        time = numeric("time_s")
    elif "distance_m" in cols:
        speed = (
            numeric("speed_kmh") / 3.6
            if "speed_kmh" in cols
            else np.full(len(df), meta.get("condition", {}).get("speed_kmh", np.nan) / 3.6)
        )
        time = numeric("distance_m") / speed
    else:
        problems.append(f"no time_s (or distance_m) column; columns are {cols}")
    if time is not None and len(time) > 1:
        d = np.diff(time)
        bad = np.flatnonzero(~(d > 0))
        if bad.size:
            problems.append(
                f"time not strictly increasing at row {bad[0] + 3} ({bad.size} place(s))"
            )
        elif np.median(d) > 0 and 1.0 / np.median(d) < min_rate_hz * (1.0 - 1e-6):
            problems.append(
                f"sampling rate {1.0 / np.median(d):.1f} Hz below the "
                f"{min_rate_hz:g} Hz the pipeline needs"
            )
    wheels = [w for w in WHEEL_NAMES if f"Y_{w}_kN" in cols or f"Q_{w}_kN" in cols]
    if not wheels:
        problems.append("no force columns (Y_<wheel>_kN, Q_<wheel>_kN, wheel w1L..w4R)")
    Y: dict[str, np.ndarray] = {}
    Q: dict[str, np.ndarray] = {}
    for w in wheels:
        for f, store, limit in (("Y", Y, MAX_LATERAL_KN), ("Q", Q, MAX_VERTICAL_KN)):
            col = f"{f}_{w}_kN"
            if col not in cols:
                problems.append(f"wheel {w}: column {col!r} missing")
                continue
            x = numeric(col)
            x = _fill_gaps(x, col, problems, notes)
            finite = x[np.isfinite(x)]
            if finite.size and np.median(np.abs(finite)) > 1000.0:
                problems.append(
                    f"column {col!r}: median {np.median(np.abs(finite)):.0f} looks "
                    f"like newtons, the format is kN"
                )
            elif finite.size and np.abs(finite).max() > limit:
                i = int(np.nanargmax(np.abs(x)))
                problems.append(
                    f"column {col!r}, row {i + 2}: {x[i]:.1f} kN beyond the "
                    f"physical bound {limit:g} kN"
                )
            if f == "Q" and finite.size and finite.min() < 0:
                i = int(np.nanargmin(x))
                problems.append(
                    f"column {col!r}, row {i + 2}: negative vertical force {x[i]:.1f} kN"
                )
            store[w] = x
    condition = None
    if meta:
        try:
            cdoc = meta.get("condition")
            if isinstance(cdoc, dict):
                condition = make_condition(cdoc)
            elif isinstance(meta.get("condition_name"), str):
                condition = get_condition(meta["condition_name"])
            else:
                problems.append(f"{side.name}: no 'condition' table or 'condition_name'")
        except RailsuspInputError as exc:
            problems.append(f"{side.name}: {exc}")
    if condition is not None and condition.track_geometry is not None:
        condition = _resolve_track(condition, table_path.parent, problems)
    if problems:
        raise RecordingError(table_path, problems)
    for note in notes:
        warnings.warn(f"{table_path.name}: {note}", stacklevel=2)
    extra = {k: v for k, v in meta.items() if k not in ("format", "condition", "wheels")}
    return Recording(np.asarray(time), Y, Q, condition, extra)  # type: ignore[arg-type]


def _fill_gaps(x: np.ndarray, col: str, problems: list[str], notes: list[str]) -> np.ndarray:
    nan = ~np.isfinite(x)
    if not nan.any():
        return x
    runs = np.flatnonzero(np.diff(np.concatenate([[0], nan.astype(int), [0]])))
    starts, ends = runs[0::2], runs[1::2]
    long = [(s, e) for s, e in zip(starts, ends, strict=True) if e - s > MAX_GAP_SAMPLES]
    if long:
        s, e = long[0]
        problems.append(
            f"column {col!r}, rows {s + 2}-{e + 1}: gap of {e - s} samples longer "
            f"than {MAX_GAP_SAMPLES}"
        )
        return x
    if nan.all():
        problems.append(f"column {col!r}: no value")
        return x
    idx = np.arange(len(x))
    notes.append(f"column {col!r}: {int(nan.sum())} missing sample(s) interpolated")
    return np.interp(idx, idx[~nan], x[~nan])


def _resolve_track(
    condition: WorkingCondition, folder: Path, problems: list[str]
) -> WorkingCondition:
    """The condition with its track-geometry file resolved against the recording's folder
    (relative names in a sidecar travel with the recording) and checked."""
    path = Path(condition.track_geometry or "")
    if not path.is_absolute():
        path = (folder / path).resolve()
    try:
        read_track_geometry(path)
    except RailsuspInputError as exc:
        problems.append(f"condition.track_geometry: {exc}")
    return condition.with_changes(track_geometry=str(path))


def recording_from_simulation(
    result, wheels: tuple[str, ...] | None = None, set_index: int = 0
) -> Recording:
    """A recording (kN) of the wheels of a simulation result (default: measured wheel); a
    failed simulation (derailment, divergence) is an error naming the reason and time."""
    if not result.ok[set_index]:
        reason = {i: (why, t) for i, why, t in result.failures()}[set_index]
        raise SimulationFailedError(
            f"simulation in condition {result.condition.name!r} failed at {reason[1]:.2f} s: "
            f"{reason[0]}; no recording can be made of it"
        )
    ws = wheels or (WHEEL_NAMES[result.measured_wheel()],)
    Y = {w: result.Y[set_index, WHEEL_NAMES.index(w)] / 1e3 for w in ws}
    Q = {w: result.Q[set_index, WHEEL_NAMES.index(w)] / 1e3 for w in ws}
    return Recording(result.time.copy(), Y, Q, result.condition, {"wagon": result.wagon_name})


def simulated_forces(pset, rec: Recording) -> np.ndarray:
    """(T, 2) forces (kN) the simulator gives for ``pset`` in a recording's condition at its
    first measured wheel, the counterpart of :meth:`Recording.forces`."""
    from railsusp.vehicle.simulate import simulate

    return recording_from_simulation(simulate(pset, rec.condition), rec.wheels[:1]).forces()


def bandwidth_filter(x: np.ndarray, fs: float, bandwidth_hz: float, axis: int = -1) -> np.ndarray:
    """An instrument's bandwidth limit: 4th-order Butterworth low-pass, zero phase (scipy
    ``sosfiltfilt``), cut-off ``bandwidth_hz`` capped at 0.45 of the sampling rate ``fs``."""
    sos = butter(4, min(bandwidth_hz, 0.45 * fs), fs=fs, output="sos")
    return sosfiltfilt(sos, x, axis=axis)


def add_sensor_noise(
    rec: Recording, noise: float, seed: int, bandwidth_hz: float = 15.0, gain_error: float = 0.01
) -> Recording:
    """Instrumented-wheelset errors: a gain error (normal, sd ``gain_error``) per channel, a
    bandwidth limit (4th-order zero-phase low-pass), and white noise of ``noise`` times the
    channel's RMS."""
    rng = np.random.default_rng(seed)
    fs = rec.sampling_rate

    def corrupt(x: np.ndarray) -> np.ndarray:
        y = bandwidth_filter(x, fs, bandwidth_hz) * (1.0 + gain_error * rng.standard_normal())
        return y + noise * np.sqrt(np.mean(x**2)) * rng.standard_normal(len(x))

    return Recording(
        rec.time.copy(),
        {w: corrupt(v) for w, v in rec.Y.items()},
        {w: np.maximum(corrupt(v), 0.0) for w, v in rec.Q.items()},
        rec.condition,
        {**rec.meta, "filter_bandwidth_hz": bandwidth_hz, "synthetic": True},
    )


def synthesise_field(
    truth,
    conditions: list[WorkingCondition],
    out: str | Path,
    *,
    seed: int = 7,
    noise: float = 0.03,
    track_seed_offset: int = 1000,
    fmt: str = "csv",
    duration_s: float | None = None,
    with_track: bool = False,
    track_noise_mm: float = 0.0,
    stated_accuracy_mm: float | None = None,
) -> Path:
    """Synthetic field recordings of the ``truth`` ParameterSet with hidden truth.

    Each condition is simulated on a track realisation different from the design track
    (seed + ``track_seed_offset``), sensor noise is added, the recordings are written in the
    documented format and listed in ``index.json``; the truth goes to ``truth.json``, a file
    the estimator never reads. ``duration_s`` records longer (or shorter) than the
    condition's duration at the same sampling rate: real runs span kilometres of track, and
    the track-realisation scatter of a statistic falls with the recorded length.

    ``with_track`` also writes the track the truth ran on as measured track geometry
    (``NAME.track.csv``, named by the recording's condition), as a track recording car run
    with the instrumented wagon would give, with a measurement error of ``track_noise_mm``
    (RMS, mm, within the measured wavelengths) on each component. The recordings state the
    geometry's accuracy (``track_accuracy_mm``) as ``stated_accuracy_mm``, by default the
    true ``track_noise_mm``: an engineer knows the specification of the geometry car.
    """
    from railsusp.vehicle.setup import section_irregularities
    from railsusp.vehicle.simulate import simulate
    from railsusp.vehicle.wagon import load_wagon

    if not 0.0 <= track_noise_mm <= 10.0:
        raise RailsuspInputError(f"track_noise_mm = {track_noise_mm:g}: accepted 0 to 10 mm")
    out = Path(out)
    names = []
    for i, cond in enumerate(conditions):
        if duration_s is not None:
            cond = cond.with_duration(duration_s)
        field_cond = cond.with_changes(seed=cond.seed + track_seed_offset)
        rec = recording_from_simulation(simulate(truth, field_cond))
        rec = add_sensor_noise(rec, noise, seed + i)
        rec.condition = cond  # the engineer knows the condition, not the track realisation
        if with_track:
            irr = section_irregularities(field_cond, [field_cond.seed], load_wagon())
            assert irr is not None, "with_track needs a condition with irregularities"
            if track_noise_mm:
                rng = np.random.default_rng([seed, i, 1])
                irr = with_measurement_error(irr, track_noise_mm * 1e-3, cond.wavelength_min_m, rng)
            track_name = f"{cond.name}.track.csv"
            write_track_geometry(out / track_name, irr, origin_m=cond.lead_in_m)
            rec.condition = cond.with_changes(
                track_geometry=track_name,
                track_accuracy_mm=track_noise_mm
                if stated_accuracy_mm is None
                else stated_accuracy_mm,
            )
        rec.meta["wagon"] = rec.meta.get("wagon", "")
        rec.write(out / cond.name, fmt)
        names.append(cond.name + (".csv" if fmt == "csv" else ".parquet"))
    write_json(
        out / "index.json", {"format": FORMAT, "recordings": names, "noise": noise, "seed": seed}
    )
    write_json(
        out / "truth.json",
        {
            "parameters_display": truth.to_display(),
            "note": "hidden truth: the estimator must not read this",
            "track_seed_offset": track_seed_offset,
        },
    )
    return out


def read_field(folder: str | Path) -> list[Recording]:
    """All recordings listed in a field folder's ``index.json`` (never ``truth.json``)."""
    folder = Path(folder)
    index = folder / "index.json"
    if not index.is_file():
        raise RailsuspInputError(f"{folder}: no index.json listing the recordings")
    doc = json.loads(index.read_text("utf-8"))
    return [read_recording(folder / name) for name in doc.get("recordings", [])]


def conditions_from(spec: str) -> list[WorkingCondition]:
    """Conditions named by ``spec``: standard names or a TOML file (as
    :func:`~railsusp.conditions.resolve_conditions`), or a field folder (``index.json``), whose
    recordings' conditions are taken with their measured track geometry, so that a campaign
    can run on the track the recordings were made on."""
    from railsusp.conditions import resolve_conditions

    folder = Path(spec)
    if folder.is_dir():
        if not (folder / "index.json").is_file():
            raise RailsuspInputError(f"conditions {spec!r}: a folder without index.json")
        return [rec.condition for rec in read_field(folder)]
    return resolve_conditions(spec)
