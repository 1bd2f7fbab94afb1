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
)
from railsusp.measured.field_table import read_field_table
from railsusp.measured.recording import Recording, RecordingError
from railsusp.measured.run_checks import check_force_rates
from railsusp.measured.sampling import (
    FiniteSampling,
    check_sparse,
    finite_rate_note,
    finite_sampling,
    short_gaps_note,
)
from railsusp.measured.sidecar import condition_on_the_table, read_sidecar, sidecar_condition
from railsusp.measured.track_columns import check_track_columns
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
    shorter ones interpolated with a warning unless together over 5 % of the samples, and
    a force column's rate of its finite values at least ``min_rate_hz``: the rule of
    :mod:`railsusp.measured.sampling`, a long run's too); all-zero or constant force
    channels; median wheel load against the wagon's static wheel load; physical bounds; the
    speed and track columns against the condition (:mod:`railsusp.measured.track_columns`).
    The table itself is read by :mod:`railsusp.measured.field_table` (a distance axis put on
    time, its jumps refused; text and booleans in an unused column noted, not refused); the
    checks of values run on the file's rows, so that what they count and name is what the
    file shows, and the forces are put on time after."""
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
    table_path = _table_of(Path(path))
    problems: list[str] = []
    notes: list[str] = []
    meta = read_sidecar(table_path.with_suffix(".json"), problems)
    try:
        table = read_field_table(table_path)
    except RecordingError as exc:
        raise RecordingError(table_path, [*problems, *exc.problems]) from None
    problems += table.problems
    notes += table.notes
    cols = table.names
    cmap = default_map([*cols, "time_s"])
    half = sorted(
        {split_header(h)[0][2:] for h in cols if h[:2] in ("Y_", "Q_")} - set(cmap.wheels)
    )
    half = [w for w in half if w in WHEEL_NAMES]  # a wheel with Y or Q only: reported below
    missing = [
        f"{f}_{w}_kN"
        for w in half
        for f in sorted({"Y", "Q"} - {split_header(h)[0][0] for h in cols if h[2:5] == w})
    ]
    for c in cols:
        base = split_header(c)[0]
        if c in cmap.used() or base in ("distance", "speed", "curvature", "cant", "grade"):
            if c in table.not_numbers:
                problems.append(table.not_numbers[c][0])
            continue
        if base[2:] in half and base[:2] in ("Y_", "Q_"):
            if c in table.not_numbers:
                problems.append(table.not_numbers[c][0])
            continue
        same = [o for o in cols if o != c and split_header(o)[0] == base]
        if same and base[:2] in ("Y_", "Q_") and base[2:] in WHEEL_NAMES:
            problems.append(
                f"column {c!r}: the force {base} is given twice (also as {same[0]!r}); "
                "accepted one column per force"
            )
            continue
        # the column a wheel lacks first: Q_wlL_kN beside Y_w1L_kN means Q_w1L_kN
        hint = did_you_mean(c, missing) or did_you_mean(c, _DOCUMENTED)
        if hint or base.startswith(("Y_", "Q_")):
            problems.append(f"column {c!r} not recognised{hint}")
        elif c in table.not_numbers:
            notes.append(f"column {c!r} not used ({table.not_numbers[c][1]}, not numbers)")
        else:
            notes.append(f"column {c!r} not used")
    if table.time is None:  # the axis does not read: the columns' problems, then stop
        raise RecordingError(table_path, [*problems])
    raw = table.channels  # the file's rows
    t = table.time
    lines = table.lines  # the file line of each sample of t, for messages
    time_problems = check_time(t, table.axis or "time_s", lines)
    problems += time_problems
    rate = 1.0 / float(np.median(np.diff(t))) if not time_problems and t.size > 1 else None
    if rate is not None and rate < min_rate_hz * (1.0 - 1e-6):
        problems.append(
            f"sampling rate {rate:.4g} Hz below the {min_rate_hz:g} Hz the pipeline needs"
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
    sampling: dict[str, FiniteSampling] = {}  # a force column's finite rows
    for w, chans in cmap.wheels.items():
        si = {}
        for f, col in chans.items():
            if col not in raw:  # not numbers: said above
                continue
            ch = raw[col]
            try:
                factor = si_factor("force", ch.unit, col)
            except RailsuspInputError as exc:
                problems.append(str(exc).replace("channel", "column", 1))
                continue
            x, p, n = check_finite(ch.values, col, ch.first_row)  # the file's rows
            problems += p
            if not p and rate is not None:  # short gaps together much of the record?
                sampling[col] = finite_sampling(ch.values, rate)
                sparse = check_sparse(sampling[col], col)
                problems += sparse
                # noted: its samples missing at its rate, not its rows off its step
                note = None if sparse else short_gaps_note(col, sampling[col])
                n = [note] if note and n else []
            notes += n
            problems += check_flat(x, col, ch.unit or "") + check_clipped(x, col, ch.unit or "")
            si[f] = table.on_time(x) * factor
        if len(si) == 2:
            units = (raw[chans["Y"]].unit or "", raw[chans["Q"]].unit or "")
            problems += check_forces(si["Y"], si["Q"], (chans["Y"], chans["Q"]), units, wl, lines)
            Y[w], Q[w] = si["Y"] / 1e3, si["Q"] / 1e3
    problems += _sparse_rates(sampling, rate, min_rate_hz, notes)
    problems = [p.replace("channel '", "column '") for p in problems]
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
    if t.size:  # speed and track columns against the condition's (or a condition's range)
        problems += check_track_columns(raw, table.row_time, condition, table.distance)
    if problems:
        raise RecordingError(table_path, problems)
    for note in notes:  # (a field table's channels are its columns)
        if note.startswith("channel '"):
            note = "column" + note.removeprefix("channel")
        warnings.warn(f"{table_path.name}: {note}", stacklevel=2)
    extra = {k: v for k, v in meta.items() if k not in ("format", "condition", "wheels")}
    return Recording(np.asarray(t), Y, Q, condition, extra)  # type: ignore[arg-type]


def _sparse_rates(
    sampling: dict[str, FiniteSampling], rate: float | None, min_rate_hz: float, notes: list[str]
) -> list[str]:
    """Problems of the force columns whose finite values are sparser than the table's rows
    and, so, slower than ``min_rate_hz`` (or than a tenth of the fastest column), as a long
    run's force channels are held (:func:`~railsusp.measured.run_checks.check_force_rates`);
    the others are noted as read at their rate, interpolated between their values."""
    if rate is None or not sampling:
        return []
    sparser = [c for c, s in sampling.items() if s.rate_hz < rate * (1.0 - 1e-6)]
    if not sparser:
        return []
    rates = {c: s.rate_hz for c, s in sampling.items()}
    fastest = max(rates, key=rates.__getitem__)
    limit = "the lowest usable rate (check-recording --min-rate, read_recording's min_rate_hz)"
    problems = check_force_rates(
        sparser, fastest, rates, min_rate_hz, {c: rate for c in rates}, limit
    )
    for c in sparser:
        note = finite_rate_note(c, sampling[c], rate)
        if note and not any(p.startswith(f"channel {c!r}") for p in problems):
            notes.append(note)
    return problems


def _table_of(path: Path) -> Path:
    """The table a recording's path names: the file itself (``.csv`` or ``.parquet``, any
    case), or the one table of its stem (``NAME``, ``NAME.json``). A stem with both a CSV
    and a Parquet table is refused, naming both (the CSV was read, silently, whatever the
    other held)."""
    if path.is_file() and path.suffix.lower() in (".csv", ".parquet"):  # up.CSV as up.csv
        return path
    if not path.name:  # "." or "/": no stem to name a table by (a ValueError's traceback)
        raise RecordingError(path, ["a folder, not a recording table"])
    stem = path.with_suffix("") if path.suffix.lower() in (".json", ".csv", ".parquet") else path
    found = [
        p for p in (stem.with_name(stem.name + s) for s in (".csv", ".parquet")) if p.is_file()
    ]
    if len(found) == 2:
        raise RecordingError(
            path,
            [
                f"both {found[0].name} and {found[1].name} exist: which is the recording? "
                "Name the table (its .csv or .parquet file), or remove the other"
            ],
        )
    if found:
        return found[0]
    what = "a folder, not a recording table" if path.is_dir() else "no .csv or .parquet table found"
    raise RecordingError(path, [what])
