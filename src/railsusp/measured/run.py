"""A measured run: a long recording read through its channel map into SI channels on one
time base, every check passed. The sections (:mod:`railsusp.measured.sections`) are cut
from it.

This module is the reader and the run it returns; the checks of the run as a whole (force
channels' rates, units, speed, cant, grade and distance within their limits) are
:mod:`railsusp.measured.run_checks`, and the speed derived from a distance channel alone is
:mod:`railsusp.measured.speed_from_distance`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError, did_you_mean
from railsusp.measured.breaks import (
    channel_nan_gaps,
    compared_paths,
    dropout_breaks,
    filled,
    inner,
    jump_steps,
    nan_gap_breaks,
    without_jumps,
)
from railsusp.measured.channels import (
    SIGNALS,
    ChannelMap,
    check_recording_name,
    default_map,
    documented_twice,
    is_documented,
)
from railsusp.measured.checks import (
    MAX_GAP_SAMPLES,
    check_clipped,
    check_finite,
    check_flat,
    check_forces,
    check_time,
    jitter_of,
)
from railsusp.measured.raw import RawChannel, read_raw
from railsusp.measured.recording import RecordingError
from railsusp.measured.run_checks import (
    MAX_SPEED_KMH,
    MIN_RUNNING_SHARE,
    channel_unit,
    check_force_rates,
    check_spans,
    check_track_channels,
    time_base,
)
from railsusp.measured.sampling import (
    FiniteSampling,
    check_sparse,
    every_k_rows,
    finite_rate_note,
    finite_sampling,
    missing_rows,
    short_gaps_note,
)
from railsusp.measured.speed_from_distance import distance_through_steps, smoothed_gradient
from railsusp.measured.units import normalise_unit, si_factor


@dataclass
class MeasuredRun:
    """One run along the line, SI units on one uniform time base."""

    source: str
    time: np.ndarray  # s
    Y: dict[str, np.ndarray]  # wheel -> N
    Q: dict[str, np.ndarray]  # wheel -> N
    speed: np.ndarray  # m/s
    position: np.ndarray  # m along the line
    curvature: np.ndarray | None = None  # 1/m, + left-hand
    cant: np.ndarray | None = None  # m
    grade: np.ndarray | None = None  # 1 (m/m), + up-grade
    rates_hz: dict[str, float] = field(default_factory=dict)  # as the file states them
    notes: list[str] = field(default_factory=list)
    #: those of the notes that say what the data lacked (NaN gaps interpolated), not how
    #: its channels were read (a slower channel interpolated onto the forces' rate)
    data_notes: list[str] = field(default_factory=list)
    #: per sample, True where the wagon runs against the run's sense of travel (wheelset 1
    #: trailing, left and right swapped against the model's); None: never
    backwards: np.ndarray | None = None
    #: sample indices i where the run breaks between samples i - 1 and i: a dropout (samples
    #: lost), either end of a NaN gap of a used channel, or a jump of the position channel
    #: (a chainage jump, an odometer's reset); no section spans one
    breaks: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: per sample, True inside a jump of the distance channel (between its samples before
    #: and after the jump: a distance interpolated across it, no place on the line); None:
    #: no jump
    jumping: np.ndarray | None = None
    #: the NaN gaps of used channels longer than the samples interpolated, on this time
    #: base: (start, end exclusive, channel). Their values are interpolated so that the
    #: run's position and track go on through them; they are left out of every section
    gaps: tuple[tuple[int, int, str], ...] = ()
    #: True where the position is the speed integrated from 0 at the first sample (no
    #: position channel): km 0 of a line description is then where the run starts
    position_from_speed: bool = False
    #: force channel -> per sample of ``time``, True where its value is interpolated
    #: across missing values (NaN: short gaps filled, and the long ones of ``gaps``), not
    #: measured; only channels with such samples
    interpolated: dict[str, np.ndarray] = field(default_factory=dict)
    #: wheel -> {"Y": channel, "Q": channel}: the channels its forces were read from (the
    #: map's, or the documented column names'), the keys of ``interpolated``
    force_channels: dict[str, dict[str, str]] = field(default_factory=dict)

    def interpolated_at(self, wheel: str, force: str) -> np.ndarray:
        """Per sample, True where ``wheel``'s ``force`` ("Y" or "Q") is interpolated across
        missing values, not measured."""
        channel = self.force_channels.get(wheel, {}).get(force)
        return self.interpolated.get(channel, np.zeros(self.time.size, dtype=bool))

    @property
    def rate_hz(self) -> float:
        return float(1.0 / np.median(np.diff(self.time)))

    @property
    def wheels(self) -> tuple[str, ...]:
        return tuple(self.Y)


#: the lowest rate of a long run's force channels: the field folders' default minimum
#: (:func:`railsusp.measured.recording_reader.read_recording`'s ``min_rate_hz``)
MIN_RUN_RATE_HZ = 50.0


def read_run(
    path: str | Path,
    channel_map: ChannelMap | None = None,
    *,
    gap_limit: int = MAX_GAP_SAMPLES,
    wheel_load_N: float | None = None,
    min_rate_hz: float = MIN_RUN_RATE_HZ,
) -> MeasuredRun:
    """Read a recording (MDF4, CSV, Parquet) through its channel map; raise
    :class:`RecordingError` listing every problem (file, channel, rows). The force channels
    must be sampled at ``min_rate_hz`` or more (the rate the sections are resampled to: a
    2 Hz run upsampled to 50 Hz would pass every later check), the speed channel forward;
    a used MDF channel must lie on a time master. A NaN gap of a used channel longer than
    ``gap_limit`` samples cuts the run as a dropout does, its samples left out of the
    sections (:mod:`railsusp.measured.breaks`); shorter ones are interpolated, at most 5 %
    of a force channel's samples (at its rate of finite samples, which must reach
    ``min_rate_hz``: :mod:`railsusp.measured.sampling`, the field reader's rule too). A
    table's speed, position or track column with a value every k rows is read at its rate
    (:func:`~railsusp.measured.sampling.every_k_rows`), and those channels' timestamps may
    jitter by :data:`~railsusp.measured.checks.SLOW_JITTER_TOLERANCE` of their step."""
    path = Path(path)
    if channel_map is not None:  # before the file is read: a long run takes a while
        check_recording_name(channel_map, path)
    try:
        raw = read_raw(
            path,
            channel_map.time if channel_map else None,
            keep=set(channel_map.used()).__contains__ if channel_map else is_documented,
        )
    except RecordingError:  # the table file's problems, listed
        raise
    except RailsuspInputError as exc:
        raise RecordingError(path, [str(exc).removeprefix(f"recording {path}: ")]) from None
    cmap = channel_map or default_map(list(raw))
    problems: list[str] = [] if channel_map else documented_twice(list(raw))
    notes: list[str] = []
    data_notes: list[str] = []
    for c in cmap.used():
        if c in raw and raw[c].master is not None:
            problems.append(
                f"channel {c!r} is sampled on the master channel {raw[c].master}, not time; "
                "accepted channels on a time master (export the run on its time base)"
            )
        if c in raw and raw[c].unreadable is not None:  # a table's column
            problems.append(f"column {c!r}{raw[c].unreadable[0]}")
        if c in raw and raw[c].groups > 1:
            problems.append(
                f"channel {c!r} appears in {raw[c].groups} groups of the file at the same "
                "time (or in other units): which one is meant cannot be told; export the run "
                "with distinct channel names (groups that follow each other in time are "
                "joined)"
            )
    missing = [c for c in cmap.used() if c not in raw]
    for c in missing:
        problems.append(
            f"channel {c!r} of the {cmap.source} not in the file{did_you_mean(c, list(raw))}"
        )
    if not cmap.wheels:
        problems.append(
            "no wheel force channels: give a channel map (--map) or name the columns "
            "Y_<wheel>_kN and Q_<wheel>_kN"
        )
    if "speed" not in cmap.signals and "position" not in cmap.signals:
        problems.append("neither a speed nor a position channel (speed_kmh, distance_m)")
    for c in cmap.units:  # a misspelt name left its channel without the unit it was given
        if c not in raw:
            problems.append(
                f"[units] channel {c!r} of the {cmap.source} not in the file"
                f"{did_you_mean(c, list(raw))}"
            )
    absent = [c for c in cmap.ignore if c not in raw]
    if absent:
        notes.append(f"ignore: channel(s) not in the file: {', '.join(absent)}")
    unused = [
        c if raw[c].unreadable is None else f"{c} ({raw[c].unreadable[1]})"
        for c in raw
        if c not in cmap.used() and c not in cmap.ignore
    ]
    if unused:
        notes.append(f"channel(s) not used: {', '.join(unused)}")
    if problems:
        raise RecordingError(path, problems)

    quantity = {c: "force" for w in cmap.wheels.values() for c in w.values()}
    quantity.update({c: SIGNALS[k] for k, c in cmap.signals.items()})
    si: dict[str, RawChannel] = {}
    sampling: dict[str, FiniteSampling] = {}  # a force channel's finite samples
    missing: dict[str, np.ndarray] = {}  # a force channel's NaN samples, on its own time
    nan_gaps: dict[str, list[tuple[int, int]]] = {}
    for name, q in quantity.items():
        ch = raw[name]
        unit = channel_unit(ch, cmap, problems, q)
        try:
            factor = si_factor(q, unit, name)
        except RailsuspInputError as exc:
            problems.append(str(exc))
            continue
        if q != "force":  # a table's column with a value every k rows: at its rate
            ch, note = every_k_rows(ch)
            notes += [note] if note else []
        # a slow channel is only interpolated: its timestamps may jitter (a CAN bus's)
        time_problems = check_time(ch.time, name, ch.first_row, dropouts=True, jitter=jitter_of(q))
        problems += time_problems
        values, finite_problems, finite_notes = check_finite(
            ch.values, name, ch.first_row, gap_limit, keep_long=True
        )
        problems += finite_problems
        if q == "force":  # (on the values with their long gaps NaN: not judged)
            sampling[name] = finite_sampling(ch.values, ch.rate_hz, gap_limit)  # the file's
            if not finite_problems:
                problems += check_sparse(sampling[name], name, gap_limit)
            missing[name] = missing_rows(ch.values, sampling[name].step)  # not rows off its step
            # noted: its samples missing at its rate, not its rows off its step
            note = short_gaps_note(name, sampling[name])
            finite_notes = [note] if note and finite_notes else []
            problems += check_flat(values, name, unit or "")  # a value in the file's unit
            problems += check_clipped(values, name, unit or "")
        notes += finite_notes
        data_notes += finite_notes
        if not time_problems and not finite_problems:
            kept = RawChannel(name, normalise_unit(unit), ch.time, values * factor, ch.first_row)
            gap_notes: list[str] = []
            nan_gaps[name] = channel_nan_gaps(kept, gap_limit, problems, gap_notes)
            notes += gap_notes
            data_notes += gap_notes
            kept.values = filled(kept.values)
            si[name] = kept
    if problems:
        raise RecordingError(path, problems)

    force_names = [c for w in cmap.wheels.values() for c in w.values()]
    finite_hz = {c: sampling[c].rate_hz for c in force_names}
    base = time_base(
        force_names,
        finite_hz,
        {c: si[c].rate_hz for c in force_names},
        {c: si[c].time.size for c in force_names},
    )
    t = si[base].time
    rates = {c: si[c].rate_hz for c in quantity}
    problems += check_force_rates(force_names, base, finite_hz, min_rate_hz, stated=rates)
    for c in force_names:
        note = finite_rate_note(c, sampling[c], rates[c])
        if note:
            notes.append(note)
            data_notes.append(note)
    problems += check_spans(si, base, quantity)
    breaks = dropout_breaks(si, base, quantity, problems, notes, data_notes)
    gap_breaks, gaps = nan_gap_breaks(si, {c: g for c, g in nan_gaps.items() if g}, t, problems)
    if problems:
        raise RecordingError(path, problems)

    def shared(c: str) -> bool:  # the channel's time base is the run's
        ch = si[c]
        return ch.time.size == t.size and np.allclose(ch.time, t, rtol=0, atol=1e-9)

    def on_base(c: str) -> np.ndarray:
        ch = si[c]
        if shared(c):
            return ch.values
        notes.append(f"channel {c!r} ({ch.rate_hz:.4g} Hz) interpolated onto {rates[base]:.4g} Hz")
        return np.interp(t, ch.time, ch.values)

    Y = {w: cmap.y_signs.get(w, 1) * on_base(c["Y"]) for w, c in cmap.wheels.items()}
    for w in sorted(cmap.y_signs):
        notes.append(f"Y of {w} ({cmap.wheels[w]['Y']!r}) negated: Y_sign = -1 in the map")
    Q = {w: on_base(c["Q"]) for w, c in cmap.wheels.items()}
    interpolated = {
        c: m if shared(c) else np.interp(t, si[c].time, 1.0 * m) > 0
        for c, m in missing.items()
        if m.any()
    }
    sig = {k: on_base(c) for k, c in cmap.signals.items()}
    speed_channel = si.get(cmap.signals.get("speed", ""))
    jumps = np.zeros(0, dtype=np.int64)
    jumping = np.zeros(0, dtype=bool)
    if "position" in cmap.signals:
        pos = si[cmap.signals["position"]]
        raw_speed = (
            np.interp(pos.time, speed_channel.time, speed_channel.values)
            if speed_channel is not None
            else None
        )
        jump = jump_steps(pos.values, pos.time, raw_speed)
        jumping = np.zeros(t.size, dtype=bool)
        if jump.size:
            # the base samples between the distance's samples before and after a jump have
            # no place on the line: cut on either side of them
            first = np.searchsorted(t, pos.time[jump], "right")
            last = np.searchsorted(t, pos.time[jump + 1], "left")
            for a, b in zip(first, last, strict=True):
                jumping[a:b] = True
            jumps = np.unique(np.concatenate([first, last]))
            notes.append(
                f"channel {pos.name!r}: {jump.size} jump(s) of the distance (a chainage jump "
                "or an odometer's reset); sections are cut there"
            )
    if "speed" in sig:
        speed = sig["speed"]
        position = sig.get("position")
        if position is None:
            position = np.concatenate(
                [[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))]
            )
    else:
        position = sig["position"]
        travelled = without_jumps(pos.values, jump)
        speed = smoothed_gradient(distance_through_steps(pos.time, travelled, t), t)
    speed_name = cmap.signals.get("speed", cmap.signals.get("position"))
    running = np.abs(speed) >= 0.5  # standing stretches are cut out as "standing" later
    if np.mean(running) < MIN_RUNNING_SHARE:
        problems.append(
            f"channel {speed_name!r}: the speed "
            f"is above 1.8 km/h in {100.0 * np.mean(running):.3g} % of the samples; the wagon "
            "does not run"
        )
    elif "speed" in sig and np.nanmedian(speed[running]) < 0.0:  # signed: going backwards
        problems.append(
            f"channel {cmap.signals['speed']!r}: median speed "
            f"{np.median(speed[running]) * 3.6:.3g} "
            "km/h, negative: the wagon runs backwards in the recording's sense, wheelset 1 "
            "trailing and left and right swapped against the model's; accepted a run with "
            "wheelset 1 leading (speed positive)"
        )
    elif np.max(np.abs(speed)) > MAX_SPEED_KMH / 3.6:
        derived = "" if "speed" in sig else f", derived from the distance in {pos.unit}"
        problems.append(
            f"channel {speed_name!r}: speed up to "
            f"{np.max(np.abs(speed)) * 3.6:.4g} km/h (read as "
            f"{si[speed_name].unit}{derived}), beyond a "
            f"working condition's {MAX_SPEED_KMH:g} km/h: a unit error?"
        )
    # the run's sense of travel: forward for a speed channel (a run mostly backwards is
    # refused above), the distance's usual sense for a distance alone (km posts may count
    # down); the stretches against it are left out when the run is cut
    sense = (
        1.0 if "speed" in sig or not running.any() or np.nanmedian(speed[running]) >= 0.0 else -1.0
    )
    backwards = running & (sense * speed < 0.0)
    if backwards.any():
        notes.append(
            f"channel {speed_name!r}: {100.0 * backwards.mean():.3g} % of the samples run "
            "backwards (wheelset 1 trailing); those stretches are left out"
        )
    paths = None
    if "position" in cmap.signals and "speed" in sig:  # outside the gaps of either
        pair = (pos.name, cmap.signals["speed"])
        spans = [(a, b) for a, b, c in gaps if c in pair]
        paths = compared_paths(pos, nan_gaps.get(pos.name, []), jump, speed, t, spans)
    problems += check_track_channels(sig, cmap.signals, paths)
    if wheel_load_N is None:
        from railsusp.vehicle.setup import static_wheel_load
        from railsusp.vehicle.wagon import load_wagon

        wheel_load_N = static_wheel_load(load_wagon())
    for w, c in cmap.wheels.items():
        problems += check_forces(
            Y[w],
            Q[w],
            (c["Y"], c["Q"]),
            (si[c["Y"]].unit or "", si[c["Q"]].unit or ""),
            wheel_load_N,
            si[c["Q"]].first_row,
        )
    if problems:
        raise RecordingError(path, problems)
    return MeasuredRun(
        str(path),
        t,
        Y,
        Q,
        np.abs(speed),
        position,
        sig.get("curvature"),
        sig.get("cant"),
        sig.get("grade"),
        rates,
        notes,
        data_notes,
        backwards if backwards.any() else None,
        inner(np.union1d(np.union1d(breaks, jumps), gap_breaks), t.size),
        jumping if jumping.any() else None,
        gaps,
        "position" not in cmap.signals,
        interpolated,
        {w: dict(c) for w, c in cmap.wheels.items()},
    )
