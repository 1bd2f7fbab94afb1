"""Registration of a recording's measured track geometry with its forces (cross-correlation).

The refinement compares series sample by sample, so the geometry must line up with the
forces; :func:`align_track` finds the distance offset that does it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from railsusp.estimate.comparison import check_time_base, measurement_filter
from railsusp.measured import Recording, simulated_forces
from railsusp.params import ParameterSet


@dataclass
class TrackAlignment:
    """Where a recording's measured track geometry lines up with its forces."""

    recording: str
    offset_m: float  # the track_offset_m that aligns them
    correlation: float  # normalised cross-correlation of simulated and measured forces there
    correlation_before: float  # ... at the recording's current offset
    shift_m: float  # offset_m minus the current offset
    #: the largest shift searched, m: ``max_shift_m``, or a third of the record if less
    searched_m: float = float("nan")
    #: the best lag is the search's first or last: the correlation may peak beyond it
    on_edge: bool = False
    #: why ``searched_m`` is less than the ``max_shift_m`` asked ("": it is not, or only by
    #: the rounding to whole samples, down, by at most :data:`ROUNDING_SAID` of it): at
    #: most a third of the record is searched, and never beyond the maximum asked
    limited_by: str = ""


#: the least correlation after alignment taken as a match (``align-track
#: --min-correlation``'s default): at a wrong lag the forces correlate by chance, -0.22 to
#: 0.10 on synthetic records, so that a search too narrow for the true offset found a
#: "peak" of 0.095 and stored it (the QA of stop 73; the true one, 8 m away, 0.984); with
#: 1 mm RMS track-measurement error and a degraded wagon the true peak was 0.80-0.85
#: (10 s records, three conditions)
MIN_ALIGNED_CORRELATION = 0.5

#: the share of ``max_shift_m`` that rounding it down to whole samples may lose without a
#: word: the default 10 m at 55 km/h and 50 Hz (steps of 0.306 m) searches ±9.78 m, which
#: every run warned of; up to 200 km/h at 50 Hz or more the default loses less than 10 %.
#: 0.5 m in steps of 0.333 m, searched ±0.333 m, is said (a third lost)
ROUNDING_SAID = 0.1


def align_track(
    rec: Recording,
    parameters: ParameterSet | None = None,
    max_shift_m: float = 10.0,
    wagon: Any = None,
) -> TrackAlignment:
    """Find the distance offset between a recording's forces and its measured track geometry
    by cross-correlation: the simulator runs once on the geometry (nominal parameters unless
    given), and the lag at which its filtered lateral and vertical forces best match the
    recording's (mean normalised correlation of both, parabolic sub-sample peak) gives the
    offset. All axles see the same geometry, so a misregistration of the geometry by d metres
    delays the forces by d / V. ``wagon``: the wagon data simulated (None: the packaged
    C80)."""
    if rec.condition.track_geometry is None:
        raise ValueError(f"recording {rec.condition.name!r} carries no measured track geometry")
    if not 0.0 < max_shift_m <= 200.0:
        raise ValueError(f"max_shift_m = {max_shift_m:g}: accepted (0, 200] m")
    # the simulation is compared with the table sample by sample: refused before it runs
    check_time_base([rec], "the alignment")
    sim = simulated_forces(parameters or ParameterSet.nominal(), rec, wagon)
    sim = measurement_filter(sim[None], rec)[0]
    meas = rec.forces()
    if sim.shape != meas.shape:
        raise ValueError(
            f"recording {rec.condition.name!r}: the simulation of its condition has "
            f"{sim.shape[0]} samples, its table {meas.shape[0]} rows; accepted "
            "condition.n_steps equal to the table's rows"
        )
    if not np.isfinite(sim).all():
        raise ValueError(
            f"recording {rec.condition.name!r}: the nominal simulation on its measured track "
            "stopped or gave non-finite forces (condition.track_geometry, track_offset_m): "
            "accepted geometry on which the wagon runs through"
        )
    step_m = rec.condition.speed / rec.sampling_rate
    # whole samples, rounded down: 0.5 m in steps of 0.333 m searched +-0.667 m (the QA of
    # stop 68), a shift beyond the maximum asked reported
    whole = int(np.floor(max_shift_m / step_m + 1e-9))
    if whole < 1:
        raise ValueError(
            f"max_shift_m = {max_shift_m:g}: less than one sample step of recording "
            f"{rec.condition.name!r} ({step_m:.3g} m at {rec.condition.speed_kmh:g} km/h and "
            f"{rec.sampling_rate:g} Hz); accepted at least {step_m:.3g} m"
        )
    max_lag = min(whole, len(meas) // 3)
    lags = np.arange(-max_lag, max_lag + 1)
    searched = max_lag * step_m
    limited_by = ""
    if max_lag < whole:
        limited_by = f"a third of the record ({len(meas) * step_m:.4g} m long): ±{searched:.3g} m"
    elif searched < (1.0 - ROUNDING_SAID) * max_shift_m - 1e-9:
        limited_by = (
            f"whole samples of {step_m:.3g} m, rounded down: ±{searched:.3g} m of the "
            f"±{max_shift_m:g} m asked"
        )

    def score(lag: int) -> float:
        a = meas[max(0, -lag) : len(meas) - max(0, lag)]
        b = sim[max(0, lag) : len(sim) - max(0, -lag)]
        a, b = a - a.mean(axis=0), b - b.mean(axis=0)
        den = np.sqrt((a * a).sum(axis=0) * (b * b).sum(axis=0))
        return float(np.mean((a * b).sum(axis=0) / np.where(den > 0, den, np.inf)))

    scores = np.array([score(int(lag)) for lag in lags])
    k = int(np.argmax(scores))
    frac = 0.0
    if 0 < k < len(lags) - 1:  # parabola through the peak and its neighbours
        c0, c1, c2 = scores[k - 1], scores[k], scores[k + 1]
        curvature = c0 - 2 * c1 + c2
        frac = 0.5 * (c0 - c2) / curvature if curvature < 0 else 0.0
    shift = -(lags[k] + frac) * step_m
    return TrackAlignment(
        rec.condition.name,
        float(rec.condition.track_offset_m + shift),
        float(scores[k]),
        float(scores[max_lag]),
        float(shift),
        searched_m=float(searched),
        on_edge=bool(max_lag > 0 and k in (0, len(lags) - 1)),
        limited_by=limited_by,
    )
