"""One stretch of a long run as sections: what a section is (:class:`Section`, cut by
:class:`SectionRules`) and how a stretch of one kind of track is split into pieces, each
kept or left out with its reason (:func:`stretch_pieces`), and adjacent left-out pieces
made one row (:func:`merged_row`), its reason in the words of
:mod:`railsusp.measured.reasons`. :func:`railsusp.measured.sections.cut_sections` finds the
stretches and puts the pieces together.

A stop (the speed below :data:`~railsusp.measured.track_kinds.MOVING_MS`) is one piece
whatever the noise on its speed, the moving run between stops is split where its speed
leaves the tolerance, and a stretch holding it longer than the maximum duration into equal
parts within it. Each step is linear in the stretch's samples.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from railsusp.conditions import WorkingCondition, field_range, make_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured.checks import label_runs
from railsusp.measured.reasons import (
    EDGE_PIECE_S,  # noqa: F401  (where a section's reasons were)
    OUTSIDE_LINE,
    VARIES,
    describe,
    percent,
    speed_ranges,
    speed_spread,
)
from railsusp.measured.run import MeasuredRun
from railsusp.measured.track_kinds import CANT_ON_TANGENT_MM, MOVING_MS, kind_shares
from railsusp.vehicle.simulation_result import WHEEL_NAMES, outer_wheel_index

#: the smallest curve radius of a working condition (its ``curve_radius_m`` bound), m
MIN_RADIUS_M: float = next(
    m.ge for m in WorkingCondition.model_fields["curve_radius_m"].metadata if hasattr(m, "ge")
)

#: the shortest record of a working condition (its ``duration_s`` bound), s: a kept piece
#: shorter made ``sections --write`` fail on its condition, after the others were cut
MIN_DURATION_S: float = field_range("duration_s")[0]


@dataclass(frozen=True)
class SectionRules:
    """How a run is cut. Radii are banded by ``radius_edges_m`` (a curve of 550 m and one
    of 580 m are one condition); curvature below 1/``tangent_radius_m`` is tangent."""

    radius_edges_m: tuple[float, ...] = (150.0, 250.0, 350.0, 450.0, 600.0, 800.0, 1200.0, 2000.0)
    tangent_radius_m: float = 3000.0
    grade_band_permille: float = 5.0
    speed_tolerance: float = 0.10  # (max - min) / mean speed within a section
    min_length_m: float = 150.0
    max_duration_s: float = 120.0
    smoothing_m: float = 10.0  # geometry channels averaged over this length
    #: curvature changing faster than this (1/m per m) is a transition (spiral), not a
    #: condition: about 1/5000 m over 100 m
    spiral_rate: float = 2e-6
    #: grade changing faster than this (per m) is a vertical curve: 1 permille over 100 m
    grade_rate: float = 1e-5

    def __post_init__(self) -> None:
        for name, value, low, high in (
            ("speed_tolerance", self.speed_tolerance, 0.0, 1.0),
            ("min_length_m", self.min_length_m, 1.0, 100_000.0),
            ("max_duration_s", self.max_duration_s, 1.0, 600.0),
            ("grade_band_permille", self.grade_band_permille, 0.1, 80.0),
            ("tangent_radius_m", self.tangent_radius_m, 100.0, 100_000.0),
        ):
            if not low <= value <= high:
                raise RailsuspInputError(f"{name} = {value:g}: accepted {low:g} to {high:g}")


@dataclass
class Section:
    """One cut stretch of the run (sample indices ``start`` to ``end``, end exclusive)."""

    name: str
    start: int
    end: int
    start_m: float
    end_m: float
    radius_m: float | None  # None: tangent
    direction: str  # left / right
    cant_mm: float
    grade_permille: float
    speed_kmh: float
    speed_spread: float  # (max - min) / mean
    kept: bool = True
    reason: str = ""
    #: a left-out row's pieces, (kind, label, seconds, metres), that its reason sums up
    pieces: tuple[tuple[str, str, float, float], ...] = field(default=(), repr=False)

    @property
    def kind(self) -> str:
        return "tangent" if self.radius_m is None else f"curve R{self.radius_m:.0f}"

    def condition(self, duration_s: float, rate_hz: float) -> WorkingCondition:
        """The working condition of this section: steady on its track from the start of
        the record (the curve, if any, begins with a 50 m spiral inside the 100 m lead-in),
        at its mean speed, on synthesised class-5 track (the unknown real track)."""
        fields = {
            "name": self.name,
            "speed_kmh": round(self.speed_kmh, 2),
            "duration_s": round(duration_s, 3),
            "n_steps": max(10, round(duration_s * rate_hz)),
            "grade_permille": round(self.grade_permille, 2),
            "cant_mm": round(self.cant_mm, 1) if self.radius_m is not None else 0.0,
        }
        if self.radius_m is not None:
            fields |= {
                "curve_radius_m": round(self.radius_m, 0),
                "curve_direction": self.direction,
                "curve_start_m": 0.0,
                "entry_spiral_m": 50.0,
            }
        return make_condition(fields)


def outside_row(run: MeasuredRun, a: int, b: int, dt: float) -> Section:
    """Stretch a..b, which the line description does not cover, as a left-out row (it was
    dropped without a row: a quarter of the example run went unmentioned); ``dt``: the
    run's sampling interval, s."""
    v = run.speed[a:b]
    piece = ("outside", OUTSIDE_LINE, (b - a) * dt, _length(run, a, b))
    return Section(
        "", a, b, float(run.position[a]), float(run.position[b - 1]), None, "left", 0.0, 0.0,
        float(v.mean()) * 3.6, speed_spread(v), False,
        OUTSIDE_LINE, (piece,),
    )  # fmt: skip


