"""The channel map: which recorded channel is which wheel's Y and Q, the speed, the position
and the optional track geometry, read from a small TOML file.

```toml
speed = "v_train"             # running speed (or leave out and give position)
position = "s_line"           # distance along the line
curvature = "curv_track"      # optional: + left-hand curve
cant = "cant_track"           # optional
grade = "grade_track"         # optional: + up-grade
time = "t"                    # tables only: the time column (MDF4: the file's time base)
ignore = ["acc_bogie_y_g"]    # channels recorded but not used
recording = "run_0503.mf4"    # optional: the run the map is for (another file is refused)

[wheels.w1R]
Y = "WS1_Y_R"
Q = "WS1_Q_R"
Y_sign = -1                   # optional: this Y channel is + towards the track centre

[units]                       # only for channels whose file states no unit
s_line = "m"
```

A map that names its ``recording`` is for that file only: a run of another name read
through it is refused, naming both (:func:`check_recording_name`): a map written for one
run, its channels renamed after a logger's reconfiguration, read another day's run
unnoticed where the names still matched. A map for every run of a measuring system names
none.

A file without a map is read through the documented column names (``Y_w1R_kN``,
``speed_kmh``, ...), which :func:`default_map` turns into a map.

railsusp takes each wheel's lateral force Y + towards the field side (the flange force of
a guiding outer wheel is +; docs/data-format.md). Measuring systems often record it
vehicle-fixed, + to the right for both wheels: ``Y_sign = -1`` on a wheel negates its Y
channel as it is read, rather than the user rewriting the file.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from railsusp.errors import RailsuspInputError, did_you_mean, repeated
from railsusp.measured.units import split_header
from railsusp.vehicle.layout import WHEEL_NAMES

#: optional quantities a map may name, with the physical quantity of their unit
SIGNALS: dict[str, str] = {
    "speed": "speed",
    "position": "position",
    "curvature": "curvature",
    "cant": "cant",
    "grade": "grade",
}
_KEYS = {*SIGNALS, "time", "ignore", "wheels", "units", "recording"}


@dataclass(frozen=True)
class ChannelMap:
    """Recorded channel name of every quantity the estimation uses."""

    wheels: dict[str, dict[str, str]]  # wheel -> {"Y": channel, "Q": channel}
    signals: dict[str, str] = field(default_factory=dict)  # speed/position/... -> channel
    time: str | None = None
    ignore: tuple[str, ...] = ()
    units: dict[str, str] = field(default_factory=dict)
    recording: str | None = None  # the recording the map was written for, if it names one
    source: str = "channel map"
    #: wheel -> -1 where its Y channel is + towards the track centre (``Y_sign = -1``)
    y_signs: dict[str, int] = field(default_factory=dict)

    def used(self) -> list[str]:
        """Every channel the map takes, in a fixed order."""
        names = [c for w in self.wheels.values() for c in (w["Y"], w["Q"])]
        return names + list(self.signals.values())


def read_channel_map(path: str | Path) -> ChannelMap:
    """Read and check a channel-map TOML; errors name the key and what is accepted."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text("utf-8-sig"))
    except (OSError, UnicodeDecodeError) as exc:
        raise RailsuspInputError(f"channel map {path}: cannot read it ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise RailsuspInputError(f"channel map {path}: not valid TOML ({exc})") from None
    return channel_map_from(doc, str(path))


def channel_map_from(doc: dict, source: str = "channel map") -> ChannelMap:
    """A :class:`ChannelMap` from a parsed TOML document."""

    def bad(msg: str) -> RailsuspInputError:
        return RailsuspInputError(f"{source}: {msg}")

    for key in doc:
        if key not in _KEYS:
            raise bad(f"key {key!r} not recognised{did_you_mean(key, sorted(_KEYS))}")
    wheels_doc = doc.get("wheels")
    if not isinstance(wheels_doc, dict) or not wheels_doc:
        raise bad("no [wheels.<wheel>] table with Y and Q channels (wheels w1L .. w4R)")
    wheels: dict[str, dict[str, str]] = {}
    y_signs: dict[str, int] = {}
    for w, chans in wheels_doc.items():
        if w not in WHEEL_NAMES:
            raise bad(f"wheel {w!r} not known{did_you_mean(w, list(WHEEL_NAMES))}; w1L .. w4R")
        if not isinstance(chans, dict) or not {"Y", "Q"} <= set(chans) <= {"Y", "Q", "Y_sign"}:
            extra = sorted(set(chans) - {"Y", "Q", "Y_sign"}) if isinstance(chans, dict) else []
            lacks = [k for k in ("Y", "Q") if not isinstance(chans, dict) or k not in chans]
            said = "; ".join(
                filter(None, [
                    f"no key {' or '.join(lacks)}" if lacks else "",
                    f"unexpected key(s) {', '.join(map(repr, extra))}" if extra else "",
                ])
            )  # fmt: skip
            # a top-level key written after the tables lands in the last one (TOML)
            top = [k for k in extra if k in _KEYS]
            hint = (
                f" ({', '.join(map(repr, top))} belongs at the top level: write top-level "
                "keys before the first [table])"
                if top
                else ""
            )
            raise bad(
                f"wheels.{w}: {said}{hint}; accepted exactly the keys Y and Q (channel "
                "names), and optionally Y_sign (1 or -1)"
            )
        for f in ("Y", "Q"):
            if not isinstance(chans[f], str) or not chans[f]:
                raise bad(f"wheels.{w}.{f}: a channel name (text) is needed")
        sign = chans.get("Y_sign", 1)
        if isinstance(sign, bool) or sign not in (1, -1):
            raise bad(
                f"wheels.{w}.Y_sign = {sign!r}: accepted 1 (Y + towards the field side, as "
                "railsusp takes it) or -1 (the channel + towards the track centre)"
            )
        if sign == -1:
            y_signs[w] = -1
        wheels[w] = {"Y": chans["Y"], "Q": chans["Q"]}
    signals = {}
    for key in SIGNALS:
        if key in doc:
            if not isinstance(doc[key], str) or not doc[key]:
                raise bad(f"{key}: a channel name (text) is needed")
            signals[key] = doc[key]
    if "speed" not in signals and "position" not in signals:
        raise bad("neither speed nor position named; the sections need one of them")
    ignore = doc.get("ignore", [])
    if not isinstance(ignore, list) or not all(isinstance(c, str) for c in ignore):
        raise bad("ignore: a list of channel names is needed")
    units = doc.get("units", {})
    if not isinstance(units, dict) or not all(isinstance(u, str) for u in units.values()):
        raise bad('units: a table of channel = "unit" is needed')
    for key in ("time", "recording"):
        if key in doc and not isinstance(doc[key], str):
            raise bad(f"{key}: text is needed")
    if doc.get("recording") == "":
        raise bad("recording = '': accepted the run's file name, or no recording key (any run)")
    used = [c for w in wheels.values() for c in w.values()] + list(signals.values())
    twice = repeated(used)
    if twice:
        raise bad(f"channel {twice[0]!r} mapped to two quantities")
    both = [c for c in ignore if c in used]
    if both:  # accepted silently (the command-line audit of stop 60)
        raise bad(f"ignore: channel {both[0]!r} is mapped too; accepted one of the two")
    return ChannelMap(
        wheels,
        signals,
        doc.get("time"),
        tuple(ignore),
        dict(units),
        doc.get("recording"),
        source,
        y_signs,
    )


def check_recording_name(cmap: ChannelMap, path: str | Path) -> None:
    """Refuse reading ``path`` through a map whose ``recording`` names another file: the
    file names are compared, the last component of the map's (split at ``/`` and ``\\``,
    folders left aside: a map written on the logger's PC names ``C:\\meas\\run.mf4``,
    one beside the data ``../data/run.mf4``) against the file's own name or, for a link,
    its target's, case aside (a file system may ignore it). Where the folders were
    compared too, such a map was refused with the same name shown on both sides. A map
    without ``recording`` takes any file."""
    if cmap.recording is None:
        return
    named = cmap.recording.replace("\\", "/").rsplit("/", 1)[-1]
    own, target = Path(path).name, Path(path).resolve().name
    if named.casefold() in (own.casefold(), target.casefold()):
        return
    link = f", a link to {target!r}" if target != own else ""
    file = f" names the file {named!r}" if named != cmap.recording else ""
    raise RailsuspInputError(
        f"{cmap.source}: recording = {cmap.recording!r}{file}, but the file read through "
        f"the map is {own!r} ({path}{link}); accepted a recording of the "
        "file's name (folders and case aside), or a map without recording (one map for "
        "every run of a measuring system)"
    )


_DOCUMENTED = {
    "speed": "speed",
    "distance": "position",
    "position": "position",
    "curvature": "curvature",
    "cant": "cant",
    "grade": "grade",
}


def is_documented(header: str) -> bool:
    """Whether a column or channel name is one of the documented names that
    :func:`default_map` recognises."""
    return _documented(header) is not None


def _documented(header: str) -> tuple[str, str] | None:
    """What a documented column name is: ("Y" or "Q", wheel), ("signal", quantity) or
    ("time", ""); None for a name it does not recognise."""
    name, _ = split_header(header)
    parts = name.split("_")
    if len(parts) == 2 and parts[0] in ("Y", "Q") and parts[1] in WHEEL_NAMES:
        return parts[0], parts[1]
    if name in ("time", "t"):
        return "time", ""
    if name in _DOCUMENTED:
        return "signal", _DOCUMENTED[name]
    return None


def default_map(headers: list[str]) -> ChannelMap:
    """The map of a table with the documented column names (``Y_w1R_kN``, ``Y_w1R [N]``,
    ``speed_kmh``, ``distance_m``, ``curvature_1_per_km``, ``cant_mm``, ``grade_permille``,
    ``time_s``); columns it does not recognise are left for the caller to report, and one
    quantity in two columns for :func:`documented_twice` (the last one is taken here)."""
    wheels: dict[str, dict[str, str]] = {}
    signals: dict[str, str] = {}
    time = None
    for h in headers:
        kind = _documented(h)
        if kind is None:
            continue
        if kind[0] in ("Y", "Q"):
            wheels.setdefault(kind[1], {})[kind[0]] = h
        elif kind[0] == "time":
            time = h
        else:
            signals[kind[1]] = h
    complete = {w: c for w, c in wheels.items() if set(c) == {"Y", "Q"}}
    return ChannelMap(complete, signals, time, source="documented column names")


def documented_twice(headers: list[str]) -> list[str]:
    """Problems of a table read through its documented column names (no channel map) that
    gives one quantity in two columns (``Q_w1R_kN`` and ``Q_w1R [N]``, ``speed_kmh`` and
    ``speed [m/s]``, ``distance_m`` and ``position_km``), one per later column: which one
    is meant cannot be told, and :func:`default_map` took the last without a word. The
    field reader refuses a force given twice alike."""
    first: dict[tuple[str, str], str] = {}
    problems = []
    for h in headers:
        kind = _documented(h)
        if kind is None or kind[0] == "time":  # (the time column: the table reader's)
            continue
        if kind in first:
            what = f"the force {kind[0]}_{kind[1]}" if kind[0] in ("Y", "Q") else f"the {kind[1]}"
            problems.append(
                f"column {h!r}: {what} is given twice (also as {first[kind]!r}); accepted one "
                "column per quantity (or a channel map naming the one to use)"
            )
        else:
            first[kind] = h
    return problems
