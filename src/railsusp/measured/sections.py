"""A long run cut into sections of one working condition each.

A section is a stretch of one kind of track (tangent, or a curve whose radius lies in one
band, on one band of grade) run at about one speed. The track comes from the run's
curvature/cant/grade channels, or from its position against a line description (a table of
km posts with radius, cant, grade), or the user gives the sections as a table of positions
(with the rows' track, or over the run's channels). Every section's speed is the
recording's; a stretch whose speed varies by more than the tolerance is split into pieces
that hold it, a stop is one piece, and a stretch longer than the maximum duration is split
into equal parts. Pieces (and transitions between kinds) shorter than the minimum length are
left out with the reason. The kept sections become the recordings of a field folder
(:func:`~railsusp.measured.sections_out.write_sections`) that the estimation reads. The
kind of track under each sample is :mod:`railsusp.measured.track_kinds`'s.
"""

from __future__ import annotations

import itertools
from dataclasses import asdict

import numpy as np
import pandas as pd

from railsusp.errors import RailsuspInputError
from railsusp.measured.checks import label_runs, runs
from railsusp.measured.line import (  # noqa: F401  (the sources of a cut, with it)
    TABLE_TRACK,
    geometry_from_line,
    read_line,
    read_section_table,
    text_cells,
)
from railsusp.measured.pieces import (  # noqa: F401  (what a section is, with the cut)
    MIN_RADIUS_M,
    MIXED_SHARE,
    OUTSIDE_LINE,
    GapCover,
    Section,
    SectionRules,
    dropout_row,
    merged_row,
    outside_row,
    stretch_pieces,
)
from railsusp.measured.recording import RecordingError
from railsusp.measured.run import MeasuredRun
from railsusp.measured.sampling import leave_out_crowded
from railsusp.measured.track_kinds import (
    stated_track_contradicted,
    track_geometry,
    track_labels,
)
from railsusp.vehicle.simulation_result import WHEEL_NAMES, outer_wheel_index


def cut_sections(
    run: MeasuredRun,
    rules: SectionRules | None = None,
    *,
    line: pd.DataFrame | None = None,
    table: pd.DataFrame | None = None,
) -> list[Section]:
    """The run cut into sections (left-out ones included, ``kept`` False with the reason).
    A section table's rows must each lie on the run, and its track must come from somewhere
    (its columns, the run's curvature channel or ``line``); a leading wheelset's outer wheel
    whose lateral force is clearly negative where it flanges is refused (:func:`_check_y_sign`)."""
    rules = rules or SectionRules()
    if table is not None and line is None and run.curvature is None and "radius_m" not in table:
        raise RailsuspInputError(
            f"{_what(table)}: the run has no curvature channel and the table no radius_m "
            "column: every section would be a level tangent; accepted a curvature channel in "
            "the map, a line description (--line, [field] line), or the table's columns "
            f"{', '.join(TABLE_TRACK)} (radius empty or 0: tangent)"
        )
    if line is None and table is None and run.curvature is None:
        _warn(run, NO_TRACK_NOTE)
    if line is not None and run.position_from_speed:
        _warn(run, LINE_FROM_ZERO_NOTE)
    geo = track_geometry(run, rules, line, table)
    for note in stated_track_contradicted(run, table, rules, line) if table is not None else ():
        _warn(run, note)
    labels = track_labels(geo, rules)
    names, rows, partial = None, None, {}
    if table is not None:
        spans, rows, partial = _table_spans(run, table)
        names = text_cells(table["name"]) if "name" in table else None
    else:
        spans = label_runs(labels)
    spans, rows = _split_at(spans, rows, _breaks(run))
    out = _collect(
        run, geo, spans, rows, names, rules, labels if table is not None else None, partial
    )
    leave_out_crowded(run.interpolated, out)  # the run passed the rule; a section must too
    if names:
        _number_split_rows(out, names)
    kept = [s for s in out if s.kept]
    width = len(str(len(kept)))
    for n, s in enumerate(kept, 1):
        s.name = s.name or f"s{n:0{width}d}-" + s.kind.replace(" ", "-")
    _check_y_sign(run, kept)
    return out


#: what a run without any track geometry is cut as, said where the run's notes are printed
NO_TRACK_NOTE = (
    "no curvature channel, line description or section table: every section is taken as "
    "tangent track (a curve's forces would be compared with a tangent simulation; give "
    "curvature in the channel map, --line or a table with radius_m)"
)


#: what a run whose position is its integrated speed reads a line description as
LINE_FROM_ZERO_NOTE = (
    "no position channel: the position is the speed integrated from 0 at the run's first "
    "sample, so the line description's km 0 is taken as where the run starts; a run that "
    "starts elsewhere has its curves cut at the wrong places (give a position channel in "
    "the map, position = ...)"
)


