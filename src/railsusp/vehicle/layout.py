"""Index layout shared by the model kernels and the simulation driver.

Degrees of freedom (49), all deviations from static equilibrium, each body in the
track-following frame at its own position along the track (x forward, y left, z up; angles
right-handed: roll about x, pitch about y, yaw about z):

* car body: y, z, roll, pitch, yaw (5)
* bolster k = 0 (front), 1 (rear): y, z, roll, yaw (4 each)
* side frame j = 2k + (0 left, 1 right): x, y, z, pitch, yaw (5 each)
* wheelset w = 0..3 front to rear: y, z, roll, yaw (4 each)

Auxiliary first-order states (24): per spring nest n = 2k + side (5 each, 20), the column
friction forces of its front wedge (ahead of the bolster end), vertical and lateral, those of
its rear wedge, vertical and lateral, and the friction force of the pair's bolster slope faces
against longitudinal slip; the car-body/bolster yaw friction moment of each bogie (2); the
centre-bowl roll friction moment of each bogie (2). The front and rear wedges' lateral
friction forces differ when the bolster yaws relative to the side frame (warp): their
difference times the wedges' half spacing is the wedges' warp moment.
"""

from __future__ import annotations

N_DOF = 49
#: auxiliary states per spring nest (its wedges' friction forces) and their offsets from the
#: nest's first one
WEDGE_STATES = 5
W_FRONT_Z, W_FRONT_Y, W_REAR_Z, W_REAR_Y, W_LONG = range(WEDGE_STATES)
N_WEDGE_AUX = 4 * WEDGE_STATES
N_AUX = N_WEDGE_AUX + 4
N_STATE = 2 * N_DOF + N_AUX

# car body
CB_Y, CB_Z, CB_ROLL, CB_PITCH, CB_YAW = 0, 1, 2, 3, 4
# bolster k: base + (0 y, 1 z, 2 roll, 3 yaw)
BOL0 = 5
# side frame j: base + (0 x, 1 y, 2 z, 3 pitch, 4 yaw)
SF0 = 13
# wheelset w: base + (0 y, 1 z, 2 roll, 3 yaw)
WS0 = 33
# auxiliary states (offset into the full state vector)
AUX_WEDGE = 2 * N_DOF  # nest n: + WEDGE_STATES n + W_*, N
AUX_YAWFR = AUX_WEDGE + N_WEDGE_AUX  # 2 body-bolster yaw friction moments, N m
AUX_ROLLFR = AUX_YAWFR + 2  # 2 centre-bowl roll friction moments, N m

# ---- constants vector (wagon + condition), K[...] ----
#: the masses and inertias the right-hand side divides the generalised forces by (each has
#: its reciprocal ``inv_<name>`` in K too); the wheelset's pitch inertia Iy_w is no divisor
INERTIAS = ("m_c", "Ix_c", "Iy_c", "Iz_c", "m_b", "Ix_b", "Iz_b", "m_f", "Iy_f", "Iz_f",
            "m_w", "Ix_w", "Iz_w")  # fmt: skip
