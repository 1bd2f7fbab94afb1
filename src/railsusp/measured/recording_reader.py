"""Reading one recording of the field-folder format: its table (CSV or Parquet, on
``time_s``, or along ``distance_m`` put on time over the speed) and its JSON sidecar
(:mod:`railsusp.measured.sidecar`), checked strictly (:mod:`railsusp.measured.checks`):
documented columns, a sound time base at a usable rate, forces in the unit their header
states and within physical bounds, the sidecar's rate and wheels as the table shows them.
Every problem of a file is reported at once, naming file, column and rows, because a field
engineer fixes a recording in one go, not one refusal at a time.
"""

from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np

from railsusp.conditions import RECORDING_MIN_RATE_HZ
from railsusp.errors import RailsuspInputError, did_you_mean
from railsusp.measured.channels import default_map
from railsusp.measured.checks import (
    check_clipped,
    check_finite,
    check_flat,
    check_forces,
    check_time,
    runs,
)
from railsusp.measured.checks import rows as row_range  # (``rows`` names a count below)
from railsusp.measured.raw import read_raw
from railsusp.measured.recording import Recording, RecordingError
from railsusp.measured.sidecar import condition_on_the_table, read_sidecar, sidecar_condition
from railsusp.measured.units import si_factor, split_header
from railsusp.numbers import is_real
from railsusp.vehicle.layout import WHEEL_NAMES
from railsusp.vehicle.setup import axle_spread, static_wheel_load
from railsusp.vehicle.wagon import WagonData, load_wagon

#: the accepted lowest usable sampling rate (read_recording's ``min_rate_hz``), Hz
MIN_RATE_RANGE_HZ = (1.0, 100_000.0)
#: relative disagreement of a sidecar's sampling rate with the data's that is refused
RATE_TOLERANCE = 0.01

_DOCUMENTED = [
    "time_s",
    "distance_m",
    "speed_kmh",
    "curvature_1_per_km",
    "cant_mm",
    "grade_permille",
    *(f"{f}_{w}_kN" for w in WHEEL_NAMES for f in ("Y", "Q")),
]


