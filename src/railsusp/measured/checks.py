"""Strict checks of recorded channels. Each check returns problem lines that name the
channel and the row range (file lines for tables, sample indices for MDF), so that a
recording is refused with every reason at once, never silently repaired.

- non-finite values: ±inf (a sensor overflow) is refused; NaN gaps up to ``gap_limit``
  samples are interpolated with a note, longer ones refused in a recording to estimate
  from (one stretch) and left for the caller in a long run, which is cut at them (how
  much of a force channel its short gaps may hold, and its effective rate:
  :mod:`railsusp.measured.sampling`);
- constant and all-zero channels (a dead bridge, an unplugged amplifier);
- the time base: not strictly increasing, jitter of the sampling interval, mixed rates;
- magnitudes: the median wheel load Q against the static wheel load of the wagon data (a
  force in the wrong unit is 1000 times off), |Y| and Q beyond physical bounds.
"""

from __future__ import annotations

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.measured.units import si_factor

#: NaN gaps up to this many samples are interpolated (with a note); a longer one refuses a
#: recording to estimate from (one stretch) and cuts a long run, its samples left out
#: (:func:`railsusp.measured.breaks.nan_gap_breaks`)
MAX_GAP_SAMPLES = 5
#: relative deviation of a sampling interval from the median that counts as jitter
JITTER_TOLERANCE = 0.01
#: the same for a long run's speed, position and track channels on their own time base
#: (a CAN bus's, stamped on receipt): they are only interpolated onto the forces' time
#: base, and a quarter of their step is the most that keeps a dropout unambiguous (an
#: interval of one step is at most 1.25 steps, one with a sample lost at least 1.75) and
#: errs by less than their own step's interpolation does (at 10 Hz and 100 km/h, 25 ms:
#: 0.7 m of position, against the 2.8 m between its samples). Force channels keep 1 %
SLOW_JITTER_TOLERANCE = 0.25


def jitter_of(quantity: str) -> float:
    """The jitter a long run's channel of ``quantity`` ("force", "speed", ...) may have."""
    return JITTER_TOLERANCE if quantity == "force" else SLOW_JITTER_TOLERANCE


#: the median Q must lie within these multiples of the static wheel load of the wagon data
WHEEL_LOAD_BAND = (0.3, 3.0)
#: a wheel load below minus this fraction of the static load is refused (noise aside, Q >= 0)
NEGATIVE_Q_FRACTION = 0.02
#: a lateral force never above this fraction of the median wheel load, anywhere in the
#: recording, is refused as a unit error (Y in kN read as N: 5 kN became 5 N); running
#: noise alone is about 1 % of the wheel load on tangent
MIN_LATERAL_FRACTION = 1e-3
#: physical bounds for a 25 t axle-load wagon, N
MAX_LATERAL_N = 300e3
MAX_VERTICAL_N = 600e3


def rows(i: int, j: int, first_row: int | np.ndarray) -> str:
    """Row range text of samples i..j (inclusive): file lines when ``first_row`` > 0
    (tables: the header is line 1), sample indices for MDF. ``first_row`` may also be the
    file line of each sample (a table resampled onto another base: ``distance_m`` tables
    put on time), so that a message still names the lines to look at."""
    if isinstance(first_row, np.ndarray):
        word, a, b = "rows", int(first_row[i]), int(first_row[j])
    else:
        word = "rows" if first_row else "samples"
        a, b = i + first_row, j + first_row
    return f"{word} {a}-{b}" if b > a else f"{word[:-1]} {a}"


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, end exclusive) of every run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist(), strict=True))


def label_runs(label: np.ndarray) -> list[tuple[int, int]]:
    """(start, end exclusive) of every run of equal values in ``label``."""
    edges = np.flatnonzero(np.diff(label)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [label.size]])
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def check_finite(
    x: np.ndarray,
    channel: str,
    first_row: int | np.ndarray,
    gap_limit: int = MAX_GAP_SAMPLES,
    *,
    keep_long: bool = False,
) -> tuple[np.ndarray, list[str], list[str]]:
    """(values with short NaN gaps interpolated, problems, notes). A gap longer than
    ``gap_limit`` samples is refused (a recording to estimate from is one stretch); with
    ``keep_long`` it stays NaN in the values, neither refused nor noted: a long run is cut
    there (:func:`railsusp.measured.breaks.nan_gap_breaks`) instead of being refused
    whole for one stretch an amplifier saturated or a logger marked invalid."""
    problems: list[str] = []
    inf = np.isinf(x)
    for s, e in runs(inf)[:3]:
        problems.append(f"channel {channel!r}, {rows(s, e - 1, first_row)}: infinite value(s)")
    nan = np.isnan(x)
    if nan.all():
        return x, [f"channel {channel!r}: no finite value"], []
    long = [(s, e) for s, e in runs(nan) if e - s > gap_limit]
    for s, e in [] if keep_long else long[:3]:
        problems.append(
            f"channel {channel!r}, {rows(s, e - 1, first_row)}: gap of {e - s} missing "
            f"samples, more than the {gap_limit} that are interpolated (a recording is one "
            "stretch; railsusp sections cuts a long run at such a gap)"
        )
    short = nan.copy()
    for s, e in long:
        short[s:e] = False
    if problems or not short.any():
        return x, problems, []
    idx = np.arange(x.size)
    out = np.interp(idx, idx[~nan], x[~nan])
    out[nan & ~short] = np.nan  # the long gaps (keep_long): the caller cuts the run there
    note = f"channel {channel!r}: {int(short.sum())} missing sample(s) interpolated"
    return out, [], [note]


