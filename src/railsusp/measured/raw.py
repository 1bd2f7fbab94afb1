"""Raw recordings as the measurement system wrote them: every channel with the name, unit,
time base and sampling rate the file states. ASAM MDF4 (``.mf4``/``.mdf``) through asammdf;
CSV and Parquet tables with unit-aware headers (``Y_kN``, ``Y [N]``, ``Y (kN)``).
"""

from __future__ import annotations

import gc
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from railsusp.errors import RailsuspInputError, did_you_mean
from railsusp.measured.recording import RecordingError
from railsusp.measured.table_file import (
    TWICE_REFUSED,
    column_numbers,
    read_frame,
    twice_said,
)
from railsusp.measured.units import si_factor, split_header

MDF_SUFFIXES = (".mf4", ".mdf", ".dat")
TABLE_SUFFIXES = (".csv", ".parquet")


@dataclass
class RawChannel:
    """One recorded channel: samples on its own time base, with the unit the file states."""

    name: str
    unit: str | None
    time: np.ndarray
    values: np.ndarray
    #: the file line (tables) of the first sample, for messages; or of each sample, where
    #: the table was resampled (:func:`railsusp.measured.checks.rows`)
    first_row: int | np.ndarray = 2
    groups: int = 1  # MDF: how many groups hold a channel of this name (used: refused)
    master: str | None = None  # MDF: what its group's master is where not time in s
    #: tables: why the column is no channel (named twice, cells not numbers), as a problem
    #: to follow ``column 'X'`` and in short; refused where the map uses it, noted where not
    unreadable: tuple[str, str] | None = None
    #: MDF: read without its samples (``read_raw``'s ``keep``): ``time`` is its first and last
    #: timestamp, ``values`` empty
    listed: bool = False

    @property
    def rate_hz(self) -> float:
        """Median sampling rate, Hz (NaN for fewer than two samples)."""
        d = np.diff(self.time)
        d = d[np.isfinite(d)]
        return float(1.0 / np.median(d)) if d.size and np.median(d) > 0 else float("nan")


def read_raw(
    path: str | Path, time_column: str | None = None, keep: Callable[[str], bool] | None = None
) -> dict[str, RawChannel]:
    """Every channel of a recording, by name; errors name the file and what is wrong.

    ``keep(name)``: of an MDF file, the channels whose samples are kept; the others are
    listed with their name, unit, master and groups but no samples (:attr:`RawChannel.listed`),
    so that a long run's memory holds only the channels a channel map uses. An instrumented
    wheelset's logger records many more (bridges, temperatures, GPS): an hour of 40 channels
    at 1 kHz is 2.3 GB of samples and timestamps in float64. Tables are read whole."""
    path = Path(path)
    if path.is_dir():
        raise RailsuspInputError(f"recording {path}: a folder, not a recording file")
    if not path.is_file():
        raise RailsuspInputError(f"recording {path}: no such file")
    suffix = path.suffix.lower()
    if suffix in MDF_SUFFIXES:
        return _read_mdf(path, keep)
    if suffix in TABLE_SUFFIXES:
        return _read_table(path, time_column)
    raise RailsuspInputError(
        f"recording {path}: suffix {path.suffix!r} not read; accepted "
        f"{', '.join(MDF_SUFFIXES + TABLE_SUFFIXES)}"
    )


def _read_mdf(path: Path, keep: Callable[[str], bool] | None) -> dict[str, RawChannel]:
    """Channels of an MDF file, each on its own group's time base (as the file states it);
    only those ``keep`` names with their samples (:func:`read_raw`). asammdf reads one
    channel at a time, so the memory held is the kept channels' and one more; the kept
    channels of one data group share its time base's array."""
    mdf = _open_mdf(path)
    out: dict[str, RawChannel] = {}
    times: dict[int, np.ndarray] = {}  # a data group's time base, s
    last = None  # the last channel read whole, to say where a damaged file breaks
    try:
        for sig in mdf.iter_channels(skip_master=True):
            last = sig
            if sig.samples.dtype.kind not in "fiub" or sig.samples.ndim != 1:
                continue  # text, byte-array and composed channels carry no measured value
            master, scale = _master(mdf, sig)
            if keep is not None and not keep(sig.name):  # its span only, for the groups
                stamps = np.asarray(sig.timestamps, dtype=float)
                span = stamps[[0, -1]] * scale if stamps.size else stamps
                part = RawChannel(
                    sig.name, sig.unit or None, span, np.empty(0), 0, master=master, listed=True
                )
            else:
                part = RawChannel(
                    sig.name,
                    sig.unit or None,
                    _group_time(times, sig, scale),
                    _values(sig),
                    first_row=0,
                    master=master,
                )
            if sig.name in out:
                out[sig.name] = _continued(out[sig.name], part)
                continue
            out[sig.name] = part
    except RailsuspInputError:
        raise
    except Exception as exc:
        where = (
            "its first channel"
            if last is None
            else f"the channel after {last.name!r} (data group {last.group_index})"
        )
        raise RailsuspInputError(
            f"recording {path}: damaged MDF file: cannot read {where} ({_reason(exc)}); "
            f"{DAMAGED_REMEDY}"
        ) from None
    finally:
        mdf.close()
    if not out:
        raise RailsuspInputError(f"recording {path}: no numeric channel in the file")
    return out


