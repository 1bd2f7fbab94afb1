"""The car body on one bolster: centre plate, centre bowl and side bearers (a kernel of the
equations of motion, :func:`railsusp.vehicle.model.rhs`, inlined there).

Per bogie, between the car body and its bolster (docs/model.md, "Centre bowl and side
bearers"):

* the centre plate's lateral spring (the bowl rim), at centre-plate height;
* the centre bowl as a ring of compression-only contact points
  (:func:`~railsusp.vehicle.suspension.bowl_ring_forces`): vertical force, roll and pitch
  moments up to edge lift-off, roll friction. The bolster pitches in its two side frames'
  windows, so the car body's pitch is taken against their mean pitch and the pitch moment's
  reaction goes to them, half each, with the bolster's pitch restraint (k/2 per window)
  between the two frames and the bogie's own pitch moment on a grade shared between them
  (force-law revision 2026-12-02.1; with the wagon switches of
  ``FORCE_LAWS_BEFORE_2026_12_02_1`` the pitch is taken against the track, as before);
* two constant-contact side bearers at +- X11/2 with their loss, lift-off and a solid stop
  after their travel;
* the body-bolster yaw friction of bowl and side bearers, an elasto-plastic slider.
"""

from __future__ import annotations

import numba as nb

from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)
from railsusp.vehicle.suspension import bowl_ring_forces, damped_slider, disc_friction_moment

_K = L.K

# numba sees module-level ints as compile-time constants
I_HCG, I_HCP, I_HB, I_RCP = _K["h_cg_c"], _K["h_cp"], _K["h_cg_b"], _K["R_cp"]
I_KCPZ, I_KCPY, I_MUCP, I_KYAW = _K["k_cpz"], _K["k_cpy"], _K["mu_cp"], _K["k_yaw"]
I_CYAW, I_KROLL, I_CROLL = _K["c_yaw"], _K["k_roll"], _K["c_roll"]
I_KCPB, I_KCPP, I_F0CP = _K["k_cpb"], _K["k_cpp"], _K["F0_cp"]
I_KSB, I_PSB, I_MUSB = _K["k_sb"], _K["P_sb"], _K["mu_sb"]
I_SBTRAVEL, I_KSBSTOP, I_CSB = _K["sb_travel"], _K["k_sb_stop"], _K["c_sb"]
I_MGRADEF, I_BOWLPF = _K["M_pitch_grade_frame"], _K["bowl_pitch_on_frames"]
I_TWIST = _K["design_twist"]

SF0 = L.SF0
AUXY, AUXR = L.AUX_YAWFR, L.AUX_ROLLFR


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def body_on_bolster(
    x, q, v, acc, dxdt, K, k, ib, d, sb_half, V, off_c, head_c, off_b, cant_c, cant_b,
    cant_rate_c, cant_rate_b, kap_c, kap_b,
):  # fmt: skip
    """Add the forces between the car body and bolster ``k`` (state index ``ib``, its
    centre ``d`` ahead of the car body's) to the generalised forces ``acc``, with the
    bowl's roll friction and the yaw friction's states' rates into ``dxdt``.

    ``off_c``, ``head_c``, ``off_b``: the track's lateral offset and heading at the car
    body and its offset at the bolster; ``cant_c``, ``cant_b``: the cant at the car body and
    at the bolster, ``cant_rate_c``, ``cant_rate_b`` its rates there; ``kap_c``, ``kap_b``:
    the curvatures there.
    """
    hcp = K[I_HCG] - K[I_HCP]  # the car body's centre-plate point below its CG
    dev = off_b - off_c - d * head_c  # lateral offset of the track at s_b from the chord
    roll_c_b = q[L.CB_ROLL] + cant_c - cant_b  # car roll seen in the bolster frame
    # centre plate, lateral (bowl); the car body's frame is rolled by cant_c - cant_b against
    # the bolster's, which moves its centre plate, h_cp above the rail, across by
    # -h_cp (cant_c - cant_b) (the design twist's lateral part: wagon [track] design_twist)
    y_cp_car = q[L.CB_Y] + d * q[L.CB_YAW] - dev + hcp * q[L.CB_ROLL]
    if K[I_TWIST] != 0.0:
        y_cp_car -= K[I_HCP] * (cant_c - cant_b)
    h_bcp = K[I_HCP] - K[I_HB]
    y_cp_bol = q[ib] - h_bcp * q[ib + 2]
    f_cpy = K[I_KCPY] * (y_cp_car - y_cp_bol)  # on bolster (+), on car (-)
    acc[ib] += f_cpy
    acc[ib + 2] += -h_bcp * f_cpy
    acc[L.CB_Y] -= f_cpy
    acc[L.CB_ROLL] -= hcp * f_cpy
    acc[L.CB_YAW] -= d * f_cpy
    # centre bowl: ring of contact points with edge lift-off (vertical, roll, pitch) on
    # the bolster's quasi-static bending and pitch restraint, and roll friction; the
    # bolster pitches in the two side frames' windows, so the car body's pitch is taken
    # against their mean pitch and the pitch moment's reaction goes to them, half each
    z_car = q[L.CB_Z] - d * q[L.CB_PITCH]
    jl = SF0 + 5 * (2 * k)
    jr = jl + 5
    pitch_frames = K[I_BOWLPF] * 0.5 * (q[jl + 3] + q[jr + 3])
    roll_rate_b_c = v[ib + 2] - v[L.CB_ROLL] - cant_rate_c
    roll_rate_b_c += cant_rate_b
    n_cp, m_roll, m_pitch, m_rfr = bowl_ring_forces(
        q[ib + 1] - z_car, roll_c_b - q[ib + 2], q[L.CB_PITCH] - pitch_frames,
        -roll_rate_b_c, K[I_RCP],
        K[I_KCPZ], K[I_KCPB], K[I_KCPP], K[I_F0CP], K[I_MUCP], K[I_KROLL], K[I_CROLL],
        x[AUXR + k], dxdt, AUXR + k,
    )  # fmt: skip
    acc[L.CB_Z] += n_cp - K[I_F0CP]
    acc[L.CB_PITCH] += -d * (n_cp - K[I_F0CP]) + m_pitch
    acc[L.CB_ROLL] += m_roll + m_rfr
    acc[ib + 1] -= n_cp - K[I_F0CP]
    acc[ib + 2] -= m_roll + m_rfr
    # on each side frame's pitch: half the bowl's reaction, its share of the bogie's
    # moment on a grade, and the restraint's k_pp / 2 in its window against the
    # bolster, which pitches with the two frames' mean (energy k_pp (th_l - th_r)^2 / 8)
    m_frame = K[I_MGRADEF] - K[I_BOWLPF] * 0.5 * m_pitch
    m_anti = K[I_BOWLPF] * 0.25 * K[I_KCPP] * (q[jr + 3] - q[jl + 3])
    acc[jl + 3] += m_frame + m_anti
    acc[jr + 3] += m_frame - m_anti
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
