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
* secondary, per spring nest: vertical springs (control springs included) and two
  variable-damping friction wedges, ahead of and behind the bolster end at +- l_w
  (:mod:`railsusp.vehicle.suspension`): column normal force F_s / (tan a -+ mu) from the
  control springs' force, scaled by X18 / X18 nominal (wedge rise and wear), half on each
  wedge; Coulomb friction on each wedge's column face against its vertical and lateral slip
  together (one friction circle per wedge: a bolster yawing relative to the side frame
  slides the two in opposite directions, a warp friction moment), on the slope faces
  against the bolster end's longitudinal slip; longitudinal shear [X16], lateral shear
  [X17] and a bolster gib stop beyond the clearance [X12].
* cross-bracing: two diagonal bars between the side frames, axial stiffness [X19], pin-hole
  spans X9 (longitudinal) and X10 (lateral): warp (parallelogram) stiffness, beside the
  wedges' warp friction.
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
  coupler force in curves (the coupler line's angle κ L/2 at each end, L the length over
  couplers: the line between like cars is parallel to the tangent halfway between them).
* roll moments (docs/model.md): the side frames roll with their bogie's wheelsets (the mean
  of their roll; the couple of the lateral forces entering a side frame at the bolster's
  height and leaving at the axles' reaches the wheel loads), and the car body's gravity
  (P-delta) roll moment W h theta of its support loads h below its CG.

