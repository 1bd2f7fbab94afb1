"""The checks of a long run as a whole, beyond those of each channel
(:mod:`railsusp.measured.checks`): every force channel sampled fast enough, the file's and
the channel map's units agreeing, and speed, cant, grade and distance within what a line
and a working condition allow (a channel beyond them is more likely in the wrong unit); the
force channel whose time base the run takes, and every channel covering its span.

Apart from :mod:`railsusp.measured.run` (which reads the recording and joins its channels on
one time base) because these are the limits and the problems they raise: each returns its
problems (or records them) for the reader to report together.
"""

from __future__ import annotations

import numpy as np

from railsusp.conditions import field_range
from railsusp.errors import RailsuspInputError
from railsusp.measured.channels import ChannelMap
from railsusp.measured.checks import jitter_of
from railsusp.measured.raw import RawChannel
from railsusp.measured.units import normalise_unit, si_factor

#: a force channel slower than this fraction of the fastest is refused, not interpolated
MIN_FORCE_RATE_FRACTION = 0.1
#: what a long run's least force rate is (:func:`check_force_rates`' ``limit``)
SECTIONS_RATE = (
    "the rate the sections are resampled to (sections --rate, [field] rate_hz; "
    "check-recording --min-rate)"
)

#: the least share of a run's samples at a running speed (1.8 km/h or more): a run that
#: stood for most of its time is read, its standing stretches left out when it is cut
MIN_RUNNING_SHARE = 0.05
#: the largest speed, cant and grade a run may show: a working condition's bounds
#: (conditions.py), beyond which a channel's unit is more likely wrong than the line
MAX_SPEED_KMH = field_range("speed_kmh")[1]
MAX_CANT_M = field_range("cant_mm")[1] * 1e-3
MAX_GRADE = field_range("grade_permille")[1] * 1e-3
#: how far the distance channel's span may differ from the integrated speed (a wheel
#: diameter's wear and slip are a few per cent; a unit slip is a factor 3.6 or 1000)
DISTANCE_SPEED_RATIO = (0.8, 1.25)


def check_track_channels(
    sig: dict[str, np.ndarray],
    names: dict[str, str],
    paths: tuple[float, float, bool] | None,
) -> list[str]:
    """Problems of a run's track channels whose values no line has, each naming the
    channel: a cant or grade beyond a working condition's range, and a distance channel
    whose path disagrees with the integrated speed (one of the two in the wrong unit: a
    speed headed ``[m/s]`` holding km/h cut sections at 234 km/h). ``paths``: the distance
    channel's path, what the speed integrates to over the same steps, and whether gaps were
    left out (:func:`~railsusp.measured.breaks.compared_paths`); None: not both channels.
    The path, not the channel's span: a run that backs up is no unit error, nor is a
    chainage jump or an odometer's reset (a unit error of 3.6 or 1000 moves every step).
    A negative cant is refused too: a condition's cant is the outer rail's height, 0 to
    200 mm; a signed channel passed here and failed only when ``sections --write`` made
    the section's condition."""
    problems = []
    if "cant" in sig and np.nanmin(sig["cant"]) < 0.0:
        problems.append(
            f"channel {names['cant']!r}: cant down to {np.nanmin(sig['cant']) * 1e3:.4g} mm, "
            f"negative; accepted 0 to {MAX_CANT_M * 1e3:g} mm, the cant's magnitude (the "
            "outer rail's height above the inner's): a signed cant? give its magnitude"
        )
    for key, limit, scale, unit in (
        ("cant", MAX_CANT_M, 1e3, "mm"),
        ("grade", MAX_GRADE, 1e3, "‰"),
    ):
        if key in sig and np.nanmax(np.abs(sig[key])) > limit * (1.0 + 1e-9):
            problems.append(
                f"channel {names[key]!r}: {key} up to {np.nanmax(np.abs(sig[key])) * scale:.4g} "
                f"{unit}, beyond a working condition's {limit * scale:g} {unit}: a unit error?"
            )
    if paths is not None:
        span, travelled, gapped = paths
        lo, hi = DISTANCE_SPEED_RATIO
        where = " outside their gaps of missing values (NaN)" if gapped else ""
        if travelled > 10.0 and not lo <= span / travelled <= hi:
            problems.append(
                f"channels {names['position']!r} and {names['speed']!r}: the distance runs over "
                f"{span:.4g} m while the speed integrates to {travelled:.4g} m{where} (ratio "
                f"{span / travelled:.3g}, accepted {lo:g} to {hi:g}): a unit error in one?"
            )
    return problems


