"""Contact tables by the rigid-profile (minimum vertical gap) method: :func:`contact_table`.

For each lateral shift of a rigid wheelset (zero yaw) on two inclined rails the wheelset roll
and height are found at which each wheel touches its rail with zero penetration; a wheel's
contact point is where the vertical wheel-rail gap is smallest, i.e. where the two surfaces
are parallel. The steps: the rail profile placed in the track frame at its gauge (measured
``gauge_depth`` below the crown) and cant (:func:`rails_in_track_frame`), the smallest gap of
each wheel, the roll that makes both gaps equal (Illinois regula falsi), a parabolic
refinement of the minimum between wheel points.

This search is apart from :mod:`railsusp.vehicle.contact`, which holds the
:class:`~railsusp.vehicle.contact.ContactTable` it fills (look-up, files) and what is read off
a table (the tread/flange split for two-point contact, equivalent conicity EN 15302 style): the
search is the numerical part, and a table read back from its file needs none of it. Its
conventions (track frame, ``LEFT``/``RIGHT`` columns, the sign of the contact angle) are
those of :mod:`railsusp.vehicle.contact`, the profiles' those of
:mod:`railsusp.vehicle.profiles`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from railsusp.vehicle.contact import ContactTable
from railsusp.vehicle.profiles import Profile

__all__ = ["contact_table", "rails_in_track_frame"]


# --------------------------------------------------------------------------------------------
# contact geometry by the rigid-profile (minimum vertical gap) method
# --------------------------------------------------------------------------------------------


class _Rail(NamedTuple):
    """One rail in the track frame, sampled with increasing track y."""

    y: np.ndarray  # track-frame lateral coordinate, m
    z: np.ndarray  # track-frame height, m (crown at 0)
    local_y: np.ndarray  # rail profile coordinate of each sample, m
    curvature: np.ndarray  # rail lateral curvature, 1/m (convex > 0)


def rails_in_track_frame(
    rail: Profile, gauge: float, gauge_depth: float, inclination: float, resolution: float
) -> tuple[_Rail, _Rail]:
    yl = np.arange(rail.y[0], rail.y[-1], resolution)
    zl, _, kappa = rail.evaluate(yl)
    g = math.atan(inclination)
    yi = yl * math.cos(g) + zl * math.sin(g)  # inclined (rail head leaning inwards, to -y)
    zi = -yl * math.sin(g) + zl * math.cos(g)
    if np.any(np.diff(yi) <= 0.0):
        raise ValueError(f"rail {rail.name!r}: the inclined side face overhangs")
    top = int(np.argmin(zi))
    z_top = zi[top]
    # gauge point: on the gauge side (-y of the crown), gauge_depth below the crown
    gauge_side_z = zi[: top + 1][::-1]
    if gauge_side_z[-1] < z_top + gauge_depth:
        raise ValueError(f"rail {rail.name!r} does not reach {gauge_depth * 1e3:.1f} mm depth")
    y_gauge = float(np.interp(z_top + gauge_depth, gauge_side_z, yi[: top + 1][::-1]))
    ty = 0.5 * gauge + (yi - y_gauge)
    tz = -(zi - z_top)
    left = _Rail(ty, tz, yl, kappa)
    right = _Rail(-ty[::-1], tz[::-1], yl[::-1], kappa[::-1])
    return left, right


def _min_gap(
    rail: _Rail, yw: np.ndarray, phi: np.ndarray, wy: np.ndarray, wz: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lowest vertical wheel-rail gap per row, with the wheelset centre at height 0.

    ``wy``, ``wz``: wheel points in the wheelset frame (m). Returns (gap, argmin, gaps).
    """
    c = np.cos(phi)[:, None]
    s = np.sin(phi)[:, None]
    ty = yw[:, None] + wy[None, :] * c - wz[None, :] * s
    tz = wy[None, :] * s + wz[None, :] * c
    gaps = tz - np.interp(ty, rail.y, rail.z)
    gaps[(ty < rail.y[0]) | (ty > rail.y[-1])] = np.inf
    j = np.argmin(gaps, axis=1)
    return gaps[np.arange(gaps.shape[0]), j], j, gaps


