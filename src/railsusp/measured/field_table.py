"""The table of a field-format recording (CSV or Parquet) read column by column, its file
read by :mod:`railsusp.measured.table_file` (which says the problems of the file itself: a
line that is not UTF-8, a separator other than a comma, a column named twice or not at
all, cells that are not numbers). A column that is not numbers is left to the reader
(:mod:`railsusp.measured.recording_reader`): refused where the recording uses it, noted
and left unused where it does not (a ``note`` column of text, a Parquet ``flag`` of
booleans refused the whole recording before). A column named twice is refused where its
name is one the format gives a meaning (:data:`FORMAT_NAMES`, ``Y_...``, ``Q_...``: which
copy is meant cannot be told), noted where not (its first copy then noted unused), as a
long run's unused channel named twice is.

Every column is kept as the file's rows, so that the reader's checks count and name what
the user sees in the file. A table along ``distance_m`` gives each row its time over its
``speed_kmh`` (the integral of ds / v), its distance checked as a time column is: strictly
increasing, and without a jump (a chainage jump or lost samples) that the resampling would
fill with invented data; :meth:`FieldTable.on_time` puts a column on the uniform time base
the recording is read on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError, did_you_mean
from railsusp.measured.checks import rows, runs
from railsusp.measured.raw import RawChannel
from railsusp.measured.table_file import TWICE_REFUSED, column_numbers, read_frame, twice_said
from railsusp.measured.units import named, normalise_unit, si_factor, split_header

#: a distance step longer than this many times the median step, taking longer than this
#: many times the median interval at the speed, is a jump (a chainage jump, lost samples):
#: a sound table is uniform in one of the two (sampled by distance, or by time), and the
#: speed is held within 10 % of its condition's
JUMP_FACTOR = 1.5

#: the speed columns a table along distance takes, as its messages name them
SPEED_NAMES = "speed_kmh, speed_mps or speed [m/s]"
#: the names (less their units) of the format's columns other than the forces (``Y_...``,
#: ``Q_...``): the axis, the speed and the track
FORMAT_NAMES = ("time", "t", "distance", "speed", "curvature", "cant", "grade")


@dataclass
class FieldTable:
    """A field table's columns as the file's rows, and the time base they are read on."""

    path: Path
    names: list[str]  # every named column but the axis, in the file's order
    axis: str | None  # the time or distance column, as headed
    #: the uniform time base the recording is read on, s (the rows' own for a table on
    #: time); None where the axis does not read
    time: np.ndarray | None
    #: numeric columns, one value per file row (first_row 2: the header is line 1), each
    #: on its rows' times (``row_time``)
    channels: dict[str, RawChannel] = field(default_factory=dict)
    #: column -> why its cells are not numbers, as a problem (where the recording uses the
    #: column) and in short (for the note of a column left unused)
    not_numbers: dict[str, tuple[str, str]] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: each row's time, s: the time column's, or along ``distance_m`` the integral of ds / v
    row_time: np.ndarray | None = None
    #: each row's distance along the track, m, for a table along ``distance_m``; else None
    distance: np.ndarray | None = None
    #: the file line of each sample of ``time`` (its nearest row), for messages; 2 (the
    #: first data line: each sample its row) for a table on time
    lines: int | np.ndarray = 2

    def on_time(self, values: np.ndarray) -> np.ndarray:
        """A column's values (one per file row) on :attr:`time`: themselves for a table on
        time; along distance, interpolated linearly between its rows' times, NaN only where
        the nearest row is empty (empty cells spread to the samples around them counted a
        table's 30 empty cells as 61 missing samples)."""
        if self.distance is None or self.time is None or self.row_time is None:
            return values
        finite = np.isfinite(values)
        if finite.sum() < 2:
            return np.full(self.time.size, np.nan)
        out = np.interp(self.time, self.row_time[finite], values[finite])
        nearest = self.lines - 2 if isinstance(self.lines, np.ndarray) else np.arange(out.size)
        out[~finite[nearest]] = np.nan
        return out


def read_field_table(path: Path) -> FieldTable:
    """The table's columns; a file that does not read as a table at all raises
    :class:`~railsusp.measured.recording.RecordingError` with its problems."""
    df, notes, twice = read_frame(path)
    cols = [str(c) for c in df.columns]
    axis = next((c for c in ("time_s", "distance_m") if c in cols), None)
    if axis is None:
        axis = next((c for c in cols if split_header(c)[0] in ("time", "t")), None)
    names = [c for c in cols if c != axis]
    problems: list[str] = []
    for c, at in twice.items():
        base = split_header(c)[0]
        if c == axis or base in FORMAT_NAMES or base.startswith(("Y_", "Q_")):
            problems.append(f"column {c!r}{twice_said(at)}{TWICE_REFUSED}")
        else:
            notes.append(f"column {c!r}{twice_said(at)}: the later ones left out")
    table = FieldTable(path, names, axis, None, problems=problems, notes=notes)
    for c in cols:
        values, why, short = column_numbers(df[c])
        if why is not None:
            table.not_numbers[c] = (f"column {c!r}{why}", short)
        elif c != axis:
            table.channels[c] = RawChannel(c, split_header(c)[1], np.zeros(0), values)
    if axis is None:
        hint = did_you_mean("time_s", cols) or did_you_mean("distance_m", cols)
        table.problems.append(
            f"no time column (time_s, or distance_m with a speed column){hint}; columns {cols}"
        )
        return table
    if axis in table.not_numbers:
        table.problems.append(table.not_numbers.pop(axis)[0])
        return table
    t = column_numbers(df[axis])[0]
    name, unit = split_header(axis)
    quantity = "position" if name == "distance" else "time"
    try:
        t = t * (1.0 if unit is None else si_factor(quantity, unit, axis))
    except RailsuspInputError as exc:
        table.problems.append(str(exc).replace("channel", "column", 1))
        return table
    if quantity == "time":
        for ch in table.channels.values():
            ch.time = t
        table.time = table.row_time = t
        return table
    # the speed column in any unit the track columns take (speed_kmh, speed_mps, speed [m/s])
    speed = table.channels.get(named(table.channels, "speed"))
    if speed is None:
        table.problems.append(
            f"column {axis!r} without a speed column ({SPEED_NAMES}); give time_s"
        )
        return table
    try:
        factor = si_factor("speed", speed.unit, speed.name)
    except RailsuspInputError as exc:
        table.problems.append(str(exc).replace("channel", "column", 1))
        return table
    v = speed.values * factor
    unit = {1 / 3.6: "km/h", 1.0: "m/s"}.get(factor) or normalise_unit(speed.unit)  # as read
    bad = distance_problems(t, v, axis, speed.first_row, speed.name, (factor, unit))
    if bad:
        table.problems += bad
        return table
    table.distance = t
    table.row_time = row_times(t, v)
    for ch in table.channels.values():
        ch.time = table.row_time
    table.time, table.lines = uniform_time(table.row_time)
    return table


def distance_problems(
    distance: np.ndarray,
    speed: np.ndarray,
    axis: str,
    first_row: int | np.ndarray,
    speed_column: str = "speed_kmh",
    speed_unit: tuple[float, str | None] = (1 / 3.6, "km/h"),
) -> list[str]:
    """Problems of a table's distance axis (m) at its ``speed`` (m/s, from the column
    ``speed_column``, whose values are named in its own unit: ``speed_unit``, the factor
    to m/s and the unit's name): every speed positive
    (a stop has no distance to sample it by), distances finite and strictly increasing,
    and no jump: a step longer than :data:`JUMP_FACTOR` times the median both in distance
    and in its time at the speed (a chainage jump, or samples lost; resampled onto time, a
    50 m jump at 60 km/h became 3 s of interpolated forces). A long run's reader cuts the
    run at such a jump (``railsusp sections``); a recording is one stretch."""
    still = ~(speed > 0)  # NaN too
    if still.any():
        a, b = runs(still)[0]
        value = "empty" if np.isnan(speed[a]) else f"{speed[a] / speed_unit[0]:g} {speed_unit[1]}"
        return [
            f"column {speed_column!r}, {rows(a, b - 1, first_row)}: speed {value} "
            f"({int(still.sum())} row(s) in all); a table along {axis} needs the speed "
            "positive in every row (a stop has no distance to sample it by: give time_s)"
        ]
    if distance.size < 3:
        return []  # (the reader refuses a table this short)
    unknown = ~np.isfinite(distance)
    if unknown.any():
        a, b = runs(unknown)[0]
        return [
            f"column {axis!r}, {rows(a, b - 1, first_row)}: distance empty or not finite "
            f"({int(unknown.sum())} row(s) in all); accepted a finite distance, m, in every "
            "row, strictly increasing"
        ]
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


def row_times(distance: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Each row's time, s, of a table along ``distance`` (m, checked by
    :func:`distance_problems`) at ``speed`` (m/s): the integral of ds / v from the first row
    (trapezoidal mean speed per step). Rows uniform in distance are not uniform in time
    where the speed varies (time = distance / speed holds only at constant speed)."""
    if distance.size < 3:  # (the reader refuses a table this short, by its rows)
        return distance / speed
    steps = np.diff(distance) / (0.5 * (speed[1:] + speed[:-1]))
    return np.concatenate([[0.0], np.cumsum(steps)])


def uniform_time(t: np.ndarray) -> tuple[np.ndarray, int | np.ndarray]:
    """A uniform time base over the rows' times ``t`` at their median interval, and the
    file line of the row nearest each of its samples (messages name the lines to look at);
    ``t`` itself where there are too few rows to have an interval."""
    if t.size < 3:
        return t, 2
    dt = float(np.median(np.diff(t)))
    uniform = np.arange(0.0, t[-1] + 0.5 * dt, dt)
    uniform = uniform[uniform <= t[-1] + 1e-9 * dt]  # (the last row, less rounding)
    nearest = np.rint(np.interp(uniform, t, np.arange(t.size))).astype(int)
    return uniform, nearest + 2
