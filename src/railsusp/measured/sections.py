"""A long run cut into sections of one working condition each.

A section is a stretch of one kind of track (tangent, or a curve whose radius lies in one
band, on one band of grade) run at about one speed. The track comes from the run's
curvature/cant/grade channels, or from its position against a line description (a table of
km posts with radius, cant, grade), or the user gives the sections as a table of positions.
Every section's speed is the recording's; a stretch whose speed varies by more than the
tolerance is split into pieces that hold it, and pieces (and transitions between kinds)
shorter than the minimum length are left out with the reason. The kept sections become
the recordings of a field folder (:func:`write_sections`) that the estimation reads.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from railsusp.conditions import WorkingCondition, make_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured.checks import runs
from railsusp.measured.line import (  # noqa: F401  (the sources of a cut, with it)
    geometry_from_line,
    read_line,
    read_section_table,
)
from railsusp.measured.run import MeasuredRun
from railsusp.vehicle.simulate import WHEEL_NAMES, outer_wheel_index

#: the smallest curve radius of a working condition (its ``curve_radius_m`` bound), m
MIN_RADIUS_M: float = next(
    m.ge for m in WorkingCondition.model_fields["curve_radius_m"].metadata if hasattr(m, "ge")
)


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


def cut_sections(
    run: MeasuredRun,
    rules: SectionRules | None = None,
    *,
    line: pd.DataFrame | None = None,
    table: pd.DataFrame | None = None,
) -> list[Section]:
    """The run cut into sections (left-out ones included, ``kept`` False with the reason)."""
    rules = rules or SectionRules()
    geo = _geometry(run, line, rules)
    if table is not None:
        spans, names = [], []
        for r in table.itertuples(index=False):
            inside = (run.position >= r.start_m) & (run.position < r.end_m)
            found = runs(inside) or [(0, 0)]  # a run that passes the range twice: twice
            spans += found
            names += [str(getattr(r, "name", ""))] * len(found)
        if "name" not in table:
            names = None
    else:
        spans, names = _label_runs(geo, rules), None
    spans, names = _split_at(spans, names, _breaks(run))
    out: list[Section] = []
    for k, (a, b) in enumerate(spans):
        label = names[k] if names else None
        outside = table is None and b > a and bool(np.isnan(geo["curvature"][a]))
        for sec in [_outside(run, a, b)] if outside else _pieces(run, geo, a, b, rules, label):
            if (
                out
                and not out[-1].kept
                and not sec.kept
                and out[-1].end == sec.start
                and OUTSIDE_LINE not in (out[-1].reason, sec.reason)  # a row of its own
            ):
                out[-1] = _merged(run, out[-1], sec)  # one row per left-out stretch
            else:
                out.append(sec)
    if names:
        for name in set(names):
            same = [s for s in out if s.kept and s.name == name]
            if len(same) > 1:  # a user's section split by speed or duration
                for j, sec in enumerate(same):
                    sec.name = f"{name}-{j + 1}"
    kept = [s for s in out if s.kept]
    width = len(str(len(kept)))
    n = 0
    for s in out:
        if s.kept:
            n += 1
            s.name = s.name or f"s{n:0{width}d}-" + s.kind.replace(" ", "-")
    return out


def _breaks(run: MeasuredRun) -> np.ndarray:
    """Where no section may go on: the run's dropouts and distance jumps, and the changes
    between running forward and backwards."""
    out = [run.breaks]
    if run.backwards is not None:
        out.append(np.flatnonzero(np.diff(run.backwards.astype(np.int8))) + 1)
    return np.unique(np.concatenate(out)).astype(np.int64)


def _split_at(
    spans: list[tuple[int, int]], names: list[str] | None, breaks: np.ndarray
) -> tuple[list[tuple[int, int]], list[str] | None]:
    """Each span cut at the break indices inside it (the names repeated)."""
    out, out_names = [], [] if names is not None else None
    for k, (a, b) in enumerate(spans):
        cuts = breaks[(breaks > a) & (breaks < b)].tolist()
        for lo, hi in zip([a, *cuts], [*cuts, b], strict=True):
            out.append((lo, hi))
            if out_names is not None:
                out_names.append(names[k])  # type: ignore[index]
    return out, out_names


def _geometry(run: MeasuredRun, line: pd.DataFrame | None, rules: SectionRules) -> dict:
    """Smoothed curvature (1/m), cant (m), grade (1) per sample."""
    if line is not None:
        geo = geometry_from_line(run.position, line)
    else:
        zero = np.zeros_like(run.time)
        geo = {
            "curvature": run.curvature if run.curvature is not None else zero,
            "cant": run.cant if run.cant is not None else zero,
            "grade": run.grade if run.grade is not None else zero,
        }
    ds = float(np.median(np.abs(np.diff(run.position)))) or 1.0
    k = max(1, round(rules.smoothing_m / ds))
    kernel = np.ones(k) / k
    out = {
        key: np.convolve(np.pad(v, (k // 2, k - 1 - k // 2), mode="edge"), kernel, "valid")
        for key, v in geo.items()
    }
    # the rate of change between the means three smoothing lengths apart: the gradient of
    # one mean takes two raw samples' difference and reads their noise as a spiral
    # (curvature noise of 1 % made a steady R600 one long transition); a transition is
    # widened by up to that length's half on either side
    idx = np.arange(run.position.size)
    ahead = np.minimum(idx + 3 * k // 2 + 1, idx.size - 1)
    behind = np.maximum(idx - 3 * k // 2 - 1, 0)
    span = np.maximum(np.abs(run.position[ahead] - run.position[behind]), 1e-9)
    with np.errstate(invalid="ignore"):
        out["transition"] = (
            np.abs(out["curvature"][ahead] - out["curvature"][behind]) / span > rules.spiral_rate
        ) | (np.abs(out["grade"][ahead] - out["grade"][behind]) / span > rules.grade_rate)
    return out


#: a curve's radius within this share of a band's edge (a grade within this share of its
#: band's width of the band's edge) keeps the band of the stretch before or after it
#: rather than flip with the channel's noise (the edges sit at common design radii)
BAND_HYSTERESIS = 0.05


def _radius_band(curv: np.ndarray, rules: SectionRules, scale: float = 1.0) -> np.ndarray:
    """Per sample, the radius band of curvature ``curv`` x ``scale`` (-1: tangent)."""
    c = np.abs(curv) * scale
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = np.where(c > 1.0 / rules.tangent_radius_m, 1.0 / c, np.inf)
    return np.where(np.isfinite(radius), np.digitize(radius, rules.radius_edges_m), -1)


def _steady(low: np.ndarray, high: np.ndarray, middle: np.ndarray) -> np.ndarray:
    """Bands with hysteresis: a sample whose band is the same for its value moved either
    way (``low``, ``high``) has it; a stretch of samples near an edge takes the band of the
    stretch before it where that band is one of theirs, else the band after it, else, as
    one, the most common band of its own ``middle`` values."""
    out = np.where(low == high, low, -9).astype(np.int64)
    n = out.size
    for a, b in runs(low != high):
        candidates = set(low[a:b].tolist()) | set(high[a:b].tolist())
        if a > 0 and int(out[a - 1]) in candidates:
            out[a:b] = out[a - 1]
        elif b < n and low[b] == high[b] and int(low[b]) in candidates:
            out[a:b] = low[b]
        else:
            values, counts = np.unique(middle[a:b], return_counts=True)
            out[a:b] = values[np.argmax(counts)]
    return out


def _label_runs(geo: dict, rules: SectionRules) -> list[tuple[int, int]]:
    """Runs of samples on one kind of track (radius band, direction of a curve, grade band),
    each band with hysteresis (:func:`_steady`): noise on a steady curve or grade near a
    band's edge does not cut it into pieces too short to keep."""
    curv = geo["curvature"]
    h = BAND_HYSTERESIS
    band = _steady(
        _radius_band(curv, rules, 1.0 + h),
        _radius_band(curv, rules, 1.0 - h),
        _radius_band(curv, rules),
    )
    g = geo["grade"] * 1e3 / rules.grade_band_permille
    with np.errstate(invalid="ignore"):
        grade_band = _steady(
            np.nan_to_num(np.round(g - h)), np.nan_to_num(np.round(g + h)),
            np.nan_to_num(np.round(g)),
        )  # fmt: skip
    band = np.where(np.isnan(curv), -2, band)  # outside the line description
    band = np.where(geo["transition"] & (band != -2), -3, band)  # a transition: own label
    label = np.where(
        band == -3,
        -3,
        band * 4 + np.where((band >= 0) & (curv < 0), 1, 0) + 1000 * grade_band,
    )
    label = np.where(band == -2, -2, label)  # NaN outside the line: one label, one run
    edges = np.flatnonzero(np.diff(label)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [label.size]])
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def _outside(run: MeasuredRun, a: int, b: int) -> Section:
    """Stretch a..b, which the line description does not cover, as a left-out row (it was
    dropped without a row: a quarter of the example run went unmentioned)."""
    v = run.speed[a:b]
    seconds = float(run.time[b - 1] - run.time[a])
    metres = float(abs(run.position[b - 1] - run.position[a]))
    piece = ("outside", OUTSIDE_LINE, seconds, metres)
    return Section(
        "", a, b, float(run.position[a]), float(run.position[b - 1]), None, "left", 0.0, 0.0,
        float(v.mean()) * 3.6, float((v.max() - v.min()) / max(v.mean(), 1e-9)), False,
        OUTSIDE_LINE, (piece,),
    )  # fmt: skip