The car body's forces on each bolster are :func:`railsusp.vehicle.body_bolster.body_on_bolster`.
"""

from __future__ import annotations

import math

import numba as nb

from railsusp.vehicle import contact_batch as CB
from railsusp.vehicle import layout as L
from railsusp.vehicle import wedge_batch as WB
from railsusp.vehicle.body_bolster import body_on_bolster
from railsusp.vehicle.contact_batch import contact_forces_8
from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)
from railsusp.vehicle.suspension import (
    gap_spring,
    series_stiffness,
)
from railsusp.vehicle.track_lookup import (
    frame_turn,
    track_frame,
    track_point,
    track_rate,
    track_value,
)
from railsusp.vehicle.wedge_batch import wedge_forces

_K = L.K

# numba sees module-level ints as compile-time constants
I_MC, I_MB, I_MF = _K["m_c"], _K["m_b"], _K["m_f"]
I_LC, I_A, I_B1, I_B2, I_R0 = _K["l_c"], _K["a"], _K["b1"], _K["b2"], _K["r0"]
I_HCG, I_HK = _K["h_cg_c"], _K["h_k"]
I_CPX, I_CPY, I_CPZ, I_KSZ, I_CSX = _K["c_px"], _K["c_py"], _K["c_pz"], _K["k_sz"], _K["c_sx"]
I_KW, I_CW, I_KGIB = _K["k_wedge"], _K["c_wedge"], _K["k_gib"]
I_TANW, I_COSW, I_MUC, I_MUS = _K["tan_wedge"], _K["cos_wedge"], _K["mu_column"], _K["mu_slope"]
I_KCTRL, I_F0CTRL, I_X18REF, I_LW = _K["k_ctrl"], _K["F0_ctrl"], _K["x18_ref"], _K["l_wedge"]
I_F0N, I_F0P = _K["F0_nest"], _K["F0_prim"]
I_V, I_GN = _K["V"], _K["g_n"]
I_FCPL, I_MGRADE = _K["F_coupler"], _K["M_pitch_grade"]
I_Q0 = _K["Q0"]
I_SFN, I_SFA, I_KRG, I_XCL = (
    _K["sf_arm_nest"],
    _K["sf_arm_axle"],
    _K["k_roll_gravity"],
    _K["x_coupler_line"],
)
I_WATCH = _K["flange_watch"]
I_IXC, I_IYC, I_IZC, I_IXB, I_IZB = _K["Ix_c"], _K["Iy_c"], _K["Iz_c"], _K["Ix_b"], _K["Iz_b"]
I_IYF = _K["Iy_f"]
I_IZF, I_IXW, I_IZW, I_HB, I_HF = _K["Iz_f"], _K["Ix_w"], _K["Iz_w"], _K["h_cg_b"], _K["h_cg_f"]
I_FROT, I_TWIST, I_TURNW = _K["frame_rotation"], _K["design_twist"], _K["turn_half_window"]
I_SFYL = _K["sf_yaw_levers"]
I_TE0, I_TE1, I_TX0, I_TX1 = (_K[name] for name in L.TURN_SPANS)
I_INV_MC, I_INV_IXC, I_INV_IYC, I_INV_IZC = (
    _K["inv_m_c"], _K["inv_Ix_c"], _K["inv_Iy_c"], _K["inv_Iz_c"]
)  # fmt: skip
I_INV_MB, I_INV_IXB, I_INV_IZB = _K["inv_m_b"], _K["inv_Ix_b"], _K["inv_Iz_b"]
I_INV_MF, I_INV_IYF, I_INV_IZF = _K["inv_m_f"], _K["inv_Iy_f"], _K["inv_Iz_f"]
I_INV_MW, I_INV_IXW, I_INV_IZW = _K["inv_m_w"], _K["inv_Ix_w"], _K["inv_Iz_w"]

BOL0, SF0, WS0 = L.BOL0, L.SF0, L.WS0
NQ = L.N_DOF
AUXW = L.AUX_WEDGE


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def add_frame_forces(acc, i_lat, i_vert, m, kappa, c, s, V, gn):
    """Add the moving frame's pseudo-forces on a body of mass m (N): lateral
    -m (V² κ cos φ + g sin φ); vertical -m (g cos φ - V² κ sin φ) as a deviation from the
    static weight m g already carried by the preloads. c, s: cosine and sine of the cant
    angle φ (each evaluated once per track position, for all bodies there)."""
    acc[i_lat] += -m * (V * V * kappa * c + gn * s)
    acc[i_vert] += -m * (gn * c - V * V * kappa * s) + m * gn


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def in_transition(s, K):
    """Whether track position s lies in a transition (widened: ``layout.TURN_SPANS``), the
    only places where the frame's angular accelerations are not zero."""
    return (K[I_TE0] <= s <= K[I_TE1]) or (K[I_TX0] <= s <= K[I_TX1])


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def frame_pitch_yaw(yaw_dd, kappa, cant_rate, c, s, V):
    """The track-following frame's angular acceleration about a body's pitch (y) and yaw (z)
    axes, rad/s² (revision 2026-12-03.1; docs/model.md, "Transitions"): the frame turns at
    ω = ψ' Z + φ' x (ψ' = V κ about the vertical, φ' the cant rate about x), whose
    components in the canted axes are (φ', ψ' sin φ, ψ' cos φ), so
    dω_y/dt = ψ'' sin φ + ψ' φ' cos φ and dω_z/dt = ψ'' cos φ - ψ' φ' sin φ (``yaw_dd``:
    ψ''; ``c``, ``s``: cos φ and sin φ)."""
    cross = V * kappa * cant_rate
    return yaw_dd * s + cross * c, yaw_dd * c - cross * s


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def add_frame_turn(acc, i_lat, i_roll, i_yaw, m_h, i_x, i_z, roll, yaw):
    """Add the turning frame's pseudo-forces on a body (revision 2026-12-03.1; docs/model.md,
    "Transitions"): its coordinates are taken against a frame whose roll accelerates by
    ``roll`` (rad/s², about the rail-level centreline) and whose yaw, about the body's own
    vertical axis, by ``yaw`` (:func:`frame_pitch_yaw`), so its relative motion carries
    -I_x roll and -I_z yaw, and a centre of gravity H above the rail the lateral m H roll
    (``m_h``) that the frame's roll takes from under it."""
    acc[i_lat] += m_h * roll
    acc[i_roll] -= i_x * roll
    acc[i_yaw] -= i_z * yaw


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def side_frame_roll(x, k):
    """Roll of bogie k's side frames (rad, or its rate from the velocities ``x``): the mean
    of its two wheelsets' roll, on whose axle boxes they sit (wagon [side_frame]
    roll_held_by_axle_boxes; with it off the kernel's arms are zero and this is unused)."""
    iw = WS0 + 8 * k
    return 0.5 * (x[iw + 2] + x[iw + 6])


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
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


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME)
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
    n_trk = trk.shape[1]
    inv_ds = 1.0 / ds  # the track grid's step, once per evaluation
    v_per_ds = V * inv_ds
    wk = out[L.OUT_CONTACT : L.OUT_CONTACT + L.N_CONTACT_WORK]  # contact work (contact_batch)
    # 1.0 where the design track curves: the frames' rotation in the equations (wagon
    # [track] frame_rotation) and the design twist between bodies ([track] design_twist)
    turn = K[I_FROT]
    twist = K[I_TWIST]
    # the window of the frame's roll acceleration, grid cells each side (track_lookup.frame_turn)
    turn_half = max(0.5, K[I_TURNW] * inv_ds)
    flange_rate = -1.0e9  # fastest approach to its flange of a wheel near it (step control)

    # ---- catalogue parameters ----
    m_w = P[0]
    Iy_w = P[2]
    r0 = K[I_R0]
    h_spin = Iy_w * V / r0  # spinning wheelset's angular momentum (spin V / r0 about +y)
    sb_half = 0.5 * P[10]  # X11 side-bearer span
    gib = P[11]  # X12
    k_px = series_stiffness(P[12], P[19])  # X13 + X20
    k_py = series_stiffness(P[13], P[19])  # X14 + X20
    k_pz = P[14]  # X15
    k_sx = P[15]  # X16
    k_sy = P[16]  # X17
    wedge_scale = P[17] / K[I_X18REF]  # X18: wedge normal forces relative to nominal
    l_w = K[I_LW]  # front and rear wedges' longitudinal offset from the nest centre
    k_bar = P[18]  # X19
    h9 = 0.5 * P[8]
    # a side frame's yaw moves a point off its centreline longitudinally: the cross-bracing
    # pins lie X10 / 2 - b2 outboard of it, the axle boxes b1 - b2 (wagon [side_frame]
    # yaw_levers; 0 before revision 2026-12-03.2)
    pin_out = (0.5 * P[9] - b2) * K[I_SFYL]
    box_out = (b1 - b2) * K[I_SFYL]
    bar_len = math.sqrt(P[8] * P[8] + P[9] * P[9])
    ux = P[8] / bar_len
    uy = P[9] / bar_len

    # ---- the eight friction wedges of the four spring nests, together (wedge_batch: SIMD
    # loops; friction_wedges's numbers bit for bit), into the contact work's point blocks,
    # which the contact fills only later; their forces are applied nest by nest below ----
    for n in range(4):
        ib = BOL0 + 4 * (n >> 1)
        side = 1.0 if (n & 1) == 0 else -1.0
        jf = SF0 + 5 * n
        ia = AUXW + L.WEDGE_STATES * n
        v_lat = v[jf + 1] - K[I_SFN] * side_frame_roll(v, n >> 1) - v[ib]
        v_warp = l_w * (v[jf + 4] - v[ib + 3])  # front wedge's lateral slip from warp
        for r in range(2):
            c = WB.BASE + n + WB.NN * r
            wk[c + WB.R_COMP * WB.NL] = q[jf + 2] - (q[ib + 1] + side * b2 * q[ib + 2])
            wk[c + WB.R_VV * WB.NL] = v[jf + 2] - (v[ib + 1] + side * b2 * v[ib + 2])
            wk[c + WB.R_VY * WB.NL] = v_lat + v_warp if r == 0 else v_lat - v_warp
            iz = ia + (L.W_FRONT_Z if r == 0 else L.W_REAR_Z)
            wk[c + WB.R_SZ * WB.NL] = x[iz]
            wk[c + WB.R_SY * WB.NL] = x[iz + 1]
        wk[WB.BASE + n + WB.R_SX * WB.NL] = x[ia + L.W_LONG]
        wk[WB.BASE + n + WB.R_VX * WB.NL] = v[jf] + side * b2 * v[ib + 3]
    wedge_forces(
        wk, K[I_F0CTRL], K[I_KCTRL], K[I_TANW], K[I_COSW], K[I_MUC], K[I_MUS], wedge_scale,
        K[I_KW], K[I_CW],
    )  # fmt: skip
    for n in range(4):
        ia = AUXW + L.WEDGE_STATES * n
        for r in range(2):
            c = WB.BASE + n + WB.NN * r
            iz = ia + (L.W_FRONT_Z if r == 0 else L.W_REAR_Z)
            dxdt[iz] = wk[c + WB.R_DZ * WB.NL]
            dxdt[iz + 1] = wk[c + WB.R_DY * WB.NL]
        dxdt[ia + L.W_LONG] = wk[WB.BASE + n + WB.R_DX * WB.NL]

    # ---- track positions ----
    s_c = s_front - (lc + a)
    i_c, f_c, in_c = track_point(s_c, s0, inv_ds, n_trk)
    kap_c, cant_c, head_c, off_c = track_frame(trk, i_c, f_c)
    cant_rate_c = track_rate(trk, L.TR_CANT, i_c, in_c, v_per_ds)

    # ---- car body pseudo-forces ----
    m_c = K[I_MC]
    cos_c, sin_c = cant_cos_sin(cant_c, 0.0, 1.0, 0.0)
    add_frame_forces(acc, L.CB_Y, L.CB_Z, m_c, kap_c, cos_c, sin_c, V, gn)
    roll_c = 0.0
    if turn != 0.0:  # (the design track curves: on tangent every term is zero)
        ix, iy, iz = K[I_IXC], K[I_IYC], K[I_IZC]
        w_y = V * kap_c * sin_c  # the frame's rates about the car body's axes
        w_z = V * kap_c * cos_c
        # Euler's terms of the frame's rates, -ω x I ω: (I_z - I_y) ψ'² sin φ cos φ in roll
        # on the arc too; in a transition (cant rate w_x), the car body's pitch
        # (I_z - I_x) φ' ψ' cos φ (1.3 kN m at the study's spiral end) and yaw
        acc[L.CB_ROLL] -= w_y * w_z * (iz - iy)
        if in_transition(s_c, K):
            yaw_dd, roll_c = frame_turn(trk, i_c, f_c, in_c, n_trk, V, v_per_ds, turn_half)
            pitch_c, yaw_c = frame_pitch_yaw(yaw_dd, kap_c, cant_rate_c, cos_c, sin_c, V)
            add_frame_turn(
                acc, L.CB_Y, L.CB_ROLL, L.CB_YAW, m_c * K[I_HCG], ix, iz, roll_c, yaw_c
            )  # fmt: skip
            w_x = cant_rate_c
            acc[L.CB_PITCH] += w_x * w_z * (iz - ix) - iy * pitch_c
            acc[L.CB_YAW] -= w_x * w_y * (iy - ix)
    # grade: pitch moment of the net coupler force (at coupler height) and of the bogies'
    # reaction (at centre-plate height); lateral coupler components in curves (chord angle)
    hk = K[I_HCG] - K[I_HK]
    acc[L.CB_PITCH] += K[I_MGRADE]
    # gravity roll moment: the support loads, h below the CG, are h theta off its centreline
    acc[L.CB_ROLL] += K[I_KRG] * q[L.CB_ROLL]
    # the coupler line between like cars is parallel to the tangent halfway between their
    # centres (x_coupler_line: half the length over couplers; the pivot's distance without it)
    f_lat_coupler = K[I_FCPL] * kap_c * K[I_XCL]
    acc[L.CB_Y] += 2.0 * f_lat_coupler
    acc[L.CB_ROLL] += 2.0 * hk * f_lat_coupler

    for k in range(2):
        d = lc if k == 0 else -lc
        s_b = s_c + d
        i_b, f_b, in_b = track_point(s_b, s0, inv_ds, n_trk)
        kap_b, cant_b, head_b, off_b = track_frame(trk, i_b, f_b)
        ib = BOL0 + 4 * k
        m_b = K[I_MB]
        # the side frames roll with the bogie's wheelsets: their nests' lateral forces act
        # arm_n above their CG and their axle boxes' arm_a (< 0: below); g_sf, the generalised
        # force on that roll, goes to the two wheelsets' roll (half each) after the primary
        arm_n = K[I_SFN]
        arm_a = K[I_SFA]
        th_sf = side_frame_roll(q, k)
        om_sf = side_frame_roll(v, k)
        g_sf = 0.0
        cos_b, sin_b = cant_cos_sin(cant_b, cant_c, cos_c, sin_c)
        add_frame_forces(acc, ib, ib + 1, m_b, kap_b, cos_b, sin_b, V, gn)
        cant_rate_b = track_rate(trk, L.TR_CANT, i_b, in_b, v_per_ds)
        roll_b = 0.0
        pitch_b = 0.0
        yaw_b = 0.0
        turning_b = turn != 0.0 and in_transition(s_b, K)
        if turning_b:
            yaw_dd, roll_b = frame_turn(trk, i_b, f_b, in_b, n_trk, V, v_per_ds, turn_half)
            pitch_b, yaw_b = frame_pitch_yaw(yaw_dd, kap_b, cant_rate_b, cos_b, sin_b, V)
            add_frame_turn(
                acc, ib, ib + 2, ib + 3, m_b * K[I_HB], K[I_IXB], K[I_IZB], roll_b, yaw_b
            )  # fmt: skip

        # ===== car body <-> bolster k: centre plate, centre bowl, side bearers =====
        body_on_bolster(
            x, q, v, acc, dxdt, K, k, ib, d, sb_half, V, off_c, head_c, off_b, cant_c, cant_b,
            cant_rate_c, cant_rate_b, kap_c, kap_b,
        )  # fmt: skip

        # ===== bolster <-> side frames (spring nests) =====
        for sidx in range(2):
            side = 1.0 if sidx == 0 else -1.0
            jf = SF0 + 5 * (2 * k + sidx)
            add_frame_forces(acc, jf + 1, jf + 2, K[I_MF], kap_b, cos_b, sin_b, V, gn)
            if turning_b:
                # the frame's roll lifts a side frame side b2 off the centreline; it has no
                # roll of its own to take (it rolls with its wheelsets)
                acc[jf + 1] += K[I_MF] * K[I_HF] * roll_b
                acc[jf + 2] -= K[I_MF] * side * b2 * roll_b
                acc[jf + 3] -= K[I_IYF] * pitch_b
                acc[jf + 4] -= K[I_IZF] * yaw_b
            # vertical nest springs + the nest's two friction wedges, ahead of and behind the
            # bolster end at +-l_w: column friction (vertical and lateral, one friction
            # circle each; their lateral forces' difference makes the warp moment) and slope
            # friction (longitudinal)
            comp = q[jf + 2] - (q[ib + 1] + side * b2 * q[ib + 2])
            f_spring = K[I_F0N] + K[I_KSZ] * comp
            dyn = q[jf + 1] - arm_n * th_sf - q[ib]
            dxn = q[jf] + side * b2 * q[ib + 3]
            vxn = v[jf] + side * b2 * v[ib + 3]
            c = WB.BASE + 2 * k + sidx  # the nest's front wedge, from wedge_forces above
            fy_f = wk[c + WB.R_FY * WB.NL]
            fy_r = wk[c + WB.R_FY * WB.NL + WB.NN]
            f_wz = wk[c + WB.R_FZ * WB.NL] + wk[c + WB.R_FZ * WB.NL + WB.NN]
            f_wy = fy_f + fy_r
            df_wy = fy_f - fy_r
            f_wx = wk[c + WB.R_FX * WB.NL]
            f_up = f_spring - K[I_F0N] + f_wz  # on bolster, deviation from static
            acc[ib + 1] += f_up
            acc[ib + 2] += side * b2 * (f_up + K[I_F0N])
            acc[jf + 2] -= f_up
            # lateral shear [X17], wedge column friction, gib stop [X12]
            f_lat = k_sy * dyn + f_wy + gap_spring(dyn, gib, K[I_KGIB])
            acc[ib] += f_lat
            acc[jf + 1] -= f_lat
            g_sf += arm_n * f_lat  # -f_lat on the frame, arm_n above its CG
            # warp: the front and rear wedges' column friction, l_w (F_front - F_rear), on
            # the bolster's yaw against the side frame's
            m_warp = l_w * df_wy
            acc[ib + 3] += m_warp
            acc[jf + 4] -= m_warp
            # longitudinal shear [X16] and wedge slope friction: the bolster end's
            # longitudinal slip (bolster yaw against side-frame longitudinal motion)
            f_lon = k_sx * dxn + K[I_CSX] * vxn + f_wx
            acc[ib + 3] += -side * b2 * f_lon
            acc[jf] -= f_lon

        # ===== cross-bracing bars between the side frames [X19] =====
        jl = SF0 + 5 * (2 * k)  # the bogie's left and right side frames
        jr = jl + 5
        for bar in range(2):
            e_l = h9 if bar == 0 else -h9  # pin longitudinal offset on the left frame
            e_r = -e_l
            dirx = -ux if bar == 0 else ux  # unit vector from the left to the right pin
            diry = -uy
            # the pins at (e_l, +pin_out) from the left frame's centre, (e_r, -pin_out) from
            # the right one's: a point (e, y) of a frame yawed psi moves by (-y psi, e psi)
            dux = (q[jr] + pin_out * q[jr + 4]) - (q[jl] - pin_out * q[jl + 4])
            duy = (q[jr + 1] + e_r * q[jr + 4]) - (q[jl + 1] + e_l * q[jl + 4])
            t_bar = k_bar * (dirx * dux + diry * duy)
            acc[jl] += t_bar * dirx
            acc[jl + 1] += t_bar * diry
            acc[jl + 4] += t_bar * (e_l * diry - pin_out * dirx)
            acc[jr] -= t_bar * dirx
            acc[jr + 1] -= t_bar * diry
            acc[jr + 4] -= t_bar * (e_r * diry + pin_out * dirx)

        # ===== side frames <-> wheelsets (primary, per axle box) =====
        for wi in range(2):
            w = 2 * k + wi
            e = a if wi == 0 else -a
            s_w = s_b + e
            i_w, f_w, in_w = track_point(s_w, s0, inv_ds, n_trk)
            kap_w, cant_w, head_w, off_w = track_frame(trk, i_w, f_w)
            iw = WS0 + 4 * w
            cos_w, sin_w = cant_cos_sin(cant_w, cant_b, cos_b, sin_b)
            add_frame_forces(acc, iw, iw + 1, m_w, kap_w, cos_w, sin_w, V, gn)
            cant_rate_w = 0.0
            if turn != 0.0 or twist != 0.0:
                cant_rate_w = track_rate(trk, L.TR_CANT, i_w, in_w, v_per_ds)
            if turn != 0.0:
                if in_transition(s_w, K):
                    yaw_dd, roll_w = frame_turn(
                        trk, i_w, f_w, in_w, n_trk, V, v_per_ds, turn_half
                    )  # fmt: skip
                    _, yaw_w = frame_pitch_yaw(yaw_dd, kap_w, cant_rate_w, cos_w, sin_w, V)
                    add_frame_turn(
                        acc, iw, iw + 2, iw + 3, m_w * r0, K[I_IXW], K[I_IZW], roll_w, yaw_w
                    )  # fmt: skip
                # the spinning wheelset turns with its frame too: the gyroscopic moments of
                # the frame's yaw rate V kappa (about the wheelset's vertical) and roll rate
                acc[iw + 2] += h_spin * V * kap_w * cos_w
                acc[iw + 3] -= h_spin * cant_rate_w
            # the design twist: the wheelset's axle boxes are in the frame of the cant at its
            # axle, the side frame's in the bogie centre's (vertical b1, lateral r0 of it)
            tw_w = 0.0
            tw_rate_w = 0.0
            if twist != 0.0:
                tw_w = cant_w - cant_b
                tw_rate_w = cant_rate_w - cant_rate_b
            dev_w = off_w - off_b - e * head_b
            yaw_w_b = q[iw + 3] + head_w - head_b  # wheelset yaw in the bogie frame
            for sidx in range(2):
                side = 1.0 if sidx == 0 else -1.0
                jf = SF0 + 5 * (2 * k + sidx)
                # longitudinal [X13 in series with X20]
                # (the side frame's point at the axle box, side box_out off its centreline)
                dx_p = q[jf] - side * box_out * q[jf + 4] + side * b1 * yaw_w_b
                dvx = (
                    v[jf]
                    - side * box_out * v[jf + 4]
                    + side * b1 * (v[iw + 3] + V * (kap_w - kap_b))
                )
                f_x = k_px * dx_p + K[I_CPX] * dvx  # on wheelset box, x
                acc[iw + 3] += -side * b1 * f_x
                acc[jf] -= f_x
                acc[jf + 4] += side * box_out * f_x
                # lateral [X14 in series with X20]
                dy_p = q[jf + 1] + e * (q[jf + 4]) - arm_a * th_sf - dev_w - (q[iw] - r0 * tw_w)
                dvy = v[jf + 1] + e * v[jf + 4] - arm_a * om_sf - (v[iw] - r0 * tw_rate_w)
                f_y = k_py * dy_p + K[I_CPY] * dvy  # on wheelset
                acc[iw] += f_y
                acc[jf + 1] -= f_y
                acc[jf + 4] -= e * f_y
                g_sf += arm_a * f_y
                # vertical [X15]
                dz_p = (q[iw + 1] + side * b1 * (q[iw + 2] + tw_w)) - (q[jf + 2] - e * q[jf + 3])
                dvz = (v[iw + 1] + side * b1 * (v[iw + 2] + tw_rate_w)) - (
                    v[jf + 2] - e * v[jf + 3]
                )
                f_z = k_pz * dz_p + K[I_CPZ] * dvz  # deviation of the upward force on frame
                acc[jf + 2] += f_z
                acc[jf + 3] += -e * (f_z + K[I_F0P])
                acc[iw + 1] -= f_z
                acc[iw + 2] -= side * b1 * (f_z + K[I_F0P])

            # ---- wheel-rail contact: the rails under the wheelset, for the eight wheels'
            # contacts evaluated together after both bogies (contact_batch) ----
            for sidx in range(2):
                c = 2 * w + sidx
                left = sidx == 0
                wk[CB.W_KAPPA * CB.NW + c] = kap_w
                wk[CB.W_RY * CB.NW + c] = track_value(trk, L.TR_YL if left else L.TR_YR, i_w, f_w)
                wk[CB.W_RZ * CB.NW + c] = track_value(trk, L.TR_ZL if left else L.TR_ZR, i_w, f_w)
                wk[CB.W_RVY * CB.NW + c] = track_rate(
                    trk, L.TR_YL if left else L.TR_YR, i_w, in_w, v_per_ds
                )
                wk[CB.W_RVZ * CB.NW + c] = track_rate(
                    trk, L.TR_ZL if left else L.TR_ZR, i_w, in_w, v_per_ds
                )
        # the side frames' roll couple on the wheelsets they sit on
        iw0 = WS0 + 8 * k
        acc[iw0 + 2] += 0.5 * g_sf
        acc[iw0 + 6] += 0.5 * g_sf

    # ---- wheel-rail contact forces (the eight wheels together) ----
    contact_forces_8(x, ctab, y0, dy, H0L, H0R, K, wk)
    for w in range(4):
        iw = WS0 + 4 * w
        for sidx in range(2):
            c = 2 * w + sidx
            side = 1.0 if sidx == 0 else -1.0
            code = int(wk[CB.W_CODE * CB.NW + c])
            if code != 0:
                return code
            shift = side * (q[iw] + r0 * q[iw + 2] - wk[CB.W_RY * CB.NW + c])
            if shift > K[I_WATCH]:
                shift_rate = side * (v[iw] + r0 * v[iw + 2] - wk[CB.W_RVY * CB.NW + c])
                flange_rate = max(flange_rate, shift_rate)
            f_yw = wk[CB.W_FY * CB.NW + c]
            f_zw = wk[CB.W_FZ * CB.NW + c]
            acc[iw] += f_yw
            acc[iw + 1] += f_zw - K[I_Q0]
            acc[iw + 2] += wk[CB.W_MX * CB.NW + c]
            acc[iw + 3] += wk[CB.W_MZ * CB.NW + c]
            # outputs: force on the rail; Y + outward (field side), Q + down
            out[L.OUT_Y + c] = -side * f_yw
            out[L.OUT_Q + c] = f_zw
        # gyroscopic coupling of the spinning wheelset
        acc[iw + 2] += h_spin * v[iw + 3]
        acc[iw + 3] -= h_spin * v[iw + 2]

    # ---- divide by inertia (multiplied by the reciprocals in K) ----
    acc[L.CB_Y] *= K[I_INV_MC]
    acc[L.CB_Z] *= K[I_INV_MC]
    acc[L.CB_ROLL] *= K[I_INV_IXC]
    acc[L.CB_PITCH] *= K[I_INV_IYC]
    acc[L.CB_YAW] *= K[I_INV_IZC]
    for k in range(2):
        ib = BOL0 + 4 * k
        acc[ib] *= K[I_INV_MB]
        acc[ib + 1] *= K[I_INV_MB]
        acc[ib + 2] *= K[I_INV_IXB]
        acc[ib + 3] *= K[I_INV_IZB]
    for j in range(4):
        jf = SF0 + 5 * j
        acc[jf] *= K[I_INV_MF]
        acc[jf + 1] *= K[I_INV_MF]
        acc[jf + 2] *= K[I_INV_MF]
        acc[jf + 3] *= K[I_INV_IYF]
        acc[jf + 4] *= K[I_INV_IZF]
    for w in range(4):
        iw = WS0 + 4 * w
        acc[iw] *= K[I_INV_MW]
        acc[iw + 1] *= K[I_INV_MW]
        acc[iw + 2] *= K[I_INV_IXW]
        acc[iw + 3] *= K[I_INV_IZW]
    # the accelerometer reads the specific force: the frame's lateral terms taken back off
    out[L.OUT_ACC_Y] = acc[L.CB_Y] + V * V * kap_c * cos_c + gn * sin_c - K[I_HCG] * roll_c
    out[L.OUT_ACC_Z] = acc[L.CB_Z]
    out[L.OUT_FLANGE_RATE] = flange_rate
    return L.OK
