"""Where a mode's energy goes: the damping ratio of one linearised mode split over the force
elements that dissipate it.

For a mode x(t) = Re(φ e^{λt}) of the linearised wagon (:mod:`railsusp.vehicle.modes`) every
viscous element c (a damper, or the stick damping of a stuck friction slider) with relative
velocity amplitude u dissipates on average P = c |u|² / 2. The mode's mean mechanical energy
is twice its mean kinetic energy, E = Σ m |v|² / 2 (v = λ q, kinetic and potential energy
equal on average for light damping), and the energy decays as e^{2σt} with σ = -ζ |λ|, so
each element's share of the damping ratio is ζ_e = P_e / (2 |λ| E) and the shares add up to
ζ. The suspension's elements are evaluated from their relative velocities (the kinematics of
``model.rhs`` on straight, level track). The wheel-rail contact (creep forces and the rail
support's damping) is the negative mean power of the contact forces on the wheelsets, whose
linearised values are the wheelsets' rows of the state matrix less the primary suspension's
forces (the gyroscopic moments do no work). Their sum is checked against the eigenvalue's ζ
(``residual``): a missing element or a wrong lever shows there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from railsusp.vehicle import layout as L
from railsusp.vehicle.modes import ModalResult
from railsusp.vehicle.operating_point import LinearisationPoint
from railsusp.vehicle.suspension import series_stiffness

#: the elements, in the order they are reported
ELEMENTS: tuple[str, ...] = (
    "centre bowl ring (elastic)",
    "centre bowl roll friction (stick damping)",
    "body-bolster yaw friction (stick damping)",
    "side bearers (elastomer loss)",
    "wedges, vertical (stick damping)",
    "wedges, lateral (stick damping)",
    "wedges, warp (column faces, stick damping)",
    "wedges, longitudinal (slope faces, stick damping)",
    "secondary longitudinal damping",
    "primary pads, longitudinal",
    "primary pads, lateral",
    "primary pads, vertical",
    "wheel-rail (creep and rail support damping)",
)


#: the damping ratio up to which a mode's shares are its damping split over the elements:
#: the split takes the mean potential energy equal to the kinetic, as for light damping. At
#: 60 km/h (loaded, stuck) the modes up to ζ 0.31 sum to 0.90-1.03 ζ; the car body's
#: kinematic mode of ζ 0.50 to 1.8 ζ, the wheelsets' of ζ 0.89 to 17 ζ
LIGHT_DAMPING_ZETA = 0.35
#: the largest ``residual`` (a share of ζ) at which the shares are taken as the split
RESIDUAL_SHARE = 0.1


@dataclass
class ModeDissipation:
    """Damping ratio of one mode per element (``shares``, summing to ``total``) beside the
    eigenvalue's damping ratio ``zeta``; ``residual`` = total - zeta; ``meaningful``
    whether the shares are that split (a lightly damped mode whose shares sum to its ζ)."""

    mode: str
    frequency_hz: float
    zeta: float
    shares: dict[str, float]

    @property
    def total(self) -> float:
        return float(sum(self.shares.values()))

    @property
    def residual(self) -> float:
        return self.total - self.zeta

    @property
    def meaningful(self) -> bool:
        """The shares split the mode's damping: ζ at most :data:`LIGHT_DAMPING_ZETA` and
        the shares' sum within :data:`RESIDUAL_SHARE` of ζ. A heavily damped mode's shares
        (an overdamped side frame's add to 2-3 ζ) are not read as a split."""
        return self.zeta <= LIGHT_DAMPING_ZETA and abs(self.residual) <= RESIDUAL_SHARE * self.zeta


def mode_dissipation(result: ModalResult, point: LinearisationPoint, mode: int) -> ModeDissipation:
    """Split mode ``mode`` of ``result`` (linearised at ``point``) over the elements."""
    lam = complex(result.eigenvalues[mode])
    q = np.asarray(result.shapes[mode], dtype=complex)
    v = lam * q
    K, P = point.K, point.P
    k = L.K
    m = point.dof_inertia()
    w = abs(lam)
    energy = 0.5 * float(np.sum(m * np.abs(v) ** 2))  # mean mechanical energy E
    power = dict.fromkeys(ELEMENTS, 0.0)

    def add(name: str, c: float, u: complex) -> None:
        power[name] += 0.5 * c * abs(u) ** 2

    # the stick damping acts while a slider sticks; at zero limits (the sliding variant) the
    # sliders pass no force at all
    stick = 0.0 if point.friction == "sliding" else 1.0

    lc, a = K[k["l_c"]], K[k["a"]]
    b1, b2 = K[k["b1"]], K[k["b2"]]
    c_wedge, l_w = K[k["c_wedge"]], K[k["l_wedge"]]
    sb_half = 0.5 * P[10]
    # the side frames roll with their wheelsets (model.side_frame_roll; arms 0 without)
    arm_n, arm_a = K[k["sf_arm_nest"]], K[k["sf_arm_axle"]]
    # the axle boxes' lateral offset from the side frame's centreline (model.rhs's box_out)
    box_out = (b1 - b2) * K[k["sf_yaw_levers"]]
    sf_rate = [0.5 * (v[L.WS0 + 8 * b + 2] + v[L.WS0 + 8 * b + 6]) for b in range(2)]
    sf_roll = [0.5 * (q[L.WS0 + 8 * b + 2] + q[L.WS0 + 8 * b + 6]) for b in range(2)]
    for b in range(2):
        d = lc if b == 0 else -lc
        ib = L.BOL0 + 4 * b
        roll_rate = v[ib + 2] - v[L.CB_ROLL]
        add(ELEMENTS[1], stick * K[k["c_roll"]], roll_rate)
        add(ELEMENTS[2], stick * K[k["c_yaw"]], v[L.CB_YAW] - v[ib + 3])
        dz_rate = v[ib + 1] - v[L.CB_Z] + d * v[L.CB_PITCH]
        for side in (1.0, -1.0):
            add(ELEMENTS[3], K[k["c_sb"]], dz_rate + side * sb_half * roll_rate)
        for sidx, side in enumerate((1.0, -1.0)):
            jf = L.SF0 + 5 * (2 * b + sidx)
            vxn = v[jf] + side * b2 * v[ib + 3]
            # each of the nest's two wedges has half the stick damping; both slip vertically
            # with the nest, laterally the front one v_y + v_w and the rear one v_y - v_w
            # (v_w = l_w times the relative yaw rate), so together they dissipate c |v_y|^2 / 2
            # laterally and c |v_w|^2 / 2 in warp: the cross terms cancel
            add(
                ELEMENTS[4],
                stick * c_wedge,
                v[jf + 2] - (v[ib + 1] + side * b2 * v[ib + 2]),
            )
            add(ELEMENTS[5], stick * c_wedge, v[jf + 1] - arm_n * sf_rate[b] - v[ib])
            add(ELEMENTS[6], stick * c_wedge, l_w * (v[jf + 4] - v[ib + 3]))
            add(ELEMENTS[7], stick * c_wedge, vxn)
            add(ELEMENTS[8], K[k["c_sx"]], vxn)
    # primary suspension (forces on the wheelsets kept for the contact's power below)
    k_px = series_stiffness(P[12], P[19])
    k_py = series_stiffness(P[13], P[19])
    k_pz = P[14]
    c_px, c_py, c_pz = K[k["c_px"]], K[k["c_py"]], K[k["c_pz"]]
    n = L.N_DOF
    acc = (result.jacobian @ _full_vector(result, mode))[n : 2 * n]
    # each axle box's lateral slip rate and force on its wheelset (the side frame's point at
    # the axle's height: model.rhs's dy_p, dvy), for the damping share and the contact's power
    lateral: dict[tuple[int, int], tuple[complex, complex]] = {}
    for ws in range(4):
        b, wi = divmod(ws, 2)
        e = a if wi == 0 else -a
        iw = L.WS0 + 4 * ws
        for sidx in range(2):
            jf = L.SF0 + 5 * (2 * b + sidx)
            dvy = v[jf + 1] + e * v[jf + 4] - arm_a * sf_rate[b] - v[iw]
            dy = q[jf + 1] + e * q[jf + 4] - arm_a * sf_roll[b] - q[iw]
            lateral[ws, sidx] = dvy, k_py * dy + c_py * dvy
    # the side frames' roll couple on their wheelsets' roll (model.rhs: g_sf, half to each):
    # the arms times the nests' lateral forces on the bolster (its lateral equation less the
    # centre plate's force) and the axle boxes' on the wheelsets
    h_cp, h_b = K[k["h_cg_c"]] - K[k["h_cp"]], K[k["h_cp"]] - K[k["h_cg_b"]]
    g_sf = []
    for b in range(2):
        d = lc if b == 0 else -lc
        ib = L.BOL0 + 4 * b
        y_car = q[L.CB_Y] + d * q[L.CB_YAW] + h_cp * q[L.CB_ROLL]
        f_cpy = K[k["k_cpy"]] * (y_car - (q[ib] - h_b * q[ib + 2]))
        f_nests = m[ib] * acc[ib] - f_cpy
        f_boxes = sum(lateral[2 * b + wi, sidx][1] for wi in range(2) for sidx in range(2))
        g_sf.append(arm_n * f_nests + arm_a * f_boxes)
    contact_power = 0.0
    for ws in range(4):
        b, wi = divmod(ws, 2)
        e = a if wi == 0 else -a
        iw = L.WS0 + 4 * ws
        f = m[iw : iw + 4] * acc[iw : iw + 4]  # all generalised forces on the wheelset
        for sidx, side in enumerate((1.0, -1.0)):
            jf = L.SF0 + 5 * (2 * b + sidx)
            dvx = v[jf] - side * box_out * v[jf + 4] + side * b1 * v[iw + 3]
            dvy, fy = lateral[ws, sidx]
            dvz = (v[iw + 1] + side * b1 * v[iw + 2]) - (v[jf + 2] - e * v[jf + 3])
            add(ELEMENTS[9], c_px, dvx)
            add(ELEMENTS[10], c_py, dvy)
            add(ELEMENTS[11], c_pz, dvz)
            dx = q[jf] - side * box_out * q[jf + 4] + side * b1 * q[iw + 3]
            fx = k_px * dx + c_px * dvx
            dz = (q[iw + 1] + side * b1 * q[iw + 2]) - (q[jf + 2] - e * q[jf + 3])
            fz = k_pz * dz + c_pz * dvz
            f[0] -= fy
            f[1] += fz
            f[2] += side * b1 * fz
            f[3] += side * b1 * fx
        f[2] -= 0.5 * g_sf[b]
        h_spin = P[2] * K[k["V"]] / K[k["r0"]]  # gyroscopic moments: no work, taken out
        f[2] -= h_spin * v[iw + 3]
        f[3] += h_spin * v[iw + 2]
        contact_power += 0.5 * float(np.real(np.vdot(v[iw : iw + 4], f)))
    power[ELEMENTS[-1]] = -contact_power
    shares = {name: p / (2.0 * w * energy) for name, p in power.items()}
    return ModeDissipation(
        mode=result.names[mode],
        frequency_hz=float(result.frequency_hz[mode]),
        zeta=float(result.damping_ratio[mode]),
        shares=shares,
    )


def _full_vector(result: ModalResult, mode: int) -> np.ndarray:
    """The mode's full state vector (displacements, velocities, auxiliary friction states)
    from the state matrix: the eigenvector of ``result.jacobian`` for its eigenvalue."""
    lam = result.eigenvalues[mode]
    vals, vecs = np.linalg.eig(result.jacobian)
    j = int(np.argmin(np.abs(vals - lam)))
    vec = vecs[:, j]
    q = vec[: L.N_DOF]
    shape = np.asarray(result.shapes[mode], dtype=complex)
    k = int(np.argmax(np.abs(shape)))
    return vec * (shape[k] / q[k])  # scaled to the stored shape


__all__ = ["ELEMENTS", "ModeDissipation", "mode_dissipation"]
