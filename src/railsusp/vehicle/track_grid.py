"""The track the kernels run on: the design geometry and the rail irregularities of a
working condition as channels on a uniform grid (:func:`track_arrays`), the
irregularities faded in from rest (:func:`fade_in_length`) on a grid fine enough for the
shortest synthesised wavelength (:func:`track_step`).

The synthetic field recordings export exactly these irregularities as their measured track
(:func:`section_irregularities`), so that a recording's geometry is the simulator's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.vehicle import layout as L
from railsusp.vehicle.setup import SolverSettings, axle_spread
from railsusp.vehicle.track import Irregularities, TrackLayout, smoothstep
from railsusp.vehicle.track_geometry import irregularities_for
from railsusp.vehicle.wagon import WagonData


def section_irregularities(
    condition: WorkingCondition, seeds: Sequence[int], wagon: WagonData
) -> Irregularities | None:
    """The rail irregularities the simulator runs on (section coordinates), per seed; the
    synthetic field recordings export exactly these as measured track geometry."""
    spread = axle_spread(wagon)
    return irregularities_for(condition, list(seeds), behind=spread + 25.0, axle_spread_m=spread)


#: the irregularities' fade-in from the section start, m: at most this long, at least
#: :data:`MIN_FADE_IN_M`
FADE_IN_M = 30.0
MIN_FADE_IN_M = 5.0


def fade_in_length(lead_in_m: float, spread_m: float) -> float:
    """Length (m) over which the irregularities fade in from the section start: 30 m, or
    the lead-in less the axle spread where that is shorter, so that the fade ends before
    the record's track reaches the trailing wheelset (the fixed 30 m took a measured 10 mm
    kink 5 m into a record without lead-in down to 2.8 mm, and a 3 mm cross-level bump
    under a 20 m lead-in to 2.8 mm: the physics audit of stop 59); never under
    :data:`MIN_FADE_IN_M` (a measured track needs that lead-in,
    :func:`~railsusp.vehicle.track_geometry.check_coverage`)."""
    return min(FADE_IN_M, max(MIN_FADE_IN_M, lead_in_m - spread_m))


def track_step(condition: WorkingCondition, settings: SolverSettings) -> float:
    """The track grid's spacing (m): the solver's ``track_step``, or an eighth of the
    shortest synthesised wavelength where that is finer, the spacing the irregularities
    are synthesised at. A coarser grid would fold the wavelengths below two steps onto
    longer ones (Class 5 with 0.2 m wavelengths on the 0.125 m grid: +39 % of power at
    0.25-0.33 m; audit of stop 62) and its linear interpolation would thin them (sinc², 19 %
    at four steps a wavelength). At the default shortest wavelength of 1 m both are 0.125 m."""
    ds = settings.track_step
    if condition.irregularity_class is not None and condition.track_geometry is None:
        ds = min(ds, condition.wavelength_min_m / 8.0)
    return ds


def track_arrays(
    condition: WorkingCondition,
    seeds: Sequence[int],
    wagon: WagonData,
    settings: SolverSettings,
    *,
    uniform_before: float | None = None,
    fade_in: tuple[float, float] | None = None,
) -> tuple[np.ndarray, float, float]:
    """Track channels (layout.TR_*) on a uniform grid for each seed: (n_seeds, N_TR, n_s).

    Geometry (curvature, cant angle, heading θ = ∫κ ds, lateral position Y = ∫θ ds) is
    shared; irregularities ramp in smoothly from s = 0 (zero behind it), so that the run
    starts from static equilibrium, over :func:`fade_in_length` (30 m, shorter where the
    lead-in is: the ramp ends before the record's track reaches the trailing wheelset).

    For a settled start (:mod:`railsusp.vehicle.settle`): ``uniform_before`` (m) continues
    the curvature and cant of that point backwards, so that the design track behind it is
    the uniform track the wagon settles on; ``fade_in`` = (from, to) (m) also fades the
    irregularities in between those points (zero before). Ahead of both, the channels are
    those of the plain call (heading and lateral position up to a rigid motion of the
    track, which the equations do not see).
    """
    behind = axle_spread(wagon) + 20.0
    ds = track_step(condition, settings)
    s = np.arange(-behind, condition.section_length_m + 20.0 + ds, ds)
    lay = TrackLayout.from_condition(condition)
    at = s if uniform_before is None else np.maximum(s, uniform_before)
    kappa = lay.curvature_at(at)
    head = np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * ds)])
    offset = np.concatenate([[0.0], np.cumsum(0.5 * (head[1:] + head[:-1]) * ds)])
    out = np.zeros((len(seeds), L.N_TR, s.size))
    out[:, L.TR_KAPPA] = kappa
    out[:, L.TR_CANT] = lay.cant_angle_at(at)
    out[:, L.TR_HEAD] = head
    out[:, L.TR_OFFSET] = offset
    irr = section_irregularities(condition, seeds, wagon)
    if irr is not None:
        rails = irr.at(s)  # (n_seeds, n_s); one measured track broadcasts over the seeds
        # zero under every wheel at the start, whole under every wheel of the record
        window = smoothstep(s / fade_in_length(condition.lead_in_m, axle_spread(wagon)))
        if fade_in is not None:
            window = window * smoothstep((s - fade_in[0]) / (fade_in[1] - fade_in[0]))
        out[:, L.TR_ZL] = rails["zL"] * window
        out[:, L.TR_ZR] = rails["zR"] * window
        out[:, L.TR_YL] = rails["yL"] * window
        out[:, L.TR_YR] = rails["yR"] * window
    return np.ascontiguousarray(out), float(s[0]), ds