def check_flat(x: np.ndarray, channel: str, unit: str = "") -> list[str]:
    """A channel that never changes: all zero, or constant (at its value in ``unit``, the
    file's, where given: "constant at 107029" said nothing of N or kN)."""
    finite = x[np.isfinite(x)]
    if finite.size == 0:
        return []
    if np.all(finite == 0.0):
        return [f"channel {channel!r}: all {finite.size} samples are zero (a dead channel)"]
    if np.ptp(finite) == 0.0:
        value = f"{finite[0]:.6g}{' ' + unit if unit else ''}"
        return [f"channel {channel!r}: constant at {value} over all samples"]
    return []


#: a force channel is taken for saturated where at least this share of its samples sits at
#: exactly its largest (or smallest) value in runs of at least CLIP_RUN samples: a
#: continuous force reaches its extreme once, an amplifier's range limit holds it there
CLIP_SHARE, CLIP_RUN, CLIP_SMOOTH, CLIP_SHARE_SMOOTH = 0.005, 5, 0.75, 0.05


def check_clipped(x: np.ndarray, channel: str, unit: str = "") -> list[str]:
    """A force channel held at its range limit (an amplifier or an A/D converter
    saturating): its peaks and p99.85 values would be the limit, not the force. A smooth
    signal written with few digits also holds its extreme value over several samples (a
    slow sine at 6 significant digits: 1 % of its samples), but it creeps onto it and off
    it, from one quantum (the smallest step of the channel) away; a signal cut by a limit
    meets it at whatever step it had. Plateaus most of which (CLIP_SMOOTH) are met and left
    from one quantum away count only from CLIP_SHARE_SMOOTH of the samples."""
    finite = x[np.isfinite(x)]
    if finite.size < 100 or np.ptp(finite) == 0.0:
        return []
    steps = np.abs(np.diff(finite))
    quantum = float(steps[steps > 0].min())
    out = []
    for which, edge in (("largest", finite.max()), ("smallest", finite.min())):
        at = np.isfinite(x) & (x == edge)
        plateaus = [(s, e) for s, e in runs(at) if e - s >= CLIP_RUN]
        held = sum(e - s for s, e in plateaus)
        crept = [
            abs(x[s - 1] - edge) <= 1.5 * quantum and abs(x[e] - edge) <= 1.5 * quantum
            for s, e in plateaus
            if s >= 1 and e < x.size
        ]
        smooth = bool(crept) and np.mean(crept) >= CLIP_SMOOTH
        if held >= (CLIP_SHARE_SMOOTH if smooth else CLIP_SHARE) * finite.size:
            out.append(
                f"channel {channel!r}: {100.0 * held / finite.size:.3g} % of the samples sit at "
                f"its {which} value {edge:.6g}{' ' + unit if unit else ''} in runs of "
                f"{CLIP_RUN} or more: saturated (clipped) at the amplifier's range? Its peaks "
                "would be the range, not the force"
            )
    return out


#: a change of sampling rate shows as at least this many intervals in a row of one whole
#: multiple of the median interval (100 Hz then 50 Hz: 2, 2, 2, ...); fewer long intervals in
#: a row are dropouts with a sample or a few kept between them (a logger's burst of losses)
RATE_CHANGE_INTERVALS = 10