def _warn(run: MeasuredRun, note: str) -> None:
    """Add ``note`` to the run's notes once, as a data note (a warning where notes are
    printed: what the cut lacks, not how a channel was read)."""
    if note not in run.notes:
        run.notes.append(note)
        run.data_notes.append(note)


def _what(table: pd.DataFrame) -> str:
    """The section table as the messages name it (its file: read_section_table's)."""
    return str(table.attrs.get("what", "section table"))


#: a section table's row whose positions the run misses over more than this (m), beyond
#: its largest distance step, is only partly on the run (its kept sections say so)
PARTIAL_ROW_M = 1.0


def _table_spans(
    run: MeasuredRun, table: pd.DataFrame
) -> tuple[list[tuple[int, int]], list, dict[int, str]]:
    """The sample spans of each row of a section table (a range the run passes twice: two
    spans), each span's row, and the reason of the kept sections of each row only partly
    on the run: it begins before the run's positions, ends after them, or the distance
    jumps over part of it (a chainage jump, an odometer's reset). Such a row is kept over
    what the run passes, saying so ("kept, 300-450 m of 300-600 m on the run"), not
    silently under the row's name as if whole. A row the run never reaches is refused: it
    vanished without a line in the cut."""
    spans, rows, partial = [], [], {}
    lo, hi = float(np.nanmin(run.position)), float(np.nanmax(run.position))
    for k, r in enumerate(table.itertuples(index=False)):
        found = runs((run.position >= r.start_m) & (run.position < r.end_m))
        if not found:
            raise RailsuspInputError(
                f"{_what(table)}, row {k + 2}: {r.start_m:g}-{r.end_m:g} m is not on the run "
                f"(positions {lo:.0f} to {hi:.0f} m); accepted rows the run passes"
            )
        covered = _covered(run, found, r.start_m, r.end_m)
        if len(covered) > 1 or (covered[0][0], covered[0][1]) != (r.start_m, r.end_m):
            on = ", ".join(_range(f"{a:.0f}", f"{b:.0f}") for a, b in covered)
            row = _range(f"{r.start_m:g}", f"{r.end_m:g}")
            partial[k] = f"kept, {on} m of {row} m on the run (row {k + 2} of the table)"
        spans += found
        rows += [k] * len(found)
    return spans, rows, partial


def _covered(
    run: MeasuredRun, found: list[tuple[int, int]], start: float, end: float
) -> list[tuple[float, float]]:
    """The stretches of the row ``start``-``end`` (m) that the spans ``found`` pass: the
    union of their position ranges between the run's breaks (a jump inside a span is no
    travel; the samples of a slow distance channel's ramp across a jump have no place),
    each end moved to the row's where it misses less than :data:`PARTIAL_ROW_M` plus the
    largest distance step (the channel's resolution and sampling)."""
    position = run.position
    if run.jumping is not None:
        position = np.where(run.jumping, np.nan, position)
    pieces = [(a, b) for a, b in _split_at(found, None, run.breaks)[0] if b - a > 1]
    pieces = [(a, b) for a, b in pieces if np.isfinite(position[a:b]).sum() > 1]
    if not pieces:
        return [(start, end)]  # nothing on the row but a ramp: not judged here
    tol = PARTIAL_ROW_M + max(float(np.nanmax(np.abs(np.diff(position[a:b])))) for a, b in pieces)
    parts = sorted(
        (float(np.nanmin(position[a:b])), float(np.nanmax(position[a:b]))) for a, b in pieces
    )
    union = [list(parts[0])]
    for a, b in parts[1:]:
        if a <= union[-1][1] + tol:
            union[-1][1] = max(union[-1][1], b)
        else:
            union.append([a, b])
    union[0][0] = start if union[0][0] <= start + tol else union[0][0]
    union[-1][1] = end if union[-1][1] >= end - tol else union[-1][1]
    return [(a, b) for a, b in union]


def _range(a: str, b: str) -> str:
    """``a-b``, or ``a to b`` where either is negative (-100-300 reads as a subtraction)."""
    return f"{a} to {b}" if a.startswith("-") or b.startswith("-") else f"{a}-{b}"


def _breaks(run: MeasuredRun) -> np.ndarray:
    """Where no section may go on: the run's dropouts and distance jumps, and the changes
    between running forward and backwards."""
    out = [run.breaks]
    if run.backwards is not None:
        out.append(np.flatnonzero(np.diff(run.backwards.astype(np.int8))) + 1)
    return np.unique(np.concatenate(out)).astype(np.int64)


