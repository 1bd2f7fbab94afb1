"""Wheel and rail profile shapes built from their dimensions: the LM-like worn tread, the
CHN60 rail head, the rail cant, and the analytic check profiles (a pure cone, a round head).

Each shape is a chain of tangent circular arcs and straight segments, solved for the tangent
points that meet the profile's dimensions (flange thickness at its measuring height, head
width), and sampled into a :class:`railsusp.vehicle.profiles.Profile` in the profile
conventions of :mod:`railsusp.vehicle.profiles`. The shapes are apart from that module
because building a profile from its design dimensions is a job of its own: the Profile type,
its spline and the profile files need none of it, and a measured profile read from a file
never passes through here.

The LM profile of TB/T 449 is not reproduced here (its coordinates are not openly available):
:func:`lm_worn_wheel` is an *LM-like* tread made of tangent circular arcs and straight
segments with the LM's characteristic dimensions (flange thickness measured EN 15313 style).
:func:`chn60_rail` builds the CHN60 (GB/T 2585, 60 kg/m) head from its R300/R80/R13 arcs and
1:20 side faces; the R300/R80 breakpoint (10 mm from the centre line) is an assumption close
to the UIC60 value (10.2 mm). :func:`conical_wheel` is the EN 15302 check case of equivalent
conicity.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.vehicle.profiles import Profile

__all__ = ["chn60_rail", "conical_wheel", "incline", "lm_worn_wheel", "round_rail"]


# --------------------------------------------------------------------------------------------
# tangent arc / straight chains
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Piece:
    """One segment of a chain on y0 <= y <= y1: a straight line or a circular arc."""

    y0: float
    y1: float
    z0: float
    slope: float = 0.0  # straight: z = z0 + slope (y - y0)
    yc: float = math.nan  # arc: z = zc - sense sqrt(R^2 - (y - yc)^2)
    zc: float = math.nan
    radius: float = math.inf
    sense: float = 0.0  # +1: z'' > 0, -1: z'' < 0
    theta0: float = 0.0  # tangent angles atan(dz/dy) at both ends
    theta1: float = 0.0

    def abscissae(self, step: float) -> np.ndarray:
        """Abscissae spaced ``step`` apart along the piece (start included, end excluded)."""
        if self.sense == 0.0:
            length = (self.y1 - self.y0) / math.cos(self.theta0)
            n = max(1, math.ceil(length / step))
            return self.y0 + (self.y1 - self.y0) * np.arange(n) / n
        n = max(1, math.ceil(self.radius * abs(self.theta1 - self.theta0) / step))
        theta = self.theta0 + (self.theta1 - self.theta0) * np.arange(n) / n
        k = self.sense / self.radius
        return self.y0 + (np.sin(theta) - math.sin(self.theta0)) / k


class _Chain:
    """Turtle that lays tangent arcs and lines with y increasing; angle theta = atan(dz/dy)."""

    def __init__(self, y: float = 0.0, z: float = 0.0, theta: float = 0.0) -> None:
        self.y, self.z, self.theta = y, z, theta
        self.pieces: list[_Piece] = []

    def arc(self, radius: float, theta_end: float) -> _Chain:
        """Circular arc of ``radius`` turning the tangent from the current angle to theta_end."""
        k = math.copysign(1.0 / radius, theta_end - self.theta)
        return self._arc(k, theta_end)

    def arc_to(self, radius: float, sense: float, y_end: float) -> _Chain:
        """Arc of ``radius`` bending with ``sense`` (+1: z'' > 0) up to abscissa y_end."""
        k = sense / radius
        s = math.sin(self.theta) + k * (y_end - self.y)
        if abs(s) >= 1.0:
            raise RailsuspInputError("arc cannot reach the requested abscissa")
        return self._arc(k, math.asin(s))

    def _arc(self, k: float, theta_end: float) -> _Chain:
        if abs(theta_end) >= math.pi / 2 or abs(self.theta) >= math.pi / 2:
            raise RailsuspInputError("arc leaves the range where z is a function of y")
        yc = self.y - math.sin(self.theta) / k
        zc = self.z + math.cos(self.theta) / k
        y1 = self.y + (math.sin(theta_end) - math.sin(self.theta)) / k
        z1 = self.z - (math.cos(theta_end) - math.cos(self.theta)) / k
        sense = math.copysign(1.0, k)
        piece = _Piece(self.y, y1, self.z, 0.0, yc, zc, 1 / abs(k), sense, self.theta, theta_end)
        self.pieces.append(piece)
        self.y, self.z, self.theta = y1, z1, theta_end
        return self

    def line_to(self, y_end: float) -> _Chain:
        """Straight segment along the current tangent up to abscissa y_end."""
        slope = math.tan(self.theta)
        self.pieces.append(
            _Piece(self.y, y_end, self.z, slope, theta0=self.theta, theta1=self.theta)
        )
        self.z += slope * (y_end - self.y)
        self.y = y_end
        return self

    def sample(self, step: float) -> tuple[np.ndarray, np.ndarray]:
        """Points (y, z) spaced ``step`` (m) apart along the chain, both ends included."""
        y = np.concatenate([p.abscissae(step) for p in self.pieces] + [np.array([self.y])])
        y = y[np.concatenate([[True], np.diff(y) > 1e-12])]
        return y, self(y)

    def __call__(self, y: np.ndarray) -> np.ndarray:
        """Height z at abscissae y inside the chain (each point on the piece that holds it)."""
        y = np.asarray(y, dtype=float)
        out = np.full(y.shape, np.nan)
        for p in self.pieces:
            m = (y >= p.y0 - 1e-12) & (y <= p.y1 + 1e-12)
            if p.sense == 0.0:
                out[m] = p.z0 + p.slope * (y[m] - p.y0)
            else:
                u = np.clip(y[m] - p.yc, -p.radius, p.radius)
                out[m] = p.zc - p.sense * np.sqrt(p.radius**2 - u * u)
        return out


def _distance_to_line(y: float, z: float, point: tuple[float, float], theta: float) -> float:
    """Signed distance of (y, z) from the line through ``point`` with direction angle theta."""
    return (y - point[0]) * math.sin(theta) - (z - point[1]) * math.cos(theta)


def _bisect(fun: Callable[[float], float], lo: float, hi: float, tol: float = 1e-12) -> float:
    f_lo = fun(lo)
    if f_lo * fun(hi) > 0.0:
        raise RailsuspInputError("no sign change: the profile dimensions cannot be met")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        f_mid = fun(mid)
        if f_mid * f_lo > 0.0:
            lo, f_lo = mid, f_mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def lm_worn_wheel(
    step: float = 1e-4,
    *,
    flange_height: float = 0.027,
    flange_thickness: float = 0.032,
    thickness_height: float = 0.010,
    back_face_offset: float = 0.070,
    rim_width: float = 0.135,
    flank_angle_deg: float = 70.0,
    root_radius: float = 0.015,
    tip_radius: float = 0.012,
    tread_radii: tuple[float, float, float] = (0.500, 0.220, 0.100),
    tread_breaks: tuple[float, float] = (0.010, 0.020),
    taping_slope: float = 1.0 / 20.0,
    field_break: float = 0.010,
    chamfer_slope: float = 1.0 / 8.0,
    name: str = "LM-like worn tread",
) -> Profile:
    """LM-like worn wheel tread (Chinese freight wheel type) built from tangent arcs, C1.

    Geometry (all in m; conventions in :mod:`railsusp.vehicle.profiles`), from the field
    side inwards:

    * a 1:8 outer chamfer joined by a convex R50 arc to a straight (conical) field-side tread;
    * a hollow (concave) tread of arcs ``tread_radii`` = R500 / R220 / R100: R500 spans the
      taping line (slope ``taping_slope`` there, rising outwards) from ``field_break`` outside
      it to ``tread_breaks[0]`` inside, R220 up to ``tread_breaks[1]`` inside, then R100;
    * a concave flange root of ``root_radius`` (R15) blending into a straight flank at
      ``flank_angle_deg`` (70 deg), the R100/R15 tangent point being solved so that the
      flange is ``flange_thickness`` (32 mm) thick at ``thickness_height`` (10 mm) below the
      taping line, measured from the flange back face at ``back_face_offset`` (70 mm) inside
      the taping line (EN 15313 style measuring height, assumed for LM);
    * a flange tip arc of ``tip_radius`` (R12) from the flank to the lowest point of the
      flange, ``flange_height`` (27 mm) below the taping line, and a back arc whose radius
      makes it end on the back face; the profile stops where that arc is at 89 deg.

    With the defaults the flange is 32 mm thick at 10 mm on the R15 root arc (60 deg), the
    flank runs from 15 to 19 mm below the taping line, and on CHN60 rail inclined 1:40 the
    equivalent conicity at 3 mm amplitude is about 0.11, flange contact at about 10 mm.
    Rim width 135 mm: the profile ends ``rim_width - back_face_offset`` = 65 mm outside the
    taping line. The wheelset back-to-back distance is a property of the wheelset, not of
    this profile. Sampled every ``step`` (m) of arc length.
    """
    flank = math.radians(flank_angle_deg)
    r500, r220, r100 = tread_radii
    # inner part, built in mirrored abscissa u = -y so that the turtle runs with u increasing
    # (the flange flank is then a rising-z, positive-angle line, the tip a convex arc).
    theta0 = math.atan(taping_slope)

    def root_chain(theta1: float) -> _Chain:
        ch = _Chain(0.0, 0.0, theta0)
        ch.arc_to(r500, +1.0, tread_breaks[0]).arc_to(r220, +1.0, tread_breaks[1])
        ch.arc(r100, theta1).arc(root_radius, flank)
        return ch

    def thickness_miss(theta1: float) -> float:
        # abscissa of the profile at the measuring height (root arc or flank) minus target
        ch = root_chain(theta1)
        if ch.z <= thickness_height:
            u = ch.y + (thickness_height - ch.z) / math.tan(flank)
        else:  # z rises monotonically inwards: find the chain abscissa at that height
            u = _bisect(lambda v: float(ch(np.array([v]))[0]) - thickness_height, 0.0, ch.y)
        return u - (back_face_offset - flange_thickness)

    tread = _Chain(0.0, 0.0, theta0).arc_to(r500, +1.0, tread_breaks[0])
    theta_lo = tread.arc_to(r220, +1.0, tread_breaks[1]).theta  # R100 starts here
    theta1 = _bisect(thickness_miss, theta_lo + 1e-9, flank - 1e-9)
    inner = root_chain(theta1)
    # flange tip: an arc of tip_radius from the flank to the lowest point (z = flange_height),
    # then a back arc that ends vertical on the back face u = back_face_offset.
    z_tangent = flange_height - tip_radius * (1.0 - math.cos(flank))
    u_tangent = inner.y + (z_tangent - inner.z) / math.tan(flank)
    back_radius = back_face_offset - u_tangent - tip_radius * math.sin(flank)
    if u_tangent <= inner.y or back_radius <= 0.0:
        raise RailsuspInputError("flange dimensions leave no room for a straight flank and the tip")
    inner.line_to(u_tangent).arc(tip_radius, 0.0).arc(back_radius, -math.radians(89.0))
    # outer part (y > 0): R500 continues outwards, then a cone, an R50 blend and the chamfer
    outer = _Chain(0.0, 0.0, -theta0)
    outer.arc_to(r500, +1.0, field_break)
    chamfer_start = rim_width - back_face_offset - 0.012
    blend = 0.050
    theta_cone = outer.theta
    theta_ch = -math.atan(chamfer_slope)
    blend_dy = blend * (math.sin(theta_cone) - math.sin(theta_ch))
    outer.line_to(chamfer_start - blend_dy).arc(blend, theta_ch)
    outer.line_to(rim_width - back_face_offset)

    u_in, z_in = inner.sample(step)
    y_out, z_out = outer.sample(step)
    y = np.concatenate([-u_in[:0:-1], y_out])
    z = np.concatenate([z_in[:0:-1], z_out])
    return Profile(y, z, name=name, kind="wheel")


def chn60_rail(
    step: float = 1e-4,
    *,
    head_width: float = 0.073,
    crown_break: float = 0.010,
    side_slope: float = 1.0 / 20.0,
    depth: float = 0.040,
    inclination: float = 0.0,
    name: str = "CHN60",
) -> Profile:
    """CHN60 (60 kg/m, GB/T 2585) rail head: R300 crown, R80 shoulders, R13 gauge corners.

    The R300 crown runs to ``crown_break`` (10 mm, assumed) either side of the centre line;
    the R80 shoulder hands over to the R13 corner at the angle that makes the R13 arc meet
    the 1:20 (``side_slope``) side face exactly at half the ``head_width`` (73 mm). The side
    faces are followed down to ``depth`` (m) below the crown, far enough for flange contact.
    The head is symmetric; ``inclination`` (tan of the cant, e.g. 1/40) turns it with
    :func:`incline`. Sampled every ``step`` (m) of arc length.
    """
    half = 0.5 * head_width
    theta_side = math.atan(1.0 / side_slope)  # direction of the side face going down

    def corner_end(theta2: float) -> _Chain:
        ch = _Chain(0.0, 0.0, 0.0).arc_to(0.300, +1.0, crown_break)
        return ch.arc(0.080, theta2).arc(0.013, theta_side)

    theta1 = math.asin(crown_break / 0.300)
    theta2 = _bisect(lambda t: corner_end(t).y - half, theta1 + 1e-9, theta_side - 1e-9)
    ch = corner_end(theta2)
    ch.line_to(ch.y + (depth - ch.z) * side_slope)
    y_half, z_half = ch.sample(step)
    y = np.concatenate([-y_half[:0:-1], y_half])
    z = np.concatenate([z_half[:0:-1], z_half])
    rail = Profile(y, z, name=name, kind="rail")
    return incline(rail, inclination) if inclination else rail


def incline(rail: Profile, inclination: float = 1.0 / 40.0) -> Profile:
    """The rail profile turned by the rail cant atan(``inclination``) (1:40 by default).

    The head leans towards the track centre (the gauge side, -y), as laid on inclined tie
    plates, so that the crown rises towards the field side with slope ``inclination``. The
    rotation is about the profile origin; the points are rotated, not resampled.
    """
    g = math.atan(inclination)
    yr = rail.y * math.cos(g) + rail.z * math.sin(g)
    zr = -rail.y * math.sin(g) + rail.z * math.cos(g)
    if np.any(np.diff(yr) <= 0.0):
        raise RailsuspInputError(
            f"profile {rail.name!r}: inclination {inclination} makes a side face overhang"
        )
    return Profile(yr, zr, name=f"{rail.name} 1:{1.0 / inclination:.0f}", kind="rail")


def conical_wheel(
    slope: float = 1.0 / 20.0, half_width: float = 0.060, step: float = 1e-4
) -> Profile:
    """A flangeless pure cone, radius r0 - slope * y (rises outwards): the EN 15302 check case."""
    y = np.arange(-half_width, half_width + 0.5 * step, step)
    return Profile(y, -slope * y, name=f"cone 1:{1.0 / slope:.0f}", kind="wheel")


def round_rail(radius: float = 0.300, half_width: float = 0.036, step: float = 1e-4) -> Profile:
    """A rail head that is one circular arc of ``radius`` (m) across ``half_width`` each side."""
    if half_width >= radius:
        raise RailsuspInputError(f"round rail: half width {half_width} >= radius {radius}")
    y = np.arange(-half_width, half_width + 0.5 * step, step)
    return Profile(
        y, radius - np.sqrt(radius**2 - y * y), name=f"round R{radius * 1e3:.0f}", kind="rail"
    )
