"""Names of the wagon's modes, as a vehicle-dynamics engineer gives them, from where their
kinetic energy sits and how the bodies move (used by :mod:`railsusp.vehicle.modes`)."""

from __future__ import annotations

import numpy as np

from railsusp.vehicle import layout as L

#: degree-of-freedom names in the order of the state (layout.py)
DOF_NAMES: tuple[str, ...] = (
    "car body y",
    "car body z",
    "car body roll",
    "car body pitch",
    "car body yaw",
    *(f"bolster {k + 1} {d}" for k in range(2) for d in ("y", "z", "roll", "yaw")),
    *(
        f"side frame {k + 1}{'LR'[s]} {d}"
        for k in range(2)
        for s in range(2)
        for d in ("x", "y", "z", "pitch", "yaw")
    ),
    *(f"wheelset {w + 1} {d}" for w in range(4) for d in ("y", "z", "roll", "yaw")),
)
#: body groups: slices of the displacement vector
GROUPS: dict[str, slice] = {
    "car body": slice(0, L.BOL0),
    "bolster": slice(L.BOL0, L.SF0),
    "side frame": slice(L.SF0, L.WS0),
    "wheelset": slice(L.WS0, L.N_DOF),
}


def name_mode(
    energy: np.ndarray, q: np.ndarray, h_cg: float, l_c: float, speed: float, h_cp: float
) -> tuple[str, str]:
    """(body group, engineering name) of a mode from its kinetic-energy shares per degree
    of freedom and its displacement shape q (complex); heights above rail: h_cg of the car
    body's CG, h_cp of the centre plate; l_c: half the bogie spacing (m)."""
    shares = {g: energy[s].sum() for g, s in GROUPS.items()}
    group = max(shares, key=shares.get)
    if group == "car body":
        return group, _car_body_name(energy, q, h_cg, l_c, h_cp)
    if group == "bolster":
        dirs = ("lateral", "bounce", "roll", "yaw")
        e = energy[GROUPS["bolster"]].reshape(2, 4)
        d = int(np.argmax(e.sum(axis=0)))
        return group, f"bolster {dirs[d]} ({_which(e[:, d], q, [L.BOL0 + d, L.BOL0 + 4 + d])})"
    if group == "side frame":
        e = energy[GROUPS["side frame"]].reshape(4, 5)
        d = int(np.argmax(e.sum(axis=0)))
        if d == 0:  # longitudinal: left/right of a bogie against each other is warp
            k = int(np.argmax(e[:, 0].reshape(2, 2).sum(axis=1)))
            left, right = q[L.SF0 + 10 * k], q[L.SF0 + 10 * k + 5]
            anti = (left * np.conj(right)).real < 0
            kind = "warp (parallelogram)" if anti else "side frames longitudinal"
            return group, f"bogie {k + 1} {kind}"
        dirs = ("longitudinal", "lateral", "bounce", "pitch", "yaw")
        per_bogie = e[:, d].reshape(2, 2).sum(axis=1)
        idx = [L.SF0 + d, L.SF0 + 10 + d]
        return group, f"side frame {dirs[d]} ({_which(per_bogie, q, idx)})"
    e = energy[GROUPS["wheelset"]].reshape(4, 4)
    by_dir = e.sum(axis=0)  # y, z, roll, yaw
    per_bogie = e.sum(axis=1).reshape(2, 2).sum(axis=1)
    lateral = by_dir[0] + by_dir[3]
    if lateral >= by_dir[1] + by_dir[2]:
        w = int(np.argmax(e[:, 0] + e[:, 3]))
        kind = (
            "kinematic (hunting-like) lateral-yaw"
            if speed > 0 and min(by_dir[0], by_dir[3]) > 0.1 * lateral
            else "lateral"
            if by_dir[0] >= by_dir[3]
            else "yaw"
        )
        idx = [L.WS0 + 4 * (w % 2), L.WS0 + 8 + 4 * (w % 2)]
        return group, f"wheelset {kind} ({_which(per_bogie, q, idx)})"
    d = 1 if by_dir[1] >= by_dir[2] else 2
    idx = [L.WS0 + d, L.WS0 + 8 + d]
    return group, f"wheelset {'bounce' if d == 1 else 'roll'} ({_which(per_bogie, q, idx)})"


def _which(per_bogie: np.ndarray, q: np.ndarray, idx: list[int]) -> str:
    """'front bogie', 'rear bogie', or both bogies in phase / anti-phase (from the
    displacements q[idx[0]] of the front and q[idx[1]] of the rear bogie's body)."""
    total = per_bogie.sum()
    if total <= 0:
        return "-"
    if per_bogie[0] > 0.8 * total:
        return "front bogie"
    if per_bogie[1] > 0.8 * total:
        return "rear bogie"
    same = (q[idx[0]] * np.conj(q[idx[1]])).real >= 0
    return "bogies in phase" if same else "bogies anti-phase"


def _car_body_name(energy: np.ndarray, q: np.ndarray, h_cg: float, l_c: float, h_cp: float) -> str:
    """Bounce, pitch, yaw, lateral, lower sway (roll) or upper sway of the car body, or a
    kinematic (hunting-like) lateral or yaw mode when the wheelsets move with the body.

    Lateral and roll of the body couple: the point of the body that does not move sideways
    (roll centre) lies at z_rc = y / φ above the CG (a point at height z above the CG moves
    y - z φ). Below the CG: lower sway (the body rolls about a point near the centre plate);
    above it: upper sway; more than 5 m away: body lateral."""
    e = energy[GROUPS["car body"]]
    parts = {
        "bounce": e[L.CB_Z],
        "pitch": e[L.CB_PITCH],
        "yaw": e[L.CB_YAW],
        "sway": e[L.CB_Y] + e[L.CB_ROLL],
    }
    kind = max(parts, key=parts.get)
    if kind in ("sway", "yaw") and _kinematic(q, l_c, h_cp - h_cg):
        return f"car body kinematic (hunting-like) {'yaw' if kind == 'yaw' else 'lateral'}"
    if kind != "sway":
        return f"car body {kind}"
    y, roll = q[L.CB_Y], q[L.CB_ROLL]
    if abs(roll) < 1e-12 * max(abs(y), 1e-30):
        return "car body lateral"
    z_rc = (y * np.conj(roll)).real / abs(roll) ** 2
    if abs(z_rc) > 5.0:
        return "car body lateral"
    height = h_cg + z_rc
    return f"car body {'lower' if z_rc < 0 else 'upper'} sway (roll centre {height:+.1f} m)"


def _kinematic(q: np.ndarray, l_c: float, dz_cp: float) -> bool:
    """Whether the wheelsets move sideways at least half as much as the car body above
    them: the mode rides on the wheelsets' rolling kinematics (body hunting-like) rather
    than on the suspension, which holds the wheelsets nearly still in a body mode.

    The body's lateral motion above a bogie is taken at its CG and at the centre plate
    (``dz_cp`` below the CG, where the body rests on the bogie; a point at z above the CG
    moves y - z roll + x yaw), the larger of the two: in an upper sway the body rolls about a
    point near its CG, which hardly moves sideways, while the centre plates swing."""

    def lateral(z: float) -> float:
        y = q[L.CB_Y] - z * q[L.CB_ROLL]
        return 0.5 * sum(abs(y + d * q[L.CB_YAW]) for d in (l_c, -l_c))

    body = max(lateral(0.0), lateral(dz_cp))
    wheels = np.abs(q[[L.WS0 + 4 * w for w in range(4)]]).mean()
    return bool(wheels >= 0.5 * body)
