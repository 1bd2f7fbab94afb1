"""Where a long run breaks: no section spans a break, so that a section's samples are one
stretch of the line recorded without a hole.

- a **dropout**: samples lost in time, every channel together (a logger's); the run is cut
  between the samples before and after it (:func:`dropout_breaks`);
- a **NaN gap** longer than the samples interpolated (:data:`~railsusp.measured.checks.
  MAX_GAP_SAMPLES`) in a used channel: an amplifier's overload, samples a logger marked
  invalid. The samples exist but a channel has no value there; the run is cut on either
  side and the gap's samples are left out of the sections, named in the cut
  (:func:`nan_gap_breaks`). Before stop 63 one such gap refused a whole 2 h run, where a
  dropout cut it;
- a **jump of the distance channel**: a chainage jump at a km post, an odometer's reset
  (:func:`jump_steps`).

A channel whose gaps leave no stretch of values as long as the shortest working condition
(:data:`MIN_STRETCH_S`) is refused: no section could be cut from it.
"""

from __future__ import annotations

import numpy as np

from railsusp.conditions import field_range
from railsusp.measured.checks import dropout_steps, jitter_of, rows, runs
from railsusp.measured.raw import RawChannel

#: the least stretch of values (s) a channel must keep between its NaN gaps, and the run
#: with every channel's gaps together: a working condition's shortest duration (no section
#: can be cut from less)
MIN_STRETCH_S: float = field_range("duration_s")[0]
#: the gaps a channel's note lists (the others counted)
GAPS_LISTED = 3
#: a distance channel's step this many times what the speed covers in it is a chainage
#: jump or an odometer's reset, not travel
JUMP_FACTOR = 5.0
#: the largest speed of a working condition, m/s: without a speed channel, a step of the
#: distance beyond what it covers (times JUMP_FACTOR) is a jump
MAX_SPEED_MS: float = field_range("speed_kmh")[1] / 3.6


def dropout_breaks(
    si: dict[str, RawChannel],
    base: str,
    quantity: dict[str, str],
    problems: list[str],
    notes: list[str],
    data_notes: list[str],
) -> np.ndarray:
    """The base samples after which the run lost samples (a logger's dropout): where the run
    is cut. A dropout is every channel's together (one logger), so each other channel's and
    the base's must coincide, both ways: a base sample inside another channel's dropout
    would take that channel's values interpolated across it, and another channel's sample
    inside the base's is a time the base alone lost (only the first was looked for: forces
    that lost samples a speed channel kept were cut there without a word). Either is a
    problem naming the channel. A sample counts as inside a dropout beyond half the base's
    interval from either end, or the channel's jitter (:func:`~railsusp.measured.checks.
    jitter_of`, of its interval) where larger: a slow channel's stamps may move that far;
    a base sample inside a speed, position or track channel's gap beyond one of that
    channel's steps (and its jitter): a slower channel's gap in a dropout of all reaches
    that far past the base's (10 Hz speed and 1000 Hz forces losing the same 0.5 s were
    refused as the speed's own loss)."""
    t = si[base].time
    lost = dropout_steps(t)
    breaks = (lost + 1) if lost is not None else np.zeros(0, dtype=np.int64)
    for c, q in quantity.items():
        ch = si[c]
        if c == base:
            continue
        tol = max(0.5 / si[base].rate_hz, jitter_of(q) / ch.rate_hz)
        # a speed, position or track channel slower than the base, in a dropout of all:
        # its last sample before and first after lie up to one of its own steps from the
        # base's, so base samples that near its gap's ends are the shared dropout's edges
        # (their values interpolated from its neighbouring sample, an error of that
        # fraction of its change over the dropout), not a loss of its own
        slower = q != "force" and ch.rate_hz < (1.0 - jitter_of(q)) * si[base].rate_hz
        edge = max(tol, (1.0 + jitter_of(q)) / ch.rate_hz) if slower else tol
        if found := _inside(ch.time, dropout_steps(ch.time, jitter_of(q)), t, edge):
            a, b, n = found
            said = (
                f"samples lost between {a:.3f} and {b:.3f} s where the forces of {base!r} have {n}"
            )
        elif found := _inside(t, lost, ch.time, tol):
            a, b, n = found
            said = (
                f"{n} sample(s) between {a:.3f} and {b:.3f} s, where the forces of {base!r} "
                "lost theirs (a dropout)"
            )
        else:
            continue
        problems.append(
            f"channel {c!r}: {said}; accepted dropouts of all channels together (one logger)"
        )
    if breaks.size:
        note = f"channel {base!r}: {breaks.size} dropout(s) (samples lost); sections are cut there"
        notes.append(note)
        data_notes.append(note)
    return breaks.astype(np.int64)