def _group_time(times: dict[int, np.ndarray], sig: Any, scale: float) -> np.ndarray:
    """The time base (s) of the channel's data group, converted once per group."""
    group = sig.group_index
    if group not in times or times[group].size != len(sig.timestamps):
        times[group] = np.asarray(sig.timestamps, dtype=float) * scale
    return times[group]


def _values(sig: Any) -> np.ndarray:
    """A channel's samples as floats, those the logger marked invalid NaN (then checked as
    gaps are)."""
    values = np.asarray(sig.samples, dtype=float)
    if sig.invalidation_bits is not None:
        invalid = np.asarray(sig.invalidation_bits, dtype=bool)
        if invalid.any():
            values = np.where(invalid, np.nan, values)
    return values


def _continued(before: RawChannel, part: RawChannel) -> RawChannel:
    """A channel name met again in another data group: a logger that went on recording in
    a new group (the part starts after the other ends, or ends before it starts, with the
    same unit and master) is one channel, joined in time (the join checked later like any
    dropout); otherwise the two cannot be told apart, and the count of groups makes
    :func:`~railsusp.measured.run.read_run` refuse the channel where the map uses it."""
    same = part.unit == before.unit and part.master == before.master
    if same and part.time.size and before.time.size and before.groups == 1:
        order = (
            (before, part)
            if part.time[0] > before.time[-1]
            else (part, before)
            if part.time[-1] < before.time[0]
            else None
        )
        if order is not None:
            return RawChannel(
                before.name,
                before.unit,
                np.concatenate([c.time for c in order]),
                np.concatenate([c.values for c in order]),
                first_row=0,
                master=before.master,
                listed=before.listed,
            )
    before.groups += 1
    return before


#: what to do with an MDF file whose blocks do not hold together (a truncated copy, an
#: interrupted logger write, a transfer that changed bytes): the one-line errors end with it
DAMAGED_REMEDY = "copy it again, or export it again from the logger"


def _reason(exc: Exception) -> str:
    """asammdf's exception as a reader can place it: its type where the text alone is a
    bare key such as ``(0, 1)`` (a block index asammdf did not find)."""
    text = str(exc)
    if isinstance(exc, OSError | ValueError) and text:
        return text
    return f"{type(exc).__name__}: {text}"


#: MDF4 master channels' sync types (ASAM MDF 4.x, cn_sync_type): the samples are on time
#: only for 1; 2 angle, 3 distance, 4 index
_SYNC_TIME, _SYNC_NAMES = 1, {2: "angle", 3: "distance", 4: "index"}


def _master(mdf: Any, sig: Any) -> tuple[str | None, float]:
    """What the channel's group's master is where it is not time (None where it is), and
    the factor taking its values to seconds (a master in ms). A distance master in metres
    was read as seconds: a 3 km run at 60 km/h became 50 minutes. :func:`~railsusp.measured
    .run.read_run` refuses a used channel on such a master; other channels do not count."""
    group = sig.group_index
    index = mdf.masters_db.get(group)
    if index is None:  # no master of its own (MDF 4.2 remote masters): the file's time
        return None, 1.0
    master = mdf.groups[group].channels[index]
    sync = getattr(master, "sync_type", _SYNC_TIME) or _SYNC_TIME  # MDF3: time always
    if sync != _SYNC_TIME:
        return f"{master.name!r} of {_SYNC_NAMES.get(sync, f'sync type {sync}')}", 1.0
    unit = (getattr(master, "unit", "") or "").strip()
    if not unit:
        return None, 1.0
    try:
        return None, si_factor("time", unit, master.name)
    except RailsuspInputError:
        return f"{master.name!r} in {unit!r}", 1.0


