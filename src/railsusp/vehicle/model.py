"""Equations of motion of the C80/K6 wagon on track: bodies, force elements, contact forces.

The state layout is in :mod:`railsusp.vehicle.layout`. Every body moves in the track-following
frame at its own position along the track; connections between bodies at different track
positions use the track's lateral offset from the chord, off(s, d) = Y(s + d) - Y(s) - d θ(s)
(≈ κ d²/2 on an arc), and the heading difference θ(s_A) - θ(s_B). Pseudo-forces of the moving
frame act on every body: lateral -m (V² κ cos φ_t + g sin φ_t), vertical
-m (g cos φ_t - V² κ sin φ_t) (φ_t the cant angle, + lifts the left rail).

Force elements (the ten sampled parameters in brackets):

* primary, per axle box: rubber pad shear in series with the adapter seat, longitudinal
  [X13 + X20] and lateral [X14 + X20]; vertical compression [X15]; linear viscous loss.
* secondary, per spring nest: vertical springs (control springs included) and a pair of
  variable-damping friction wedges (:mod:`railsusp.vehicle.suspension`): column normal force
  F_s / (tan a -+ mu) from the control springs' force, scaled by X18 / X18 nominal (wedge
  rise and wear); Coulomb friction on the column face against vertical and lateral slip
  together (one friction circle), on the slope faces against longitudinal slip (warp);
  longitudinal shear [X16], lateral shear [X17] and a bolster gib stop beyond the clearance
  [X12].
* cross-bracing: two diagonal bars between the side frames, axial stiffness [X19], pin-hole
  spans X9 (longitudinal) and X10 (lateral): warp (parallelogram) stiffness.
* car body to bolster: centre bowl as a ring of compression-only contact points (vertical
  stiffness, roll and pitch moments up to edge lift-off), lateral spring (bowl rim), yaw and
  roll friction; two constant-contact side bearers at +- X11/2 [X11] with lift-off and a
  solid stop after their travel; body-bolster yaw friction of bowl and side bearers.
* wheel-rail contact per wheel: contact-function tables (rolling radius, contact angle,
  contact lateral position, rigid-contact rise, Hertz constant, Kalker coefficients) of the
  wheel's lateral shift relative to its rail; Hertz normal force in series with the rail
  support along the contact normal; Kalker linear creep with Shen-Hedrick-Elkins saturation.
  Lift-off gives zero force. Two-point contact: tread and flange have their own tables and
  act together (single-point option: the table's contact jumps from tread to flange).
* couplers: pitch moment of the grade force at coupler height; lateral component of the
  coupler force in curves (chord angle κ x_k at each end).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

import railsusp.vehicle.kernel_cache  # noqa: F401  (before any kernel is compiled)
from railsusp.vehicle import layout as L
from railsusp.vehicle.suspension import (
    bowl_ring_forces,
    damped_slider,
    disc_friction_moment,
    friction_wedges,
    gap_spring,
    series_stiffness,
)

_K = L.K

# numba sees module-level ints as compile-time constants
I_MC, I_IXC, I_IYC, I_IZC = _K["m_c"], _K["Ix_c"], _K["Iy_c"], _K["Iz_c"]
I_MB, I_IXB, I_IZB = _K["m_b"], _K["Ix_b"], _K["Iz_b"]
I_MF, I_IYF, I_IZF = _K["m_f"], _K["Iy_f"], _K["Iz_f"]
I_MW, I_IXW, I_IYW, I_IZW = _K["m_w"], _K["Ix_w"], _K["Iy_w"], _K["Iz_w"]
I_LC, I_A, I_B1, I_B2, I_R0 = _K["l_c"], _K["a"], _K["b1"], _K["b2"], _K["r0"]
I_HCG, I_HCP, I_HB, I_HK, I_XK, I_RCP = (_K["h_cg_c"], _K["h_cp"], _K["h_cg_b"], _K["h_k"],
                                        _K["x_k"], _K["R_cp"])  # fmt: skip
I_CPX, I_CPY, I_CPZ, I_KSZ, I_CSX = _K["c_px"], _K["c_py"], _K["c_pz"], _K["k_sz"], _K["c_sx"]
I_KW, I_CW, I_KGIB = _K["k_wedge"], _K["c_wedge"], _K["k_gib"]
I_TANW, I_COSW, I_MUC, I_MUS = _K["tan_wedge"], _K["cos_wedge"], _K["mu_column"], _K["mu_slope"]
I_KCTRL, I_F0CTRL, I_X18REF = _K["k_ctrl"], _K["F0_ctrl"], _K["x18_ref"]
I_KCPZ, I_KCPY, I_MUCP, I_KYAW = _K["k_cpz"], _K["k_cpy"], _K["mu_cp"], _K["k_yaw"]
I_CYAW, I_KROLL, I_CROLL = _K["c_yaw"], _K["k_roll"], _K["c_roll"]
I_KSB, I_PSB, I_MUSB, I_KRZ, I_KRY = _K["k_sb"], _K["P_sb"], _K["mu_sb"], _K["k_rz"], _K["k_ry"]
I_SBTRAVEL, I_KSBSTOP, I_CSB = _K["sb_travel"], _K["k_sb_stop"], _K["c_sb"]
I_CRZ, I_CRY = _K["c_rz"], _K["c_ry"]
I_F0CP, I_F0N, I_F0P = _K["F0_cp"], _K["F0_nest"], _K["F0_prim"]
I_Z0L, I_Z0R = _K["Z0_L"], _K["Z0_R"]
I_V, I_GN, I_MU = _K["V"], _K["g_n"], _K["mu"]
I_FCPL, I_MGRADE, I_CREEP = _K["F_coupler"], _K["M_pitch_grade"], _K["creep_factor"]
I_Q0, I_NREF = _K["Q0"], _K["N_ref"]
I_PENMAX, I_LIFTMAX = _K["pen_max"], _K["lift_max"]
I_WATCH = _K["flange_watch"]
I_NPTS = _K["contact_points"]

BOL0, SF0, WS0 = L.BOL0, L.SF0, L.WS0
NQ = L.N_DOF
AUXW, AUXY, AUXR = L.AUX_WEDGE, L.AUX_YAWFR, L.AUX_ROLLFR
NCTW = L.CT_PER_WHEEL


@nb.njit(cache=True, inline="always")
def track_lookup(trk, ch, s, s0, ds):
    """Linear interpolation of track channel ``ch`` at distance s (clamped at the ends)."""
    u = (s - s0) / ds
    n = trk.shape[1]
    if u <= 0.0:
        return trk[ch, 0]
    if u >= n - 1:
        return trk[ch, n - 1]
    i = int(u)
    f = u - i
    return trk[ch, i] * (1.0 - f) + trk[ch, i + 1] * f


@nb.njit(cache=True, inline="always")
def track_frame(trk, s, s0, ds):
    """Curvature (1/m), cant angle (rad), heading (rad) and lateral position (m) of the
    design track at distance s: the frame a body at s moves in."""
    return (
        track_lookup(trk, L.TR_KAPPA, s, s0, ds),
        track_lookup(trk, L.TR_CANT, s, s0, ds),
        track_lookup(trk, L.TR_HEAD, s, s0, ds),
        track_lookup(trk, L.TR_OFFSET, s, s0, ds),
    )


@nb.njit(cache=True, inline="always")
def track_rate(trk, ch, s, s0, ds, V):
    """Time rate V d(channel)/ds of track channel ``ch`` at distance s (per second)."""
    u = (s - s0) / ds
    n = trk.shape[1]
    i = int(u)
    if u <= 0.0 or i >= n - 1:
        return 0.0
    return V * (trk[ch, i + 1] - trk[ch, i]) / ds


@nb.njit(cache=True, inline="always")
def add_frame_forces(acc, i_lat, i_vert, m, kappa, cant, V, gn):
    """Add the moving frame's pseudo-forces on a body of mass m (N): lateral
    -m (V² κ cos φ + g sin φ); vertical -m (g cos φ - V² κ sin φ) as a deviation from the
    static weight m g already carried by the preloads."""
    c = math.cos(cant)
    s = math.sin(cant)
    acc[i_lat] += -m * (V * V * kappa * c + gn * s)
    acc[i_vert] += -m * (gn * c - V * V * kappa * s) + m * gn


@nb.njit(cache=True, inline="always")
def hertz_rail_normal_force(dn, G, krn):
    """Normal force N (N) for normal approach dn (m) of Hertz contact in series with rail.

    dn = G N^(2/3) + N / krn (Hertz law P = (dz/G)^1.5 plus linear rail support). Solved for
    u = N^(1/3) by Newton from above (the cubic is convex and increasing), N = u^3.
    """
    if dn <= 0.0:
        return 0.0
    u1 = math.sqrt(dn / G)  # Hertz alone
    u2 = (krn * dn) ** (1.0 / 3.0)  # rail alone
    u = u1 if u1 < u2 else u2
    c = krn * G
    d = krn * dn
    for _ in range(6):
        f = u * u * u + c * u * u - d
        fp = 3.0 * u * u + 2.0 * c * u
        u -= f / fp
    return u * u * u


@nb.njit(cache=True, inline="always")
def she_saturation(fx, fy, mu_n):
    """Shen-Hedrick-Elkins factor scaling linear creep forces to saturation at mu N.

    F = mu N (beta - beta^2/3 + beta^3/27) for beta = |F_lin| / (mu N) <= 3, else mu N.
    Returns the factor F / |F_lin| (1 for vanishing creep, 0 when unloaded).
    """
    f = math.sqrt(fx * fx + fy * fy)
    if mu_n <= 0.0:
        return 0.0
    if f < 1e-9 * mu_n:
        return 1.0
    beta = f / mu_n
    if beta < 3.0:
        fs = mu_n * (beta - beta * beta / 3.0 + beta * beta * beta / 27.0)
    else:
        fs = mu_n
    return fs / f


@nb.njit(cache=True, inline="always")
def table_index(y, y0, dy, n):
    """Interval index i and fraction f of shift y on a table of n uniform rows from y0 by dy;
    i = -1 when y lies outside the table (flange climb beyond the tabulated range)."""
    u = (y - y0) / dy
    if u < 0.0 or u > n - 1:
        return -1, 0.0
    i = int(u)
    if i >= n - 1:
        i = n - 2
    return i, u - i


@nb.njit(cache=True, inline="always")
def table_row(ctab, col0, y, y0, dy, row):
    """Interpolate the contact-table columns of one wheel at shift y into ``row``.

    Returns False when y lies outside the table (flange climb beyond the tabulated range).
    """
    i, f = table_index(y, y0, dy, ctab.shape[1])
    if i < 0:
        return False
    for c in range(NCTW):
        row[c] = ctab[col0 + c, i] * (1.0 - f) + ctab[col0 + c, i + 1] * f
    return True


#: columns of the per-contact scratch rows filled by :func:`contact_geometry`
G_GAP, G_DELTA, G_LAT, G_R, G_HERTZ, G_F11, G_F22, G_F23, G_RATE, G_N = range(10)
N_GEO = 10


@nb.njit(cache=True)
def contact_geometry(
    ws_y, ws_z, ws_roll, vy, vz, vroll, side, block, rail_y, rail_z, rail_vy, rail_vz,
    ctab, y0, dy, H0, Z0, K, row, geo,
):  # fmt: skip
    """Geometry of one contact point (``block`` 0 tread, 1 flange) of one wheel (side +1
    left, -1 right): fills ``geo`` (G_* columns: vertical gap to the undeflected rail, m,
    < 0 when touching; contact angle; lateral arm; rolling radius; Hertz constant; Kalker
    coefficients at the reference load; rate of the gap, m/s). Returns a failure code; lift
    beyond the flange height is judged on the tread contact.
    """
    col0 = block * L.CT_FLANGE + (0 if side > 0 else NCTW)
    r0 = K[I_R0]
    yrel = ws_y + r0 * ws_roll - rail_y  # the wheel's shift at contact level
    if block > 0:  # the flange is mostly clear of its rail: look up the gap first
        i, f = table_index(yrel, y0, dy, ctab.shape[1])
        if i < 0:
            return L.FAIL_FLANGE_CLIMB
        lat = ctab[col0 + L.CT_L, i] * (1.0 - f) + ctab[col0 + L.CT_L, i + 1] * f
        h = ctab[col0 + L.CT_H, i] * (1.0 - f) + ctab[col0 + L.CT_H, i + 1] * f
        gap = ws_z + side * lat * ws_roll - rail_z - (h - H0) - Z0
        if gap >= 0.0:
            geo[G_GAP] = gap
            geo[G_DELTA] = 0.0
            return L.OK
    if not table_row(ctab, col0, yrel, y0, dy, row):
        return L.FAIL_FLANGE_CLIMB
    lat = row[2]
    gap = ws_z + side * lat * ws_roll - rail_z - (row[3] - H0) - Z0
    if block == 0 and gap > K[I_LIFTMAX]:
        return L.FAIL_LIFT
    slope = side * math.tan(row[1])  # dH/dy of this wheel
    geo[G_GAP] = gap
    geo[G_DELTA] = row[1]
    geo[G_LAT] = lat
    geo[G_R] = row[0]
    geo[G_HERTZ] = row[4]
    geo[G_F11] = row[5]
    geo[G_F22] = row[6]
    geo[G_F23] = row[7]
    geo[G_RATE] = vz + side * lat * vroll - rail_vz - slope * (vy + r0 * vroll - rail_vy)
    return L.OK


@nb.njit(cache=True)
def shared_rail_normal_forces(a1, g1, a2, g2, m11, m12, m22):
    """Normal forces (N) of two Hertz contacts pressing one elastically supported rail.

    a1, a2: rigid approaches along each contact's normal (m); g1, g2: Hertz constants
    (approach = g N^(2/3)); m_ij = n_i . C n_j: the rail support's compliance C =
    diag(1/k_lateral, 1/k_vertical) projected on the contact normals (m/N). Each contact's
    elastic approach is a_i = g_i N_i^(2/3) + sum_j m_ij N_j: the rail deflects under both
    forces, so a tread load also lowers the rail under the flange. Solved for u_i = N_i^(1/3)
    by Newton from the single-contact solutions (upper bounds, since m12 > 0); a contact
    that the other one's deflection opens carries nothing.
    """
    n1 = hertz_rail_normal_force(a1, g1, 1.0 / m11) if a1 > 0.0 else 0.0
    n2 = hertz_rail_normal_force(a2, g2, 1.0 / m22) if a2 > 0.0 else 0.0
    if n2 == 0.0 or a2 - m12 * n1 <= 0.0:
        return n1, 0.0
    if n1 == 0.0 or a1 - m12 * n2 <= 0.0:
        return 0.0, n2
    u1 = n1 ** (1.0 / 3.0)
    u2 = n2 ** (1.0 / 3.0)
    for _ in range(8):
        c1 = u1 * u1 * u1
        c2 = u2 * u2 * u2
        f1 = g1 * u1 * u1 + m11 * c1 + m12 * c2 - a1
        f2 = g2 * u2 * u2 + m12 * c1 + m22 * c2 - a2
        j11 = 2.0 * g1 * u1 + 3.0 * m11 * u1 * u1
        j12 = 3.0 * m12 * u2 * u2
        j21 = 3.0 * m12 * u1 * u1
        j22 = 2.0 * g2 * u2 + 3.0 * m22 * u2 * u2
        det = j11 * j22 - j12 * j21
        d1 = (j22 * f1 - j12 * f2) / det
        d2 = (j11 * f2 - j21 * f1) / det
        u1 = max(u1 - d1, 0.0)
        u2 = max(u2 - d2, 0.0)
        if abs(d1) + abs(d2) < 1e-9 * (u1 + u2):  # N to ~3e-9 relative
            break
    return u1 * u1 * u1, u2 * u2 * u2


@nb.njit(cache=True)
def wheel_rail_forces(
    ws_y, ws_z, ws_roll, ws_yaw, vy, vz, vroll, vyaw, kappa, side,
    rail_y, rail_z, rail_vy, rail_vz, ctab, y0, dy, H0, Z0, K, row, geo, tot,
):  # fmt: skip
    """All contact forces of one wheel (side +1 left, -1 right) on its rail, in the track
    frame: the tread contact and, with two-point contact (K contact_points = 2), the flange
    contact acting at the same time on the same elastic rail.

    Per contact: Hertz normal force (:func:`shared_rail_normal_forces`), rail support damping
    along the normal, Kalker creep with Shen-Hedrick-Elkins saturation. Writes tot =
    [Y_on_wheel, Q_on_wheel (up), Fx_on_wheel, roll and yaw moments of the contact forces
    about the wheelset centre (lever r0 for Y, so that normal forces stay the gradient of
    one contact potential), tread normal force, shift towards the flange, its rate] and
    returns a failure code (0 ok). ``geo``: scratch, shape (2, N_GEO).
    """
    r0 = K[I_R0]
    V = K[I_V]
    n_points = 2 if K[I_NPTS] > 1.5 else 1
    for i in range(6):
        tot[i] = 0.0
    tot[6] = side * (ws_y + r0 * ws_roll - rail_y)
    tot[7] = side * (vy + r0 * vroll - rail_vy)
    k_lat = K[I_KRY]  # rail support per wheel, N/m
    k_vert = K[I_KRZ]
    a0 = 0.0  # rigid approach along the normal of each contact, m
    a1 = 0.0
    for b in range(n_points):
        code = contact_geometry(
            ws_y, ws_z, ws_roll, vy, vz, vroll, side, b, rail_y, rail_z, rail_vy, rail_vz,
            ctab, y0, dy, H0, Z0, K, row, geo[b],
        )  # fmt: skip
        if code != 0:
            return code
        if b == 0:
            a0 = -geo[0, G_GAP] * math.cos(geo[0, G_DELTA])
        else:
            a1 = -geo[1, G_GAP] * math.cos(geo[1, G_DELTA])
    # normal forces: both contacts deflect the same rail (compliance diag(1/k_ry, 1/k_rz))
    s0, c0 = math.sin(geo[0, G_DELTA]), math.cos(geo[0, G_DELTA])
    m00 = s0 * s0 / k_lat + c0 * c0 / k_vert
    if n_points == 2 and a1 > 0.0:
        s1, c1 = math.sin(geo[1, G_DELTA]), math.cos(geo[1, G_DELTA])
        m11 = s1 * s1 / k_lat + c1 * c1 / k_vert
        m01 = s0 * s1 / k_lat + c0 * c1 / k_vert
        n0, n1 = shared_rail_normal_forces(a0, geo[0, G_HERTZ], a1, geo[1, G_HERTZ], m00, m01, m11)
    else:
        n0 = hertz_rail_normal_force(a0, geo[0, G_HERTZ], 1.0 / m00) if a0 > 0.0 else 0.0
        n1 = 0.0
    geo[0, G_N] = n0
    geo[1, G_N] = n1
    n_ref = K[I_NREF]
    for b in range(n_points):
        N = geo[b, G_N]
        if N <= 0.0:
            continue
        if geo[b, G_HERTZ] * N ** (2.0 / 3.0) > K[I_PENMAX]:  # Hertz approach, not the rail
            return L.FAIL_PENETRATION
        delta = geo[b, G_DELTA]
        cd = math.cos(delta)
        sd = math.sin(delta)
        # rail support damping along the normal (pads and ballast), never pulling the wheel
        N -= (cd * cd * K[I_CRZ] + sd * sd * K[I_CRY]) * geo[b, G_RATE] * cd
        if N <= 0.0:
            continue
        # Kalker coefficients scale with the contact area: f11, f22 ~ N^(2/3), f23 ~ N
        scale = (N / n_ref) ** (2.0 / 3.0) * K[I_CREEP]
        f11 = geo[b, G_F11] * scale
        f22 = geo[b, G_F22] * scale
        f23 = geo[b, G_F23] * scale * (N / n_ref) ** (1.0 / 3.0)
        r = geo[b, G_R]
        lat = geo[b, G_LAT]
        # creepages (Kalker): longitudinal, lateral, spin
        xi_x = 1.0 - r / r0 - side * lat * (vyaw / V + kappa)
        xi_y = (vy + r * vroll) / V - ws_yaw
        spin = (vyaw / V + kappa) * cd - side * sd / r0
        fx = -f11 * xi_x
        fy = -f22 * xi_y - f23 * spin
        eps = she_saturation(fx, fy, K[I_MU] * N)
        fx *= eps
        fy *= eps
        # normal n = (-side sin d, cos d), contact-plane lateral t = (cos d, side sin d)
        f_y = -side * N * sd + fy * cd
        f_z = N * cd + side * fy * sd
        tot[0] += f_y
        tot[1] += f_z
        tot[2] += fx
        tot[3] += side * lat * f_z + r0 * f_y
        tot[4] += -side * lat * fx
        if b == 0:
            tot[5] = N
    return L.OK


@nb.njit(cache=True)
def rhs(x, dxdt, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, out):
    """Time derivative of the state; fills ``out`` with the output channels.

    Returns a failure code (0 ok). P: catalogue parameters X1..X20 (SI); K: constants.
    """
    V = K[I_V]
    gn = K[I_GN]
    lc = K[I_LC]
    a = K[I_A]
    b1 = K[I_B1]
    b2 = K[I_B2]
    v = x[NQ : 2 * NQ]
    q = x[:NQ]
    acc = dxdt[NQ : 2 * NQ]
    for i in range(NQ):
        dxdt[i] = v[i]
        acc[i] = 0.0
    # generalised forces accumulate in acc, divided by inertia at the end
    row = np.empty(NCTW)
    geo = np.empty((2, N_GEO))
    tot = np.empty(8)
    flange_rate = -1.0e9  # fastest approach to its flange of a wheel near it (step control)

    # ---- catalogue parameters ----
    m_w = P[0]
    Ix_w = P[1]
    Iy_w = P[2]
    Iz_w = P[3]
    sb_half = 0.5 * P[10]  # X11 side-bearer span
    gib = P[11]  # X12
    k_px = series_stiffness(P[12], P[19])  # X13 + X20
    k_py = series_stiffness(P[13], P[19])  # X14 + X20
    k_pz = P[14]  # X15
    k_sx = P[15]  # X16
    k_sy = P[16]  # X17
    wedge_scale = P[17] / K[I_X18REF]  # X18: wedge normal forces relative to nominal
    k_bar = P[18]  # X19
    h9 = 0.5 * P[8]
    bar_len = math.sqrt(P[8] * P[8] + P[9] * P[9])
    ux = P[8] / bar_len
    uy = P[9] / bar_len

    # ---- track positions ----
    s_c = s_front - (lc + a)
    kap_c, cant_c, head_c, off_c = track_frame(trk, s_c, s0, ds)
    cant_rate_c = track_rate(trk, L.TR_CANT, s_c, s0, ds, V)

    # ---- car body pseudo-forces ----
    m_c = K[I_MC]
    add_frame_forces(acc, L.CB_Y, L.CB_Z, m_c, kap_c, cant_c, V, gn)
    # grade: pitch moment of the net coupler force (at coupler height) and of the bogies'
    # reaction (at centre-plate height); lateral coupler components in curves (chord angle)
    hk = K[I_HCG] - K[I_HK]
    hcp = K[I_HCG] - K[I_HCP]
    acc[L.CB_PITCH] += K[I_MGRADE]
    f_lat_coupler = K[I_FCPL] * kap_c * K[I_XK]
    acc[L.CB_Y] += 2.0 * f_lat_coupler
    acc[L.CB_ROLL] += 2.0 * hk * f_lat_coupler

    for k in range(2):
        d = lc if k == 0 else -lc
        s_b = s_c + d
        kap_b, cant_b, head_b, off_b = track_frame(trk, s_b, s0, ds)
        ib = BOL0 + 4 * k
        m_b = K[I_MB]
        add_frame_forces(acc, ib, ib + 1, m_b, kap_b, cant_b, V, gn)

        # ===== car body <-> bolster k =====
        dev = off_b - off_c - d * head_c  # lateral offset of the track at s_b from the chord
        roll_c_b = q[L.CB_ROLL] + cant_c - cant_b  # car roll seen in the bolster frame
        # centre plate, lateral (bowl): car CP point is hcp below the car CG
        y_cp_car = q[L.CB_Y] + d * q[L.CB_YAW] - dev + hcp * q[L.CB_ROLL]
        h_bcp = K[I_HCP] - K[I_HB]
        y_cp_bol = q[ib] - h_bcp * q[ib + 2]
        f_cpy = K[I_KCPY] * (y_cp_car - y_cp_bol)  # on bolster (+), on car (-)
        acc[ib] += f_cpy
        acc[ib + 2] += -h_bcp * f_cpy
        acc[L.CB_Y] -= f_cpy
        acc[L.CB_ROLL] -= hcp * f_cpy
        acc[L.CB_YAW] -= d * f_cpy
        # centre bowl: ring of contact points with edge lift-off (vertical, roll, pitch) and
        # roll friction
        z_car = q[L.CB_Z] - d * q[L.CB_PITCH]
        roll_rate_b_c = v[ib + 2] - v[L.CB_ROLL] - cant_rate_c
        roll_rate_b_c += track_rate(trk, L.TR_CANT, s_b, s0, ds, V)
        n_cp, m_roll, m_pitch, m_rfr = bowl_ring_forces(
            q[ib + 1] - z_car, roll_c_b - q[ib + 2], q[L.CB_PITCH], -roll_rate_b_c, K[I_RCP],
            K[I_KCPZ], K[I_F0CP], K[I_MUCP], K[I_KROLL], K[I_CROLL], x[AUXR + k], dxdt, AUXR + k,
        )  # fmt: skip
        acc[L.CB_Z] += n_cp - K[I_F0CP]
        acc[L.CB_PITCH] += -d * (n_cp - K[I_F0CP]) + m_pitch
        acc[L.CB_ROLL] += m_roll + m_rfr
        acc[ib + 1] -= n_cp - K[I_F0CP]
        acc[ib + 2] -= m_roll + m_rfr
        # side bearers at +- X11/2 (constant contact elastomer with its loss, lift-off, solid
        # stop after the travel)
        n_sb_sum = 0.0
        dz_rate = v[ib + 1] - v[L.CB_Z] + d * v[L.CB_PITCH]
        for side in (1.0, -1.0):
            comp = (q[ib + 1] + side * sb_half * q[ib + 2]) - (z_car + side * sb_half * roll_c_b)
            comp_rate = dz_rate + side * sb_half * roll_rate_b_c
            f_sb = K[I_PSB] + K[I_KSB] * comp + K[I_CSB] * comp_rate
            if comp > K[I_SBTRAVEL]:
                f_sb += K[I_KSBSTOP] * (comp - K[I_SBTRAVEL])
            if f_sb < 0.0:
                f_sb = 0.0
            n_sb_sum += f_sb
            df = f_sb - K[I_PSB]
            acc[L.CB_Z] += df
            acc[L.CB_ROLL] += side * sb_half * f_sb
            acc[L.CB_PITCH] += -d * df
            acc[ib + 1] -= df
            acc[ib + 2] -= side * sb_half * f_sb
        # body-bolster yaw friction (centre bowl + side bearers): elasto-plastic slider
        m_lim = disc_friction_moment(K[I_MUCP], n_cp, K[I_RCP]) + K[I_MUSB] * n_sb_sum * sb_half
        rel_rate = v[L.CB_YAW] + V * (kap_c - kap_b) - v[ib + 3]
        m_fr = damped_slider(x[AUXY + k], m_lim, K[I_KYAW], K[I_CYAW], rel_rate, dxdt, AUXY + k)
        acc[L.CB_YAW] -= m_fr
        acc[ib + 3] += m_fr

        # ===== bolster <-> side frames (spring nests) =====
        for sidx in range(2):
            side = 1.0 if sidx == 0 else -1.0
            jf = SF0 + 5 * (2 * k + sidx)
            add_frame_forces(acc, jf + 1, jf + 2, K[I_MF], kap_b, cant_b, V, gn)
            # vertical nest springs + friction wedge pair: column friction (vertical and
            # lateral, one friction circle) and slope friction (longitudinal, warp)
            comp = q[jf + 2] - (q[ib + 1] + side * b2 * q[ib + 2])
            comp_rate = v[jf + 2] - (v[ib + 1] + side * b2 * v[ib + 2])
            f_spring = K[I_F0N] + K[I_KSZ] * comp
            ia = AUXW + 3 * (2 * k + sidx)
            dyn = q[jf + 1] - q[ib]
            dxn = q[jf] + side * b2 * q[ib + 3]
            vxn = v[jf] + side * b2 * v[ib + 3]
            f_wz, f_wy, f_warp = friction_wedges(
                comp, comp_rate, v[jf + 1] - v[ib], vxn, K[I_F0CTRL], K[I_KCTRL], K[I_TANW],
                K[I_COSW], K[I_MUC], K[I_MUS], wedge_scale, K[I_KW], K[I_CW], x, dxdt, ia,
            )  # fmt: skip
            f_up = f_spring - K[I_F0N] + f_wz  # on bolster, deviation from static
            acc[ib + 1] += f_up
            acc[ib + 2] += side * b2 * (f_up + K[I_F0N])
            acc[jf + 2] -= f_up
            # lateral shear [X17], wedge column friction, gib stop [X12]
            f_lat = k_sy * dyn + f_wy + gap_spring(dyn, gib, K[I_KGIB])
            acc[ib] += f_lat
            acc[jf + 1] -= f_lat
            # longitudinal shear [X16] and wedge slope friction (warp): bolster yaw against
            # side-frame longitudinal motion
            f_lon = k_sx * dxn + K[I_CSX] * vxn + f_warp
            acc[ib + 3] += -side * b2 * f_lon
            acc[jf] -= f_lon

        # ===== cross-bracing bars between the side frames [X19] =====
        jl = SF0 + 5 * (2 * k)
        jr = SF0 + 5 * (2 * k + 1)
        for bar in range(2):
            e_l = h9 if bar == 0 else -h9  # pin longitudinal offset on the left frame
            e_r = -e_l
            dirx = -ux if bar == 0 else ux  # unit vector from the left to the right pin
            diry = -uy
            dux = q[jr] - q[jl]
            duy = (q[jr + 1] + e_r * q[jr + 4]) - (q[jl + 1] + e_l * q[jl + 4])
            t_bar = k_bar * (dirx * dux + diry * duy)
            acc[jl] += t_bar * dirx
            acc[jl + 1] += t_bar * diry
            acc[jl + 4] += e_l * t_bar * diry
            acc[jr] -= t_bar * dirx
            acc[jr + 1] -= t_bar * diry
            acc[jr + 4] -= e_r * t_bar * diry

        # ===== side frames <-> wheelsets (primary, per axle box) =====
        for wi in range(2):
            w = 2 * k + wi
            e = a if wi == 0 else -a
            s_w = s_b + e
            kap_w, cant_w, head_w, off_w = track_frame(trk, s_w, s0, ds)
            iw = WS0 + 4 * w
            add_frame_forces(acc, iw, iw + 1, m_w, kap_w, cant_w, V, gn)
            dev_w = off_w - off_b - e * head_b
            yaw_w_b = q[iw + 3] + head_w - head_b  # wheelset yaw in the bogie frame
            for sidx in range(2):
                side = 1.0 if sidx == 0 else -1.0
                jf = SF0 + 5 * (2 * k + sidx)
                # longitudinal [X13 in series with X20]
                dx_p = q[jf] + side * b1 * yaw_w_b
                dvx = v[jf] + side * b1 * (v[iw + 3] + V * (kap_w - kap_b))
                f_x = k_px * dx_p + K[I_CPX] * dvx  # on wheelset box, x
                acc[iw + 3] += -side * b1 * f_x
                acc[jf] -= f_x
                # lateral [X14 in series with X20]
                dy_p = q[jf + 1] + e * (q[jf + 4]) - dev_w - q[iw]
                dvy = v[jf + 1] + e * v[jf + 4] - v[iw]
                f_y = k_py * dy_p + K[I_CPY] * dvy  # on wheelset
                acc[iw] += f_y
                acc[jf + 1] -= f_y
                acc[jf + 4] -= e * f_y
                # vertical [X15]
                dz_p = (q[iw + 1] + side * b1 * q[iw + 2]) - (q[jf + 2] - e * q[jf + 3])
                dvz = (v[iw + 1] + side * b1 * v[iw + 2]) - (v[jf + 2] - e * v[jf + 3])
                f_z = k_pz * dz_p + K[I_CPZ] * dvz  # deviation of the upward force on frame
                acc[jf + 2] += f_z
                acc[jf + 3] += -e * (f_z + K[I_F0P])
                acc[iw + 1] -= f_z
                acc[iw + 2] -= side * b1 * (f_z + K[I_F0P])

            # ---- wheel-rail contact ----
            zl = track_lookup(trk, L.TR_ZL, s_w, s0, ds)
            zr = track_lookup(trk, L.TR_ZR, s_w, s0, ds)
            yl = track_lookup(trk, L.TR_YL, s_w, s0, ds)
            yr = track_lookup(trk, L.TR_YR, s_w, s0, ds)
            vzl = track_rate(trk, L.TR_ZL, s_w, s0, ds, V)
            vzr = track_rate(trk, L.TR_ZR, s_w, s0, ds, V)
            vyl = track_rate(trk, L.TR_YL, s_w, s0, ds, V)
            vyr = track_rate(trk, L.TR_YR, s_w, s0, ds, V)
            for sidx in range(2):
                side = 1.0 if sidx == 0 else -1.0
                left = sidx == 0
                code = wheel_rail_forces(
                    q[iw],
                    q[iw + 1],
                    q[iw + 2],
                    q[iw + 3],
                    v[iw],
                    v[iw + 1],
                    v[iw + 2],
                    v[iw + 3],
                    kap_w,
                    side,
                    yl if left else yr,
                    zl if left else zr,
                    vyl if left else vyr,
                    vzl if left else vzr,
                    ctab,
                    y0,
                    dy,
                    H0L if left else H0R,
                    K[I_Z0L] if left else K[I_Z0R],
                    K,
                    row,
                    geo,
                    tot,
                )
                if code != 0:
                    return code
                if tot[6] > K[I_WATCH]:
                    flange_rate = max(flange_rate, tot[7])
                f_yw, f_zw = tot[0], tot[1]
                acc[iw] += f_yw
                acc[iw + 1] += f_zw - K[I_Q0]
                acc[iw + 2] += tot[3]
                acc[iw + 3] += tot[4]
                # outputs: force on the rail; Y + outward (field side), Q + down
                out[L.OUT_Y + 2 * w + sidx] = -side * f_yw
                out[L.OUT_Q + 2 * w + sidx] = f_zw
            # gyroscopic coupling of the spinning wheelset (spin V / r0 about +y)
            h_spin = Iy_w * V / K[I_R0]
            acc[iw + 2] += h_spin * v[iw + 3]
            acc[iw + 3] -= h_spin * v[iw + 2]

    # ---- divide by inertia ----
    acc[L.CB_Y] /= m_c
    acc[L.CB_Z] /= m_c
    acc[L.CB_ROLL] /= K[I_IXC]
    acc[L.CB_PITCH] /= K[I_IYC]
    acc[L.CB_YAW] /= K[I_IZC]
    for k in range(2):
        ib = BOL0 + 4 * k
        acc[ib] /= K[I_MB]
        acc[ib + 1] /= K[I_MB]
        acc[ib + 2] /= K[I_IXB]
        acc[ib + 3] /= K[I_IZB]
    for j in range(4):
        jf = SF0 + 5 * j
        acc[jf] /= K[I_MF]
        acc[jf + 1] /= K[I_MF]
        acc[jf + 2] /= K[I_MF]
        acc[jf + 3] /= K[I_IYF]
        acc[jf + 4] /= K[I_IZF]
    for w in range(4):
        iw = WS0 + 4 * w
        acc[iw] /= m_w
        acc[iw + 1] /= m_w
        acc[iw + 2] /= Ix_w
        acc[iw + 3] /= Iz_w
    out[L.OUT_ACC_Y] = acc[L.CB_Y] + V * V * kap_c * math.cos(cant_c) + gn * math.sin(cant_c)
    out[L.OUT_ACC_Z] = acc[L.CB_Z]
    out[L.OUT_FLANGE_RATE] = flange_rate
    return L.OK
