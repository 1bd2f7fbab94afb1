"""A long run as the source of a pipeline's recordings: read through its channel map, cut
into sections (against its geometry channels, a line description or a section table), the
kept sections' working conditions, and the field folder written from them.

``railsusp sections`` does the same steps by hand; ``railsusp run`` with ``[field]
recording = ...`` does them here, so that the campaign knows the sections' conditions
before the field stage writes their recordings. The cut is cached per file state (path,
size, modification time) and rules: the configuration check, the stage hashes and the
field stage ask for it. One cut is kept (a 2 h run at 1 kHz is about 0.5 GB), and none
once the pipeline's field stage is passed, written or skipped (:func:`release_cut`): the
sections' conditions, which the later stages ask for, are cached on their own (a few kB).
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.measured.channels import read_channel_map
from railsusp.measured.pieces import MIN_DURATION_S
from railsusp.measured.run import MeasuredRun, read_run
from railsusp.measured.sections import (
    Section,
    SectionRules,
    cut_sections,
    read_line,
    read_section_table,
)
from railsusp.measured.sections_out import section_recording, write_sections

log = logging.getLogger("railsusp.measured")


@dataclass(frozen=True)
class RunSource:
    """A long run and how to cut it: the recording, its channel map (None: the documented
    column names), a line description or a section table (neither: the run's own geometry
    channels), the rules, the sampling rate of the written sections, and the static wheel
    load its wheel loads are checked against (None: the packaged C80's)."""

    recording: Path
    channel_map: Path | None = None
    line: Path | None = None
    table: Path | None = None
    rules: SectionRules = field(default_factory=SectionRules)
    rate_hz: float = 50.0
    wheel_load_N: float | None = None

    def __post_init__(self) -> None:
        if self.line is not None and self.table is not None:
            raise RailsuspInputError("give a line description or a section table, not both")
        if not 10.0 <= self.rate_hz <= 5000.0:
            raise RailsuspInputError(f"rate {self.rate_hz:g} Hz: accepted 10 to 5000 Hz")

    def files(self) -> tuple[Path, ...]:
        return tuple(p for p in (self.recording, self.channel_map, self.line, self.table) if p)

    def state(self) -> tuple:
        """What the cut depends on: the files' paths, sizes and modification times, the
        rules and the rate (the key of the cache, and part of the pipeline's stage hash)."""
        stats = []
        for p in self.files():
            st = Path(p).stat()
            stats.append((str(Path(p).resolve()), st.st_size, st.st_mtime_ns))
        return (tuple(stats), self.rules, self.rate_hz, self.wheel_load_N)


def cut_run(source: RunSource) -> tuple[MeasuredRun, list[Section]]:
    """The run read (every check passed) and cut; a bad recording raises
    :class:`~railsusp.measured.RecordingError`, a bad map, line or table an input error."""
    return _cut(source, source.state())


@lru_cache(maxsize=1)
def _cut(source: RunSource, _state: tuple) -> tuple[MeasuredRun, list[Section]]:
    """The cut of ``source`` at file state ``_state`` (the cache's key). One is kept: four
    kept a pipeline's 2 h runs alive, 0.5 GB each, for the pipeline's life."""
    cmap = read_channel_map(source.channel_map) if source.channel_map else None
    run = read_run(
        source.recording, cmap, min_rate_hz=source.rate_hz, wheel_load_N=source.wheel_load_N
    )
    secs = cut_sections(
        run,
        source.rules,
        line=read_line(source.line) if source.line else None,
        table=read_section_table(source.table) if source.table else None,
    )
    if not any(s.kept for s in secs):
        raise RailsuspInputError(f"{source.recording}: {none_kept(secs, source.rules)}")
    return run, secs


#: what each kind of left-out piece (:attr:`Section.pieces`) says of the run
_LEFT_OUT = {
    "standing": "standing",
    "transition": "transition (curvature or grade changing)",
    "mixed": "more than one kind of track in a table row",
    "gap": "gaps of missing values",
    "radius": "curves tighter than a working condition",
    "wheel": "curves whose outer wheel is not recorded",
    "outside": "not covered by the line description",
    "jump": "jumps of the distance channel",
    "backwards": "running backwards",
    "reversal": "reversing (the speed through 0)",
    "cant": "cant without a curvature (a curve cut as tangent)",
    "dropout": "dropouts (samples lost)",
    "brief": f"pieces shorter than a working condition's {MIN_DURATION_S:g} s",
}


def none_kept(secs: list[Section], rules: SectionRules) -> str:
    """Why a cut kept no section, over the whole run: the metres (and a stop's seconds)
    each kind of left-out piece took, and for pieces too short for a condition what cut
    them (``[field] min_length_m``, ``max_duration_s``, ``speed_tolerance``, named with their
    values). The first three rows' reasons said a transition where the run's hour of
    tangent had been split into one-second pieces by ``max_duration_s = 1``."""
    metres: dict[str, float] = {}
    seconds: dict[str, float] = {}
    for s in secs:
        for kind, label, t, m in s.pieces:
            if kind == "short":
                why = label.split("|")[2]
                kind = "duration" if "duration" in why else "speed" if "speed" in why else kind
            metres[kind] = metres.get(kind, 0.0) + m
            seconds[kind] = seconds.get(kind, 0.0) + t
    short = {
        "short": f"shorter than field.min_length_m = {rules.min_length_m:g} m",
        "duration": (
            f"shorter than field.min_length_m = {rules.min_length_m:g} m once split at "
            f"field.max_duration_s = {rules.max_duration_s:g} s"
        ),
        "speed": (
            f"shorter than field.min_length_m = {rules.min_length_m:g} m once split where the "
            f"speed left field.speed_tolerance = {rules.speed_tolerance:g}"
        ),
    }
    parts = []
    for kind in sorted(metres, key=lambda k: -max(metres[k], seconds[k])):
        what = short.get(kind) or _LEFT_OUT.get(kind, kind)
        timed = kind in ("standing", "reversal")  # (no length)
        amount = f"{seconds[kind]:.0f} s" if timed else f"{metres[kind]:.0f} m"
        parts.append(f"{amount} {what}")
    settings = [k for k in ("short", "duration", "speed") if k in metres]
    hint = ""
    if settings:
        hint = "; accepted settings under which a stretch is long enough: " + ", ".join(
            {
                "short": "a smaller field.min_length_m",
                "duration": "a longer field.max_duration_s",
                "speed": "a wider field.speed_tolerance",
            }[k]
            for k in settings
        )
    return f"no section kept: {'; '.join(parts)}{hint}"


def section_conditions(source: RunSource) -> list[WorkingCondition]:
    """The working conditions of the kept sections, as the field folder will state them
    (duration of the section resampled to the source's rate)."""
    return list(_conditions(source, source.state()))


@lru_cache(maxsize=8)
def _conditions(source: RunSource, _state: tuple) -> tuple[WorkingCondition, ...]:
    """The kept sections' conditions of ``source`` at file state ``_state``: cached apart
    from the cut, so that the stages after the field stage, which ask for them again, do not
    read the run again once its cut is let go (:func:`write_run_field`)."""
    run, secs = cut_run(source)
    return tuple(section_recording(run, s, source.rate_hz).condition for s in secs if s.kept)


def write_run_field(source: RunSource, out: str | Path, final: str | Path | None = None) -> Path:
    """The kept sections of the run written as a field folder (``railsusp sections
    --write``: recordings, ``index.json``, ``sections.csv``, ``en14363.csv``, ...);
    ``final``: where the folder will live when ``out`` is a temporary one. The run's notes
    (NaN gaps interpolated, channels interpolated onto the forces' rate) are warned of, as
    ``railsusp check-recording`` prints them: the pipeline's field stage said nothing.
    The cut is let go afterwards (the pipeline needs only its conditions from here on,
    cached apart: :func:`section_conditions`), not kept alive for the pipeline's life."""
    run, secs = cut_run(source)
    for note in run.notes:
        text = f"{Path(source.recording).name}: {note}"
        if note in run.data_notes:  # what the data lacked (gaps interpolated): a warning
            warnings.warn(text, stacklevel=2)
        else:  # how the channels were read: a note, as check-recording says it
            log.info("note: %s", text)
    try:
        folder = write_sections(run, secs, out, source.rate_hz, final, source.wheel_load_N)
        section_conditions(source)  # cached now (already, where the pipeline asked before)
        return folder
    finally:
        release_cut()


def release_cut() -> None:
    """Let the cached cut go (the whole run: 0.5 GB for 2 h at 1 kHz); the kept sections'
    conditions stay cached apart (:func:`section_conditions`). The pipeline calls it once
    its field stage is passed, written or up to date and skipped: the configuration check
    filled the cache, and a resumed run, whose field stage is skipped, never came to
    :func:`write_run_field`, which let it go, and kept the run for the pipeline's life."""
    _cut.cache_clear()
