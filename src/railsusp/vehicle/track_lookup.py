"""Compiled look-up of the track arrays at a body's distance along the track.

The simulator's track arrays (:func:`railsusp.vehicle.track_grid.track_arrays`) hold, per channel
(layout ``TR_*``: curvature, cant, heading, lateral position, rail irregularities), samples
on a uniform grid s0 + i ds. A body reads several channels at one distance, so the grid cell
is found once (:func:`track_point`) and every channel interpolated in it. Outside the grid
the first or last sample holds and rates are zero.
"""

from __future__ import annotations

import numba as nb

from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def track_point(s, s0, inv_ds, n):
    """Grid cell of distance s on n samples from s0 by ds: (index i, fraction f, inside).

    ``inv_ds`` is 1 / ds (a multiplication, not a division, per body; issue 24). Before the
    grid (i, f) = (0, 0) and after it (n - 2, 1), so that :func:`track_value` returns the end
    sample; ``inside`` is False there (rates are zero)."""
    u = (s - s0) * inv_ds
    if u <= 0.0:
        return 0, 0.0, False
    if u >= n - 1:
        return n - 2, 1.0, False
    i = int(u)
    return i, u - i, True


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def track_value(trk, ch, i, f):
    """Channel ``ch`` linearly interpolated in grid cell (i, f)."""
    return trk[ch, i] * (1.0 - f) + trk[ch, i + 1] * f


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def track_rate(trk, ch, i, inside, v_per_ds):
    """Time rate V d(channel)/ds of channel ``ch`` in grid cell i (per second);
    ``v_per_ds`` is V / ds, the grid cells passed per second."""
    if not inside:
        return 0.0
    return v_per_ds * (trk[ch, i + 1] - trk[ch, i])


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def track_frame(trk, i, f):
    """Curvature (1/m), cant angle (rad), heading (rad) and lateral position (m) of the
    design track in grid cell (i, f): the frame a body there moves in."""
    return (
        track_value(trk, L.TR_KAPPA, i, f),
        track_value(trk, L.TR_CANT, i, f),
        track_value(trk, L.TR_HEAD, i, f),
        track_value(trk, L.TR_OFFSET, i, f),
    )


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def frame_turn(trk, i, f, inside, n, V, v_per_ds, half):
    """The track-following frame's yaw and roll accelerations at grid cell (i, f), rad/s²
    (revision 2026-12-03.1; docs/model.md, "Transitions"): yaw V² dκ/ds, the curvature's
    slope in the cell (a clothoid's 1 / (R L)), and roll V² d²φ/ds² of the cant angle φ, its
    second difference at the nearest sample. The cant is linear between samples, so its
    rate V dφ/ds steps at a sample where the slope changes (a cant ramp's ends); the step's
    impulse is spread over ``half`` cells (at least 0.5) either side of that sample: the
    roll acceleration is V² times the slope's change across the window [u - half,
    u + half] over its width (the derivative of the slope's moving average), so that a body
    passing it gains the frame's roll rate change in full, and an RK4 step no longer than
    the window's passage integrates it (half = 0.5: the cant's second difference at the
    nearest sample). The yaw is spread over the same window where it is wider than a cell
    (a curvature step's impulse). Zero outside the grid and where the window leaves it."""
    if not inside:
        return 0.0, 0.0
    yaw = V * v_per_ds * (trk[L.TR_KAPPA, i + 1] - trk[L.TR_KAPPA, i])
    u = i + f
    lo = u - half
    hi = u + half
    if lo < 0.0 or hi >= n - 1:
        return yaw, 0.0
    il = int(lo)
    ih = int(hi)
    if half > 0.5:
        # a step of the curvature (a curve entered or left without spiral) is an impulse
        # of the yaw rate within one cell: spread over the same window as the roll's (the
        # slope of the curvature's moving average), so that an RK4 step longer than the
        # cell's passage takes it once (0 to 1.48 times on a 5 mm grid at 40 km/h)
        k = L.TR_KAPPA
        k_lo = trk[k, il] + (lo - il) * (trk[k, il + 1] - trk[k, il])
        k_hi = trk[k, ih] + (hi - ih) * (trk[k, ih + 1] - trk[k, ih])
        yaw = V * v_per_ds * (k_hi - k_lo) / (2.0 * half)
    c = L.TR_CANT
    d = (trk[c, ih + 1] - trk[c, ih]) - (trk[c, il + 1] - trk[c, il])
    return yaw, v_per_ds * v_per_ds * d / (2.0 * half)