#: the reason of a stretch that the line description does not cover
OUTSIDE_LINE = "not covered by the line description (no km posts there)"


#: a left-out piece too short for a condition, of less than this (s), beside another
#: left-out stretch is where a band's edge fell (a few samples between a transition and the
#: next stretch), not a reason of its own: its row names the neighbour's reason alone.
#: Judged by time, not length, so that a stop (no length at all) is never folded away.
EDGE_PIECE_S = 1.0


def _describe(pieces: tuple[tuple[str, str, float, float], ...]) -> str:
    """A left-out row's reason from its pieces, one phrase per kind in their order: a
    stop's seconds summed, pieces too short for a condition counted with their lengths
    (edge pieces left out where there is more), a transition or a radius by its words."""
    real = [p for p in pieces if not (p[0] == "short" and p[2] < EDGE_PIECE_S)] or pieces
    groups: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for kind, label, seconds, metres in real:
        groups.setdefault((kind, label), []).append((seconds, metres))
    out = []
    for (kind, label), items in groups.items():
        if kind == "standing":
            out.append(f"standing ({sum(t for t, _ in items):.0f} s)")
        elif kind == "short":
            what, minimum, why = label.split("|")
            ms = [m for _, m in items]
            out.append(
                f"{what} of {ms[0]:.0f} m, shorter than the {minimum} m minimum{why}"
                if len(ms) == 1
                else f"{what}: {len(ms)} pieces of {min(ms):.0f}-{max(ms):.0f} m, each shorter "
                f"than the {minimum} m minimum{why}"
            )
        else:
            out.append(label)
    return "; ".join(out)