def _inside(
    own: np.ndarray, gaps: np.ndarray | None, other: np.ndarray, tol: float
) -> tuple[float, float, int] | None:
    """The first of ``gaps`` (steps i -> i + 1 of the time base ``own`` that lost samples:
    :func:`~railsusp.measured.checks.dropout_steps`) that holds samples of the time base
    ``other`` more than ``tol`` s from either end: its two times and their count; None
    where none does."""
    for i in [] if gaps is None else gaps:
        a, b = float(own[i]), float(own[i + 1])
        n = int(np.count_nonzero((other > a + tol) & (other < b - tol)))
        if n:
            return a, b, n
    return None


def _longest_stretch(t: np.ndarray, missing: np.ndarray) -> float:
    """The longest time (s) between the first and last sample of a run of samples not
    ``missing`` (0 where every sample is)."""
    spans = runs(~missing)
    return max((float(t[e - 1] - t[s]) for s, e in spans), default=0.0)


def channel_nan_gaps(
    ch: RawChannel, gap_limit: int, problems: list[str], notes: list[str]
) -> list[tuple[int, int]]:
    """The NaN gaps (start, end exclusive, the channel's own samples) left in ``ch``'s
    values after :func:`~railsusp.measured.checks.check_finite` with ``keep_long``: each
    longer than ``gap_limit`` samples. A note names the channel, the gaps' rows and times
    and their lengths; a channel whose gaps leave no stretch of :data:`MIN_STRETCH_S` is a
    problem (the run is mostly missing there)."""
    missing = np.isnan(ch.values)
    gaps = runs(missing)
    if not gaps:
        return []
    t = ch.time
    share = 100.0 * float(missing.mean())
    longest = _longest_stretch(t, missing)
    if longest < MIN_STRETCH_S:
        problems.append(
            f"channel {ch.name!r}: {share:.3g} % of its samples missing (NaN) in {len(gaps)} "
            f"gap(s) of more than {gap_limit} samples, its longest stretch of values "
            f"{longest:.3g} s; accepted a channel with a stretch of at least {MIN_STRETCH_S:g} s "
            "(a working condition's shortest duration: no section can be cut from less)"
        )
        return gaps
    listed = "; ".join(
        f"{rows(s, e - 1, ch.first_row)} ({t[s]:.3f}-{t[e - 1]:.3f} s, {e - s} samples)"
        for s, e in gaps[:GAPS_LISTED]
    )
    more = f"; and {len(gaps) - GAPS_LISTED} more" if len(gaps) > GAPS_LISTED else ""
    notes.append(
        f"channel {ch.name!r}: {len(gaps)} gap(s) of missing values (NaN) longer than the "
        f"{gap_limit} samples interpolated, {share:.3g} % of its samples: {listed}{more}; the "
        "run is cut there, the gaps' samples left out of the sections"
    )
    return gaps


