"""Whether a posterior's sections resolve the frequency bands of its statistics, and how
its settings mark statistics that changed when the band RMS came to follow the band edges
(:class:`~railsusp.estimate.posterior_settings.PosteriorSettings`, docs/posterior.md).

Two families read a spectrum in bands: the EN 14363 summary's four bands
(:func:`~railsusp.estimate.summaries.band_segment`) and the ``third-octave`` family's 18
(:func:`~railsusp.estimate.summaries.line_segment`). Each now lengthens its Welch
segment where a section is so short that a band would hold no line of the spectrum (and
read a constant floor), and a section too short for any segment to resolve them is
refused. The settings of sections whose statistics so changed carry
:data:`BAND_RESOLUTION` in :meth:`~PosteriorSettings.to_dict`, so that their hash differs
from that of the same settings trained before and an estimator folder of before is refused,
not mixed with the new statistics.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.estimate.statistic_families import THIRD_OCTAVE_HZ
from railsusp.estimate.summaries import (
    bands_widened,
    check_band_resolution,
    check_sections_resolve,
    half_segment,
    line_segment,
)

#: the key :meth:`PosteriorSettings.to_dict` adds where a section is so short that a band
#: RMS follows the band edges, and its values: the settings' hash then differs from that
#: of the same settings trained before. The EN 14363 summary's (its frequency step at most
#: its narrowest band: :func:`~railsusp.estimate.summaries.band_segment`) is the value of
#: the folders trained since it; the third-octave family's (a line in each of its bands:
#: :func:`~railsusp.estimate.summaries.line_segment`) makes another value
BAND_RESOLUTION = "band_resolution"
BAND_RESOLUTION_RULE = "frequency step at most the narrowest band"
THIRD_OCTAVE_RULE = "a line of the spectrum in every third-octave band"


def _rate(cond: WorkingCondition) -> float:
    return 1.0 / cond.sample_interval


def third_octave_widened(n: int, fs: float) -> bool:
    """Whether sections of ``n`` samples at ``fs`` take a longer segment for the
    ``third-octave`` family (:func:`~railsusp.estimate.summaries.line_segment`) than the
    half of the record they took before it followed the band edges: their third-octave
    statistics changed."""
    return line_segment(n, fs, THIRD_OCTAVE_HZ) not in (None, half_segment(n))


def band_resolution_mark(
    conditions: Iterable[WorkingCondition], families: tuple[str, ...]
) -> str | None:
    """The value of :data:`BAND_RESOLUTION` for settings of ``conditions`` (each at its
    section's duration) and statistics ``families``, or None where no band statistic of
    theirs changed: :data:`BAND_RESOLUTION_RULE` where the EN 14363 summary's segment is
    longer than it was, :data:`THIRD_OCTAVE_RULE` where the third-octave family's is, both
    joined by ``; `` where both are."""
    conditions = tuple(conditions)
    rules = []
    if any(bands_widened(c.n_steps, _rate(c)) for c in conditions):
        rules.append(BAND_RESOLUTION_RULE)
    if "third-octave" in families and any(
        third_octave_widened(c.n_steps, _rate(c)) for c in conditions
    ):
        rules.append(THIRD_OCTAVE_RULE)
    return "; ".join(rules) or None


def check_resolution(cond: WorkingCondition, section_s: float, families: tuple[str, ...]) -> None:
    """A one-line error unless sections of ``section_s`` of the condition ``cond`` resolve
    the bands of the EN 14363 summary (:func:`~railsusp.estimate.summaries.
    check_band_resolution`) and, with ``families`` holding it, of the ``third-octave``
    family (:func:`check_third_octave_resolution`)."""
    check_band_resolution(cond, section_s)
    if "third-octave" in families:
        check_third_octave_resolution(cond, section_s)


def check_third_octave_resolution(cond: WorkingCondition, section_s: float) -> None:
    """A one-line error naming ``section_s`` and the shortest section whose third-octave
    bands all hold a line of the spectrum (:func:`~railsusp.estimate.summaries.
    line_segment`) at the rate of the condition ``cond``, unless its sections of
    ``section_s`` do; at a rate at which a band lies wholly above 0.45 of it, naming the
    rate instead. A band without a line read the floor in every case (a constant the flows
    cannot learn from). At 50 Hz sections of 8.4 s or more resolve them."""

    check_sections_resolve(
        cond,
        section_s,
        lambda n, fs: line_segment(n, fs, THIRD_OCTAVE_HZ) is not None,
        THIRD_OCTAVE_HZ,
        "the statistics family 'third-octave' has bands from {top:.3g} Hz, above 0.45 times "
        "the rate",
        "the statistics family 'third-octave' holds a line of the spectrum in each of its "
        "bands ({width:.3g} Hz the narrowest) in sections",
        ", or statistics without 'third-octave'",
        step_bound=False,  # a line in each band: shorter sections than 1 / width may do
    )


def check_stored_mark(stored: Any, settings: Any) -> None:
    """A one-line error where settings an estimator folder stored (their
    :data:`BAND_RESOLUTION` value ``stored``; ``settings`` made from them) are of sections
    whose band statistics were computed before the band RMS followed the band edges: the
    folder's emulator or flows learnt from statistics this railsusp no longer computes (a
    synthetic likelihood of 2 s sections read the new statistics of a recording with
    them, and reported it calibrated)."""
    mark = band_resolution_mark(settings.conditions, settings.statistics)
    if mark is None or stored == mark:
        return
    summary_changed = BAND_RESOLUTION_RULE in mark and BAND_RESOLUTION_RULE not in str(stored)
    which, why = (
        ("band RMS", "its spectrum's frequency step wider than the narrowest band")
        if summary_changed
        else ("third-octave band RMS", "a third-octave band without a line of its spectrum")
    )
    raise RailsuspInputError(
        f"an estimator of {settings.section_s:g} s sections (section_s = "
        f"{settings.section_s:g}) trained before the {which} followed the band edges "
        f"({why}): its statistics are not this railsusp's; train it again (railsusp "
        "posterior train) into another folder"
    )


def mark_difference(old: dict[str, Any], new: dict[str, Any]) -> str | None:
    """What the :data:`BAND_RESOLUTION` values of stored settings ``old`` and of ``new``
    (both :meth:`PosteriorSettings.to_dict`) say where they differ, for the refusal of a
    run folder trained with other settings; None where they agree."""
    was, now = old.get(BAND_RESOLUTION), new.get(BAND_RESOLUTION)
    if was == now or now is None:
        return None
    if THIRD_OCTAVE_RULE in now and THIRD_OCTAVE_RULE not in str(was):
        return (
            "its third-octave band statistics are of before they followed the band edges: "
            "sections this long left a third-octave band without a line of the spectrum"
        )
    return (
        "its band statistics are of before they followed the band edges: the frequency "
        "step of sections this short was wider than the narrowest band"
    )
