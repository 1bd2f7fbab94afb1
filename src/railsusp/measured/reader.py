"""The field folder: recordings in the documented format (one working condition each),
listed in ``index.json``, each a table and a JSON sidecar. The reader checks every
recording strictly (:mod:`railsusp.measured.checks`) and reports every problem of a file
at once, naming file, column and rows; every path a file names must lie inside its folder.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from railsusp.conditions import (
    RECORDING_MIN_RATE_HZ,
    WorkingCondition,
    get_condition,
    make_condition,
)
from railsusp.errors import RailsuspInputError, did_you_mean, repeated
from railsusp.input_checks import json_numbers
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
from railsusp.measured.recording import FORMAT, Recording, RecordingError
from railsusp.measured.units import si_factor, split_header
from railsusp.numbers import is_real
from railsusp.vehicle.layout import WHEEL_NAMES
from railsusp.vehicle.setup import axle_spread, static_wheel_load
from railsusp.vehicle.track_geometry import check_coverage, read_track_geometry
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


def inside(folder: Path, name: Any, what: str) -> Path:
    """``folder / name`` when ``name`` is a relative path that stays inside ``folder``;
    otherwise an error naming ``what`` (a data file must not reach outside its folder)."""
    if not isinstance(name, str) or not name:
        raise RailsuspInputError(f"{what}: {name!r} is not a file name")
    root = folder.resolve()
    target = (root / name).resolve()
    if Path(name).is_absolute() or not target.is_relative_to(root):
        raise RailsuspInputError(
            f"{what}: {name!r} lies outside the folder {folder}; name a file inside it"
        )
    return target


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
    meta = _read_sidecar(table_path.with_suffix(".json"), problems)
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
    condition = _condition(meta, table_path, problems, axle_spread(wagon)) if meta else None
    if condition is not None and rate is not None:
        condition = _on_the_table(
            condition, meta, t.size, rate, table_path.with_suffix(".json").name, problems
        )
    if problems:
        raise RecordingError(table_path, problems)
    for note in notes:
        warnings.warn(f"{table_path.name}: {note}", stacklevel=2)
    extra = {k: v for k, v in meta.items() if k not in ("format", "condition", "wheels")}
    return Recording(np.asarray(t), Y, Q, condition, extra)  # type: ignore[arg-type]


def _on_the_table(
    condition: WorkingCondition,
    meta: dict,
    rows: int,
    rate: float,
    side: str,
    problems: list[str],
) -> WorkingCondition | None:
    """The sidecar's condition against the table it describes (``rows`` at ``rate`` Hz):
    its ``duration_s`` must be the table's (its ``n_steps`` may sample it at another rate:
    record statistics are each taken at their own rate; what compares the simulation with
    the table sample by sample refuses it before any work,
    :func:`~railsusp.estimate.comparison.check_time_base`), since the estimate simulates the
    condition's record and compares it with the table (a
    4 s condition on a 1 s table compared 4 s of simulation with 1 s of measurement,
    silently). A condition that states neither (the documented sidecar's), or a standard
    one named by ``condition_name``, takes the table's record (before, the default 20 s of
    1000 steps, whatever the table)."""
    duration = rows / rate
    doc = meta.get("condition")
    if not (isinstance(doc, dict) and ("duration_s" in doc or "n_steps" in doc)):
        try:
            return condition.with_changes(duration_s=round(duration, 6), n_steps=rows)
        except RailsuspInputError as exc:
            problems.append(f"{side}: {exc}")
            return None
    slack = 1.5 * max(1.0 / rate, condition.sample_interval)  # its rate may be its own
    if abs(condition.duration_s - duration) > slack:
        problems.append(
            f"{side}: condition duration_s {condition.duration_s:g} s, the table {rows} rows at "
            f"{rate:.6g} Hz ({duration:.6g} s): accepted the table's duration (the estimate "
            "simulates the condition's record and compares it with the table)"
        )
    return condition


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


def _read_sidecar(side: Path, problems: list[str]) -> dict[str, Any]:
    """The sidecar as a dict (empty, with a problem, when missing or not a JSON object)."""
    if not side.is_file():
        problems.append(f"metadata sidecar {side.name} missing")
        return {}
    try:
        meta = json.loads(side.read_text("utf-8-sig"))
    except UnicodeDecodeError:
        problems.append(f"{side.name}: not UTF-8 text")
        return {}
    except json.JSONDecodeError as exc:
        problems.append(f"{side.name}: not valid JSON ({exc.msg}, line {exc.lineno})")
        return {}
    if not isinstance(meta, dict):
        problems.append(
            f"{side.name}: a JSON object {{...}} is needed, not a {type(meta).__name__}"
        )
        return {}
    if meta.get("format") != FORMAT:
        problems.append(f"{side.name}: format {meta.get('format')!r}, expected {FORMAT!r}")
    problems += _sidecar_fields(meta, side.name)
    return meta


def _sidecar_fields(meta: dict[str, Any], side: str) -> list[str]:
    """Problems of the sidecar's ``wheels`` (a list of distinct wheel names) and
    ``filter_bandwidth_hz`` (null, or a positive number of Hz: the comparison low-passes the
    model's forces at it, so a string or a negative value would fail there, naming nothing)."""
    out = []
    wheels = meta.get("wheels")
    if wheels is not None and (
        not isinstance(wheels, list)
        or not all(isinstance(w, str) and w in WHEEL_NAMES for w in wheels)
        or len(set(wheels)) != len(wheels)
    ):
        out.append(
            f"{side}: wheels = {json.dumps(wheels)}: accepted a list of distinct wheel names "
            f'{WHEEL_NAMES[0]} .. {WHEEL_NAMES[-1]} (e.g. ["w1R"])'
        )
    bw = meta.get("filter_bandwidth_hz")
    if bw is not None and not (is_real(bw) and 0.0 < bw < math.inf):
        out.append(
            f"{side}: filter_bandwidth_hz = {json.dumps(bw)}: accepted a number of Hz above 0 "
            "(the instrument's bandwidth; null or left out: none)"
        )
    return out


def _condition(
    meta: dict[str, Any], table_path: Path, problems: list[str], axle_spread_m: float
) -> WorkingCondition | None:
    """The sidecar's working condition (numbers must be JSON numbers), its track geometry
    resolved inside the recording's folder, read and checked to cover the record under
    every axle, ``axle_spread_m`` (the recorded wagon's;
    :func:`~railsusp.vehicle.track_geometry.check_coverage`; the simulation checks again
    with the run's wagon)."""
    side = table_path.with_suffix(".json").name
    cdoc = meta.get("condition")
    named = meta.get("condition_name")
    if isinstance(cdoc, dict) and named is not None and named != cdoc.get("name"):
        problems.append(  # the name was ignored, silently (command-line audit of stop 60)
            f"{side}: a 'condition' table (name {cdoc.get('name')!r}) and condition_name "
            f"{named!r}: accepted one of them (or the same name in both)"
        )
        return None
    try:
        if isinstance(cdoc, dict):
            condition = make_condition(json_numbers(cdoc))
        elif isinstance(meta.get("condition_name"), str):
            condition = get_condition(meta["condition_name"])
        else:
            problems.append(f"{side}: no 'condition' table or 'condition_name'")
            return None
    except RailsuspInputError as exc:
        problems.append(f"{side}: {exc}")
        return None
    if condition.track_geometry is None:
        return condition
    try:
        geo = inside(table_path.parent, condition.track_geometry, f"{side}: track_geometry")
        condition = condition.with_changes(track_geometry=str(geo))
        check_coverage(read_track_geometry(geo), condition, axle_spread_m)
    except RailsuspInputError as exc:
        problems.append(str(exc) if str(exc).startswith(side) else f"{side}: track_geometry: {exc}")
        return None
    return condition


def read_index(folder: str | Path) -> list[Path]:
    """The recordings a field folder's ``index.json`` lists, each inside the folder."""
    folder = Path(folder)
    index = folder / "index.json"
    if not index.is_file():
        raise RailsuspInputError(f"{folder}: no index.json listing the recordings")
    try:
        doc = json.loads(index.read_text("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RailsuspInputError(f"{index}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("recordings"), list):
        raise RailsuspInputError(
            f'{index}: a JSON object with a "recordings" list of file names is needed'
        )
    if not doc["recordings"]:
        raise RailsuspInputError(f"{index}: the recordings list is empty")
    if "format" in doc and doc["format"] != FORMAT:
        raise RailsuspInputError(f"{index}: format {doc['format']!r}; accepted {FORMAT!r}")
    names = doc["recordings"]
    twice = repeated(names)
    if twice:  # the same recording counted twice would weigh it double in the estimate
        raise RailsuspInputError(
            f"{index} recordings: {', '.join(twice)} listed more than once; accepted each once"
        )
    return [inside(folder, n, f"{index} recordings") for n in names]


#: how many times :func:`read_field` reads a folder replaced while it read it
SWAP_RETRIES = 3


def _folder_identity(folder: str | Path) -> tuple[int, int] | None:
    """The folder's device and inode (a folder swapped in by an atomic rename is another
    inode); None while it is missing (between the swap's two renames)."""
    try:
        st = os.stat(folder)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def read_field(
    folder: str | Path,
    *,
    wheel_load_N: float | None = None,
    wagon: str | Path | WagonData | None = None,
) -> list[Recording]:
    """All recordings listed in a field folder's ``index.json`` (never ``truth.json``),
    read as recordings of ``wagon`` (default: the packaged loaded C80): their wheel loads
    checked against its static wheel load (or ``wheel_load_N``; a tare C80's 24.5 kN was
    refused against the loaded one's) and their measured track's lead-in against its axle
    spread (:func:`read_recording`). Two recordings of one condition name are refused: the
    estimate, the validation and ``align-track`` tell recordings apart by it (two
    ``straight`` files got each other's track offset and one validation figure).

    A folder replaced while it is read (a writer's atomic swap: ``synth-field``, ``sections
    --write``) is read again, up to :data:`SWAP_RETRIES` times: a read across the swap
    returned recordings of two generations under one ``index.json``, with no error (the
    concurrency audit of stop 66; the command-line readers hold the folder's lock, a
    library call does not)."""
    for _ in range(SWAP_RETRIES):
        before = _folder_identity(folder)
        try:
            paths = read_index(folder)
            recordings = [read_recording(p, wheel_load_N=wheel_load_N, wagon=wagon) for p in paths]
        except (OSError, RailsuspInputError):
            if _folder_identity(folder) == before:
                raise  # the folder as it is (or missing throughout): said as always
            continue
        if _folder_identity(folder) == before:
            break
    else:
        raise RailsuspInputError(
            f"{folder}: replaced {SWAP_RETRIES} times while it was read (a writer such as "
            "synth-field or sections --write works in it); read it again once it is done"
        )
    seen: dict[str, Path] = {}
    for path, rec in zip(paths, recordings, strict=True):
        name = rec.condition.name
        if name in seen:
            raise RailsuspInputError(
                f"{Path(folder) / 'index.json'}: {seen[name].name} and {path.name} are both "
                f"recordings of condition {name!r}; accepted one condition name per recording "
                "(give each its own: condition_name in the sidecar, or the condition's name)"
            )
        seen[name] = path
    return recordings


def conditions_from(
    spec: str, *, wagon: str | Path | WagonData | None = None
) -> list[WorkingCondition]:
    """Conditions named by ``spec``: standard names or a TOML file (as
    :func:`~railsusp.condition_files.resolve_conditions`), or a field folder (``index.json``), whose
    recordings' conditions are taken with their measured track geometry, so that a campaign
    can run on the track the recordings were made on; read as recordings of ``wagon``
    (:func:`read_field`; the wagon the campaign simulates)."""
    from railsusp.condition_files import resolve_conditions

    folder = Path(spec)
    if folder.is_dir():
        if not (folder / "index.json").is_file():
            raise RailsuspInputError(f"conditions {spec!r}: a folder without index.json")
        return [rec.condition for rec in read_field(folder, wagon=wagon)]
    return resolve_conditions(spec)