def filled(x: np.ndarray) -> np.ndarray:
    """``x`` with its NaN samples interpolated linearly (held at the ends): a channel's
    long gaps, so that it can be put on the run's time base and the run's position and
    track computed through them. Their samples are never in a section (:func:`nan_gap_breaks`
    marks them), nor in the comparison of the distance with the speed
    (:func:`compared_paths`): a gap held flat at an end covers no distance."""
    nan = np.isnan(x)
    if not nan.any():
        return x
    idx = np.arange(x.size)
    return np.interp(idx, idx[~nan], x[~nan])


def span_mask(n: int, spans: list[tuple[int, int]]) -> np.ndarray:
    """Per sample of ``n``, True inside one of ``spans`` (start, end exclusive)."""
    mask = np.zeros(n, dtype=bool)
    for a, b in spans:
        mask[a:b] = True
    return mask


def nan_gap_breaks(
    si: dict[str, RawChannel],
    gaps: dict[str, list[tuple[int, int]]],
    t: np.ndarray,
    problems: list[str],
) -> tuple[np.ndarray, tuple[tuple[int, int, str], ...]]:
    """Each channel's NaN gaps on the run's time base ``t``: the base samples whose values
    came from a gap (on a slower channel's time base, those between its last value before
    the gap and its first after), as (start, end exclusive, channel), and the breaks at
    their ends. Where the channels' gaps together leave no stretch of :data:`MIN_STRETCH_S`
    with every channel's values (each alone has one, at other times), a problem naming
    them, with the share of samples missing in any and the longest stretch."""
    spans: list[tuple[int, int, str]] = []
    for c, own in gaps.items():
        ct = si[c].time
        for s, e in own:
            first = int(np.searchsorted(t, ct[s - 1], "right")) if s > 0 else 0
            last = int(np.searchsorted(t, ct[e], "left")) if e < ct.size else t.size
            if last > first:
                spans.append((first, last, c))
    if not spans:
        return np.zeros(0, dtype=np.int64), ()
    missing = span_mask(t.size, [(a, b) for a, b, _ in spans])
    longest = _longest_stretch(t, missing)
    if longest < MIN_STRETCH_S:
        names = ", ".join(repr(c) for c in dict.fromkeys(c for _, _, c in spans))
        problems.append(
            f"channels {names}: {100.0 * float(missing.mean()):.3g} % of the samples missing "
            f"(NaN) in one of them or more, their longest stretch with every channel's values "
            f"{longest:.3g} s; accepted a stretch of at least {MIN_STRETCH_S:g} s (a working "
            "condition's shortest duration)"
        )
    edges = np.array([x for a, b, _ in spans for x in (a, b)], dtype=np.int64)
    return np.unique(edges), tuple(sorted(spans))


def inner(idx: np.ndarray, n: int) -> np.ndarray:
    """The break indices that split a run of ``n`` samples (1 to n - 1), as int64."""
    idx = np.asarray(idx, dtype=np.int64)
    return idx[(idx > 0) & (idx < n)]


def jump_steps(x: np.ndarray, t: np.ndarray, speed: np.ndarray | None) -> np.ndarray:
    """Indices i of the distance channel's steps x[i] -> x[i + 1] that are no travel: a
    chainage jump at a km post, an odometer's reset. Each change of the value is judged
    over the time since the value last changed (a channel held between its updates steps
    once per update: travel): with the speed, a change more than :data:`JUMP_FACTOR` times
    what the speed covers in that time (1 m at the least); without it, more than that
    times the median rate of change or what the fastest working condition covers."""
    steps = np.diff(x)
    moved = np.flatnonzero(steps != 0)
    if moved.size == 0:
        return moved
    since = t[np.concatenate([[0], moved[:-1] + 1])]  # when the value took its last level
    elapsed = t[moved + 1] - since
    change = np.abs(steps[moved])
    if speed is not None:
        fastest = np.maximum(np.abs(speed[moved + 1]), np.abs(speed[moved]))
        reach = fastest * elapsed
    else:
        rate = float(np.median(change / np.maximum(elapsed, 1e-12)))
        reach = np.maximum(rate, 1.2 * MAX_SPEED_MS / JUMP_FACTOR) * elapsed
    return moved[change > JUMP_FACTOR * reach + 1.0]


