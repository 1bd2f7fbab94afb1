"""What a long run's cut says of the stretches it leaves out: a left-out row's reason from
its pieces (:func:`describe`), one phrase per kind, and the speed's range over the pieces a
tolerance cut (:func:`speed_ranges`). Apart from :mod:`railsusp.measured.pieces`, which cuts
the pieces, because these are the words: each piece is ``(kind, label, seconds, metres)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from railsusp.measured.track_kinds import MOVING_MS


class _Piece(Protocol):
    """What :func:`speed_ranges` takes of a left-out row
    (:class:`~railsusp.measured.pieces.Section`)."""

    start: int
    end: int
    pieces: tuple[tuple[str, str, float, float], ...]


def speed_spread(v: np.ndarray) -> float:
    """The speed's spread over a piece, (max - min) / mean (a section's ``speed_spread``)."""
    return float((v.max() - v.min()) / max(v.mean(), 1e-9))


#: the reason of a stretch that the line description does not cover
OUTSIDE_LINE = "not covered by the line description (no km posts there)"


#: a left-out piece too short for a condition, of less than this (s), beside another
#: left-out stretch is where a band's edge fell (a few samples between a transition and the
#: next stretch), not a reason of its own: its row names the neighbour's reason alone.
#: Judged by time, not length, so that a stop (no length at all) is never folded away; a
#: piece cut by the speed is no edge (a noisy speed cuts a whole stretch into such pieces).
EDGE_PIECE_S = 1.0

#: why a tangent's cant is a curve's where no source gives the curvature
CANT_WITHOUT_CURVATURE = (
    "without a curvature (no curvature channel, line description or table radius_m): a "
    "curve cut as tangent, whose condition has no cant; give the curvature (the map's "
    "curvature = ..., --line, or a table's radius_m)"
)

#: how a piece left out because its speed left the tolerance begins its cause
VARIES = "speed varies beyond"


def percent(share: float) -> str:
    """A share in per cent as a reason shows it: two digits, whole ones from 10 %."""
    return f"{100 * share:.0f}" if 100 * share >= 9.5 else f"{100 * share:.2g}"


def describe(
    pieces: tuple[tuple[str, str, float, float], ...],
    varies: dict[str, tuple[float, float, float]] | None = None,
) -> str:
    """A left-out row's reason from its pieces, one phrase per kind in their order: a
    stop's seconds summed, pieces too short for a condition counted with their lengths
    (edge pieces left out where there is more: a piece cut by the speed is none), a
    transition or a radius by its words. ``varies``: per label of short pieces cut by the
    speed, the speed's range and spread over them, said with the tolerance (a noisy speed
    under a tight tolerance is seen for what it is)."""
    # an edge piece: short, under EDGE_PIECE_S, and not cut by the speed; a noisy speed
    # under a tight tolerance cut a whole tangent into pieces under a second each, and its
    # row said "transition" alone (the QA of stop 68)
    real = [
        p for p in pieces if not (p[0] == "short" and p[2] < EDGE_PIECE_S and VARIES not in p[1])
    ] or pieces
    groups: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for kind, label, seconds, metres in real:
        groups.setdefault((kind, label), []).append((seconds, metres))
    out = []
    for (kind, label), items in groups.items():
        if kind == "standing":
            out.append(f"standing ({sum(t for t, _ in items):.0f} s)")
        elif kind == "reversal":  # the speed through 0: no stop
            out.append(
                f"reversing ({sum(t for t, _ in items):.1f} s under {MOVING_MS * 3.6:.1f} "
                "km/h between running forward and backwards)"
            )
        elif kind == "cant":  # its pieces' cant (mm) in their labels
            mm = [float(x[1]) for x in pieces if x[0] == "cant"]
            if mm and float(label) == mm[0]:  # once, for them all
                out.append(f"cant {_span(min(mm), max(mm))} mm {CANT_WITHOUT_CURVATURE}")
        elif kind == "short":
            what, minimum, why = label.split("|")
            ms = [m for _, m in items]
            if varies and label in varies:
                low, high, spread = varies[label]
                why = why.replace(
                    VARIES,
                    f"speed varies from {low:.1f} to {high:.1f} km/h ({percent(spread)} %) "
                    "there, beyond",
                )
            out.append(
                f"{what} of {ms[0]:.0f} m, shorter than the {minimum} m minimum{why}"
                if len(ms) == 1
                else f"{what}: {len(ms)} pieces of {_span(min(ms), max(ms))} m, each shorter "
                f"than the {minimum} m minimum{why}"
            )
        elif kind == "brief":  # long enough, but shorter in time than a condition's record
            what, minimum = label.split("|")
            ts = [t for t, _ in items]
            out.append(
                f"{what} of {ts[0]:.2g} s, shorter than a working condition's {minimum} s "
                "minimum duration"
                if len(ts) == 1
                else f"{what}: {len(ts)} pieces of {min(ts):.2g}-{max(ts):.2g} s, each shorter "
                f"than a working condition's {minimum} s minimum duration"
            )
        else:
            out.append(label)
    return "; ".join(out)


def _span(low: float, high: float) -> str:
    """``low-high`` to the metre, or one number where they round alike."""
    return f"{low:.0f}" if f"{low:.0f}" == f"{high:.0f}" else f"{low:.0f}-{high:.0f}"


def speed_ranges(
    speed: np.ndarray, group: Sequence[_Piece]
) -> dict[str, tuple[float, float, float]]:
    """Per label of the short pieces of ``group`` cut by the speed, the speed's least and
    largest value over them all (km/h) and its spread ((max - min) / mean,
    a section's ``speed_spread``); linear in their samples."""
    spans: dict[str, list[tuple[int, int]]] = {}
    for s in group:
        for kind, label, _, _ in s.pieces:
            if kind == "short" and VARIES in label:
                spans.setdefault(label, []).append((s.start, s.end))
    out = {}
    for label, items in spans.items():
        v = np.concatenate([speed[a:b] for a, b in items])
        out[label] = (float(v.min()) * 3.6, float(v.max()) * 3.6, speed_spread(v))
    return out
