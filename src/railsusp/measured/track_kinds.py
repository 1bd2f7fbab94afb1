"""The kind of track under each sample of a long run, from which its sections are cut
(:mod:`railsusp.measured.sections`): the run's curvature, cant and grade (from its channels,
a line description or a section table) averaged over a length of track, the transitions
(spirals, vertical curves) where they change, and per sample a label of one kind of track:
radius band and direction of a curve, grade band, each with hysteresis at the bands' edges.

Lengths are taken along the track, not in samples: a standing wagon's samples cover no
length, so they neither set the averaging length (a run standing for half its samples
averaged over 10 samples, not 10 m, and read 1 % curvature noise as a spiral) nor make a
transition (a change of curvature over no length at all).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import pandas as pd

from railsusp.measured.checks import runs
from railsusp.measured.line import geometry_from_line, geometry_from_table, running_sense
from railsusp.measured.run import MeasuredRun

#: a wagon slower than this (m/s, 1.8 km/h) stands: its samples cover no track; a stop
#: noisy about zero speed is one standing stretch, not pieces of a few samples each
MOVING_MS = 0.5

#: a curve's radius within this share of a band's edge (a grade within this share of its
#: band's width of the band's edge) keeps the band of the stretch before or after it
#: rather than flip with the channel's noise (the edges sit at common design radii)
BAND_HYSTERESIS = 0.05

#: a tangent's cant (mm) from which it is a curve's whose radius no source gives (its
#: stretch a kind of its own, left out by :func:`railsusp.measured.pieces.stretch_pieces`),
#: or, where the curvature is known, a wide curve's taken as tangent (kept, its cant written
#: as 0, said): below it, a cant channel's offset. The table and sections.csv showed the
#: measured cant, the condition had none (the QA of stop 68)
CANT_ON_TANGENT_MM = 5.0

#: the label of a transition's samples, and of those a line description does not cover
TRANSITION, OUTSIDE = -3, -2


class TrackRules(Protocol):
    """What the labelling takes of :class:`~railsusp.measured.sections.SectionRules`."""

    radius_edges_m: tuple[float, ...]
    tangent_radius_m: float
    grade_band_permille: float
    smoothing_m: float
    spiral_rate: float
    grade_rate: float


def track_geometry(
    run: MeasuredRun,
    rules: TrackRules,
    line: pd.DataFrame | None = None,
    table: pd.DataFrame | None = None,
) -> dict[str, np.ndarray]:
    """Per sample: curvature (1/m), cant (m), grade (1), averaged over ``smoothing_m`` of
    track, and ``transition`` (True where the curvature or grade changes faster than a
    steady condition's), and ``curvature_known`` (False where no source gives the
    curvature, which is then 0). The track is the line description's, else the run's
    channels (a missing one: 0); a section table's track columns
    (:func:`geometry_from_table`) replace the quantities they give over its rows, as
    stated: no average, no transition (the user says the row is steady)."""
    if line is not None:
        geo = geometry_from_line(run.position, line)
    else:
        zero = np.zeros_like(run.time)
        geo = {
            "curvature": run.curvature if run.curvature is not None else zero,
            "cant": run.cant if run.cant is not None else zero,
            "grade": run.grade if run.grade is not None else zero,
        }
    moving = run.speed >= MOVING_MS
    # the track one sample covers, from the moving samples' speed: the median step of the
    # distance was 0 where the run stood for half its samples or the odometer held its
    # value between updates (1 m steps), and the 10 m average shrank to 10 samples
    ds = float(np.median(run.speed[moving])) / run.rate_hz if moving.any() else 1.0
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
    limit = {"curvature": rules.spiral_rate, "grade": rules.grade_rate}
    with np.errstate(invalid="ignore"):
        change = {
            key: np.abs(out[key][ahead] - out[key][behind]) / span > rate
            for key, rate in limit.items()
        }
    stated = geometry_from_table(run.position, table) if table is not None else {}
    for key, values in stated.items():
        inside = ~np.isnan(values)
        out[key] = np.where(inside, values, out[key])
        if key in change:
            change[key] &= ~inside
    out["transition"] = (change["curvature"] | change["grade"]) & moving  # a stop: none
    # where the curvature comes from somewhere (a tangent there is one): a channel, the
    # line description, or the table's radius over its rows; elsewhere a cant is a curve's
    # whose radius the run does not give (:data:`CANT_ON_TANGENT_MM`)
    known = np.full(run.time.shape, line is not None or run.curvature is not None)
    if "curvature" in stated:
        known |= ~np.isnan(stated["curvature"])
    out["curvature_known"] = known
    return out


#: a section table's radius that differs from the run's own (channel or line description,
#: averaged over the row) by more than this factor, either way, is said to contradict it
STATED_RADIUS_FACTOR = 1.25


def stated_track_contradicted(
    run: MeasuredRun, table: pd.DataFrame, rules: TrackRules, line: pd.DataFrame | None = None
) -> list[str]:
    """A note per row of a section table whose stated curve (``radius_m``, ``direction``)
    contradicts the run's own curvature (its channel or ``line``, averaged as the cut
    averages it, over the row's moving samples): another hand, a tangent against a curve
    or the reverse, or a radius off by more than :data:`STATED_RADIUS_FACTOR`. The table's
    track is used as stated (docs/data-format.md), but a typed hand decides which wheel is
    outer, and nothing after the cut can catch it: the sections are written without
    curvature (the QA of stop 73: a table's R350 right over the channel's R600 left was
    written with the inner wheel as the compared one, without a word). None where the run
    has no curvature of its own or the table states none."""
    if "radius_m" not in table or (line is None and run.curvature is None):
        return []
    own = track_geometry(run, rules, line)["curvature"]
    stated = geometry_from_table(run.position, table)["curvature"]
    moving = run.speed >= MOVING_MS
    tangent = 1.0 / rules.tangent_radius_m
    # both quoted as the table writes them, seen towards increasing positions: the stated
    # curvature was mirrored for a run whose position falls, and the run's is mirrored back
    sense = running_sense(run.position)
    notes = []
    for k, r in enumerate(table.itertuples(index=False)):
        inside = (run.position >= r.start_m) & (run.position < r.end_m) & moving
        if not inside.any() or np.isnan(stated[inside]).all():
            continue
        said, found = float(np.nanmean(stated[inside])), float(np.mean(own[inside]))
        curves = (abs(said) > tangent, abs(found) > tangent)
        if curves == (False, False):
            continue
        agree = curves == (True, True) and said * found > 0.0
        if agree and 1.0 / STATED_RADIUS_FACTOR <= found / said <= STATED_RADIUS_FACTOR:
            continue
        notes.append(
            f"{table.attrs.get('what', 'section table')}, row {k + 2}: it states "
            f"{_curve_words(sense * said, tangent)}, the run's "
            f"{'line description' if line is not None else 'curvature channel'} gives "
            f"{_curve_words(sense * found, tangent)} there (averaged over the row"
            f"{'; both seen towards increasing positions' if sense < 0 else ''}): the "
            "table's is used, as stated; check its radius_m and direction (the hand decides "
            "which wheel is outer)"
        )
    return notes


def _curve_words(curvature: float, tangent: float) -> str:
    """A curvature as an engineer says it: ``R 600 m left``, or ``tangent``. Positive
    curvature is a left-hand curve, as :func:`~railsusp.measured.line.geometry_from_line`
    writes it, seen in the run's direction."""
    if abs(curvature) <= tangent:
        return "tangent"
    return f"R {1.0 / abs(curvature):.0f} m {'left' if curvature > 0 else 'right'}"


