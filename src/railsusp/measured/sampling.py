"""How a force channel's finite samples lie, and the one rule both readers hold them to
(a recording of the field format, :mod:`railsusp.measured.recording_reader`, and a long
run, :mod:`railsusp.measured.run`):

- the channel's **effective rate** is its rate over its step between finite samples: the
  most common one, where it is a whole number of rows k >= 2 between more than half of
  them (a value in every second row of a 100 Hz table is 50 Hz data, as a 50 Hz channel
  of an MDF4 file is), else 1 (every row, its empty cells missing); it must reach the
  rate limit that applies (the field reader's ``min_rate_hz``, ``check-recording
  --min-rate``; a long run's, the rate its sections are resampled to:
  :func:`railsusp.measured.run_checks.check_force_rates`);
- at that rate, the samples missing in short NaN gaps (each within ``gap_limit`` samples:
  interpolated) or lying off its step may fill at most :data:`MAX_INTERPOLATED_SHARE` of
  them: interpolated values are not measured forces. Longer gaps are no share of this: a
  recording to estimate from is refused at one, a long run cut there.

A long run's speed, position or track column is held to a like rule (:func:`every_k_rows`):
with a value every k rows it is a channel at the table's rate over k, its samples missing
only where a row of that step is empty.

Before, the field reader refused a 100 Hz table with a value in every other row (50 %
"missing") where the long run's accepted one with a note, and the long run's accepted 20 %
of its samples missing one by one, which ``sections --write`` then wrote as measured. The
step was the median: with every third row empty (steps of 1 and 2 as often) it was 1.5,
133 Hz of a 200 Hz table and nothing missing, where one row less made it 1 and a third
of the samples missing, refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from railsusp.measured.checks import MAX_GAP_SAMPLES
from railsusp.measured.raw import RawChannel

#: the largest share of a force channel's samples (at its effective rate) that its short
#: NaN gaps, or samples off its step, may hold
MAX_INTERPOLATED_SHARE = 0.05


@dataclass(frozen=True)
class FiniteSampling:
    """Where a channel's finite samples lie among its rows."""

    step: float  # rows between finite samples: a whole k >= 2 where most are, else 1
    rate_hz: float  # its effective rate: the written rate over ``step``
    missing: int  # samples of that rate missing in short gaps, or lying off its step
    samples: int  # its samples at that rate (finite and missing; long gaps aside)
    interpolated: int = 0  # of ``missing``, those missing in short gaps (not off its step)

    @property
    def share(self) -> float:
        """The share of its samples missing (or off its step)."""
        return self.missing / self.samples if self.samples else 0.0


def finite_sampling(
    x: np.ndarray, rate_hz: float, gap_limit: int = MAX_GAP_SAMPLES
) -> FiniteSampling:
    """How the finite samples of ``x`` (one per row at ``rate_hz``) lie: their step (the
    most common one between them, where it is k >= 2 rows between more than half of them;
    else 1), the effective rate, and the samples of that rate missing in the short NaN gaps
    (of up to ``gap_limit`` rows, ends included). At a step of 1 these are the NaN samples;
    at a step k a gap of k·m rows is m - 1 missing, and a step shorter than k (values not on
    a regular step: NaN scattered over half the rows) counts too. A median or fractional
    step hid them: a third of the rows empty read as a step of 1.5, nothing missing."""
    at = np.flatnonzero(~np.isnan(x))
    if at.size < 2:  # (no finite value, or one: the reader refuses it)
        return FiniteSampling(1.0, rate_hz, 0, x.size)
    d = np.diff(at)
    d = d[d <= gap_limit + 1]  # a longer gap is refused or cut at, never interpolated
    step = float(regular_step(d))
    ends = np.array([at[0], x.size - 1 - at[-1]])
    ends = ends[ends <= gap_limit]
    per_gap = np.rint(d / step) - 1.0  # below 0: a value off the step
    at_ends = np.rint(ends / step).sum()
    missing = int(np.abs(per_gap).sum() + at_ends)
    interpolated = int(np.maximum(per_gap, 0.0).sum() + at_ends)
    return FiniteSampling(step, rate_hz / step, missing, at.size + missing, interpolated)


