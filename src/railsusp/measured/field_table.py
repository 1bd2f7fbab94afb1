"""The table of a field-format recording (CSV or Parquet) read column by column, with the
problems of the file itself said in the project's words: a line that is not UTF-8 (its
line number), a separator other than a comma, a column named twice or not at all, cells
that are not numbers (every column at once, each with its first row). A column that is not
numbers is left to the reader (:mod:`railsusp.measured.recording_reader`): refused where
the recording uses it, noted and left unused where it does not (a ``note`` column of
text, a Parquet ``flag`` of booleans refused the whole recording before).

A table along ``distance_m`` is put on time over its ``speed_kmh`` (:func:`on_time`),
its distance checked as a time column is: strictly increasing, and without a jump (a
chainage jump or lost samples) that the resampling would fill with invented data.
"""

from __future__ import annotations

import csv
import io
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.errors import RailsuspInputError, did_you_mean
from railsusp.integrity import csv_last_line_cut
from railsusp.measured.checks import rows, runs
from railsusp.measured.raw import RawChannel
from railsusp.measured.recording import RecordingError
from railsusp.measured.units import si_factor, split_header

#: a distance step longer than this many times the median step, taking longer than this
#: many times the median interval at the speed, is a jump (a chainage jump, lost samples):
#: a sound table is uniform in one of the two (sampled by distance, or by time), and the
#: speed is held within 10 % of its condition's
JUMP_FACTOR = 1.5
#: lines of a table named in one message (the others counted)
LINES_NAMED = 3


@dataclass
class FieldTable:
    """A field table's columns, on time where its axis reads."""

    path: Path
    names: list[str]  # every named column but the axis, in the file's order
    axis: str | None  # the time or distance column, as headed
    time: np.ndarray | None  # s, None where the axis does not read
    channels: dict[str, RawChannel] = field(default_factory=dict)  # numeric, on ``time``
    #: column -> why its cells are not numbers, as a problem (where the recording uses the
    #: column) and in short (for the note of a column left unused)
    not_numbers: dict[str, tuple[str, str]] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def read_field_table(path: Path) -> FieldTable:
    """The table's columns; a file that does not read as a table at all raises
    :class:`RecordingError` with its problems."""
    df, problems, notes = _frame(path)
    cols = [str(c) for c in df.columns]
    axis = next((c for c in ("time_s", "distance_m") if c in cols), None)
    if axis is None:
        axis = next((c for c in cols if split_header(c)[0] in ("time", "t")), None)
    names = [c for c in cols if c != axis]
    table = FieldTable(path, names, axis, None, problems=problems, notes=notes)
    for c in cols:
        values, why, short = _numbers(df[c])
        if why is not None:
            table.not_numbers[c] = (f"column {c!r}{why if why[0] == ',' else ' ' + why}", short)
        elif c != axis:
            table.channels[c] = RawChannel(c, split_header(c)[1], np.zeros(0), values)
    if axis is None:
        hint = did_you_mean("time_s", cols) or did_you_mean("distance_m", cols)
        table.problems.append(
            f"no time column (time_s, or distance_m with speed_kmh){hint}; columns {cols}"
        )
        return table
    if axis in table.not_numbers:
        table.problems.append(table.not_numbers.pop(axis)[0])
        return table
    t = _numbers(df[axis])[0]
    name, unit = split_header(axis)
    quantity = "position" if name == "distance" else "time"
    try:
        t = t * (1.0 if unit is None else si_factor(quantity, unit, axis))
    except RailsuspInputError as exc:
        table.problems.append(str(exc).replace("channel", "column", 1))
        return table
    for ch in table.channels.values():
        ch.time = t
    if quantity == "time":
        table.time = t
        return table
    speed = table.channels.get("speed_kmh")
    if speed is None:
        table.problems.append(f"column {axis!r} without a speed_kmh column; give time_s")
        return table
    bad = distance_problems(t, speed.values / 3.6, axis, speed.first_row)
    if bad:
        table.problems += bad
        return table
    table.time = on_time(table.channels, t, speed.values / 3.6)
    return table