def check_force_rates(
    force_names: list[str],
    base: str,
    rates: dict[str, float],
    min_rate_hz: float,
    stated: dict[str, float] | None = None,
    limit: str = SECTIONS_RATE,
) -> list[str]:
    """Problems of force channels sampled too slowly, one per channel: every force channel,
    not only the fastest (``base``, whose time base the run takes), must reach
    ``min_rate_hz``, the rate the sections are resampled to, and a tenth of the fastest.
    A slower force channel would be interpolated onto the fastest one's time base: a 25 Hz
    Q under a 200 Hz Y was accepted with a note, its dynamics above 12.5 Hz gone (its
    standard deviation 4.7 kN for 7.2; the audit of stop 63), where the docs promise forces
    sampled at least at the sections' rate. A rate equal to the least one is accepted (1000
    Hz stated as 999.9999 Hz). ``rates``: each channel's rate of its finite samples
    (:func:`railsusp.measured.sampling.finite_sampling`); ``stated``: the rate its time
    column states, where it may differ (a channel whose finite samples are sparser is named
    as such); ``limit``: what ``min_rate_hz`` is, in the reader's words (a field recording's
    is its --min-rate). The field reader holds its force columns to it too."""
    problems = []
    fastest = rates[base]
    for c in force_names:
        least = max(min_rate_hz, MIN_FORCE_RATE_FRACTION * fastest)
        if rates[c] >= least * (1.0 - 1e-6):
            continue
        by_rate = least == min_rate_hz  # the sections' rate is the limit missed, not a tenth
        why = (
            limit
            if by_rate
            else "a tenth of the fastest force channel's: interpolation cannot restore more"
        )
        written = (stated or {}).get(c, rates[c])
        if rates[c] < written * (1.0 - 1e-6):  # its finite samples are the sparser
            said = (
                f"forces sampled at {rates[c]:.4g} Hz (a finite value about every "
                f"{written / rates[c]:.3g} samples of its {written:.4g} Hz, the others empty)"
            )
        elif c == base or rates[c] >= fastest * (1.0 - 1e-6):  # as fast as the base
            said = f"forces sampled at {rates[c]:.4g} Hz"
        elif by_rate:
            said = f"{rates[c]:.4g} Hz against {fastest:.4g} Hz of {base!r}"
        else:
            said = (
                f"{rates[c]:.4g} Hz against {fastest:.4g} Hz of {base!r}: too slow to "
                "interpolate onto its time base"
            )
        problems.append(f"channel {c!r}: {said}; accepted at least {least:.6g} Hz, {why}")
    return problems


def _same_unit(quantity: str, a: str, b: str, channel: str) -> bool:
    """``a`` and ``b`` name one unit of ``quantity``: the same factor to SI (``kmh`` and
    ``km/h``, ``KN`` and ``kN``), or, where either is no unit of it, the same spelling."""
    try:
        return si_factor(quantity, a, channel) == si_factor(quantity, b, channel)
    except RailsuspInputError:
        return normalise_unit(a) == normalise_unit(b)


def channel_unit(
    ch: RawChannel, cmap: ChannelMap, problems: list[str], quantity: str
) -> str | None:
    """The channel's unit: the file's; the map's where the file states none; a map unit
    that contradicts the file's is a problem (another spelling of it is not)."""
    mapped = cmap.units.get(ch.name)
    if mapped and ch.unit and not _same_unit(quantity, mapped, ch.unit, ch.name):
        problems.append(
            f"channel {ch.name!r}: the file states unit {ch.unit!r}, the channel map {mapped!r}"
        )
    return ch.unit or mapped


def time_base(
    force_names: list[str],
    finite_hz: dict[str, float],
    stated: dict[str, float],
    samples: dict[str, int],
) -> str:
    """The force channel whose time base the run takes: the fastest by its finite samples'
    rate, then by its stated rate, rates compared to 6 digits (where float noise, 200.0000001
    against 199.9999999 Hz, chose among channels as fast); of those, the one with the
    most ``samples`` (the longest, or the one that lost none: another's lost sample is then
    refused as a dropout, not taken for the logger's), ties broken by the first name."""

    def rounded(hz: float) -> float:
        return float(f"{hz:.6g}")

    return min(
        force_names,
        key=lambda c: (-rounded(finite_hz[c]), -rounded(stated[c]), -samples[c], c),
    )


def beyond_base(ch: RawChannel, base: RawChannel) -> list[str]:
    """The problem of a force channel ``ch`` whose samples reach beyond the span of the
    run's time base (``base``, the fastest force channel) by more than a sample interval of
    either: the run is that span, and its other forces' samples beyond it were dropped
    without a word (a 180 s run whose fastest channel stopped at 60 s was cut to 60 s).
    Speed, position and track channels longer than the forces are taken as usual."""
    tol = max(1.0 / ch.rate_hz, 1.0 / base.rate_hz)
    t = base.time
    if ch.time[0] >= t[0] - tol and ch.time[-1] <= t[-1] + tol:
        return []
    return [
        f"channel {ch.name!r}: covers {ch.time[0]:.3f}-{ch.time[-1]:.3f} s, beyond the "
        f"{t[0]:.3f}-{t[-1]:.3f} s of {base.name!r} (the forces' time base, the fastest): "
        "cut the file to the span every force channel covers"
    ]


def check_spans(si: dict[str, RawChannel], base: str, quantity: dict[str, str]) -> list[str]:
    """Problems of channels (``quantity``: name -> its quantity, "force" or another) that
    do not cover the span of the run's time base (``base``'s) to within a sample interval
    of their own (and their jitter: :func:`~railsusp.measured.checks.jitter_of`), and of
    force channels reaching beyond it (:func:`beyond_base`)."""
    problems = []
    t = si[base].time
    for c, q in quantity.items():
        ch = si[c]
        tol = (1.0 + jitter_of(q)) / ch.rate_hz  # its last sample's time may jitter
        if ch.time[0] > t[0] + tol or ch.time[-1] < t[-1] - tol:
            problems.append(  # (what is accepted, and the remedy: it said neither)
                f"channel {c!r}: covers {ch.time[0]:.3f}-{ch.time[-1]:.3f} s, not the "
                f"{t[0]:.3f}-{t[-1]:.3f} s of the forces; accepted a channel covering their "
                f"span to within {tol:.3g} s at either end (its sampling interval and "
                "jitter): cut the file to the span every used channel covers"
            )
        elif q == "force":
            problems += beyond_base(ch, si[base])
    return problems