_K_NAMES = (
    # masses and inertias
    "m_c", "Ix_c", "Iy_c", "Iz_c", "m_b", "Ix_b", "Iz_b", "m_f", "Iy_f", "Iz_f",
    "m_w", "Ix_w", "Iy_w", "Iz_w",
    # geometry
    "l_c", "a", "b1", "b2", "r0", "h_cg_c", "h_cp", "h_cg_b", "h_k", "x_k", "R_cp",
    # the side frame's roll with its wheelsets (wagon [side_frame] roll_held_by_axle_boxes;
    # both 0 without): the heights of the bolster's and the axles' lateral forces above the
    # side frame's centre of gravity, m
    "sf_arm_nest", "sf_arm_axle",
    # 1.0: the cross-bracing pins' and the axle boxes' lateral offsets from the side frame's
    # centreline are levers of its yaw (wagon [side_frame] yaw_levers; 0.0: their motion
    # taken at the centreline, before revision 2026-12-03.2)
    "sf_yaw_levers",
    # the car body's gravity (P-delta) roll moment per radian of roll, W h (N m/rad; W its
    # static support load, h its CG's height above the centre plate; 0 without, wagon
    # [car_body] gravity_roll_moment); the coupler line's angle per unit curvature, m
    "k_roll_gravity", "x_coupler_line",
    # fixed elements
    "c_px", "c_py", "c_pz", "k_sz", "c_sx", "k_gib",
    # friction wedges, per nest: tan(wedge angle), cos, column and slope friction, control
    # springs (all wedges of the nest) and their static force, stick stiffness and damping
    # (all wedges of the nest), X18 nominal (the wedge normal forces scale with X18 / X18
    # nominal), the front and rear wedges' longitudinal offset from the nest centre (m)
    "tan_wedge", "cos_wedge", "mu_column", "mu_slope", "k_ctrl", "F0_ctrl",
    "k_wedge", "c_wedge", "x18_ref", "l_wedge",
    # centre bowl: its ring's stiffness (liner and rim), the bolster's bending under it and
    # the bolster's pitch restraint in the side-frame windows (quasi-static, suspension.py)
    "k_cpz", "k_cpb", "k_cpp", "k_cpy", "mu_cp", "k_yaw", "c_yaw", "k_roll", "c_roll",
    "k_sb", "c_sb", "P_sb", "mu_sb", "sb_travel", "k_sb_stop",
    # 1.0: the bowl's pitch moment is the car body's pitch against its bogie's side frames and
    # its reaction reaches them (wagon [centre_plate] pitch_reaction_on_side_frames); 0.0:
    # against the track, with no reaction (before revision 2026-12-02.1)
    "bowl_pitch_on_frames",
    "k_rz", "k_ry", "c_rz", "c_ry",
    # 1.0: the rail damping's push capped at the Hertz force (wagon [track]
    # rail_damping_capped); 0.0: the damper in parallel (before revision 2026-11-30.2)
    "rail_damping_cap",
    # 1.0: the track-following frames' rotation in the bodies' equations, their yaw and roll
    # accelerations in transitions and their rates in the wheelsets' gyroscopic moments
    # (wagon [track] frame_rotation); 1.0: the design twist between connected bodies' frames
    # in the primary's deflections and the centre plate's lateral one (wagon [track]
    # design_twist); 0.0:
    # left out (before revision 2026-12-03.1), or a condition without a curve, where both
    # are zero (skipped: 3-10 % of an evaluation on tangent); the side frame's CG above rail
    # top, m; the half-width over which the frame's roll acceleration at a cant ramp's end
    # is spread, at least the integration step's run V max_step (m: less than the grid's
    # half cell, which is used then, on the default grid below 225 km/h)
    "frame_rotation", "design_twist", "h_cg_f", "turn_half_window",
    # the track positions (m) of the entry and the exit transition, widened (TURN_SPANS:
    # outside them the frame turns at a constant rate, its accelerations are not evaluated)
    "turn_entry_from", "turn_entry_to", "turn_exit_from", "turn_exit_to",
    # static preloads, N
    "F0_cp", "F0_nest", "F0_prim", "Q0", "Z0_L", "Z0_R", "N_ref",
    # condition
    "V", "g_n", "mu", "F_coupler", "M_pitch_grade", "creep_factor",
    # on a grade, each side frame's share of its bogie's pitch moment (the car body's pull at
    # the centre plate, the bogie's own grade components at their centres of gravity), N m;
    # 0 without (wagon [bogie] grade_pitch_moment)
    "M_pitch_grade_frame",
    # limits for the non-physical state check
    "pen_max", "lift_max",
    # step control: a wheel shifted towards its flange beyond this (m) and moving towards it
    # faster than this (m/s) takes fine steps
    "flange_watch", "flange_split_speed",
    # contact points per wheel: 1 (tread table only) or 2 (tread and flange tables)
    "contact_points",
    # yaw-aware contact (wagon [contact] yaw_geometry): 1.0 on, 0.0 the zero-yaw contact
    "yaw_geometry",
    # reciprocals the contact kernel multiplies by (a division costs several multiplications):
    # 1/V, 1/r0 and the rail support compliances 1/k_ry, 1/k_rz
    "inv_V", "inv_r0", "inv_k_ry", "inv_k_rz",
    # the bodies' reciprocal masses and inertias (INERTIAS): the generalised forces are
    # multiplied by these rather than divided by the inertias (eighteen divisions an
    # evaluation, 0-3 % of it measured at stop 78; issue 24)
    *(f"inv_{name}" for name in INERTIAS),
)  # fmt: skip
K = {name: i for i, name in enumerate(_K_NAMES)}
TURN_SPANS = ("turn_entry_from", "turn_entry_to", "turn_exit_from", "turn_exit_to")
N_K = len(_K_NAMES)

