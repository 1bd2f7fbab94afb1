"""The contact table of the wagon's wheel/rail pair in the kernels' layout (``contact_arrays``).

Per lateral shift of the wheelset, for each wheel's tread and flange contact: rolling radius,
contact angle, lateral arm, the height at which the wheel touches, the Hertz constant and
Kalker's creep coefficients at the static wheel load, and the contact point's lead per radian
of wheelset yaw. It is made once per wagon (cached) from the profiles by the rigid-profile
search (:mod:`railsusp.vehicle.rigid_profile_contact`), the coefficients at the static wheel
load (``static_wheel_load``).

It is apart from :mod:`railsusp.vehicle.setup`, which makes the inputs of one parameter set
in one condition (the constants vector with its static preloads) and the solver's settings:
this table depends on the wagon alone and is shared by every set and condition.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from railsusp.conditions import GRAVITY
from railsusp.errors import RailsuspInputError
from railsusp.params import spec
from railsusp.vehicle import layout as L
from railsusp.vehicle.contact import ContactTable, flange_split
from railsusp.vehicle.contact_forces import hertz_contact, kalker_creep_coefficients
from railsusp.vehicle.profile_shapes import chn60_rail, lm_worn_wheel
from railsusp.vehicle.profiles import read_profile
from railsusp.vehicle.rigid_profile_contact import contact_table
from railsusp.vehicle.wagon import WagonData


@dataclass(frozen=True)
class ContactArrays:
    """Contact table in the kernel's layout: (N_CT, n_y) over a uniform shift grid."""

    table: np.ndarray
    y0: float
    dy: float
    H0L: float
    H0R: float
    delta0: float
    n_ref: float
    flange_shift: float  # smallest shift of a wheel towards its flange with flange contact, m
    contact_points: int  # per wheel: 1 (tread table only) or 2 (tread and flange)
    flange_split: float | None  # wheel profile abscissa splitting tread from flange, m
    yaw_geometry: bool = True  # the lead column holds r tan(delta) (else 0: zero-yaw contact)


#: lateral shift range of the contact table (m): the field side of the tread must stay in
#: range under wide gauge; beyond the flange the table shows climbing, flagged as failure
CONTACT_TABLE_HALF_RANGE = 0.035

#: smallest relative curvature given to Hertz at near-conformal (flange-root) points, 1/m
MIN_RELATIVE_CURVATURE = 0.5


def _kernel_blocks(
    tab: ContactTable, y: np.ndarray, n_ref: float, yaw_geometry: bool = True
) -> np.ndarray:
    """Kernel rows (2 x CT_PER_WHEEL: left, right) of one contact table.

    Rolling radius, contact angle, lateral arm, touching height H, Hertz constant G,
    Kalker f11, f22, f23 at the static load, and the contact point's longitudinal lead per
    radian of wheelset yaw, r tan(delta) (0 without ``yaw_geometry``; the kernel's yawed
    wheelset geometry, :func:`railsusp.vehicle.wheel_rail.contact_geometry`). Shifts at
    which the table's wheel part has nothing above the rail (NaN rows of a flange table) take
    the nearest finite values and a touching height 50 mm below the lowest one, so they never
    touch.
    """
    out = np.empty((2 * L.CT_PER_WHEEL, y.size))
    for col0, wheel in ((0, 0), (L.CT_RIGHT, 1)):
        sign = 1.0 if wheel == 0 else -1.0
        rise = tab.contact_z[:, wheel] + tab.rolling_radius[:, wheel]  # axle height at touch
        ok = np.isfinite(rise)

        def fill(a: np.ndarray, ok: np.ndarray = ok) -> np.ndarray:
            return a if ok.all() else np.interp(y, y[ok], a[ok])

        arm = fill((tab.contact_y[:, wheel] - y) * sign)
        radius = fill(tab.rolling_radius[:, wheel])
        wl = np.maximum(fill(tab.wheel_curvature_long[:, wheel]), 2 * MIN_RELATIVE_CURVATURE)
        lat = fill(tab.wheel_curvature_lat[:, wheel] + tab.rail_curvature_lat[:, wheel])
        lat = np.maximum(lat, 2 * MIN_RELATIVE_CURVATURE)
        if not ok.all():
            rise = np.where(ok, rise, np.nanmin(rise) - 0.05)
        patch = hertz_contact(n_ref, wl, lat, 0.0)
        f11, f22, f23, _ = kalker_creep_coefficients(patch.a, patch.b)
        out[col0 + L.CT_R] = radius
        # contact angle consistent with the rigid-contact rise (normal force = gradient of the
        # contact potential, so the table forces are conservative): tan(delta) = +-dH/dy
        tan_delta = np.gradient(rise, y) * sign
        out[col0 + L.CT_DELTA] = np.arctan(tan_delta)
        out[col0 + L.CT_L] = arm
        out[col0 + L.CT_H] = rise
        out[col0 + L.CT_G] = patch.approach / n_ref ** (2.0 / 3.0)
        out[col0 + L.CT_F11] = f11
        out[col0 + L.CT_F22] = f22
        out[col0 + L.CT_F23] = f23
        out[col0 + L.CT_LEAD] = radius * tan_delta if yaw_geometry else 0.0
    return out


