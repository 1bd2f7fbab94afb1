"""Compiled wheel-rail contact of one wheel: table look-up, Hertz normal force on an elastic
rail, Kalker creep with Shen-Hedrick-Elkins saturation (the simulator's kernel).

The force laws are those of :mod:`railsusp.vehicle.contact_forces` (NumPy, for the tables
and tests), rewritten for the right-hand side: every function returns its results as a tuple
(no array is allocated per evaluation), each trigonometric function of the contact angle is
evaluated once per contact, and the fractional powers of the normal force are one cube root.
The normal forces, of one contact and of tread and flange on one rail, are solved in
:mod:`railsusp.vehicle.normal_contact`.
The two-point contact (tread and flange acting together on one elastic rail) follows
docs/model.md. The right-hand side evaluates the eight wheels together with
:mod:`railsusp.vehicle.contact_batch` (SIMD), which is tested against this kernel.

Yawed wheelset (angle of attack psi, relative to the rail): the contact point of a wheel of
revolution on a prismatic rail lies where the wheel's surface is parallel to the rail's, which
for a yawed wheel is not below the axle but ahead of or behind it: the contact lead
x_c = side r tan(delta) psi (the left wheel's contact leads for psi > 0, nose to the left;
the leading outer wheel of a curving bogie runs with its flange contact ahead of the axle).
This is the first-order "contact lead" of the yawed wheelset (Iwnicki (ed.), Handbook of
Railway Vehicle Dynamics, the chapter on wheel-rail contact; Shabana, Zaazaa & Sugiyama,
Railroad Vehicle Dynamics: A Computational Approach, 2008; Wang Kaiyun's "contact trace
line" method; the longitudinal contact location of a yawed wheelset and its effect on the
wheelset's motion, up to about 10 mm from the axle's vertical plane and small: Mathematical
Problems in Engineering 2016, article 1901089), derived here for the tables' wheel-shift
coordinate: minimising the gap of the wheel section at the
angle theta from the bottom, which is shifted laterally by r theta psi and raised by
r theta^2 / 2, gives theta = tan(delta) psi, i.e. the lead above, a touching height higher by
x_c^2 / (2 r) = r tan^2(delta) psi^2 / 2, a rail contact point moved by x_c psi (where the
contact angle is read) and a rolling radius smaller by x_c^2 / (2 r); the yawed axle also holds
each wheel l cos(psi) from the wheelset centre, l psi^2 / 2 further in (at 10 mrad on the
flange the two psi^2 terms are 0.16 and -0.10 mm of touching height; checked against a
brute-force search over the yawed wheel of revolution). The contact normal stays in the
rail's cross-section (the rail is a prism), so the normal/lateral force split follows the
contact angle at the moved point, the lateral force acts at x_c - side l psi from the
wheelset centre (a yaw moment: the gradient of the touching height's psi^2 terms, so the
normal forces stay conservative) and the material of the led point has the vertical velocity
-V x_c / r0 of the wheel's spin, whose part in the contact plane adds -side sin(delta) x_c / r0
to the lateral creepage: with the yaw slip's own projection -psi cos(delta) the classical
-psi / cos(delta) of a yawed wheelset in flange contact (the lateral velocity's part keeps the
unprojected (y' + r roll') / V of the zero-yaw kernel). The table's lead column holds
r tan(delta) (0 for the zero-yaw model); the constant K yaw_geometry switches the yaw terms
on, so that a row of zero lead (a flat touching height) keeps the arm -side l psi of the
yawed axle; at psi = 0 every correction is an exact 0.0 and the forces are those of the
zero-yaw kernel bit for bit (tests/vehicle/test_yawed_contact.py).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)
from railsusp.vehicle.normal_contact import hertz_rail_normal_force, shared_rail_normal_forces

_K = L.K
I_R0, I_MU, I_CREEP = _K["r0"], _K["mu"], _K["creep_factor"]
I_CRZ, I_CRY, I_DCAP = _K["c_rz"], _K["c_ry"], _K["rail_damping_cap"]
I_NREF, I_PENMAX, I_LIFTMAX = _K["N_ref"], _K["pen_max"], _K["lift_max"]
I_NPTS, I_YAWGEO = _K["contact_points"], _K["yaw_geometry"]
I_INVV, I_INVR0, I_INVKRY, I_INVKRZ = _K["inv_V"], _K["inv_r0"], _K["inv_k_ry"], _K["inv_k_rz"]

NCTW = L.CT_PER_WHEEL
CT_R, CT_DELTA, CT_L, CT_H = L.CT_R, L.CT_DELTA, L.CT_L, L.CT_H
CT_G, CT_F11, CT_F22, CT_F23 = L.CT_G, L.CT_F11, L.CT_F22, L.CT_F23
CT_LEAD = L.CT_LEAD


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def she_saturation(fx, fy, mu_n):
    """Shen-Hedrick-Elkins factor scaling linear creep forces to saturation at mu N.

    F = mu N (beta - beta^2/3 + beta^3/27) for beta = |F_lin| / (mu N) <= 3, else mu N.
    Returns the factor F / |F_lin| = 1 - beta/3 + beta^2/27 (below saturation), 1/beta
    beyond (1 for vanishing creep, 0 when unloaded).
    """
    if mu_n <= 0.0:
        return 0.0
    f = math.sqrt(fx * fx + fy * fy)
    beta = f / mu_n
    if beta < 3.0:
        return 1.0 - beta / 3.0 + beta * beta / 27.0
    return 1.0 / beta


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def table_index(y, y0, inv_dy, n):
    """Interval index i and fraction f of shift y on a table of n uniform rows from y0 by dy
    (``inv_dy`` = 1 / dy); i = -1 when y lies outside the table (flange climb beyond the
    tabulated range)."""
    u = (y - y0) * inv_dy
    if u < 0.0 or u > n - 1:
        return -1, 0.0
    i = int(u)
    if i >= n - 1:
        i = n - 2
    return i, u - i


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def _cell(ctab, c, i, f):
    """Column c of the contact table interpolated at (i, f)."""
    return ctab[c, i] * (1.0 - f) + ctab[c, i + 1] * f


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def contact_geometry(
    ws_y, ws_z, ws_roll, ws_yaw, vy, vz, vroll, vyaw, side, block, rail_y, rail_z, rail_vy,
    rail_vz, ctab, y0, inv_dy, H0, Z0, r0, inv_r0, lift_max, yawed,
):  # fmt: skip
    """Geometry of one contact point (``block`` 0 tread, 1 flange) of one wheel (side +1
    left, -1 right) of a wheelset yawed by ``ws_yaw`` (rad, relative to the rail; yaw rate
    ``vyaw``); ``yawed``: the yaw-aware contact is on (wagon ``[contact] yaw_geometry``),
    else the zero-yaw contact (lead and arm 0, the table read at the wheel's shift).

    Returns (code, gap, cd, sd, lat, r, hertz, f11, f22, f23, rate, x_c, x_pos): failure
    code; vertical gap to the undeflected rail (m, < 0 when touching); cosine and sine of the
    contact angle; lateral arm; rolling radius; Hertz constant; Kalker coefficients at the
    reference load; rate of the gap (m/s); longitudinal lead of the contact point ahead of
    the wheel's axle point (m); the contact point's longitudinal place from the wheelset
    centre, x_c - side l psi (m: the yawed axle puts the wheel itself at -side l psi).
    A flange clear of its rail returns only its gap (the rest 0); lift beyond the flange
    height is judged on the tread contact.

    Yaw (module docstring): the lead x_c = side r tan(delta) psi and the arm l are read at
    the wheel's shift; the table is then read at the shift moved by x_c psi (the rail point
    of the yawed wheel's section at the lead) less side l psi^2 / 2 (the yawed axle holds
    the wheel l cos(psi) from the centre: both wheels move inwards), the touching height is
    raised by x_c^2 / (2 r) and the rolling radius lowered by as much. The gap rate follows:
    the move's rate is (x_c + x_pos) psi' and d(x_c^2 / 2r)/dt = x_c x_c' / r (the lead
    coefficient and the arm taken as constant over the step). 1 / r is one Newton step of
    the reciprocal from 1 / r0, r0^-1 (2 - r / r0): relative error (1 - r / r0)^2, 1e-3 on
    the flange, of a term that is itself second order (no division in the kernel's path).
    """
    col0 = block * L.CT_FLANGE + (0 if side > 0 else NCTW)
    yrel = ws_y + r0 * ws_roll - rail_y  # the wheel's shift at contact level
    i, f = table_index(yrel, y0, inv_dy, ctab.shape[1])
    if i < 0:
        return L.FAIL_FLANGE_CLIMB, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    lead = _cell(ctab, col0 + CT_LEAD, i, f)  # r tan(delta), m per rad of yaw
    x_c = side * lead * ws_yaw
    x_pos = 0.0
    # the switch, not x_c != 0: a row of zero lead (flat touching height) keeps the arm
    if yawed:  # the yawed contact's rail point
        x_pos = x_c - side * _cell(ctab, col0 + CT_L, i, f) * ws_yaw
        move = 0.5 * (x_c + x_pos) * ws_yaw
        f += move * inv_dy  # mostly within the same table interval: no new index
        if f < 0.0 or f > 1.0:
            i, f = table_index(yrel + move, y0, inv_dy, ctab.shape[1])
        if i < 0:
            return (
                L.FAIL_FLANGE_CLIMB, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
            )  # fmt: skip
    lat = _cell(ctab, col0 + CT_L, i, f)
    h = _cell(ctab, col0 + CT_H, i, f)
    r = _cell(ctab, col0 + CT_R, i, f)
    drop = inv_2r = 0.0  # the led point's height above the axle's lowest point
    if yawed:
        inv_2r = 0.5 * inv_r0 * (2.0 - r * inv_r0)
        drop = x_c * x_c * inv_2r
    gap = ws_z + side * lat * ws_roll - rail_z - (h - H0) - Z0 + drop
    if block > 0 and gap >= 0.0:  # the flange is mostly clear of its rail
        return L.OK, gap, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if block == 0 and gap > lift_max:
        return L.FAIL_LIFT, gap, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    delta = _cell(ctab, col0 + CT_DELTA, i, f)
    cd = math.cos(delta)
    sd = math.sin(delta)
    slope = side * sd / cd  # dH/dy of this wheel
    rate = (
        vz + side * lat * vroll - rail_vz
        - slope * (vy + r0 * vroll - rail_vy + (x_c + x_pos) * vyaw)
        + 2.0 * x_c * (side * lead * vyaw) * inv_2r
    )  # fmt: skip
    return (
        L.OK, gap, cd, sd, lat, r - drop, _cell(ctab, col0 + CT_G, i, f),
        _cell(ctab, col0 + CT_F11, i, f), _cell(ctab, col0 + CT_F22, i, f),
        _cell(ctab, col0 + CT_F23, i, f), rate, x_c, x_pos,
    )  # fmt: skip


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def creep_contact_forces(
    N, rate, cd, sd, lat, r, hertz, f11, f22, f23, x_c, x_pos, side, vy, vroll, ws_yaw, vyaw,
    kappa, K, yawed,
):  # fmt: skip
    """Forces of one loaded contact point on the wheel, in the track frame.

    N: Hertz normal force (N) before the rail support's damping along the normal; cd, sd:
    cosine and sine of the contact angle; x_c, x_pos: the contact's lead ahead of the
    wheel's axle point and its longitudinal place from the wheelset centre (m,
    :func:`contact_geometry`). With the yaw-aware contact (``yawed``) the lateral creepage
    is that of the led point: the yaw slip -psi projected on the contact plane (cos delta),
    the spin's vertical velocity -V x_c / r0 projected on it (side sin delta) and the yaw
    rate's lateral velocity at x_pos; the lateral force acts at x_pos (yaw moment x_pos F_y).
    Without it the creepage is the zero-yaw kernel's (yaw slip -psi unprojected). Returns
    (code, lateral force, vertical force, longitudinal force, roll moment, yaw moment, normal
    force) — all 0 for a contact that the damping unloads. Kalker coefficients scale with the
    contact area: f11, f22 ~ N^(2/3), f23 ~ N (one cube root of N / N_ref for both).
    """
    r0 = K[I_R0]
    inv_r0 = K[I_INVR0]
    inv_v = K[I_INVV]
    # Hertz approach G N^(2/3) beyond pen_max (not the rail's), cubed: no fractional power
    pen = K[I_PENMAX]
    if N * N * (hertz * hertz * hertz) > pen * pen * pen:
        return L.FAIL_PENETRATION, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # rail support damping along the normal (pads and ballast), never pulling the wheel,
    # and pushing at most as hard as the Hertz spring it acts through (a damper in series
    # with the contact passes no force before the contact does: no step at a touch-down)
    damping = -(cd * cd * K[I_CRZ] + sd * sd * K[I_CRY]) * rate * cd
    N += min(damping, N) if K[I_DCAP] != 0.0 else damping  # (K rail_damping_cap)
    if N <= 0.0:
        return L.OK, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    n_ref = K[I_NREF]
    u = np.cbrt(N / n_ref)
    scale = u * u * K[I_CREEP]
    c11 = f11 * scale
    c22 = f22 * scale
    c23 = f23 * scale * u
    # creepages (Kalker): longitudinal, lateral, spin
    yaw_rate = vyaw * inv_v + kappa  # wheelset yaw per metre run, absolute
    xi_x = 1.0 - r * inv_r0 - side * lat * yaw_rate
    if yawed:
        xi_y = (vy + r * vroll) * inv_v - ws_yaw * cd - side * sd * x_c * inv_r0 + yaw_rate * x_pos
    else:
        xi_y = (vy + r * vroll) * inv_v - ws_yaw
    spin = yaw_rate * cd - side * sd * inv_r0
    fx = -c11 * xi_x
    fy = -c22 * xi_y - c23 * spin
    eps = she_saturation(fx, fy, K[I_MU] * N)
    fx *= eps
    fy *= eps
    # normal n = (-side sin d, cos d), contact-plane lateral t = (cos d, side sin d)
    f_y = -side * N * sd + fy * cd
    f_z = N * cd + side * fy * sd
    return L.OK, f_y, f_z, fx, side * lat * f_z + r0 * f_y, x_pos * f_y - side * lat * fx, N


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME)
def wheel_rail_forces(
    ws_y, ws_z, ws_roll, ws_yaw, vy, vz, vroll, vyaw, kappa, side,
    rail_y, rail_z, rail_vy, rail_vz, ctab, y0, dy, H0, Z0, K,
):  # fmt: skip
    """All contact forces of one wheel (side +1 left, -1 right) on its rail, in the track
    frame: the tread contact and, with two-point contact (K contact_points = 2), the flange
    contact acting at the same time on the same elastic rail.

    Per contact: Hertz normal force (:func:`shared_rail_normal_forces`), rail support damping
    along the normal, Kalker creep with Shen-Hedrick-Elkins saturation, each at the contact
    point of the wheelset yawed by ``ws_yaw`` relative to the track (rate ``vyaw``; module
    docstring) when K yaw_geometry is 1 (else the zero-yaw contact). Returns (code,
    Y_on_wheel, Q_on_wheel (up), Fx_on_wheel, roll and yaw moments of the contact forces
    about the wheelset centre (lever r0 for Y, so that normal forces stay the gradient of
    one contact potential), tread normal force, shift towards the flange, its rate).
    """
    r0 = K[I_R0]
    inv_r0 = K[I_INVR0]
    inv_dy = 1.0 / dy
    shift = side * (ws_y + r0 * ws_roll - rail_y)
    shift_rate = side * (vy + r0 * vroll - rail_vy)
    lift_max = K[I_LIFTMAX]
    yawed = K[I_YAWGEO] > 0.5
    code, gap0, c0, s0, lat0, r_0, g0, f11_0, f22_0, f23_0, rate0, x0, p0 = contact_geometry(
        ws_y, ws_z, ws_roll, ws_yaw, vy, vz, vroll, vyaw, side, 0, rail_y, rail_z, rail_vy,
        rail_vz, ctab, y0, inv_dy, H0, Z0, r0, inv_r0, lift_max, yawed,
    )  # fmt: skip
    if code != 0:
        return code, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, shift, shift_rate
    two = K[I_NPTS] > 1.5
    a1 = lat1 = r_1 = g1 = f11_1 = f22_1 = f23_1 = rate1 = x1 = p1 = 0.0
    c1 = 1.0
    s1 = 0.0
    if two:
        code, gap1, c1, s1, lat1, r_1, g1, f11_1, f22_1, f23_1, rate1, x1, p1 = contact_geometry(
            ws_y, ws_z, ws_roll, ws_yaw, vy, vz, vroll, vyaw, side, 1, rail_y, rail_z,
            rail_vy, rail_vz, ctab, y0, inv_dy, H0, Z0, r0, inv_r0, lift_max, yawed,
        )  # fmt: skip
        if code != 0:
            return code, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, shift, shift_rate
        a1 = -gap1 * c1
    # normal forces: both contacts deflect the same rail (compliance diag(1/k_ry, 1/k_rz))
    c_lat = K[I_INVKRY]  # rail support compliance per wheel, m/N
    c_vert = K[I_INVKRZ]
    a0 = -gap0 * c0
    m00 = s0 * s0 * c_lat + c0 * c0 * c_vert
    if two and a1 > 0.0:
        m11 = s1 * s1 * c_lat + c1 * c1 * c_vert
        m01 = s0 * s1 * c_lat + c0 * c1 * c_vert
        n0, n1 = shared_rail_normal_forces(a0, g0, a1, g1, m00, m01, m11)
    else:
        n0 = hertz_rail_normal_force(a0, g0, 1.0 / m00) if a0 > 0.0 else 0.0
        n1 = 0.0
    fy = fz = fx = mx = mz = n_tread = 0.0
    if n0 > 0.0:
        code, fy, fz, fx, mx, mz, n_tread = creep_contact_forces(
            n0, rate0, c0, s0, lat0, r_0, g0, f11_0, f22_0, f23_0, x0, p0, side, vy, vroll,
            ws_yaw, vyaw, kappa, K, yawed,
        )  # fmt: skip
        if code != 0:
            return code, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, shift, shift_rate
    if n1 > 0.0:
        code, gy, gz, gx, nx, nz, _ = creep_contact_forces(
            n1, rate1, c1, s1, lat1, r_1, g1, f11_1, f22_1, f23_1, x1, p1, side, vy, vroll,
            ws_yaw, vyaw, kappa, K, yawed,
        )  # fmt: skip
        if code != 0:
            return code, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, shift, shift_rate
        fy += gy
        fz += gz
        fx += gx
        mx += nx
        mz += nz
    return L.OK, fy, fz, fx, mx, mz, n_tread, shift, shift_rate