def _open_mdf(path: Path) -> Any:
    """asammdf's MDF of ``path``; a damaged file is a one-line input error. The half-built
    object asammdf leaves behind then fails again in its ``__del__`` ("Exception ignored in
    MDF4.__del__" on stderr after our error): that one message is silenced while it goes."""
    from asammdf import MDF

    def hook(unraisable: Any) -> None:
        if not getattr(unraisable.object, "__qualname__", "").startswith("MDF"):
            default(unraisable)

    default = sys.unraisablehook
    sys.unraisablehook = hook
    try:
        try:
            return MDF(str(path))
        except Exception as exc:  # asammdf raises many types on a damaged file
            message = (
                f"recording {path}: not a readable MDF file ({_reason(exc)}): not MDF, "
                f"or truncated or damaged; {DAMAGED_REMEDY}"
            )
        with warnings.catch_warnings():  # its file, left open by asammdf: not the user's
            warnings.simplefilter("ignore", ResourceWarning)
            gc.collect()  # the half-built object's __del__ runs now, under the hook
    finally:
        sys.unraisablehook = default
    raise RailsuspInputError(message)


def _read_table(path: Path, time_column: str | None) -> dict[str, RawChannel]:
    """Channels of a CSV/Parquet table sharing its time column (``time_s``, ``t [s]``, ...).
    The file is read as a field table's is (:func:`~railsusp.measured.table_file.read_frame`:
    its lines that are not UTF-8 named, a ``;`` separator said, lines with more cells than
    the header refused), raising :class:`~railsusp.measured.recording.RecordingError` with
    every problem of the file. A column named twice, or of cells that are not numbers, is a
    problem where it is the time column; another is kept as :attr:`RawChannel.unreadable`
    (its first copy), for :func:`~railsusp.measured.run.read_run` to refuse where the map
    uses it and note where not: a logger's second ``status`` column, or a text ``state``,
    refused a whole long run."""
    df, _, twice = read_frame(path)  # (a column without a name: never a used channel)
    cols = [str(c) for c in df.columns]
    tcol = time_column
    if tcol is None:
        tcol = next((c for c in cols if split_header(c)[0] in ("time", "t")), None)
    if tcol is None or tcol not in cols:
        hint = did_you_mean(tcol, cols) if tcol else ""
        raise RecordingError(
            path, [f"no time column ({tcol or 'time_s, time [s]'}){hint}; columns {cols}"]
        )
    tname, tunit = split_header(tcol)
    if tname == "distance":  # its metres were read as seconds: 2 km at 60 km/h as 33 km
        raise RecordingError(
            path,
            [
                f"column {tcol!r}, the time column, is a distance, not time; accepted a time "
                "column (time_s, 't [s]'; the map's time = ...), the distance as position = ..."
            ],
        )
    try:  # a unit other than s and ms was read as seconds (a "time [msec]" column of 200 Hz)
        factor = 1.0 if tunit is None else si_factor("time", tunit, tcol)
    except RailsuspInputError as exc:
        raise RecordingError(path, [str(exc)]) from None
    t, why, _ = column_numbers(df[tcol])
    problems = []
    if tcol in twice:
        problems.append(f"column {tcol!r}{twice_said(twice[tcol])}{TWICE_REFUSED}")
    if why is not None:
        problems.append(f"column {tcol!r}{why}")
    if problems:
        raise RecordingError(path, problems)
    t = t * factor
    out = {}
    for c in cols:
        if c == tcol:
            continue
        x, why, short = column_numbers(df[c])
        x = np.full(t.size, np.nan) if why is not None else x  # (never read as values)
        ch = RawChannel(c, split_header(c)[1], t, x)
        if c in twice:
            at = ", ".join(str(i) for i in twice[c])
            ch.unreadable = (f"{twice_said(twice[c])}{TWICE_REFUSED}", f"in columns {at}")
        elif why is not None:
            ch.unreadable = (why, f"{short}, not numbers")
        out[c] = ch
    return out