def contact_arrays(wagon: WagonData) -> ContactArrays:
    """Contact functions of the wagon's wheel/rail pair, with Hertz and Kalker coefficients
    (:func:`_contact_arrays`), computed once per wagon and contents of its profile files (a
    profile edited in place is read again)."""
    return _contact_arrays(wagon, tuple(sorted(wagon.profile_digests().items())))


@functools.lru_cache(maxsize=8)
def _contact_arrays(wagon: WagonData, _profile_files: tuple) -> ContactArrays:
    """Contact functions of the wagon's wheel/rail pair, with Hertz and Kalker coefficients.

    Per shift: rolling radius, contact angle, lateral arm of the contact point from the
    wheelset centre, axle-point rise H (rise + arm x roll) at which the wheel just touches,
    Hertz constant G (approach = G N^(2/3), from the local curvatures at the static load),
    and Kalker's f11, f22, f23 at the static load (scaled with N inside the kernel).

    Two-point contact (``wagon.contact.model``): the wheel profile is split between tread
    and flange (:func:`railsusp.vehicle.contact.flange_split`) and each part gets its own
    table, so the tread keeps its load while the flange contact builds up. Single-point:
    one table of the whole profile, whose contact jumps from tread to flange.

    ``wagon.contact.yaw_geometry`` (default) fills the lead column r tan(delta), with which
    the kernel places the contact of a yawed wheelset ahead of or behind the axle; false
    fills it with 0: the zero-yaw contact of the model before 2026-11-24.
    """
    tr = wagon.track
    # Decoupled wheels (no wheelset roll in the table): each wheel's touching height is a
    # function of its own lateral shift at contact level, y_w + r0 roll - y_rail. The
    # wheelset roll then enters the contact through that shift and the lever of the contact
    # point, so normal forces stay the gradient of one contact potential (conservative).
    prof = wagon.profiles
    wheel = lm_worn_wheel() if prof.wheel == "lm-like" else read_profile(prof.wheel, kind="wheel")
    rail = chn60_rail() if prof.rail == "chn60" else read_profile(prof.rail, kind="rail")
    kw = {
        "track_gauge": tr.gauge,
        "rail_inclination": tr.rail_inclination,
        "nominal_radius": wagon.wheelset.rolling_radius,
        "wheelset_roll": False,
        "y_min": -CONTACT_TABLE_HALF_RANGE,
        "y_max": CONTACT_TABLE_HALF_RANGE,
    }
    tab = contact_table(wheel, rail, **kw)
    left, right = tab.flangeway_clearance()
    if not (math.isfinite(left) and math.isfinite(right)):  # a profile without a flange
        raise RailsuspInputError(
            f"wheel {tab.meta['wheel']!r} on rail {tab.meta['rail']!r}: no flange contact within "
            f"+-{CONTACT_TABLE_HALF_RANGE * 1e3:.0f} mm of shift; accepted profiles whose "
            "flanges limit the wheelset's lateral shift"
        )
    n_ref = static_wheel_load(wagon)
    y = tab.y
    arrays = np.empty((L.N_CT, y.size))
    split = flange_split(tab) if wagon.contact.model == "two-point" else None
    yaw = wagon.contact.yaw_geometry
    if split is None:  # single point (or a conformal profile): the flange block never touches
        arrays[: L.CT_FLANGE] = _kernel_blocks(tab, y, n_ref, yaw)
        arrays[L.CT_FLANGE :] = arrays[: L.CT_FLANGE]
        arrays[L.CT_FLANGE + L.CT_H] = -1.0
        arrays[L.CT_FLANGE + L.CT_RIGHT + L.CT_H] = -1.0
        points = 1
    else:
        tread = contact_table(wheel, rail, wheel_range=(split, math.inf), **kw)
        flange = contact_table(wheel, rail, wheel_range=(-math.inf, split), **kw)
        arrays[: L.CT_FLANGE] = _kernel_blocks(tread, y, n_ref, yaw)
        arrays[L.CT_FLANGE :] = _kernel_blocks(flange, y, n_ref, yaw)
        points = 2
    i0 = int(np.argmin(np.abs(y)))
    for col0 in (0, L.CT_RIGHT):  # heights from the centred tread contact of each wheel
        h0 = arrays[col0 + L.CT_H, i0]
        arrays[col0 + L.CT_H] -= h0
        if points == 2:
            arrays[L.CT_FLANGE + col0 + L.CT_H] -= h0
    return ContactArrays(
        table=np.ascontiguousarray(arrays),
        y0=float(y[0]),
        dy=float(y[1] - y[0]),
        H0L=float(arrays[L.CT_H, i0]),
        H0R=float(arrays[L.CT_RIGHT + L.CT_H, i0]),
        delta0=float(arrays[L.CT_DELTA, i0]),
        n_ref=n_ref,
        flange_shift=min(left, -right),
        contact_points=points,
        flange_split=split,
        yaw_geometry=yaw,
    )


def static_wheel_load(wagon: WagonData, wheelset_mass: float | None = None) -> float:
    """Static vertical wheel load (N) on level track: total wagon weight / 8."""
    m_w = spec("X1").nominal if wheelset_mass is None else wheelset_mass
    total = wagon.car_body.mass + 2 * wagon.bolster.mass + 4 * wagon.side_frame.mass + 4 * m_w
    return total * GRAVITY / 8.0
