"""The speed and track columns of a field table (``speed_kmh``, ``curvature_1_per_km``,
``cant_mm``, ``grade_permille``; any unit the header states) held against what a line can
have and against the recording's working condition. The estimate simulates the condition,
not these columns: a recording whose columns say another speed or another track than its
sidecar's condition (a 30 km/h run filed as the 60 km/h condition, a curve's geometry in a
tangent's recording) would be compared with the wrong simulation, silently. So each value
must lie within a working condition's range, and within a tolerance of the condition's
design track at the sample's place (the tolerances of ``railsusp sections``, which cuts a
long run into such conditions: :class:`~railsusp.measured.pieces.SectionRules`).
"""

from __future__ import annotations

import numpy as np

from railsusp.conditions import WorkingCondition, field_range
from railsusp.errors import RailsuspInputError
from railsusp.measured.checks import rows, runs
from railsusp.measured.pieces import SectionRules
from railsusp.measured.raw import RawChannel
from railsusp.measured.units import named, si_factor, split_header
from railsusp.vehicle.track import TrackLayout

_RULES = SectionRules()
#: a sample's speed may differ from its condition's by this share (the speed tolerance of
#: ``railsusp sections``, (max - min) / mean within a section: every sample of a section
#: it cuts lies within it of the section's mean, which becomes the condition's speed)
SPEED_TOLERANCE = _RULES.speed_tolerance
#: a tangent's measured curvature may reach 1 / this radius, m (``sections``' tangent)
TANGENT_RADIUS_M = _RULES.tangent_radius_m
#: and a curve's may differ from the design curvature by this share of it besides
CURVATURE_SHARE = 0.2
#: a measured cant may differ from the design cant by this, mm (cross-level irregularity
#: and the measuring system's error; the cant of a section ``sections`` cuts is the run's)
CANT_TOLERANCE_MM = 20.0
#: a measured grade may differ from the design grade by this, ‰ (a ``sections`` grade band)
GRADE_TOLERANCE_PERMILLE = _RULES.grade_band_permille
#: a sample is compared with the design track within this distance of its place, m (the
#: track's registration; a spiral's curvature and cant change along it)
REGISTRATION_M = 10.0

#: column name -> (quantity for its unit, display unit, factor from SI to it)
_COLUMNS = {
    "speed": ("speed", "km/h", 3.6),
    "curvature": ("curvature", "1/km", 1e3),
    "cant": ("cant", "mm", 1e3),
    "grade": ("grade", "‰", 1e3),
}


def check_track_columns(
    channels: dict[str, RawChannel],
    time: np.ndarray,
    condition: WorkingCondition | None,
    distance: np.ndarray | None = None,
) -> list[str]:
    """Problems of the table's speed and track columns (values in the units their headers
    state, one per file row at ``time``, s; ``distance``: each row's, m, for a table along
    distance): each value within a working condition's range (speed above 0 and at most its
    highest, |cant| and |grade| within theirs, the curvature of a radius no tighter than its
    smallest), and, with the ``condition``, within the tolerances above of its speed and of
    its design track at each row's place along the record (:func:`places`). NaN cells are
    not judged (the column is not used). Each problem names the column, its first rows,
    their value, how many rows and the accepted range."""
    problems: list[str] = []
    place = None
    if condition is not None:
        place = places(channels, time, condition, distance)
    for col, ch in channels.items():
        base = split_header(col)[0]
        if base not in _COLUMNS:
            continue
        quantity, unit, scale = _COLUMNS[base]
        try:
            x = ch.values * si_factor(quantity, ch.unit, col) * scale
        except RailsuspInputError as exc:
            problems.append(str(exc).replace("channel", "column", 1))
            continue
        lo, hi, why = _accepted(base, x.size, condition, place)
        problems += _outside(x, lo, hi, col, ch.first_row, base, unit, why)
    return problems


def places(
    channels: dict[str, RawChannel],
    time: np.ndarray,
    condition: WorkingCondition,
    distance: np.ndarray | None = None,
) -> np.ndarray:
    """Each row's place along the condition's track, m: the leading wheelset's distance
    from the section start, the condition's lead-in at the first row. The distance from
    the first row is the table's ``distance`` where it is the axis; else its speed column
    integrated over time (trapezoidal, its empty cells interpolated), where every value of
    it lies within the condition's speed tolerance (a speed refused is no place to judge
    the track by); else the condition's speed times the time. Placed at the condition's
    speed, a run at 56 km/h filed as 60 km/h drifted 1.1 m/s, a spiral 20 m away from its
    design after 20 s, and was refused where its curvature was exactly the design's."""
    if distance is not None:
        return condition.lead_in_m + (distance - distance[0])
    speed = channels.get(named(channels, "speed"))
    if speed is not None and time.size >= 2:
        try:
            v = speed.values * si_factor("speed", speed.unit, speed.name)
        except RailsuspInputError:
            v = np.full(time.size, np.nan)
        finite = np.isfinite(v)
        tol = SPEED_TOLERANCE * condition.speed
        if finite.sum() >= 2 and np.all(np.abs(v[finite] - condition.speed) <= tol * 1.000001):
            v = np.interp(time, time[finite], v[finite])
            steps = 0.5 * (v[1:] + v[:-1]) * np.diff(time)
            return condition.lead_in_m + np.concatenate([[0.0], np.cumsum(steps)])
    return condition.lead_in_m + condition.speed * (time - time[0])