def dropout_steps(t: np.ndarray, jitter: float = JITTER_TOLERANCE) -> np.ndarray | None:
    """Indices i of the intervals t[i] -> t[i + 1] that lost samples (a logger's dropout):
    whole multiples (two or more) of the median interval within the jitter tolerance, on a
    time base whose other intervals are the median one. None where the time base is not
    one rate with dropouts: another interval, or a shorter one (two rates, or jitter), or
    :data:`RATE_CHANGE_INTERVALS` long intervals in a row of one multiple (the rate
    changed, 100 Hz then 50 Hz). Long intervals in a row of other multiples, or fewer of
    them, are dropouts close together (samples 10-19 lost but sample 15 kept: 6 then 5
    intervals): the run is cut at each, the samples between them a piece too short to
    keep. Before stop 63 any two long intervals in a row were a rate change, and two
    dropouts one sample apart refused a whole run as mixed sampling rates. ``jitter``: how
    far an interval may lie off its whole multiple, as a share of one interval (at least
    :data:`JITTER_TOLERANCE` of the multiple: a slow channel's
    :data:`SLOW_JITTER_TOLERANCE` is its stamps' jitter, no larger over a longer interval)."""
    d = np.diff(t)
    med = float(np.median(d))
    ratio = d / med
    steps = np.rint(ratio)
    off = np.abs(ratio - steps)
    whole = (steps >= 1) & (off <= np.maximum(JITTER_TOLERANCE * steps, jitter))
    if not np.all(whole):
        return None
    lost = np.flatnonzero(steps >= 2)
    if lost.size >= RATE_CHANGE_INTERVALS and any(  # runs of equal intervals: a rate change?
        steps[a] >= 2 and b - a >= RATE_CHANGE_INTERVALS for a, b in label_runs(steps)
    ):
        return None
    return lost


def check_time(
    t: np.ndarray,
    channel: str,
    first_row: int | np.ndarray,
    min_samples: int = 10,
    dropouts: bool = False,
    jitter: float = JITTER_TOLERANCE,
) -> list[str]:
    """Time base of a channel: enough samples, finite, strictly increasing, one rate. With
    ``dropouts``, intervals that lost whole samples are accepted (a long run is cut at
    them: :func:`dropout_steps`); otherwise they are refused, however many. ``jitter``: the
    share of the median interval an interval may differ from it by (a long run's speed,
    position and track channels: :data:`SLOW_JITTER_TOLERANCE`; 10 Hz stamped on a CAN
    bus's receipt, a few ms off, refused the whole run at 1 %)."""
    if t.size < min_samples:
        return [f"channel {channel!r}: {t.size} sample(s); at least {min_samples} are needed"]
    bad_t = ~np.isfinite(t)
    if bad_t.any():
        s, e = runs(bad_t)[0]
        return [f"channel {channel!r}, {rows(s, e - 1, first_row)}: time is not a number"]
    d = np.diff(t)
    back = np.flatnonzero(~(d > 0))
    if back.size:
        i = int(back[0])
        return [
            f"channel {channel!r}, {rows(i, i + 1, first_row)}: time not strictly increasing "
            f"({back.size} place(s))"
        ]
    med = float(np.median(d))
    off = np.abs(d / med - 1.0) > jitter
    if not off.any():
        return []
    s, e = runs(off)[0]
    lost = dropout_steps(t, jitter)
    if lost is not None and lost.size:
        if dropouts:
            return []
        # intervals of whole samples lost at one rate (a logger's dropout), not two rates
        i = int(lost[0])
        n = round(float(d[i] / med)) - 1
        return [
            f"channel {channel!r}, {rows(i, i + 1, first_row)}: {d[i]:.4g} s between two "
            f"samples at {1.0 / med:.4g} Hz, {n} sample(s) missing ({lost.size} such "
            "gap(s)): a dropout cannot be interpolated; railsusp sections cuts a long run "
            "at its dropouts, or record without them"
        ]
    # (a slow channel's stamps beyond its jitter: a rate change only as a run of them)
    changed = jitter <= JITTER_TOLERANCE or any(
        b - a >= RATE_CHANGE_INTERVALS for a, b in runs(off)
    )
    if d.max() / d.min() > 1.5 and changed:
        fast, slow = 1.0 / d.min(), 1.0 / d.max()
        return [
            f"channel {channel!r}, {rows(s, e, first_row)}: mixed sampling rates "
            f"({fast:.4g} Hz and {slow:.4g} Hz in one time base); resample before, or "
            f"record one rate"
        ]
    slow = (
        " (a speed, position or track channel's, only interpolated onto the forces' time "
        f"base; a force channel's {100 * JITTER_TOLERANCE:g} %)"
        if jitter > JITTER_TOLERANCE
        else ""
    )
    return [
        f"channel {channel!r}, {rows(s, e, first_row)}: sampling-interval jitter "
        f"{100 * np.abs(d / med - 1).max():.2g} % of the {med:.4g} s interval, more than "
        f"the {100 * jitter:g} % accepted{slow} ({int(off.sum())} interval(s))"
    ]