def regular_step(d: np.ndarray) -> int:
    """The rows between a channel's finite values (``d``, the differences of their rows):
    the most common difference where it is k >= 2 and holds more than half of them (a tie:
    the shorter), else 1."""
    if not d.size:
        return 1
    counts = np.bincount(d)
    k = int(np.argmax(counts))
    return k if k >= 2 and 2 * counts[k] > d.size else 1


def missing_rows(x: np.ndarray, step: float) -> np.ndarray:
    """Per row of ``x``, True where its NaN is missing data, not a row off the channel's
    regular ``step`` (:func:`finite_sampling`'s): inside a NaN run between finite values d
    rows apart where round(d / step) >= 2, or at either end where round(rows / step) >= 1,
    as :func:`finite_sampling` counts its missing samples (long gaps included). At a step
    of 1 every NaN is. The NaN of every second row of a 50 Hz channel in a 100 Hz table
    are no gaps: marked, they had every section left out as half interpolated."""
    nan = np.isnan(x)
    at = np.flatnonzero(~nan)
    if at.size == 0:
        return nan
    # missing samples at the channel's rate per stretch of NaN rows: before the first
    # finite value, between each two, after the last
    lost = np.concatenate(
        [
            [np.rint(at[0] / step)],
            np.rint(np.diff(at) / step) - 1.0,
            [np.rint((x.size - 1 - at[-1]) / step)],
        ]
    )
    stretch = np.searchsorted(at, np.arange(x.size), side="right")  # 0: before the first
    return nan & (lost[stretch] >= 1.0)


def short_gaps_note(channel: str, s: FiniteSampling) -> str | None:
    """The note of a force channel's samples missing at its rate in short gaps (``s``, its
    :func:`finite_sampling`: ``interpolated``), None where none is: at a step of 1 every
    NaN row of such a gap, as :func:`~railsusp.measured.checks.check_finite` counts them;
    at a step k only the samples of that rate missing (its rows off the step are no data
    missing: a column filled every second row was also noted as "3000 missing sample(s)
    interpolated", beside its note of being sampled at 50 Hz)."""
    if not s.interpolated:
        return None
    rate = f" (of its {s.rate_hz:.4g} Hz)" if s.step > 1.0 else ""
    return f"channel {channel!r}: {s.interpolated} missing sample(s){rate} interpolated"