def _radius_band(curv: np.ndarray, rules: TrackRules, scale: float = 1.0) -> np.ndarray:
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


def track_labels(geo: dict[str, np.ndarray], rules: TrackRules) -> np.ndarray:
    """Per sample, a label of one kind of track (radius band, direction of a curve, grade
    band; :data:`TRANSITION`, :data:`OUTSIDE` a line description; a tangent with cant of
    :data:`CANT_ON_TANGENT_MM` or more where no source gives the curvature), each band with
    hysteresis (:func:`_steady`): noise on a steady curve or grade near a band's edge does
    not cut it into pieces too short to keep."""
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
    band = np.where(np.isnan(curv), OUTSIDE, band)
    band = np.where(geo["transition"] & (band != OUTSIDE), TRANSITION, band)
    label = np.where(
        band == TRANSITION,
        TRANSITION,
        band * 4 + np.where((band >= 0) & (curv < 0), 1, 0) + 1000 * grade_band,
    )
    if "curvature_known" in geo:  # a canted stretch without curvature: a kind of its own
        c = np.abs(np.nan_to_num(geo["cant"])) * 1e3 / CANT_ON_TANGENT_MM
        canted = _steady(*((c >= 1.0 + x).astype(np.int64) for x in (h, -h, 0.0))) == 1
        canted &= ~geo["curvature_known"] & (band == -1)
        label = np.where(canted, label + 3, label)  # (tangent -4 + 3: no other label's)
    return np.where(band == OUTSIDE, OUTSIDE, label)  # NaN outside the line: one label


def kind_shares(
    geo: dict[str, np.ndarray], label: np.ndarray, i: int, j: int
) -> list[tuple[str, float]]:
    """The kinds of track of samples i..j and the share of each, in the order met: a
    transition, a tangent or a curve by its median radius and direction, with its grade
    where the kinds' grade bands differ, a stretch outside the line description."""
    lab = label[i:j]
    values, first, counts = np.unique(lab, return_index=True, return_counts=True)
    kinds = [int(v) for v in values if v not in (TRANSITION, OUTSIDE)]
    grades = {round(v / 1000) for v in kinds}  # label = 1000 grade band + 4 band + side
    shares: dict[str, float] = {}
    for v, _, n in sorted(zip(values, first, counts, strict=True), key=lambda x: x[1]):
        if v == TRANSITION:
            text = "transition"
        elif v == OUTSIDE:
            text = "outside the line description"
        else:
            mine = lab == v
            curv = float(np.median(geo["curvature"][i:j][mine]))
            band = (int(v) - 1000 * round(v / 1000)) // 4
            text = (
                "tangent"
                if band < 0
                else f"curve R{1.0 / max(abs(curv), 1e-12):.0f} "
                + ("right" if curv < 0 else "left")
            )
            if len(grades) > 1:
                grade = float(np.median(geo["grade"][i:j][mine])) * 1e3
                text += f" at {grade:.0f} permille"
        shares[text] = shares.get(text, 0.0) + n / lab.size
    return list(shares.items())