def _split_at(
    spans: list[tuple[int, int]], rows: list | None, breaks: np.ndarray
) -> tuple[list[tuple[int, int]], list]:
    """Each span cut at the break indices inside it, and the row of each (None: no table)."""
    out, out_rows = [], []
    for k, (a, b) in enumerate(spans):
        cuts = breaks[(breaks > a) & (breaks < b)].tolist()
        for lo, hi in itertools.pairwise([a, *cuts, b]):
            out.append((lo, hi))
            out_rows.append(rows[k] if rows is not None else None)
    return out, out_rows


def _collect(
    run: MeasuredRun,
    geo: dict,
    spans: list[tuple[int, int]],
    rows: list,
    names: list[str] | None,
    rules: SectionRules,
    labels: np.ndarray | None,
    partial: dict[int, str],
) -> list[Section]:
    """Every span's pieces in order, consecutive left-out pieces (of one table row) merged
    into one row, built once per stretch: merged piece by piece, a noisy stop's thousands
    of pieces made the cut quadratic in time (27 s for an 80 s stop). ``partial``: the
    reason of the kept sections of each table row only partly on the run. A dropout before
    a span (samples lost) is a row of its own (:func:`dropout_row`)."""
    dt = 1.0 / run.rate_hz  # once: the property takes the median of the whole run's steps
    gaps = GapCover.of(run.gaps)  # once: looked up per piece
    lost = _dropouts(run, dt)
    out: list[Section] = []
    pending: list[Section] = []
    pending_row = None
    for (a, b), row in zip(spans, rows, strict=True):
        name = names[row] if names and row is not None else None
        if a in lost:  # the samples lost before this span: a row of its own
            if pending:
                out.append(merged_row(run, pending))
                pending = []
            out.append(dropout_row(run, a, dt))
            lost.discard(a)
        outside = labels is None and b > a and bool(np.isnan(geo["curvature"][a]))
        for sec in (
            [outside_row(run, a, b, dt)]
            if outside
            else stretch_pieces(run, geo, a, b, rules, name, labels, dt, gaps)
        ):
            alone = sec.kept or sec.reason == OUTSIDE_LINE  # (an uncovered stretch: own row)
            if pending and (alone or pending[-1].end != sec.start or row != pending_row):
                out.append(merged_row(run, pending))
                pending = []
            if alone:
                if sec.kept and row in partial:
                    sec.reason = "; ".join(filter(None, [partial[row], sec.reason]))
                out.append(sec)
            else:
                pending.append(sec)
                pending_row = row
    if pending:
        out.append(merged_row(run, pending))
    return out


def _dropouts(run: MeasuredRun, dt: float) -> set[int]:
    """The run's breaks where it lost samples (a logger's dropout: a time step of more
    than 1.5 sampling intervals), each the first sample after the loss."""
    k = run.breaks[(run.breaks > 0) & (run.breaks < run.time.size)]
    return set(k[np.diff(run.time)[k - 1] > 1.5 * dt].tolist())


def _number_split_rows(out: list[Section], names: list[str]) -> None:
    """Number the kept pieces of a table row split by speed, duration or a break
    (``name-1``, ``name-2``), in table order, skipping a number another row's name (or an
    earlier number) has taken, case aside: a row "a" split in two was "a-1", "a-2" beside a
    row named "a-1", one recording written over the other."""
    taken = {n.casefold() for n in names}
    for name in names:
        same = [s for s in out if s.kept and s.name == name]
        if len(same) < 2:
            continue
        number = 0
        for sec in same:
            number += 1
            while f"{name}-{number}".casefold() in taken:
                number += 1
            sec.name = f"{name}-{number}"
            taken.add(sec.name.casefold())


#: curves of this radius or tighter (m): the leading wheelset's outer wheel flanges there,
#: loaded or empty, at any speed (the model: the tare wagon +3.4 kN at R500, +7.4 at R350;
#: the loaded one +30 kN and more), its lateral force towards the field side (flange force +)
SIGN_RADIUS_M = 450.0
#: how far below zero its median must lie for the run to be refused: the larger of these,
#: kN, and this share of its median wheel load, so that a transducer's zero offset of a kN
#: or two on an empty wagon is not read as a sign (a flipped loaded channel reads -30 kN)
SIGN_MARGIN_KN, SIGN_MARGIN_SHARE = 5.0, 0.1
#: curves of this radius or tighter where a negative median is noted, not refused: at
#: R600 with cant excess the model's tare wagon has it at +0.1 to +1.6 kN, and -0.2 kN on
#: a slow up-grade under 1000 kN of coupler tension
SIGN_NOTE_RADIUS_M = 600.0


