"""The track-following frame's share of the right-hand side: pseudo-forces and cant angle.

Every body moves in the track-following frame at its own position along the track; the
frame's curvature and cant put pseudo-forces on it (docs/model.md, "Track-following
frames"). Compiled helpers inlined into :func:`railsusp.vehicle.model.rhs` and its pieces
(:mod:`railsusp.vehicle.spring_nests`).
"""

from __future__ import annotations

import math

import numba as nb

from railsusp.vehicle.kernel_cache import FASTMATH  # (sets the kernel cache before any compiles)


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def add_frame_forces(acc, i_lat, i_vert, m, kappa, c, s, V, gn):
    """Add the moving frame's pseudo-forces on a body of mass m (N): lateral
    -m (V² κ cos φ + g sin φ); vertical -m (g cos φ - V² κ sin φ) as a deviation from the
    static weight m g already carried by the preloads. c, s: cosine and sine of the cant
    angle φ (each evaluated once per track position, for all bodies there)."""
    acc[i_lat] += -m * (V * V * kappa * c + gn * s)
    acc[i_vert] += -m * (gn * c - V * V * kappa * s) + m * gn


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def cant_cos_sin(cant, cant_near, cos_near, sin_near):
    """Cosine and sine of the cant angle, bit for bit those of ``math.cos`` and ``math.sin``:
    1 and the angle itself (+-0) where there is no cant (tangent track), those of a body
    nearby (``cos_near``, ``sin_near`` of ``cant_near``) where its cant is the same number
    (the body of a curve), else the C library's. Of the fourteen calls per evaluation, none
    is left on tangent and two in a curve's body (issue 24)."""
    if cant == 0.0:
        return 1.0, cant
    if cant == cant_near:  # (nonzero: equal numbers are the same bits)
        return cos_near, sin_near
    return math.cos(cant), math.sin(cant)