def _accepted(
    base: str, n: int, condition: WorkingCondition | None, place: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, str]:
    """(lowest, highest) accepted per sample, in the column's display unit, and why."""
    if base == "speed":
        top = field_range("speed_kmh")[1]
        if condition is None:
            # (a speed of 0 is refused: the lowest accepted is the least number above it)
            return np.full(n, np.nextafter(0.0, 1.0)), np.full(n, top), "a condition's"
        v = condition.speed_kmh
        return (
            np.full(n, v * (1 - SPEED_TOLERANCE)),
            np.full(n, v * (1 + SPEED_TOLERANCE)),
            f"the condition's {v:g} km/h within {100 * SPEED_TOLERANCE:g} %, the default speed "
            "tolerance of railsusp sections",
        )
    if base == "curvature":
        top = 1e3 / field_range("curve_radius_m")[0]
        bound = (np.full(n, -top), np.full(n, top), "the curvature of a condition's tightest "
                 "radius")  # fmt: skip
    elif base == "cant":
        top = field_range("cant_mm")[1]
        bound = (np.full(n, -top), np.full(n, top), "a condition's cant")
    else:
        lo, hi = field_range("grade_permille")
        bound = (np.full(n, lo), np.full(n, hi), "a condition's grade")
    if condition is None or place is None:
        return bound
    layout = TrackLayout.from_condition(condition)
    near = place[:, None] + np.linspace(-REGISTRATION_M, REGISTRATION_M, 21)[None, :]
    if base == "curvature":
        design = layout.curvature_at(near) * 1e3
        tol = 1e3 / TANGENT_RADIUS_M + CURVATURE_SHARE * np.abs(design).max(axis=1)
        why = (
            f"the condition's design curvature, + left-hand, within "
            f"{1e3 / TANGENT_RADIUS_M:.3g} 1/km (a {TANGENT_RADIUS_M:g} m radius) and "
            f"{100 * CURVATURE_SHARE:g} % of it"
        )
    elif base == "cant":  # as a condition states it: the outer rail's height, >= 0
        design = np.abs(layout.cant_at(near)) * 1e3
        tol = np.full(n, CANT_TOLERANCE_MM)
        why = (
            "the condition's cant, the outer rail's height above the inner's, within "
            f"{CANT_TOLERANCE_MM:g} mm"
        )
    else:
        design = layout.grade_at(near) * 1e3
        tol = np.full(n, GRADE_TOLERANCE_PERMILLE)
        why = (
            f"the condition's grade, + up, within {GRADE_TOLERANCE_PERMILLE:g} ‰, a grade band "
            "of railsusp sections"
        )
    if base != "grade":
        why += f"; the design track anywhere within {REGISTRATION_M:g} m of the sample's place"
    return design.min(axis=1) - tol, design.max(axis=1) + tol, why


def _outside(
    x: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    col: str,
    first_row: int | np.ndarray,
    what: str,
    unit: str,
    why: str,
) -> list[str]:
    """The problem of the values of ``x`` outside ``lo``..``hi`` (NaN not judged)."""
    bad = ~np.isnan(x) & ~((x >= lo) & (x <= hi))
    if not bad.any():
        return []
    s, e = runs(bad)[0]
    values = x[bad]
    count = f"{values.size} row(s)"
    if values.min() != values.max() or values.size > e - s:
        count += f" outside, {values.min():.4g} to {values.max():.4g} {unit}"
    there = "" if np.ptp(lo) == 0.0 and np.ptp(hi) == 0.0 else " at the first such row"
    return [
        f"column {col!r}, {rows(s, e - 1, first_row)}: {what} {x[s]:.4g} {unit} ({count}); "
        f"accepted {_low(lo[s])} to {hi[s]:.4g} {unit}{there} ({why})"
    ]


def _low(value: float) -> str:
    """The lowest accepted value as said: "above 0" where it is the least number above 0."""
    return "above 0 and up" if 0.0 < value < 1e-300 else f"{value:.4g}"