def compared_steps(
    own_time: np.ndarray,
    own_gaps: list[tuple[int, int]],
    jump: np.ndarray,
    t: np.ndarray,
    spans: list[tuple[int, int]],
) -> np.ndarray:
    """The steps of a distance channel (its samples i -> i + 1, on its own time base
    ``own_time``) over which its path is compared with the integrated speed: True where
    the step is no ``jump``, touches none of the channel's own NaN gaps (``own_gaps``) and
    spans no sample of the run's time base ``t`` inside ``spans`` (the gaps of the distance
    and speed channels on it). A gap's values are filled, held flat at the run's ends
    (:func:`filled`): compared there, a run whose position was missing for its first 20 s
    read as a unit error (600 m against 900 m, a ratio of 0.67) instead of being cut."""
    ok = np.ones(max(own_time.size - 1, 0), dtype=bool)
    ok[jump] = False
    for s, e in own_gaps:  # steps s - 1 -> s up to e - 1 -> e touch a missing sample
        ok[max(s - 1, 0) : e] = False
    if spans:
        # the missing samples before each
        count = np.concatenate([[0], np.cumsum(span_mask(t.size, spans))])
        lo = np.searchsorted(t, own_time[:-1], "left")
        hi = np.searchsorted(t, own_time[1:], "right")
        ok &= count[hi] == count[lo]
    return ok


def distance_path(x: np.ndarray, steps: np.ndarray) -> float:
    """The path a distance channel runs over, m: the sum of its ``steps`` (a mask of its
    steps, :func:`compared_steps`: its jumps and gaps left out; a run that backs up covers
    its stretch twice; a reset covers nothing)."""
    return float(np.sum(np.abs(np.diff(x))[steps]))


def speed_path(speed: np.ndarray, t: np.ndarray, own_time: np.ndarray, steps: np.ndarray) -> float:
    """What the speed (m/s on the run's time base ``t``) integrates to, m, over the same
    ``steps`` of the distance channel (on its time base ``own_time``): the two are compared
    over one stretch of time."""
    v = np.abs(speed)
    covered = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    return float(np.sum(np.diff(np.interp(own_time, t, covered))[steps]))


def compared_paths(
    pos: RawChannel,
    own_gaps: list[tuple[int, int]],
    jump: np.ndarray,
    speed: np.ndarray,
    t: np.ndarray,
    spans: list[tuple[int, int]],
) -> tuple[float, float, bool]:
    """The distance channel ``pos``'s path, what the ``speed`` (on the run's time base
    ``t``) integrates to over the same steps, m, and whether gaps were left out: its
    jumps, its own NaN gaps and the samples of ``spans`` (the distance and speed channels'
    gaps on ``t``) left out of both (:func:`compared_steps`). On the distance's own
    samples: on the forces', a slow channel's jump is spread over many steps, each too
    small to tell."""
    steps = compared_steps(pos.time, own_gaps, jump, t, spans)
    path = distance_path(pos.values, steps)
    return path, speed_path(speed, t, pos.time, steps), bool(spans or own_gaps)


def without_jumps(x: np.ndarray, jump: np.ndarray) -> np.ndarray:
    """The distance along the path: each jump's step replaced by the steps around it
    (interpolated over the steps that are travel; a jump at either end or two in a row,
    a single wrong sample, included)."""
    steps = np.diff(x)
    if jump.size:
        ok = np.ones(steps.size, dtype=bool)
        ok[jump] = False
        idx = np.arange(steps.size)
        steps[jump] = np.interp(jump, idx[ok], steps[ok]) if ok.any() else 0.0
    return np.concatenate([[x[0]], x[0] + np.cumsum(steps)])