def read_recording(
    path: str | Path,
    *,
    min_rate_hz: float = RECORDING_MIN_RATE_HZ,
    wheel_load_N: float | None = None,
    wagon: str | Path | WagonData | None = None,
) -> Recording:
    """Read and check a recording of the field-folder format; raise
    :class:`RecordingError` listing every problem (file, column, rows).

    Checks: sidecar present, a JSON object of this format, condition valid (numbers as
    numbers), sampling rate and wheels as the data show them; table readable with at
    least 10 rows; columns documented (close misspellings pointed out; other extra columns
    are noted and left unused); time strictly increasing without jitter or mixed rates, at
    least ``min_rate_hz``; forces in the unit their header states (``Y_w1R_kN``,
    ``Y_w1R [N]``); non-finite values (±inf refused, NaN gaps over 5 samples refused,
    shorter ones interpolated with a warning); all-zero or constant force channels; median
    wheel load against the wagon's static wheel load; physical bounds."""
    lo, hi = MIN_RATE_RANGE_HZ
    if not (is_real(min_rate_hz) and lo <= min_rate_hz <= hi):
        raise RailsuspInputError(f"min_rate_hz = {min_rate_hz!r}: accepted {lo:g} to {hi:g} Hz")
    if wheel_load_N is not None and not (is_real(wheel_load_N) and 1e3 <= wheel_load_N <= 1e6):
        raise RailsuspInputError(
            f"wheel_load_N = {wheel_load_N!r}: accepted a static wheel load of 1000 to "
            "1000000 N, or None (the wagon's)"
        )
    if not isinstance(path, str | os.PathLike):
        raise RailsuspInputError(f"path = {path!r}: a recording's path (str or Path) is needed")
    path = Path(path)
    table_path = next(
        (
            p
            for p in (path, path.with_suffix(".csv"), path.with_suffix(".parquet"))
            if p.is_file() and p.suffix.lower() in (".csv", ".parquet")  # up.CSV as up.csv
        ),
        None,
    )
    if table_path is None:
        what = (
            "a folder, not a recording table"
            if path.is_dir()
            else "no .csv or .parquet table found"
        )
        raise RecordingError(path, [what])
    problems: list[str] = []
    notes: list[str] = []
    meta = read_sidecar(table_path.with_suffix(".json"), problems)
    try:
        raw = _raw(table_path)
    except RailsuspInputError as exc:
        raise RecordingError(
            table_path, [*problems, str(exc).removeprefix(f"recording {table_path}: ")]
        ) from None
    cols = list(raw)
    cmap = default_map([*cols, "time_s"])
    half = sorted(
        {split_header(h)[0][2:] for h in cols if h[:2] in ("Y_", "Q_")} - set(cmap.wheels)
    )
    half = [w for w in half if w in WHEEL_NAMES]  # a wheel with Y or Q only: reported below
    for c in cols:
        base = split_header(c)[0]
        if c in cmap.used() or base in ("distance", "speed", "curvature", "cant", "grade"):
            continue
        if base[2:] in half and base[:2] in ("Y_", "Q_"):
            continue
        same = [o for o in cols if o != c and split_header(o)[0] == base]
        if same and base[:2] in ("Y_", "Q_") and base[2:] in WHEEL_NAMES:
            problems.append(
                f"column {c!r}: the force {base} is given twice (also as {same[0]!r}); "
                "accepted one column per force"
            )
            continue
        hint = did_you_mean(c, _DOCUMENTED)
        if hint or base.startswith(("Y_", "Q_")):
            problems.append(f"column {c!r} not recognised{hint}")
        else:
            notes.append(f"column {c!r} not used")
    t = next(iter(raw.values())).time if raw else np.zeros(0)
    lines = next(iter(raw.values())).first_row if raw else 2  # file lines, for messages
    time_problems = check_time(t, "time_s", lines)
    problems += time_problems
    if not time_problems and 1.0 / np.median(np.diff(t)) < min_rate_hz * (1.0 - 1e-6):
        problems.append(
            f"sampling rate {1.0 / np.median(np.diff(t)):.4g} Hz below the "
            f"{min_rate_hz:g} Hz the pipeline needs"
        )
    for w in half:
        have = {split_header(h)[0][0] for h in cols if split_header(h)[0][2:] == w}
        for f in sorted({"Y", "Q"} - have):
            problems.append(f"wheel {w}: column '{f}_{w}_kN' missing")
    if not cmap.wheels and not half:
        problems.append("no force columns (Y_<wheel>_kN, Q_<wheel>_kN, wheel w1L..w4R)")
    Y: dict[str, np.ndarray] = {}
    Q: dict[str, np.ndarray] = {}
    wagon = load_wagon(wagon)  # the recorded wagon: its static wheel load and axle spread
    wl = static_wheel_load(wagon) if wheel_load_N is None else wheel_load_N
    for w, chans in cmap.wheels.items():
        si = {}
        for f, col in chans.items():
            ch = raw[col]
            try:
                factor = si_factor("force", ch.unit, col)
            except RailsuspInputError as exc:
                problems.append(str(exc).replace("channel", "column", 1))
                continue
            x, p, n = check_finite(ch.values, col, lines)
            problems += p
            notes += n
            problems += check_flat(x, col) + check_clipped(x, col, ch.unit or "")
            si[f] = x * factor
        if len(si) == 2:
            units = (raw[chans["Y"]].unit or "", raw[chans["Q"]].unit or "")
            problems += check_forces(si["Y"], si["Q"], (chans["Y"], chans["Q"]), units, wl, lines)
            Y[w], Q[w] = si["Y"] / 1e3, si["Q"] / 1e3
    problems = [p.replace("channel '", "column '") for p in problems]
    # the table's rate, where its time base is sound: the sidecar's rate and record against it
    rate = 1.0 / float(np.median(np.diff(t))) if not time_problems and t.size > 1 else None
    if meta and rate is not None:
        stated = meta.get("sampling_rate_hz")
        if isinstance(stated, bool) or not isinstance(stated, (int, float, type(None))):
            problems.append(f"sidecar sampling_rate_hz: {stated!r} is not a number")
        elif stated is not None and not (math.isfinite(stated) and stated > 0):
            problems.append(  # NaN compares false with everything: it passed the check below
                f"sidecar sampling_rate_hz: {stated!r}: accepted a positive number, the rate of "
                f"the time column ({rate:.6g} Hz)"
            )
        elif stated is not None and abs(stated / rate - 1.0) > RATE_TOLERANCE:
            problems.append(
                f"sidecar sampling_rate_hz {stated:g} Hz, the time column {rate:.6g} Hz"
            )
        side_wheels = meta.get("wheels")
        if isinstance(side_wheels, list) and cmap.wheels and side_wheels != list(cmap.wheels):
            problems.append(
                f"sidecar wheels {side_wheels}, the table's force columns {list(cmap.wheels)}"
            )
    condition = sidecar_condition(meta, table_path, problems, axle_spread(wagon)) if meta else None
    if condition is not None and rate is not None:
        condition = condition_on_the_table(
            condition, meta, t.size, rate, table_path.with_suffix(".json").name, problems
        )
    if problems:
        raise RecordingError(table_path, problems)
    for note in notes:
        warnings.warn(f"{table_path.name}: {note}", stacklevel=2)
    extra = {k: v for k, v in meta.items() if k not in ("format", "condition", "wheels")}
    return Recording(np.asarray(t), Y, Q, condition, extra)  # type: ignore[arg-type]


