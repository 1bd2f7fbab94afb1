"""Wheel-rail contact geometry: rigid-profile contact tables and equivalent conicity.

The force laws (Hertz, Kalker, Shen-Hedrick-Elkins) are in :mod:`railsusp.vehicle.contact_forces`.

Conventions
-----------
Track frame: x forward (running direction), y to the LEFT, z UP. The left wheel and rail are
on the +y side. A wheelset shift ``y`` (m) is its lateral displacement relative to the track
centre line, positive to the left. The wheelset roll ``roll`` (rad) is a rotation about +x,
positive when the left wheel rises. The rise (m) is the vertical motion of the wheelset centre
relative to the centred position, positive up.

Per-wheel arrays have shape (n, 2): column ``LEFT`` (0) and ``RIGHT`` (1). The contact angle
``delta`` of either wheel is positive when the normal force of the rail on the wheel points
towards the track centre (tread sloping down towards the flange, flange contact), so that
in the track frame the normal force on the left wheel is N (-sin d_L, cos d_L) and on the
right wheel N (+sin d_R, cos d_R) in (y, z). Centred on new profiles d_L = d_R > 0. Wheel
and rail contact positions are given in their profile coordinates (see
:mod:`railsusp.vehicle.profiles`: from the taping line / rail centre line, + towards the
field side), and in the track frame (``contact_y``, ``contact_z``; rail crown at z = 0).

Curvatures (1/m) are positive for a convex surface: wheel rolling-direction curvature
cos(profile angle) / r, wheel lateral (profile) curvature (negative on a hollow tread), rail
lateral curvature (rail longitudinal curvature 0 on tangent track).

Creep forces are those of the rail on the wheel, in the contact plane: Fx longitudinal, Fy
lateral, Mz spin moment, with creepages xi_x, xi_y (-) and spin phi (1/m).
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from railsusp.vehicle.profiles import Profile

__all__ = [
    "LEFT",
    "RIGHT",
    "ContactTable",
    "contact_table",
    "equivalent_conicity",
    "equivalent_conicity_curve",
    "flange_split",
]

Array = np.ndarray | float

LEFT, RIGHT = 0, 1

_PER_WHEEL = (
    "rolling_radius",
    "contact_angle",
    "wheel_y",
    "rail_y",
    "contact_y",
    "contact_z",
    "wheel_curvature_long",
    "wheel_curvature_lat",
    "rail_curvature_lat",
)


@dataclass(frozen=True, eq=False)
class ContactTable:
    """Contact functions of a rigid wheelset (zero yaw) on a track, tabulated over shift ``y``.

    ``y`` (m) is uniform and increasing (index = (y - y[0]) / step for fast look-up).
    ``roll`` (rad), ``rise`` (m): wheelset roll and centre rise, shape (n,). Per-wheel arrays,
    shape (n, 2), columns LEFT/RIGHT: ``rolling_radius`` (m), ``contact_angle`` (rad),
    ``wheel_y`` / ``rail_y`` (m, contact point in wheel / rail profile coordinates),
    ``contact_y`` / ``contact_z`` (m, track frame), ``wheel_curvature_long``,
    ``wheel_curvature_lat``, ``rail_curvature_lat`` (1/m) and ``flange`` (bool: contact angle
    above ``meta['flange_angle']``). ``meta`` records the inputs (names, gauge, ...).

    Beyond the flangeway clearance the rigid wheelset can only go on by climbing the rail:
    there the table describes flange climb (the rise grows several mm per mm of shift, the
    contact runs over the flank onto the flange tip). A simulator should let the flange
    contact act through elastic penetration near the jump rather than follow that climb.
    """

    y: np.ndarray
    roll: np.ndarray
    rise: np.ndarray
    rolling_radius: np.ndarray
    contact_angle: np.ndarray
    wheel_y: np.ndarray
    rail_y: np.ndarray
    contact_y: np.ndarray
    contact_z: np.ndarray
    wheel_curvature_long: np.ndarray
    wheel_curvature_lat: np.ndarray
    rail_curvature_lat: np.ndarray
    flange: np.ndarray
    meta: dict[str, Any]

    @property
    def delta_r(self) -> np.ndarray:
        """Rolling radius difference r_L - r_R (m), shape (n,)."""
        return self.rolling_radius[:, LEFT] - self.rolling_radius[:, RIGHT]

    def flangeway_clearance(self) -> tuple[float, float]:
        """First shifts (m) with flange contact: (left wheel, y > 0; right wheel, y < 0).

        Resolved to the table step; NaN where the table range holds no flange contact.
        """
        left = self.y[(self.y > 0) & self.flange[:, LEFT]]
        right = self.y[(self.y < 0) & self.flange[:, RIGHT]]
        return (
            float(left.min()) if left.size else math.nan,
            float(right.max()) if right.size else math.nan,
        )

    def at(self, y: np.ndarray | float, *, clip: bool = False) -> ContactTable:
        """The table linearly interpolated at shifts ``y`` (m, 1-D or scalar).

        Across the flange jump the interpolation blends tread and flange values over one
        table step. Outside the table range a ValueError is raised, or with ``clip=True``
        the end values are held.
        """
        yq = np.atleast_1d(np.asarray(y, dtype=float)).ravel()
        if not clip and (yq.min() < self.y[0] - 1e-12 or yq.max() > self.y[-1] + 1e-12):
            raise ValueError(
                f"shift {yq.min() * 1e3:.3f}..{yq.max() * 1e3:.3f} mm outside the table range "
                f"{self.y[0] * 1e3:.3f}..{self.y[-1] * 1e3:.3f} mm"
            )
        cols = {"y": yq}
        for name in ("roll", "rise"):
            cols[name] = np.interp(yq, self.y, getattr(self, name))
        for name in _PER_WHEEL:
            arr = getattr(self, name)
            cols[name] = np.stack([np.interp(yq, self.y, arr[:, k]) for k in (0, 1)], axis=1)
        cols["flange"] = cols["contact_angle"] > self.meta["flange_angle"]
        return replace(self, **cols)

    def save(self, path: str | Path) -> Path:
        """Write the table to a ``.npz`` file (arrays plus JSON metadata)."""
        from railsusp.store import atomic_write_bytes

        path = Path(path)
        arrays = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "meta"}
        buf = io.BytesIO()
        np.savez(buf, meta=np.array(json.dumps(self.meta)), **arrays)
        return atomic_write_bytes(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> ContactTable:
        """Read a table written by :meth:`save`."""
        with np.load(Path(path), allow_pickle=False) as data:
            kw = {f.name: np.array(data[f.name]) for f in fields(cls) if f.name != "meta"}
            meta = json.loads(str(data["meta"]))
        return cls(meta=meta, **kw)

    def to_dataframe(self):
        """A pandas DataFrame, one row per shift; per-wheel columns end in _L / _R."""
        import pandas as pd

        cols: dict[str, np.ndarray] = {"y": self.y, "roll": self.roll, "rise": self.rise}
        for name in (*_PER_WHEEL, "flange"):
            arr = getattr(self, name)
            cols[f"{name}_L"] = arr[:, LEFT]
            cols[f"{name}_R"] = arr[:, RIGHT]
        return pd.DataFrame(cols)


# --------------------------------------------------------------------------------------------
# contact geometry by the rigid-profile (minimum vertical gap) method
# --------------------------------------------------------------------------------------------


class _Rail(NamedTuple):
    """One rail in the track frame, sampled with increasing track y."""

    y: np.ndarray  # track-frame lateral coordinate, m
    z: np.ndarray  # track-frame height, m (crown at 0)
    local_y: np.ndarray  # rail profile coordinate of each sample, m
    curvature: np.ndarray  # rail lateral curvature, 1/m (convex > 0)


def _place_rails(
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
    profile there (:func:`flange_split`, ``wheel_range``) into a tread and a flange table.

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
    model (:func:`flange_split`). Shifts at which no point of that part lies above the rail
    get NaN heights, positions and curvatures.
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
    left, right = _place_rails(rail, track_gauge, gauge_depth, rail_inclination, resolution)
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


def flange_split(table: ContactTable, min_jump: float = 0.005) -> float | None:
    """Wheel profile abscissa (m) that splits the tread from the flange for two-point contact.

    On the flange side of the left wheel (shifts y > 0) the rigid contact point runs up the
    tread and then jumps to the flange root or flank, skipping the stretch of profile between
    them: no point of that stretch is ever in contact alone. Its middle is the split, so a
    tread part and a flange part (``contact_table(..., wheel_range=...)``) each keep one
    contact point and both can touch at once (two-point contact). None when the largest jump
    is shorter than ``min_jump`` (m): a conformal profile with no distinct flange contact.
    """
    side = table.y > 0.0
    u = table.wheel_y[side, LEFT]
    if u.size < 2:
        return None
    jumps = u[:-1] - u[1:]  # the contact moves to -u (towards the flange) with growing y
    i = int(np.argmax(jumps))
    if not jumps[i] >= min_jump:
        return None
    return float(0.5 * (u[i] + u[i + 1]))


# --------------------------------------------------------------------------------------------
# equivalent conicity (EN 15302, harmonic linearisation)
# --------------------------------------------------------------------------------------------


def equivalent_conicity(
    table: ContactTable, amplitude: float | np.ndarray = 0.003, n_phase: int = 1440
) -> float | np.ndarray:
    """Equivalent conicity at lateral amplitude(s) ``amplitude`` (m), EN 15302 style.

    Harmonic linearisation of the rolling radius difference over a sinusoidal lateral
    motion y = A sin(theta): lambda_e(A) = c1 / (2 A), with c1 = (1/pi) * integral over one
    period of dr(A sin theta) sin(theta) d theta the first Fourier coefficient of
    dr = r_L - r_R. For a cone of slope tan(gamma) with dr = 2 tan(gamma) y this returns
    tan(gamma) exactly. A scalar amplitude gives a float, an array an array.
    """
    amp = np.asarray(amplitude, dtype=float)
    if np.any(amp <= 0.0):
        raise ValueError("conicity amplitude must be positive")
    if np.any(amp > min(-table.y[0], table.y[-1]) + 1e-12):
        raise ValueError(
            f"amplitude {amp.max() * 1e3:.2f} mm beyond the table range "
            f"{table.y[0] * 1e3:.2f}..{table.y[-1] * 1e3:.2f} mm"
        )
    theta = np.linspace(0.0, 2.0 * np.pi, n_phase, endpoint=False)
    s = np.sin(theta)
    dr = np.interp(amp[..., None] * s, table.y, table.delta_r)
    c1 = 2.0 * np.mean(dr * s, axis=-1)
    lam = c1 / (2.0 * amp)
    return float(lam) if lam.ndim == 0 else lam


def equivalent_conicity_curve(
    table: ContactTable, amplitudes: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(amplitudes, equivalent conicity) for amplitudes 1..10 mm unless given (m)."""
    amps = np.arange(1, 11) * 1e-3 if amplitudes is None else np.asarray(amplitudes, float)
    return amps, np.asarray(equivalent_conicity(table, amps))