def _solve_roll(
    left: _Rail,
    right: _Rail,
    yw: np.ndarray,
    wheel_pts: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    with_roll: bool,
    tol: float = 1e-11,
    phi_max: float = 0.05,
) -> np.ndarray:
    """Roll angle making both minimum gaps equal (Illinois regula falsi, vectorised)."""
    wy_l, wz_l, wy_r, wz_r = wheel_pts
    if not with_roll:
        return np.zeros_like(yw)

    def f(phi: np.ndarray) -> np.ndarray:
        return _min_gap(left, yw, phi, wy_l, wz_l)[0] - _min_gap(right, yw, phi, wy_r, wz_r)[0]

    a = np.full_like(yw, -phi_max)
    b = np.full_like(yw, phi_max)
    fa, fb = f(a), f(b)
    if not (np.all(fa < 0.0) and np.all(fb > 0.0)):
        raise ValueError("no roll angle within +-0.05 rad lets both wheels touch their rails")
    side = np.zeros(yw.shape, dtype=int)
    c = a.copy()
    for _ in range(100):
        c = (a * fb - b * fa) / (fb - fa)
        fc = f(c)
        if np.all(np.abs(fc) < tol):
            break
        upper = fc > 0.0
        b = np.where(upper, c, b)
        fb = np.where(upper, fc, fb)
        fa = np.where(upper & (side == 1), 0.5 * fa, fa)
        a = np.where(~upper, c, a)
        fa = np.where(~upper, fc, fa)
        fb = np.where(~upper & (side == -1), 0.5 * fb, fb)
        side = np.where(upper, 1, -1)
    else:
        raise RuntimeError("wheelset roll iteration did not converge")
    return c