def every_k_rows(ch: RawChannel) -> tuple[RawChannel, str | None]:
    """A table's speed, position or track column as the slow channel it is, where its
    finite values fall every k >= 2 rows (k rows between more than half of them): a 5 Hz
    speed written in every 20th row of a 100 Hz table, the other cells empty, was refused
    as 95 % missing. Its samples are then its rows of that step: its finite rows, and
    between two of them d rows apart round(d / k) - 1 rows missing (NaN, evenly between),
    as are the rows of its step before its first value and after its last; it is read at
    the table's rate over k and interpolated onto the forces' time base as a slow MDF
    channel is, only those samples missing (short gaps interpolated, longer ones cut at).
    A finite value off that step stays a sample of its own, its time checked as a slow
    channel's (:data:`~railsusp.measured.checks.SLOW_JITTER_TOLERANCE`). With the note
    that says so; the column as it is (None) where no such step holds."""
    x = ch.values
    at = np.flatnonzero(~np.isnan(x))
    if at.size < 3 or isinstance(ch.first_row, np.ndarray) or not ch.first_row:  # (MDF: 0)
        return ch, None
    d = np.diff(at)
    k = regular_step(d)  # (every gap counts here: a slow column's step is many rows)
    if k < 2:
        return ch, None
    m = np.maximum(np.rint(d / k), 1.0).astype(np.int64)  # its steps between two values
    j = np.arange(int(m.sum())) - np.repeat(np.cumsum(m) - m, m)  # 0 .. m - 1 in each
    inside = np.repeat(at[:-1], m) + np.rint(j * np.repeat(d / m, m)).astype(np.int64)
    head = at[0] - k * np.arange(at[0] // k, 0, -1)
    tail = at[-1] + k * np.arange(1, (x.size - 1 - at[-1]) // k + 1)
    idx = np.concatenate([head, inside, at[-1:], tail])
    out = RawChannel(ch.name, ch.unit, ch.time[idx], x[idx], ch.first_row + idx)
    note = finite_rate_note(ch.name, FiniteSampling(k, ch.rate_hz / k, 0, idx.size), ch.rate_hz)
    return out, note


def check_sparse(
    s: FiniteSampling,
    channel: str,
    gap_limit: int = MAX_GAP_SAMPLES,
    max_share: float = MAX_INTERPOLATED_SHARE,
) -> list[str]:
    """The problem of a force channel (its :func:`finite_sampling`) whose short gaps
    together hold more than ``max_share`` of its samples: each gap passed the
    ``gap_limit`` rule, but together they are much of the record."""
    if s.share <= max_share:
        return []
    pct = f"{100.0 * s.share:.3g} %"
    if s.step > 1.0:
        said = (
            f"a finite value about every {s.step:.3g} samples ({s.rate_hz:.4g} Hz), "
            f"{s.missing} of its {s.samples} samples at that rate ({pct}) missing (NaN) or "
            "off that step"
        )
    else:
        said = f"{s.missing} of its {s.samples} samples ({pct}) missing (NaN)"
    return [
        f"channel {channel!r}: {said}, in gaps of up to {gap_limit} samples; accepted at "
        f"most {100.0 * max_share:g} % of a force channel's samples in such gaps (each "
        "interpolated): interpolated values are not measured forces"
    ]


def finite_rate_note(channel: str, s: FiniteSampling, stated_hz: float) -> str | None:
    """What a channel whose finite samples are sparser than its rate is read as (None: as
    its rate): its finite values' rate, interpolated between them."""
    if not s.rate_hz < stated_hz * (1.0 - 1e-6):
        return None
    return (
        f"channel {channel!r}: a finite value about every {s.step:.3g} samples of its "
        f"{stated_hz:.4g} Hz (the others empty): sampled at {s.rate_hz:.4g} Hz, "
        "interpolated between them"
    )


def section_interpolated(
    interpolated: dict[str, np.ndarray],
    start: int,
    end: int,
    max_share: float = MAX_INTERPOLATED_SHARE,
) -> str | None:
    """Why a section of a long run (samples ``start`` to ``end``, end exclusive) is left out
    where a force channel's values interpolated across empty ones (``MeasuredRun.
    interpolated``) fill more than ``max_share`` of it; None where none does. The run as a
    whole passed the rule, but its gaps may crowd into one section, and ``sections --write``
    writes them as if measured: the field reader could no longer tell them."""
    worst, share = None, 0.0
    for channel, mask in sorted(interpolated.items()):
        here = float(np.mean(mask[start:end])) if end > start else 0.0
        if here > share:
            worst, share = channel, here
    if worst is None or share <= max_share:
        return None
    return (
        f"{100.0 * share:.3g} % of the samples of channel {worst!r} here interpolated across "
        f"empty values; accepted at most {100.0 * max_share:g} % in a section (written, they "
        "would read as measured forces)"
    )


def leave_out_crowded(interpolated: dict[str, np.ndarray], sections: list) -> None:
    """Leave out, in place, each kept section (``start``, ``end``, ``kept``, ``reason``: a
    :class:`~railsusp.measured.pieces.Section`) that :func:`section_interpolated` refuses,
    with its reason."""
    for s in sections:
        crowded = section_interpolated(interpolated, s.start, s.end) if s.kept else None
        if crowded:
            s.kept, s.reason = False, crowded
