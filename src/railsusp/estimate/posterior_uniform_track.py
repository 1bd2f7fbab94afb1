"""The rule that a posterior's records lie on uniform design track (docs/posterior.md).

The sections of a long recording must be drawn like the training section: a training section
that holds the entry to a curve, or a record that runs out of its arc, is not like the
steady curving of a long recording's later sections. Checked for the trained settings
(:class:`~railsusp.estimate.posterior_settings.PosteriorSettings`) and for each recording
read for an estimate (:mod:`railsusp.estimate.posterior_recordings`).
"""

from __future__ import annotations

from typing import Any

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError


def check_uniform_record(
    cond: WorkingCondition, record_s: float, wagon: Any = None, recording: bool = False
) -> None:
    """Refuse a condition whose design track (curvature, cant) changes under the wagon
    while it records ``record_s`` seconds: the sections of a long recording must be drawn
    like the training section, and a training section that holds the entry to a curve is
    not like the steady curving of the sections after it (measured: the curve's median
    Y/Q 0.281 in the first section against 0.303 in the next five, 2 standard deviations
    of its scatter over the prior; the fused posterior of 6 sections then held X13's truth
    in 12 % of the cases). ``wagon``: whose axle spread (None: the packaged C80).
    ``recording``: the condition is a recording's own (its ``lead_in_m`` may differ from
    the trained one) and ``record_s`` its sections' length: the same rule, said of it."""
    if cond.curve_radius_m is None:
        return
    from railsusp.vehicle.settle import design_is_uniform
    from railsusp.vehicle.setup import axle_spread
    from railsusp.vehicle.wagon import load_wagon

    spread = axle_spread(load_wagon(wagon))
    start = cond.lead_in_m - spread  # the trailing wheelset when the record starts
    entry = cond.curve_start_m + cond.entry_spiral_m
    who = f"recording {cond.name!r}: " if recording else ""
    if start < entry:
        unlike = (
            "unlike the steady curving the estimator was trained on"
            if recording
            else "unlike the steady curving of a long recording's later sections"
        )
        raise RailsuspInputError(
            f"{who}lead_in_m = {cond.lead_in_m:g} m (condition {cond.name!r}): the recorded "
            f"sections would hold the entry to the curve (until {entry:g} m, the wagon "
            f"{spread:.3g} m long), {unlike}; accepted at least {entry + spread:.4g} m"
        )
    if not design_is_uniform(cond, start, cond.lead_in_m + cond.speed * record_s):
        if recording:
            last = max(0.0, (entry + (cond.arc_length_m or 0.0) - cond.lead_in_m) / cond.speed)
            raise RailsuspInputError(
                f"{who}arc_length_m = {cond.arc_length_m:g} m (condition {cond.name!r}): the "
                f"curve ends within its {record_s:g} s of sections; accepted a recording "
                f"whose sections lie in the arc (at most {last:.4g} s from lead_in_m = "
                f"{cond.lead_in_m:g} m)"
            )
        raise RailsuspInputError(
            f"arc_length_m = {cond.arc_length_m:g} m (condition {cond.name!r}): the curve "
            f"ends within the {record_s:g} s of the longest checked record; accepted an arc "
            "that lasts it (or none: until the end)"
        )