def contact_table(
    wheel: Profile,
    rail: Profile,
    *,
    track_gauge: float = 1.435,
    gauge_depth: float = 0.016,
    back_to_back: float = 1.353,
    back_face_offset: float = 0.070,
    rail_inclination: float = 1.0 / 40.0,
    nominal_radius: float = 0.42,
    y_min: float = -0.020,
    y_max: float = 0.020,
    step: float = 1e-4,
    resolution: float = 2e-5,
    flange_angle_deg: float = 45.0,
    wheelset_roll: bool = True,
    wheel_range: tuple[float, float] | None = None,
) -> ContactTable:
    """Contact functions of a rigid wheelset (zero yaw) on two inclined rails, by shift y.

    Rigid-profile method: for each lateral shift the wheelset roll and height are found such
    that each wheel touches its rail with zero penetration; the contact point of a wheel is
    where the vertical wheel-rail gap is smallest (where the surfaces are parallel). When
    the gap at the flange closes the minimum moves abruptly from the tread to the flange
    root / flank: a single contact point with a jump. Two-point contact splits the wheel
    profile there (:func:`~railsusp.vehicle.contact.flange_split`, ``wheel_range``) into a
    tread and a flange table.

    Inputs: ``wheel`` and ``rail`` profiles (profile conventions; the rail in its own, not
    inclined, axes); ``track_gauge`` (m) measured ``gauge_depth`` (m) below the crown;
    ``back_to_back`` (m) between flange back faces, the taping line lying
    ``back_face_offset`` (m) outside the back face (profile origin); ``rail_inclination``
    (tan of the cant); ``nominal_radius`` r0 (m) at the taping line; shifts from ``y_min``
    to ``y_max`` every ``step`` (m); wheel points every ``resolution`` (m).
    ``wheelset_roll=False`` keeps roll at zero and lets each wheel find its height
    independently (decoupled wheels, for checks of the conicity definition only).
    ``wheel_range`` (m, profile coordinates, with ``wheelset_roll=False`` only) keeps only
    the wheel points in that interval: the tread or the flange part of a two-point contact
    model (:func:`~railsusp.vehicle.contact.flange_split`). Shifts at which no point of that
    part lies above the rail get NaN heights, positions and curvatures.
    """
    if not (y_min < y_max and step > 0.0 and resolution > 0.0):
        raise ValueError("need y_min < y_max, step > 0 and resolution > 0")
    if wheel.kind != "wheel" or rail.kind != "rail":
        raise ValueError(
            f"contact_table(wheel, rail) got a {wheel.kind!r} and a {rail.kind!r} profile "
            "(read rail files with read_profile(path, kind='rail'))"
        )
    n = round((y_max - y_min) / step) + 1
    yw = y_min + step * np.arange(n)
    left, right = rails_in_track_frame(rail, track_gauge, gauge_depth, rail_inclination, resolution)
    u = np.arange(wheel.y[0], wheel.y[-1], resolution)
    if wheel_range is not None:
        if wheelset_roll:
            raise ValueError("wheel_range needs wheelset_roll=False (decoupled wheels)")
        u = u[(u >= wheel_range[0]) & (u <= wheel_range[1])]
        if u.size < 3:
            raise ValueError(
                f"wheel_range {wheel_range[0] * 1e3:.1f}..{wheel_range[1] * 1e3:.1f} mm holds "
                f"fewer than three points of wheel profile {wheel.name!r}"
            )
    zp, dzp, kp = wheel.evaluate(u)
    radius = nominal_radius + zp
    wz = -radius
    offset = 0.5 * back_to_back + back_face_offset
    pts = (offset + u, wz, -(offset + u), wz)

    # solve in chunks of shifts (memory: chunk x wheel points), the centred shift appended
    ys = np.append(yw, 0.0)
    phi = np.empty_like(ys)
    heights = np.empty((ys.size, 2))  # wheelset centre height that makes each wheel touch
    idx = np.empty((ys.size, 2), dtype=int)
    frac = np.empty((ys.size, 2))
    chunk = max(1, 2_000_000 // u.size)
    for lo in range(0, ys.size, chunk):
        sl = slice(lo, min(lo + chunk, ys.size))
        p = _solve_roll(left, right, ys[sl], pts, wheelset_roll)
        phi[sl] = p
        for k, rl in enumerate((left, right)):
            g, j, gaps = _min_gap(rl, ys[sl], p, pts[2 * k], pts[2 * k + 1])
            heights[sl, k] = np.where(np.isfinite(g), -g, np.nan)  # NaN: nothing above the rail
            # parabolic refinement of the minimum between neighbouring wheel points
            jm = np.clip(j, 1, u.size - 2)
            rows = np.arange(jm.size)
            g0, g1, g2 = gaps[rows, jm - 1], gaps[rows, jm], gaps[rows, jm + 1]
            with np.errstate(invalid="ignore"):  # inf gaps: points with no rail below
                den = g0 - 2.0 * g1 + g2
                ok = np.isfinite(den) & (den > 0.0) & (jm == j)
                t = np.where(ok, 0.5 * (g0 - g2) / np.where(ok, den, 1.0), 0.0)
            idx[sl, k] = j
            frac[sl, k] = np.clip(t, -0.5, 0.5)

    uc = u[idx] + frac * resolution  # contact abscissa on each wheel profile, (n+1, 2)
    r = np.interp(uc, u, radius)
    slope = np.interp(uc, u, dzp)
    kw = np.interp(uc, u, kp)
    prof_angle = np.arctan(-slope)  # tread angle, + when rising towards the field side
    sign = np.array([1.0, -1.0])
    delta = prof_angle + sign * phi[:, None]
    wy = sign * (offset + uc)
    cy = ys[:, None] + wy * np.cos(phi)[:, None] + r * np.sin(phi)[:, None]
    height = heights.mean(axis=1)  # equal with roll; decoupled wheels: their mean
    cz = heights + wy * np.sin(phi)[:, None] - r * np.cos(phi)[:, None]
    rail_y = np.empty_like(cy)
    rail_k = np.empty_like(cy)
    for k, rl in enumerate((left, right)):
        rail_y[:, k] = np.interp(cy[:, k], rl.y, rl.local_y)
        rail_k[:, k] = np.interp(cy[:, k], rl.y, rl.curvature)
    free = np.isnan(heights)
    for arr in (uc, r, delta, cy, rail_y, rail_k, kw):
        arr[free] = np.nan

    flange_angle = math.radians(flange_angle_deg)
    main = slice(0, n)
    meta = {
        "wheel": wheel.name,
        "rail": rail.name,
        "track_gauge": track_gauge,
        "gauge_depth": gauge_depth,
        "back_to_back": back_to_back,
        "back_face_offset": back_face_offset,
        "rail_inclination": rail_inclination,
        "nominal_radius": nominal_radius,
        "step": step,
        "resolution": resolution,
        "flange_angle": flange_angle,
        "wheelset_roll": wheelset_roll,
        "wheel_range": None if wheel_range is None else [float(v) for v in wheel_range],
    }
    return ContactTable(
        y=yw,
        roll=phi[main],
        rise=height[main] - height[-1],
        rolling_radius=r[main],
        contact_angle=delta[main],
        wheel_y=uc[main],
        rail_y=rail_y[main],
        contact_y=cy[main],
        contact_z=cz[main],
        wheel_curvature_long=(np.cos(prof_angle) / r)[main],
        wheel_curvature_lat=-kw[main],
        rail_curvature_lat=rail_k[main],
        flange=delta[main] > flange_angle,
        meta=meta,
    )