def dropout_row(run: MeasuredRun, k: int, dt: float) -> Section:
    """The samples lost between samples k - 1 and k (a logger's dropout) as a left-out row
    of no samples (start = end = k), from the one's position to the other's: the cut broke
    there without a row, where a NaN gap has one ("every stretch with its reason")."""
    seconds = float(run.time[k] - run.time[k - 1]) - dt
    metres = float(abs(run.position[k] - run.position[k - 1]))
    reason = f"no samples: a dropout of the logger ({seconds:.3g} s of samples lost)"
    v = run.speed[k - 1 : k + 1]
    piece = ("dropout", reason, seconds, metres)
    return Section(
        "", k, k, float(run.position[k - 1]), float(run.position[k]), None, "left", 0.0, 0.0,
        float(v.mean()) * 3.6, speed_spread(v), False, reason, (piece,),
    )  # fmt: skip


#: a section table's piece of which more than this share is another kind of track than
#: its main one (or a transition) is left out: its condition would be the main kind's
MIXED_SHARE = 0.10


def stretch_pieces(
    run: MeasuredRun,
    geo: dict,
    a: int,
    b: int,
    rules: SectionRules,
    name: str | None,
    labels: np.ndarray | None,
    dt: float,
    gaps: GapCover,
) -> list[Section]:
    """Stretch a..b as sections: each stop (speed below :data:`MOVING_MS`) one piece, the
    run between split where the speed leaves the tolerance, and a stretch that holds it
    longer than the maximum duration into equal parts within it; pieces shorter than the
    minimum are left out. ``labels``: a section table's per-sample kinds of track (None:
    the stretch is one kind already, and a mostly transition one is one row); ``dt``: the
    run's sampling interval, s (``run.rate_hz`` takes the median of the whole run's);
    ``gaps``: the run's NaN gaps (:class:`GapCover`, built once per cut)."""
    if labels is None and geo["transition"][a:b].mean() > 0.5:
        return [_section(run, geo, a, b, rules, name, None, "", dt, gaps)]
    moving = run.speed[a:b] >= MOVING_MS
    out = []
    for lo, hi in label_runs(moving.astype(np.int8)):
        lo, hi = lo + a, hi + a
        if not moving[lo - a]:
            out.append(_section(run, geo, lo, hi, rules, name, labels, "stop", dt, gaps))
            continue
        for i, j, cause in _steady_parts(run, lo, hi, rules, (lo > a, hi < b), dt):
            out.append(_section(run, geo, i, j, rules, name, labels, cause, dt, gaps))
    return out


def _steady_parts(
    run: MeasuredRun,
    lo: int,
    hi: int,
    rules: SectionRules,
    stops: tuple[bool, bool],
    dt: float,
) -> list[tuple[int, int, str]]:
    """A moving stretch lo..hi (``stops``: a stop before it, after it) as pieces that hold
    the speed tolerance, each longer than ``max_duration_s`` split into as many equal parts
    as bring them within it (the greedy split took 120 s and left the rest, dropped as
    "speed varies" at a steady speed); where equal parts would be shorter than the minimum
    length and parts of the whole maximum duration are not (below about 5 km/h), parts of
    the maximum duration and a shorter rest. Each piece with what cut it: "speed",
    "duration" or ""."""
    out = []
    whole = max(1, math.floor(rules.max_duration_s / dt + 1e-9))  # samples
    i = lo
    while i < hi:
        j = _tolerance_end(run.speed, i, hi, rules.speed_tolerance)
        m = max(1, math.ceil((j - i) * dt / rules.max_duration_s - 1e-9))
        bounds = [i + round(q * (j - i) / m) for q in range(m + 1)]
        if m > 1 and _length(run, i, bounds[1]) < rules.min_length_m <= _length(run, i, i + whole):
            bounds = [*range(i, j, whole), j]
        for p, q in itertools.pairwise(bounds):
            by_speed = (p == i and (i > lo or stops[0])) or (q == j and (j < hi or stops[1]))
            out.append((p, q, "speed" if by_speed else "duration" if m > 1 else ""))
        i = j
    return out