def check_forces(
    Y: np.ndarray,
    Q: np.ndarray,
    names: tuple[str, str],
    units: tuple[str, str],
    static_wheel_load_N: float,
    first_row: int | np.ndarray,
) -> list[str]:
    """Magnitudes of one wheel's Y and Q (N): the median Q against the static wheel load of
    the wagon data (a unit the magnitude contradicts), and the physical bounds."""
    problems = []
    yname, qname = names
    q = Q[np.isfinite(Q)]
    if q.size and np.any(q != 0):
        med = float(np.median(q))
        low, high = WHEEL_LOAD_BAND
        ratio = med / static_wheel_load_N
        if not low <= ratio <= high:
            hint = ""
            for unit, f in (("N", 1.0), ("kN", 1e3), ("MN", 1e6)):
                if low <= ratio * f / _factor(units[1]) <= high and f != _factor(units[1]):
                    hint = f"; the values look like {unit}, not {units[1]}"
            if not hint:  # right unit, another wagon (a tare C80's 24.5 kN)
                hint = "; another wagon? give its data (--wagon, or wagon = in a pipeline)"
            problems.append(
                f"channel {qname!r}: median wheel load {med / 1e3:.4g} kN (read as "
                f"{units[1]}) against the static wheel load {static_wheel_load_N / 1e3:.4g} kN "
                f"of the wagon data: outside {low:g}-{high:g} times it{hint}"
            )
            return problems  # bounds on a wrongly scaled channel say nothing more
        floor = -NEGATIVE_Q_FRACTION * static_wheel_load_N
        neg = Q < floor
        if neg.any():
            problems.append(
                _beyond(
                    neg, Q, qname, first_row, "negative wheel load", "down to", lowest=True,
                    after=f"; accepted down to {floor / 1e3:.3g} kN "
                    f"({100 * NEGATIVE_Q_FRACTION:g} % of the static wheel load)",
                )
            )  # fmt: skip
        problems += _check_lateral_scale(Y, yname, units[0], med)
    for x, name, bound in ((Y, yname, MAX_LATERAL_N), (Q, qname, MAX_VERTICAL_N)):
        over = np.abs(x) > bound
        if over.any():
            problems.append(
                _beyond(
                    over, np.abs(x), name, first_row, "|force|", "up to",
                    after=f" beyond the physical bound {bound / 1e3:g} kN",
                )
            )  # fmt: skip
    return problems


def _check_lateral_scale(Y: np.ndarray, name: str, unit: str, wheel_load_N: float) -> list[str]:
    """A lateral force whose largest magnitude stays below MIN_LATERAL_FRACTION of the
    median wheel load ``wheel_load_N``: the Q channel's magnitude checks its unit, Y's had
    no lower check (stop 77's hunt: Y in kN marked N read as a few newtons and passed)."""
    y = np.abs(Y[np.isfinite(Y)])
    if not y.size or wheel_load_N <= 0.0:
        return []
    largest = float(y.max())
    if largest >= MIN_LATERAL_FRACTION * wheel_load_N:
        return []
    hint = ""
    for other, f in (("kN", 1e3), ("MN", 1e6)):
        if (
            f != _factor(unit)
            and largest * f / _factor(unit) >= MIN_LATERAL_FRACTION * wheel_load_N
        ):
            hint = f"; the values look like {other}, not {unit}"
            break
    return [
        f"channel {name!r}: |Y| at most {largest:.4g} N (read as {unit}) against a median "
        f"wheel load of {wheel_load_N / 1e3:.4g} kN; accepted a lateral force reaching "
        f"{100 * MIN_LATERAL_FRACTION:g} % of the wheel load somewhere in the recording{hint}"
    ]


def _beyond(
    bad: np.ndarray,
    x: np.ndarray,
    name: str,
    first_row: int | np.ndarray,
    what: str,
    word: str,
    *,
    after: str,
    lowest: bool = False,
) -> str:
    """A message on the samples ``bad`` of channel ``name`` (values ``x``, N): the first
    stretch's rows, the extreme of all of them (the lowest or the highest) and, where there
    are more than one, its row and how many samples in how many stretches, as the gap and
    jitter messages count theirs (the first stretch alone hid a 678.8 kN behind 301.1 kN)."""
    stretches = runs(bad)
    s, e = stretches[0]
    masked = np.where(bad, x, np.nan)
    i = int(np.nanargmin(masked) if lowest else np.nanargmax(masked))
    head = f"channel {name!r}, {rows(s, e - 1, first_row)}: {what}"
    if bad.sum() == 1:
        return f"{head} {x[i] / 1e3:.4g} kN{after}"
    count = f"{int(bad.sum())} such sample(s) in {len(stretches)} stretch(es), the first named"
    return f"{head} {word} {x[i] / 1e3:.4g} kN (at {rows(i, i, first_row)}; {count}){after}"


def _factor(unit: str) -> float:
    """A force unit's factor to N, in any spelling the reader accepts (``KN`` as ``kN``)."""
    try:
        return si_factor("force", unit, "force")
    except RailsuspInputError:
        return 1.0