def _pieces(
    run: MeasuredRun, geo: dict, a: int, b: int, rules: SectionRules, name: str | None
) -> list[Section]:
    """Stretch a..b as sections: split where the speed leaves the tolerance or the
    duration passes the maximum; pieces shorter than the minimum left out."""
    v = run.speed
    if geo["transition"][a:b].mean() > 0.5 and name is None:
        return [_section(run, geo, a, b, rules, name, split=False)]
    out = []
    i = a
    while i < b:
        j, lo, hi = i + 1, v[i], v[i]
        while j < b:
            lo, hi = min(lo, v[j]), max(hi, v[j])
            if (hi - lo) > rules.speed_tolerance * 0.5 * (hi + lo) or (
                run.time[j] - run.time[i] > rules.max_duration_s
            ):
                break
            j += 1
        out.append(_section(run, geo, i, j, rules, name, split=(j < b or i > a)))
        i = j
    return out


def _merged(run: MeasuredRun, a: Section, b: Section) -> Section:
    """Two adjacent left-out stretches as one row, with both reasons."""
    v = run.speed[a.start : b.end]
    pieces = a.pieces + b.pieces
    return Section(
        "",
        a.start,
        b.end,
        a.start_m,
        b.end_m,
        None,
        "left",
        0.0,
        0.5 * (a.grade_permille + b.grade_permille),
        float(v.mean()) * 3.6,
        float((v.max() - v.min()) / max(v.mean(), 1e-9)),
        False,
        _describe(pieces),
        pieces,
    )


def _section(
    run: MeasuredRun, geo: dict, i: int, j: int, rules: SectionRules, name: str | None, split: bool
) -> Section:
    sl = slice(i, j)
    curv = float(np.median(geo["curvature"][sl]))
    radius = 1.0 / abs(curv) if abs(curv) > 1.0 / rules.tangent_radius_m else None
    v = run.speed[sl]
    length = float(abs(run.position[j - 1] - run.position[i]))
    spread = float((v.max() - v.min()) / max(v.mean(), 1e-9))
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
    seconds = float(run.time[j - 1] - run.time[i])
    if run.jumping is not None and np.mean(run.jumping[sl]) > 0.5:
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
    elif float(v.mean()) * 3.6 < 1.0:  # before the length: a stop has none
        piece = ("standing", "")
    elif length < rules.min_length_m:
        why = " (speed varies beyond the tolerance)" if split else ""
        piece = ("short", f"{sec.kind}|{rules.min_length_m:g}|{why}")
    elif (
        radius is not None
        and (outer := WHEEL_NAMES[outer_wheel_index(sec.direction)]) not in run.wheels
    ):
        piece = ("wheel", f"{sec.direction}-hand curve: its outer wheel {outer}, the one "
                 "compared, is not recorded")  # fmt: skip
    else:
        return sec
    sec.kept = False
    sec.pieces = ((*piece, seconds, length),)
    sec.reason = _describe(sec.pieces)
    return sec


def sections_table(sections: list[Section]) -> pd.DataFrame:
    """One row per section, kept or not, with the reason."""
    rows = []
    for s in sections:
        d = asdict(s)
        rows.append(
            {
                "section": s.name or "-",
                "kind": s.kind if s.kept or "transition" not in s.reason else "transition",
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