def _reverses(run: MeasuredRun, i: int, j: int) -> bool:
    """Whether the wagon runs one way before samples i..j (a stop) and the other after
    them: the speed passing through 0 (the run's speed is its magnitude), which showed as
    "standing (0 s)" beside a backwards stretch (the QA of stop 68)."""
    back = run.backwards
    return back is not None and 0 < i and j < back.size and bool(back[i - 1] != back[j])


def _length(run: MeasuredRun, i: int, j: int) -> float:
    """The track samples i..j cover, m."""
    return float(abs(run.position[j - 1] - run.position[i]))


def _tolerance_end(v: np.ndarray, i: int, b: int, tolerance: float) -> int:
    """The first sample j > i (at most b) at which the speed of i..j spreads beyond the
    tolerance ((max - min) / mean), found in blocks of doubling size: linear in j - i."""
    low = high = float(v[i])
    start, size = i + 1, 64
    while start < b:
        stop = min(b, start + size)
        lows = np.minimum(np.minimum.accumulate(v[start:stop]), low)
        highs = np.maximum(np.maximum.accumulate(v[start:stop]), high)
        over = (highs - lows) > tolerance * 0.5 * (highs + lows)
        if over.any():
            return start + int(np.argmax(over))
        low, high = float(lows[-1]), float(highs[-1])
        start, size = stop, 2 * size
    return b


@dataclass(frozen=True)
class GapCover:
    """A run's NaN gaps (:attr:`~railsusp.measured.run.MeasuredRun.gaps`) as the stretches
    between their edges, each with the channels whose gaps cover it (none: empty): built once
    per cut, so that finding a piece's is a binary search. A piece lies wholly inside or
    outside each gap (a break sits at every gap's edge); looked up through every gap for
    every piece, the cut of a 2 h run with 6857 gaps took 9 s."""

    edges: np.ndarray  # the gaps' starts and ends, sorted, unique
    channels: tuple[tuple[str, ...], ...]  # per stretch edges[k]..edges[k + 1]

    @classmethod
    def of(cls, gaps: tuple[tuple[int, int, str], ...]) -> GapCover:
        """The cover of ``gaps`` (start, end exclusive, channel), in their order: a
        channel's own gaps are apart, so a stretch has at most one per channel and the
        cover is built in the gaps times the channels."""
        edges = np.unique(np.array([x for a, b, _ in gaps for x in (a, b)], dtype=np.int64))
        cover: list[list[str]] = [[] for _ in range(max(edges.size - 1, 0))]
        for a, b, channel in gaps:
            for k in range(int(np.searchsorted(edges, a)), int(np.searchsorted(edges, b))):
                cover[k].append(channel)
        return cls(edges, tuple(tuple(dict.fromkeys(c)) for c in cover))

    def names(self, i: int, j: int) -> str:
        """The channels (quoted, comma-separated) of the gaps that cover most of samples
        i..j, or "": the stretches i..j overlaps (one where it lies inside a gap or between
        two, as the breaks make every piece)."""
        if j <= i or not self.channels:
            return ""
        lo = max(int(np.searchsorted(self.edges, i, "right")) - 1, 0)
        hi = min(int(np.searchsorted(self.edges, j, "left")), len(self.channels))
        covered, names = 0, {}
        for k in range(lo, hi):
            if self.channels[k]:
                covered += max(0, min(int(self.edges[k + 1]), j) - max(int(self.edges[k]), i))
                names.update(dict.fromkeys(self.channels[k]))
        return ", ".join(map(repr, names)) if covered > 0.5 * (j - i) else ""


def merged_row(run: MeasuredRun, group: list[Section]) -> Section:
    """Adjacent left-out stretches as one row, with all their reasons (one row of a table's
    name keeps it)."""
    first, last = group[0], group[-1]
    if len(group) == 1:
        return first
    v = run.speed[first.start : last.end]
    pieces = tuple(p for s in group for p in s.pieces)
    n = np.array([s.end - s.start for s in group], float)
    names = {s.name for s in group}
    return Section(
        names.pop() if len(names) == 1 else "",
        first.start,
        last.end,
        first.start_m,
        last.end_m,
        None,
        "left",
        0.0,
        float(np.dot(n, [s.grade_permille for s in group]) / n.sum()),
        float(v.mean()) * 3.6,
        speed_spread(v),
        False,
        describe(pieces, speed_ranges(run.speed, group)),
        pieces,
    )


