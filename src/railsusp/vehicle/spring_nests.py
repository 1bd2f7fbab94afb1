"""The bogie's secondary suspension: spring nests with their friction wedges, cross-bracing.

Compiled pieces of the right-hand side (:func:`railsusp.vehicle.model.rhs`, inlined there:
the same operations in the same order, so the same numbers bit for bit), for bogie k:

* each side's spring nest between the bolster end and the side frame: vertical springs
  (control springs included), the two friction wedges' forces already computed for all
  eight wedges together (:mod:`railsusp.vehicle.wedge_batch`, read from the work vector
  ``wk``: column friction vertical and lateral, their front-rear difference the warp
  moment, slope friction longitudinal), longitudinal [X16] and lateral [X17] shear, and the
  bolster gib stop beyond its clearance [X12];
* the two diagonal cross-bracing bars between the side frames [X19], pinned X9 apart
  longitudinally and X10 laterally: the warp (parallelogram) stiffness beside the wedges'
  warp friction.
"""

from __future__ import annotations

import numba as nb

from railsusp.vehicle import layout as L
from railsusp.vehicle import wedge_batch as WB
from railsusp.vehicle.kernel_cache import FASTMATH  # (sets the kernel cache before any compiles)
from railsusp.vehicle.suspension import gap_spring

_K = L.K

# numba sees module-level ints as compile-time constants
I_F0N, I_KSZ, I_KGIB, I_CSX = _K["F0_nest"], _K["k_sz"], _K["k_gib"], _K["c_sx"]
BOL0, SF0 = L.BOL0, L.SF0


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def spring_nest_forces(acc, q, v, K, wk, k, b2, l_w, arm_n, th_sf, k_sx, k_sy, gib):
    """Add the forces of bogie k's two spring nests between bolster and side frames to
    ``acc`` (module docstring); returns the generalised force their lateral forces put on
    the side frames' roll (``arm_n`` above their CG, ``th_sf`` their roll).

    ``q``, ``v``: positions and velocities; ``wk``: the work vector holding the wedges'
    forces; ``b2`` half the nests' lateral span; ``l_w`` the wedges' offset ahead of and
    behind the nest centre; ``k_sx``, ``k_sy`` the nest's shear stiffnesses [X16, X17];
    ``gib`` the gib clearance [X12].
    """
    ib = BOL0 + 4 * k
    g_sf = 0.0
    for sidx in range(2):
        side = 1.0 if sidx == 0 else -1.0
        jf = SF0 + 5 * (2 * k + sidx)
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
    return g_sf


@nb.njit(cache=True, fastmath=FASTMATH, inline="always")
def cross_bracing_forces(acc, q, k, k_bar, h9, ux, uy):
    """Add the axial forces of bogie k's two diagonal cross-bracing bars to its side frames'
    generalised forces ``acc`` (module docstring): ``k_bar`` their axial stiffness [X19],
    ``h9`` half the pins' longitudinal span [X9 / 2], (``ux``, ``uy``) the unit vector along
    a bar in plan (from X9 and X10)."""
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