def _frame(path: Path) -> tuple[pd.DataFrame, list[str], list[str]]:
    """The table's cells (text for CSV), with the problems and notes of its header: a
    column named twice (pandas renamed the second ``X.1``), one with no name (a trailing
    comma on each line: left out without a word where all its cells are empty)."""
    if path.suffix.lower() == ".parquet":
        try:
            return pd.read_parquet(path), [], []
        except Exception as exc:  # pyarrow raises many types on a damaged file
            raise RecordingError(path, [f"cannot read the table ({_first_line(exc)})"]) from None
    data = path.read_bytes()
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise RecordingError(path, [_not_utf8(data)]) from None
    header = next(csv.reader(io.StringIO(text)), [])
    if len(header) == 1 and any(sep in header[0] for sep in ";\t"):
        sep = "';'" if ";" in header[0] else "a tab"
        raise RecordingError(
            path,
            [
                f"the header {header[0]!r} is one column: its cells are separated by {sep}; "
                "accepted a comma-separated table with '.' as decimal mark"
            ],
        )
    try:  # (index_col=False: lines of one cell more than the header took its first
        # column for the row labels, every column shifted by one)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", pd.errors.ParserWarning)
            df = pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False, index_col=False)
    except Exception as exc:  # pandas raises many types on a damaged file
        longer = _longer_lines(text, len(header))
        raise RecordingError(
            path, [longer or f"cannot read the table ({_first_line(exc)})"]
        ) from None
    if caught and (longer := _longer_lines(text, len(header))):  # cut off, were they read
        raise RecordingError(path, [longer])
    if csv_last_line_cut(path, len(df.columns)):
        raise RecordingError(
            path,
            [
                f"the last line is cut short (fewer cells than the header's {len(df.columns)}, "
                "no line end): a file truncated in copying? Its last value would be read "
                "wrong; remove the line or copy the file again"
            ],
        )
    problems: list[str] = []
    notes: list[str] = []
    drop = []
    for name, n in Counter(header).items():
        at = [i for i, h in enumerate(header) if h == name]
        if not name.strip():
            for i in at:
                drop.append(df.columns[i])
                cells = df.iloc[:, i].str.strip()
                if (cells != "").any():
                    notes.append(
                        f"column {i + 1} has no name in the header (its cells are not "
                        "empty): not used"
                    )
        elif n > 1:
            problems.append(
                f"column {name!r} appears {n} times in the header (columns "
                f"{', '.join(str(i + 1) for i in at)}); accepted each column once"
            )
            drop += [df.columns[i] for i in at[1:]]
    return df.drop(columns=drop), problems, notes


def _longer_lines(text: str, n_header: int) -> str | None:
    """The lines with values in more cells than the header's (empty cells after the last
    are a comma at a line's end, no value), as a problem; None where there are none."""
    longer = [
        i for i, cells in enumerate(csv.reader(io.StringIO(text)), start=1)
        if len(cells) > n_header and any(c.strip() for c in cells[n_header:])
    ]  # fmt: skip
    if not longer:
        return None
    return (
        f"{'line' if len(longer) == 1 else 'lines'} {_listed(longer)}: more cells than the "
        f"header's {n_header}; accepted a value under each header"
    )


def _listed(numbers: list[int]) -> str:
    """The first :data:`LINES_NAMED` of ``numbers``, and how many in all."""
    more = f" ({len(numbers)} in all)" if len(numbers) > LINES_NAMED else ""
    return ", ".join(str(n) for n in numbers[:LINES_NAMED]) + more


def _first_line(exc: Exception) -> str:
    return (str(exc).splitlines() or [type(exc).__name__])[0]


def _not_utf8(data: bytes) -> str:
    """The lines of ``data`` that are not UTF-8, named by their numbers (the header is line
    1), with the first offending byte."""
    bad = []
    for number, line in enumerate(data.removeprefix(b"\xef\xbb\xbf").split(b"\n"), start=1):
        try:
            line.decode("utf-8")
        except UnicodeDecodeError as exc:
            bad.append((number, line[exc.start]))
    if not bad:  # (a sequence split across a line end cannot be: "\n" is never inside one)
        return "not UTF-8 text; accepted a UTF-8 table"
    numbers = [n for n, _ in bad]
    where = f"{'line' if len(bad) == 1 else 'lines'} {_listed(numbers)}"
    header = " (the header)" if numbers[0] == 1 else ""
    return (
        f"{where}{header}: not UTF-8 text (byte 0x{bad[0][1]:02x}); accepted a UTF-8 table "
        "(save it as UTF-8, not in a national code page)"
    )


