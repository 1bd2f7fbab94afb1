"""Names of the wagon's modes, as a vehicle-dynamics engineer gives them, from where their
kinetic energy sits and how the bodies move (used by :mod:`railsusp.vehicle.modes`).

A mode with no kinetic energy at all (no body moves: only auxiliary friction states relax,
as the sliding linearisation's zero-limit sliders do, λ = -1 / their relaxation time) is
named :data:`NO_MOTION_NAME` in the group :data:`NO_MOTION_GROUP`: the largest share of an
all-zero energy vector says nothing, and such a root is no body's mode."""

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
#: group and name of a mode in which no body moves (zero kinetic energy: module docstring)
NO_MOTION_GROUP = "friction states"
NO_MOTION_NAME = "friction-state relaxation (no motion)"


def name_mode(
    energy: np.ndarray,
    q: np.ndarray,
    h_cg: float,
    l_c: float,
    speed: float,
    h_cp: float,
    overdamped: bool = False,
) -> tuple[str, str]:
    """(body group, engineering name) of a mode from its kinetic-energy shares per degree
    of freedom and its displacement shape q (complex); heights above rail: h_cg of the car
    body's CG, h_cp of the centre plate; l_c: half the bogie spacing (m). A mode without
    kinetic energy is :data:`NO_MOTION_NAME` (module docstring). An ``overdamped`` root (a
    real eigenvalue) does not oscillate: its name ends in ", overdamped" and never says
    "hunting-like", so that it is not read as the oscillating mode of the same shape (the
    tare wagon's 5.01 Hz wheelset mode and a 22 ms root had one name)."""
    if not energy.sum() > 0.0:
        return NO_MOTION_GROUP, NO_MOTION_NAME
    group, name = _name(energy, q, h_cg, l_c, speed, h_cp)
    if overdamped:
        name = name.replace("kinematic (hunting-like)", "kinematic") + ", overdamped"
    return group, name


def _name(
    energy: np.ndarray, q: np.ndarray, h_cg: float, l_c: float, speed: float, h_cp: float
) -> tuple[str, str]:
    """(body group, name) of a mode with kinetic energy, as :func:`name_mode` gives it but
    for an overdamped root's mark."""
    shares = {g: energy[s].sum() for g, s in GROUPS.items()}
    group = max(shares, key=shares.get)
    if group == "car body":
        return group, _car_body_name(energy, q, h_cg, l_c, h_cp)
    if group == "bolster":
        dirs = ("lateral", "bounce", "roll", "yaw")
        e = energy[GROUPS["bolster"]].reshape(2, 4)
        d = int(np.argmax(e.sum(axis=0)))
        which = _which(e[:, d], q[L.BOL0 + d], q[L.BOL0 + 4 + d])
        return group, f"bolster {dirs[d]} ({which})"
    if group == "side frame":
        e = energy[GROUPS["side frame"]].reshape(4, 5)
        d = int(np.argmax(e.sum(axis=0)))
        per_bogie = e[:, d].reshape(2, 2).sum(axis=1)
        if d == 0:
            return group, _longitudinal_side_frames(per_bogie, q)
        dirs = ("longitudinal", "lateral", "bounce", "pitch", "yaw")
        which = _which(per_bogie, q[L.SF0 + d], q[L.SF0 + 10 + d])
        return group, f"side frame {dirs[d]} ({which})"
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
        i = L.WS0 + 4 * (w % 2)
        return group, f"wheelset {kind} ({_which(per_bogie, q[i], q[i + 8])})"
    d = 1 if by_dir[1] >= by_dir[2] else 2
    which = _which(per_bogie, q[L.WS0 + d], q[L.WS0 + 8 + d])
    return group, f"wheelset {'bounce' if d == 1 else 'roll'} ({which})"


def distinct_names(names: list[str]) -> list[str]:
    """``names`` (in the order of |λ|), each mode whose name an earlier one already has
    marked by its rank among them (", second", ", third", ", 4th", ...), so that every row
    of a mode table, and every mode a decay or dissipation table names, is one mode; the
    friction-state roots, which no body's motion tells apart, keep their one name."""
    seen: dict[str, int] = {}
    out = []
    for name in names:
        k = seen[name] = seen.get(name, 0) + 1
        if k == 1 or name == NO_MOTION_NAME:
            out.append(name)
        else:
            out.append(f"{name}, {_ORDINALS.get(k, f'{k}th')}")
    return out