def _raw(table_path: Path):
    """The table's channels on its ``time_s`` column, or on ``distance_m`` over the speed."""
    import pandas as pd

    try:
        if table_path.suffix.lower() == ".csv":
            cols = [str(c) for c in pd.read_csv(table_path, nrows=0, encoding="utf-8").columns]
        else:
            cols = [str(c) for c in pd.read_parquet(table_path).columns]
    except Exception as exc:  # pandas and pyarrow raise many types on a damaged file
        raise RailsuspInputError(
            f"recording {table_path}: cannot read the table "
            f"({(str(exc).splitlines() or [type(exc).__name__])[0]})"
        ) from None
    if "time_s" in cols or "distance_m" not in cols:
        return read_raw(table_path, "time_s" if "time_s" in cols else None)
    raw = read_raw(table_path, "distance_m")
    speed = raw.get("speed_kmh")
    if speed is None:
        raise RailsuspInputError(
            f"recording {table_path}: distance_m without a speed_kmh column; give time_s"
        )
    v = speed.values
    still = ~(v > 0)  # NaN too
    if still.any():
        a, b = runs(still)[0]
        raise RailsuspInputError(
            f"recording {table_path}: column 'speed_kmh', {row_range(a, b - 1, speed.first_row)}: "
            f"speed {v[a]:g} km/h; a table along distance_m needs the speed positive in "
            "every row (a stop has no distance to sample it by: give time_s)"
        )
    return _on_time(raw, speed.time, v / 3.6)


def _on_time(raw: dict, distance: np.ndarray, speed: np.ndarray) -> dict:
    """Channels sampled along the track (``distance`` m, at ``speed`` m/s) put on a uniform
    time base: each sample's time is the integral of ds / v from the first (trapezoidal
    mean speed per step), and the channels are interpolated onto the median interval of
    those times. Samples that are uniform in distance are not uniform in time where the
    speed varies (time = distance / speed held only at constant speed). A stretch
    standing or backing up (speed not positive, distance not increasing) is left to the
    time checks, unconverted."""
    step_speed = 0.5 * (speed[1:] + speed[:-1])
    ds = np.diff(distance)
    if ds.size < 2 or not (
        np.all(np.isfinite(step_speed)) and np.all(step_speed > 0) and np.all(ds > 0)
    ):
        t = distance / speed  # as before; the time checks name what is wrong
        for ch in raw.values():
            ch.time = t
        return raw
    t = np.concatenate([[0.0], np.cumsum(ds / step_speed)])
    dt = float(np.median(np.diff(t)))
    uniform = np.arange(0.0, t[-1] + 0.5 * dt, dt)
    uniform = uniform[uniform <= t[-1]]
    sample = np.rint(np.interp(uniform, t, np.arange(t.size))).astype(int)
    for ch in raw.values():
        ch.values = np.interp(uniform, t, ch.values)
        ch.time = uniform
        ch.first_row = ch.first_row + sample  # messages name the file's lines
    return raw