def _numbers(raw: pd.Series) -> tuple[np.ndarray, str | None, str]:
    """A column as floats, or why it is not numbers: in full, with its first row (file
    lines: the header is line 1) and the count, and in short, for a note. Empty and
    ``nan`` cells are NaN."""
    if raw.dtype.kind == "b" or (raw.dtype == object and raw.map(type).eq(bool).any()):
        return np.zeros(0), "holds booleans (true/false), not numbers", "booleans"
    if raw.dtype.kind in "fiu":
        return raw.to_numpy(dtype=float), None, ""
    text = raw.where(raw.notna(), "").astype(str).str.strip()  # a Parquet null: empty
    vals = pd.to_numeric(text.replace("", "nan"), errors="coerce")
    bad = vals.isna() & ~text.str.lower().isin(["", "nan"])
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        comma = " (',' as decimal mark? accepted '.')" if "," in str(raw.iloc[i]) else ""
        return (
            np.zeros(0),
            f", row {i + 2}: {raw.iloc[i]!r} is not a number{comma} ({int(bad.sum())} such "
            "cell(s))",
            f"text, {raw.iloc[i]!r} in row {i + 2}",
        )
    return vals.to_numpy(dtype=float), None, ""


def distance_problems(
    distance: np.ndarray, speed: np.ndarray, axis: str, first_row: int | np.ndarray
) -> list[str]:
    """Problems of a table's distance axis (m) at its ``speed`` (m/s): every speed positive
    (a stop has no distance to sample it by), distances finite and strictly increasing,
    and no jump: a step longer than :data:`JUMP_FACTOR` times the median both in distance
    and in its time at the speed (a chainage jump, or samples lost; resampled onto time, a
    50 m jump at 60 km/h became 3 s of interpolated forces). A long run's reader cuts the
    run at such a jump (``railsusp sections``); a recording is one stretch."""
    still = ~(speed > 0)  # NaN too
    if still.any():
        a, b = runs(still)[0]
        return [
            f"column 'speed_kmh', {rows(a, b - 1, first_row)}: speed {speed[a] * 3.6:g} km/h; "
            f"a table along {axis} needs the speed positive in every row (a stop has no "
            "distance to sample it by: give time_s)"
        ]
    if distance.size < 3:
        return []  # (the reader refuses a table this short)
    unknown = ~np.isfinite(distance)
    if unknown.any():
        a, b = runs(unknown)[0]
        return [f"column {axis!r}, {rows(a, b - 1, first_row)}: distance is not a number"]
    ds = np.diff(distance)
    back = np.flatnonzero(~(ds > 0))
    if back.size:
        i = int(back[0])
        return [
            f"column {axis!r}, {rows(i, i + 1, first_row)}: distance not strictly increasing "
            f"({back.size} place(s)); a table along {axis} needs it increasing in every row"
        ]
    dt = ds / (0.5 * (speed[1:] + speed[:-1]))
    step, interval = float(np.median(ds)), float(np.median(dt))
    jumps = np.flatnonzero((ds > JUMP_FACTOR * step) & (dt > JUMP_FACTOR * interval))
    if not jumps.size:
        return []
    i = int(jumps[0])
    return [
        f"column {axis!r}, {rows(i, i + 1, first_row)}: a step of {ds[i]:.4g} m against the "
        f"median {step:.4g} m, {dt[i]:.4g} s at {speed[i] * 3.6:.4g} km/h against the median "
        f"{interval:.4g} s ({jumps.size} such step(s)); accepted steps up to {JUMP_FACTOR:g} "
        "times the median in distance or in time: a chainage jump or lost samples cannot be "
        "interpolated (a recording is one stretch; railsusp sections cuts a long run at such "
        "a jump)"
    ]


def on_time(channels: dict[str, RawChannel], distance: np.ndarray, speed: np.ndarray):
    """Channels sampled along the track (``distance`` m, at ``speed`` m/s, checked by
    :func:`distance_problems`) put on a uniform time base, which is returned: each
    sample's time is the integral of ds / v from the first (trapezoidal mean speed per
    step), and the channels are interpolated onto the median interval of those times.
    Samples that are uniform in distance are not uniform in time where the speed varies
    (time = distance / speed held only at constant speed). Each channel's ``first_row``
    becomes the file line of each sample, so that messages name the lines to look at."""
    if distance.size < 3:  # (the reader refuses a table this short, by its rows)
        for ch in channels.values():
            ch.time = distance / speed
        return distance / speed
    t = np.concatenate([[0.0], np.cumsum(np.diff(distance) / (0.5 * (speed[1:] + speed[:-1])))])
    dt = float(np.median(np.diff(t)))
    uniform = np.arange(0.0, t[-1] + 0.5 * dt, dt)
    uniform = uniform[uniform <= t[-1] + 1e-9 * dt]  # (the last row, less rounding)
    sample = np.rint(np.interp(uniform, t, np.arange(t.size))).astype(int)
    for ch in channels.values():
        ch.values = np.interp(uniform, t, ch.values)
        ch.time = uniform
        ch.first_row = ch.first_row + sample
    return uniform
