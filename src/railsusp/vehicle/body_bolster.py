"""The car body on bolster k: centre bowl, side bearers, and their yaw friction.

One compiled piece of the right-hand side (:func:`railsusp.vehicle.model.rhs`, inlined there:
the same operations in the same order, so the same numbers bit for bit), for one bogie:

* the centre bowl's rim laterally (a spring between the car's centre-plate point, ``h_cp``
  below its CG, and the bolster's), and the bowl as a ring of compression-only contact points
  (:func:`~railsusp.vehicle.suspension.bowl_ring_forces`: vertical force, roll and pitch
  moments up to edge lift-off, roll friction);
* two constant-contact side bearers at +- X11/2: elastomer preload, stiffness and loss,
  lift-off, and a solid stop after their travel;
* the body-bolster yaw friction of bowl and side bearers together, an elasto-plastic slider
  whose limit is the bowl's disc friction moment plus the bearers' (docs/model.md).

Forces are added to the generalised forces ``acc`` of the car body and bolster k; the roll and
yaw friction states' rates go to ``dxdt``.
"""

from __future__ import annotations

import numba as nb

from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH  # (sets the kernel cache before any compiles)
from railsusp.vehicle.suspension import bowl_ring_forces, damped_slider, disc_friction_moment

_K = L.K

# numba sees module-level ints as compile-time constants
I_HCP, I_HB, I_RCP = _K["h_cp"], _K["h_cg_b"], _K["R_cp"]
I_KCPZ, I_KCPY, I_MUCP, I_KYAW = _K["k_cpz"], _K["k_cpy"], _K["mu_cp"], _K["k_yaw"]
I_CYAW, I_KROLL, I_CROLL = _K["c_yaw"], _K["k_roll"], _K["c_roll"]
I_KCPB, I_KCPP, I_F0CP = _K["k_cpb"], _K["k_cpp"], _K["F0_cp"]
I_KSB, I_PSB, I_MUSB = _K["k_sb"], _K["P_sb"], _K["mu_sb"]
I_SBTRAVEL, I_KSBSTOP, I_CSB = _K["sb_travel"], _K["k_sb_stop"], _K["c_sb"]
AUXY, AUXR = L.AUX_YAWFR, L.AUX_ROLLFR


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def body_bolster_forces(
    acc, dxdt, x, K, k, d, off_c, head_c, cant_c, cant_rate_c, kap_c, off_b, cant_b,
    cant_rate_b, kap_b, V, hcp, sb_half,
):  # fmt: skip
    """Add the forces between the car body and bolster k (module docstring) to ``acc``.

    ``x``: the state (positions, then velocities); ``d``: the bolster's distance ahead of the
    car's centre (m); the car's track frame at its centre (``off_c`` lateral offset from the
    chord, ``head_c`` heading, ``cant_c``, ``cant_rate_c``, ``kap_c`` curvature) and the
    bolster's (``off_b``, ``cant_b``, ``cant_rate_b``, ``kap_b``); ``V`` the speed; ``hcp``
    the centre plate's depth below the car's CG; ``sb_half`` half the side bearers' span.
    """
    q = x[: L.N_DOF]
    v = x[L.N_DOF : 2 * L.N_DOF]
    ib = L.BOL0 + 4 * k
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
    # centre bowl: ring of contact points with edge lift-off (vertical, roll, pitch) on
    # the bolster's quasi-static bending and pitch restraint, and roll friction
    z_car = q[L.CB_Z] - d * q[L.CB_PITCH]
    roll_rate_b_c = v[ib + 2] - v[L.CB_ROLL] - cant_rate_c
    roll_rate_b_c += cant_rate_b
    n_cp, m_roll, m_pitch, m_rfr = bowl_ring_forces(
        q[ib + 1] - z_car, roll_c_b - q[ib + 2], q[L.CB_PITCH], -roll_rate_b_c, K[I_RCP],
        K[I_KCPZ], K[I_KCPB], K[I_KCPP], K[I_F0CP], K[I_MUCP], K[I_KROLL], K[I_CROLL],
        x[AUXR + k], dxdt, AUXR + k,
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