def _check_y_sign(run: MeasuredRun, kept: list[Section]) -> None:
    """Refuse a wheel whose lateral force Y is clearly negative (median below
    -max(:data:`SIGN_MARGIN_KN`, :data:`SIGN_MARGIN_SHARE` x its median Q)) in a kept curve
    of :data:`SIGN_RADIUS_M` or less where it is the leading wheelset's outer wheel, which
    flanges there: its channel is + towards the track centre (a vehicle-fixed channel, + to
    the right for both wheels, reads so on the left wheels), or the curve's direction is
    the other (the curvature channel + right-hand). Mean and RMS of |Y| hide it; the signed
    percentiles, p99.85 and the estimate do not. A negative median short of that, or in a
    curve up to :data:`SIGN_NOTE_RADIUS_M`, is noted: it can be the wagon's (cant excess,
    an empty wagon, coupler tension) or a zero offset."""
    problems: dict[str, str] = {}
    for s in kept:
        if s.radius_m is None or s.radius_m > SIGN_NOTE_RADIUS_M:
            continue
        outer = WHEEL_NAMES[outer_wheel_index(s.direction)]
        if outer not in run.Y or outer in problems:
            continue
        median = float(np.nanmedian(run.Y[outer][s.start : s.end])) / 1e3
        if not median < 0.0:
            continue
        load = float(np.nanmedian(run.Q[outer][s.start : s.end])) / 1e3
        margin = max(SIGN_MARGIN_KN, SIGN_MARGIN_SHARE * load)
        where = (
            f"wheel {outer}: Y median {median:.1f} kN in {s.name} ({s.direction}-hand "
            f"R{s.radius_m:.0f}, {s.start_m:.0f}-{s.end_m:.0f} m), where it is the leading "
            "outer wheel"
        )
        if s.radius_m <= SIGN_RADIUS_M and median < -margin:
            problems[outer] = (
                f"{where} and flanges: accepted Y + towards the field side (flange force +; "
                f"a channel + towards the track centre: Y_sign = -1 in the map's "
                f"[wheels.{outer}]) and curvature + left-hand (a line's or table's direction "
                "as run)"
            )
        else:
            note = (
                f"{where}: negative, which a slow or empty wagon with cant excess can give; "
                "if its forces look wrong, check its sign (+ towards the field side; "
                f"Y_sign = -1 in the map's [wheels.{outer}] negates it)"
            )
            if note not in run.notes:
                run.notes.append(note)
    if problems:
        raise RecordingError(run.source, list(problems.values()))


def _shown_kind(s: Section) -> str:
    """A left-out row's kind in the table: that of most of its track (by length: a
    transition's, a table row's mixed track, or a kind whose pieces were too short), or
    "mixed" where no kind holds all but :data:`MIXED_SHARE` of it. A row of a tangent and a
    curve cut into short pieces by a noisy speed, with a transition between, was shown as
    a "transition" (the QA of stop 68). A row of no samples: what it is ("dropout")."""
    if s.kept or len(s.pieces) < 1:
        return s.kind
    if s.start == s.end:  # no samples: no track (a dropout_row)
        return s.pieces[0][0]
    metres: dict[str, float] = {}
    for kind, label, _, length in s.pieces:
        if kind in ("transition", "mixed"):
            metres[kind] = metres.get(kind, 0.0) + length
        elif kind in ("short", "brief"):
            what = label.split("|")[0]
            metres[what] = metres.get(what, 0.0) + length
    if not {"transition", "mixed"} & set(metres):
        return s.kind  # (a merged row's own kind is a tangent's: its pieces' is shown)
    main = max(metres, key=metres.__getitem__)
    return main if metres[main] >= (1.0 - MIXED_SHARE) * sum(metres.values()) else "mixed"


def sections_table(sections: list[Section]) -> pd.DataFrame:
    """One row per section, kept or not, with the reason."""
    rows = []
    for s in sections:
        d = asdict(s)
        rows.append(
            {
                "section": s.name or "-",
                "kind": _shown_kind(s),
                "from_m": round(d["start_m"], 1),
                "to_m": round(d["end_m"], 1),
                "length_m": round(abs(d["end_m"] - d["start_m"]), 1),  # against the km posts too
                "speed_kmh": round(s.speed_kmh, 1),
                "speed_spread_pct": round(100 * s.speed_spread, 1),
                "cant_mm": round(s.cant_mm, 0),
                "grade_permille": round(s.grade_permille, 1),
                "kept": "yes" if s.kept else "no",
                "reason": s.reason,
            }
        )
    return pd.DataFrame(rows)