# ---- contact table columns, per wheel and contact point ----
# blocks of CT_PER_WHEEL rows: tread left, tread right, flange left, flange right
# CT_LEAD: the contact point's longitudinal lead per radian of wheelset yaw, r tan(delta) (m;
# 0 everywhere for the zero-yaw contact model, wagon [contact] yaw_geometry = false)
CT_R, CT_DELTA, CT_L, CT_H, CT_G, CT_F11, CT_F22, CT_F23, CT_LEAD = range(9)
CT_PER_WHEEL = 9
CT_RIGHT = CT_PER_WHEEL
CT_FLANGE = 2 * CT_PER_WHEEL  # offset of the flange contact's blocks
N_CT = 4 * CT_PER_WHEEL

# ---- track channels ----
TR_KAPPA, TR_CANT, TR_HEAD, TR_OFFSET, TR_ZL, TR_ZR, TR_YL, TR_YR = range(8)
N_TR = 8

# ---- output channels ----
OUT_Y = 0  # 8 wheels: wheelset w, left (2w) / right (2w + 1): lateral force on rail, + outward
OUT_Q = 8  # 8 wheels: vertical force on rail, + down
OUT_ACC_Y = 16  # car body lateral acceleration at CG (uncompensated), m/s^2
OUT_ACC_Z = 17  # car body vertical acceleration at CG, m/s^2
N_OUT = 18
#: working channel after the stored ones, read by the integrator's step control, not stored:
#: the fastest approach to its own flange (m/s) of the wheels within the watch distance of
#: it (-1e9 when none is)
OUT_FLANGE_RATE = N_OUT
#: then the eight wheels' contact work vector (railsusp.vehicle.contact_batch), so that the
#: right-hand side allocates nothing
OUT_CONTACT = N_OUT + 1
N_CONTACT_WORK = 65 * 8
N_OUT_WORK = OUT_CONTACT + N_CONTACT_WORK

#: wheel names, output order: wheelset w1 (leading) .. w4, left / right in the running direction
WHEEL_NAMES = tuple(f"w{w + 1}{side}" for w in range(4) for side in ("L", "R"))

# ---- failure codes ----
OK = 0
FAIL_NAN = 1
FAIL_PENETRATION = 2
FAIL_LIFT = 3
FAIL_FLANGE_CLIMB = 4
#: what a set's status starts as before the integrator's call, so that a set whose compiled
#: integration stopped without writing its code (an error inside the parallel loop, which
#: Numba does not pass on: the set and those after it on the same thread) reads as failed,
#: not as a success with empty series (the review of stop 76)
FAIL_UNFINISHED = 5
FAILURE_REASONS = {
    OK: "ok",
    FAIL_NAN: "state became NaN or infinite (numerical divergence)",
    FAIL_PENETRATION: "wheel-rail penetration beyond the physical bound",
    FAIL_LIFT: "wheel lift beyond the flange height (derailment)",
    FAIL_FLANGE_CLIMB: "wheelset lateral shift beyond the contact table (flange climb)",
    FAIL_UNFINISHED: (
        "the compiled integration stopped without a result (an error inside it, e.g. a "
        "division by a zero mass or span, in this set or one before it on the same thread)"
    ),
}

# catalogue indices (X1..X20 -> 0..19)
P_X = {f"X{i}": i - 1 for i in range(1, 21)}