_ORDINALS = {2: "second", 3: "third"}


def _longitudinal_side_frames(per_bogie: np.ndarray, q: np.ndarray) -> str:
    """Name of a mode whose energy is mostly the side frames' longitudinal motion: bogie warp
    (the parallelogram mode) where each bogie's left and right side frames move against each other,
    side frames longitudinal where they move together, and whose bogie (front, rear, or both
    in phase / anti-phase) as the other bogie modes are told apart.

    The kind comes from both bogies together: the warp part |x_L - x_R|² of the two against
    the in-phase part |x_L + x_R|² (their difference is -4 Re(x_L conj(x_R)), so for one
    bogie this is the sign test of the two side frames' phase). The phase of the two bogies
    is that of their warp coordinates x_L - x_R in a warp mode and of x_L + x_R otherwise:
    the front bogie's side frames are L.SF0 (left) and L.SF0 + 5 (right), the rear's 10 on."""
    left = q[[L.SF0, L.SF0 + 10]]
    right = q[[L.SF0 + 5, L.SF0 + 15]]
    warp = float(np.sum((left * np.conj(right)).real)) < 0.0
    coord = left - right if warp else left + right
    which = _which(per_bogie, coord[0], coord[1])
    return f"{'bogie warp' if warp else 'side frames longitudinal'} ({which})"


def _which(per_bogie: np.ndarray, front: complex, rear: complex) -> str:
    """'front bogie', 'rear bogie' (80 % or more of the energy in one), or both bogies in
    phase / anti-phase, from the complex amplitudes of one coordinate of the front and of
    the rear bogie (the bogie's body's displacement, or a combination such as warp)."""
    total = per_bogie.sum()
    if total <= 0:
        return "-"
    if per_bogie[0] > 0.8 * total:
        return "front bogie"
    if per_bogie[1] > 0.8 * total:
        return "rear bogie"
    same = (front * np.conj(rear)).real >= 0
    return "bogies in phase" if same else "bogies anti-phase"


def _car_body_name(energy: np.ndarray, q: np.ndarray, h_cg: float, l_c: float, h_cp: float) -> str:
    """Bounce, pitch, yaw, lateral, lower sway (roll) or upper sway of the car body, or a
    kinematic (hunting-like) lateral or yaw mode when the wheelsets move with the body,
    with its leading end where its two ends do not move in phase or anti-phase
    (:func:`_leading_end`).

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
        name = f"car body kinematic (hunting-like) {'yaw' if kind == 'yaw' else 'lateral'}"
        leading = _leading_end(q, l_c, h_cp - h_cg)
        return f"{name} ({leading} end leading)" if leading else name
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


#: the least phase (rad) by which one centre plate's lateral motion leads the other's for a
#: kinematic body mode to be named by its leading end (10°: a plain lateral mode has 0, a
#: plain yaw mode 180°, the loaded wagon's two mixed stuck modes 54° and 45°)
_LEAD_MIN_RAD = np.deg2rad(10.0)


def _leading_end(q: np.ndarray, l_c: float, dz_cp: float) -> str:
    """'front' or 'rear': the end of the car body whose centre plate's lateral motion leads
    the other's by more than :data:`_LEAD_MIN_RAD` (and less than 180° less it); '' where
    the two move in phase or in anti-phase (a plain lateral or yaw mode).

    With the centre-bowl friction stuck, the body's kinematic lateral and yaw couple into
    two modes of nearly one frequency, both mostly lateral (the loaded wagon's 1.67 and
    1.70 Hz): which way the motion runs along the body tells them apart. The front plate
    (bogie 1, l_c ahead of the CG, ``dz_cp`` above it) moves y - dz roll + l_c yaw, the rear
    one y - dz roll - l_c yaw; a shape q e^(iωt) leads where its phase is larger."""
    base = q[L.CB_Y] - dz_cp * q[L.CB_ROLL]
    front, rear = base + l_c * q[L.CB_YAW], base - l_c * q[L.CB_YAW]
    if abs(front) == 0.0 or abs(rear) == 0.0:
        return ""
    lead = float(np.angle(front * np.conj(rear)))
    if _LEAD_MIN_RAD < abs(lead) < np.pi - _LEAD_MIN_RAD:
        return "front" if lead > 0.0 else "rear"
    return ""


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