def _section(
    run: MeasuredRun,
    geo: dict,
    i: int,
    j: int,
    rules: SectionRules,
    name: str | None,
    labels: np.ndarray | None,
    cause: str,
    dt: float,
    gaps: GapCover,
) -> Section:
    """Samples i..j as a section, or left out with the reason. ``cause``: what cut it off
    ("speed", "duration", "stop": the piece is a stop, "": the stretch's ends); ``gaps``:
    the run's NaN gaps."""
    sl = slice(i, j)
    curv = float(np.median(geo["curvature"][sl]))
    radius = 1.0 / abs(curv) if abs(curv) > 1.0 / rules.tangent_radius_m else None
    v = run.speed[sl]
    length = _length(run, i, j)
    spread = speed_spread(v)
    sec = Section(
        name or "",
        i,
        j,
        float(run.position[i]),
        float(run.position[j - 1]),
        radius,
        "right" if curv < 0 else "left",
        float(np.median(geo["cant"][sl])) * 1e3,
        float(np.median(geo["grade"][sl])) * 1e3,
        float(v.mean()) * 3.6,
        spread,
    )
    shares = kind_shares(geo, labels, i, j) if labels is not None else [("", 1.0)]
    known = "curvature_known" not in geo or bool(np.mean(geo["curvature_known"][sl]) > 0.5)
    gap = gaps.names(i, j)
    if gap:
        piece = ("gap", f"no values: a gap of missing values (NaN) in channel(s) {gap}, "
                 "longer than those interpolated")  # fmt: skip
    elif run.jumping is not None and np.mean(run.jumping[sl]) > 0.5:
        piece = ("jump", "a jump of the distance channel (a chainage jump or an odometer's "
                 "reset): no place on the line")  # fmt: skip
    elif run.backwards is not None and np.mean(run.backwards[sl]) > 0.5:
        piece = ("backwards", "running backwards (wheelset 1 trailing, left and right "
                 "swapped against the model's)")  # fmt: skip
    elif np.mean(geo["transition"][sl]) > 0.5:
        piece = ("transition", "transition (curvature or grade changing)")
    elif radius is not None and radius < MIN_RADIUS_M:
        piece = ("radius", f"radius {radius:.3g} m, below the {MIN_RADIUS_M:g} m a working "
                 "condition takes (a curvature channel in another unit?)")  # fmt: skip
    elif cause == "stop" or float(v.mean()) * 3.6 < 1.0:  # before the length: a stop has none
        piece = ("reversal" if _reverses(run, i, j) else "standing", "")
    elif radius is None and abs(sec.cant_mm) >= CANT_ON_TANGENT_MM and not known:
        piece = ("cant", f"{sec.cant_mm:.0f}")
    elif 1.0 - max(share for _, share in shares) > MIXED_SHARE:  # a table's row only
        parts = ", ".join(f"{kind} {100 * share:.0f} %" for kind, share in shares)
        piece = ("mixed", f"more than one kind of track ({parts}): a section is one, with at "
                 f"most {100 * MIXED_SHARE:.0f} % of others")  # fmt: skip
    elif length < rules.min_length_m:
        why = {
            "speed": f" ({VARIES} the {percent(rules.speed_tolerance)} % tolerance)",
            "duration": f" (split at the {rules.max_duration_s:g} s maximum duration)",
        }.get(cause, "")
        piece = ("short", f"{sec.kind}|{rules.min_length_m:g}|{why}")
    elif (j - i) * dt < MIN_DURATION_S * (1.0 - 1e-9):  # long enough, but quickly passed
        piece = ("brief", f"{sec.kind}|{MIN_DURATION_S:g}")
    elif (
        radius is not None
        and (outer := WHEEL_NAMES[outer_wheel_index(sec.direction)]) not in run.wheels
    ):
        piece = ("wheel", f"{sec.direction}-hand curve: its outer wheel {outer}, the one "
                 "compared, is not recorded")  # fmt: skip
    else:
        if radius is None:  # a tangent's condition has no cant: shown as written
            if abs(sec.cant_mm) >= CANT_ON_TANGENT_MM:
                sec.reason = (
                    f"kept as tangent (radius over {rules.tangent_radius_m:g} m), its cant "
                    f"of {sec.cant_mm:.0f} mm written as 0: a condition has cant in a curve only"
                )
            sec.cant_mm = 0.0
        return sec
    sec.kept = False
    sec.pieces = ((*piece, (j - i) * dt, length),)
    sec.reason = describe(sec.pieces)
    return sec
