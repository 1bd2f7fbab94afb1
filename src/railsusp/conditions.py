"""Working conditions: the study's three (its Table 6) by name, the groups of fields that
choose the track input, and the lowest sampling rate of a recording.

The condition model (:class:`WorkingCondition`: speed, track layout, irregularity class,
validated on construction, with SI views) and its strict construction with one-line errors
(:func:`make_condition`, :func:`field_range`) are :mod:`railsusp.working_condition`; the names
of it that other modules use are re-exported here, where most of them import them.

The study's three conditions (its Table 6), all at 60 km/h:

* ``straight``: tangent track, FRA Class 5 irregularities.
* ``curve``: R = 300 m. The study gives no cant or spirals. A heavy-haul line carrying loaded
  and empty trains sets cant for the mean running speed rather than the maximum: with about
  53 km/h, h = 11.8 V^2 / R = 110 mm (Chinese practice, V in km/h), i.e. 32 mm cant deficiency
  at 60 km/h (balance cant 141.6 mm). Entry and exit spirals of 60 m (cant run-off 1.8 per
  mille, within the 1:500 limit). The entry spiral lies in the lead-in, so the 20 s
  recording is in the full circular arc, as the measured curve forces of the study are (a
  settled start, ``SolverSettings.start``, begins in the arc a short run-in before it).
* ``uphill``: the study writes slope "0.1". Read as a ratio (10 % = 100 per mille) it is
  beyond adhesion for any heavy-haul train, and as 0.1 per mille it is flat, so neither is a
  "long and steep" grade. We take 12 per mille, the ruling grade of China's heavy-haul coal
  lines (Daqin, Shuohuang), as the default; ``grade_permille`` changes it. The coupler force
  defaults to 650 kN tension: the grade and running resistance of about 5000 t of trailing
  load (mid-train position of a 10 000 t train, 12 per mille + 1.3 N/kN resistance).

The recording duration defaults to 20 s sampled to 1000 output steps, the study's series
length (50 Hz output).
"""

from __future__ import annotations

from typing import Any

from railsusp.errors import ConditionError

# the condition model and its checks: railsusp.working_condition; re-exported here, where
# most modules import them
from railsusp.working_condition import CANT_BASE_M as CANT_BASE_M
from railsusp.working_condition import GRAVITY as GRAVITY
from railsusp.working_condition import WorkingCondition as WorkingCondition
from railsusp.working_condition import field_range as field_range
from railsusp.working_condition import make_condition as make_condition

#: The lowest sampling rate at which the pipeline reads a recording (Hz): its statistics and
#: time-aligned comparisons need the forces to 25 Hz (read_field's ``min_rate_hz``; a
#: long run's sections, ``[field] rate_hz``; a synthetic recording's n_steps / duration_s).
RECORDING_MIN_RATE_HZ = 50.0


#: fields that choose the track input rather than the vehicle's operation: a surrogate that
#: reads the track, or one trained on synthesised track (the average over realisations),
#: serves a condition that differs only in these
TRACK_INPUT_FIELDS: tuple[str, ...] = (
    "seed",
    "track_geometry",
    "track_offset_m",
    "track_accuracy_mm",
)
#: the track input and the record's length: what a recording may differ in from the
#: condition its surrogate was trained on (the sampling interval is checked apart: the
#: network's steps are the training's)
TRACK_AND_LENGTH_FIELDS: tuple[str, ...] = (*TRACK_INPUT_FIELDS, "duration_s", "n_steps")


#: The study's Table 6 conditions, with the documented choices above.
STANDARD_CONDITIONS: dict[str, WorkingCondition] = {
    "straight": WorkingCondition(name="straight", seed=1),
    "curve": WorkingCondition(
        name="curve",
        curve_radius_m=300.0,
        cant_mm=110.0,
        curve_start_m=20.0,
        entry_spiral_m=60.0,
        exit_spiral_m=60.0,
        arc_length_m=None,
        seed=2,
    ),
    "uphill": WorkingCondition(name="uphill", grade_permille=12.0, coupler_force_kN=650.0, seed=3),
}


def get_condition(name: str, /, **overrides: Any) -> WorkingCondition:
    """A standard condition by name, optionally with fields changed, validated strictly
    (:func:`make_condition`); ``name=`` among the changes renames it
    (``get_condition("straight", speed_kmh=80, name="straight80")``)."""
    if not isinstance(name, str):
        raise ConditionError(
            f"condition {name!r} is not a name; accepted: {', '.join(STANDARD_CONDITIONS)}"
        )
    key = name.strip().lower()
    if key not in STANDARD_CONDITIONS:
        raise ConditionError(
            f"unknown condition {name!r}; accepted: {', '.join(STANDARD_CONDITIONS)}"
        )
    cond = STANDARD_CONDITIONS[key]
    return cond.with_changes(**overrides) if overrides else cond
