"""Wheel-rail contact tables: :class:`ContactTable`, the contact functions of a wheelset by
lateral shift (look-up, files), and what is read off a table: the tread/flange split of
two-point contact and the equivalent conicity (EN 15302 style, harmonic linearisation).

The table is computed by the rigid-profile method in
:mod:`railsusp.vehicle.rigid_profile_contact`; the force laws (Hertz, Kalker,
Shen-Hedrick-Elkins) are in :mod:`railsusp.vehicle.contact_forces`.

Conventions
-----------
Track frame: x forward (running direction), y to the LEFT, z UP. The left wheel and rail are
on the +y side. A wheelset shift ``y`` (m) is its lateral displacement relative to the track
centre line, positive to the left. The wheelset roll ``roll`` (rad) is a rotation about +x,
positive when the left wheel rises. The rise (m) is the vertical motion of the wheelset centre
relative to the centred position, positive up.

Per-wheel arrays have shape (n, 2): column ``LEFT`` (0) and ``RIGHT`` (1). The contact angle
``delta`` of either wheel is positive when the normal force of the rail on the wheel points
towards the track centre (tread sloping down towards the flange, flange contact), so that
in the track frame the normal force on the left wheel is N (-sin d_L, cos d_L) and on the
right wheel N (+sin d_R, cos d_R) in (y, z). Centred on new profiles d_L = d_R > 0. Wheel
and rail contact positions are given in their profile coordinates (see
:mod:`railsusp.vehicle.profiles`: from the taping line / rail centre line, + towards the
field side), and in the track frame (``contact_y``, ``contact_z``; rail crown at z = 0).

Curvatures (1/m) are positive for a convex surface: wheel rolling-direction curvature
cos(profile angle) / r, wheel lateral (profile) curvature (negative on a hollow tread), rail
lateral curvature (rail longitudinal curvature 0 on tangent track).

Creep forces are those of the rail on the wheel, in the contact plane: Fx longitudinal, Fy
lateral, Mz spin moment, with creepages xi_x, xi_y (-) and spin phi (1/m).
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "LEFT",
    "RIGHT",
    "ContactTable",
    "equivalent_conicity",
    "equivalent_conicity_curve",
    "flange_split",
]

Array = np.ndarray | float

LEFT, RIGHT = 0, 1

_PER_WHEEL = (
    "rolling_radius",
    "contact_angle",
    "wheel_y",
    "rail_y",
    "contact_y",
    "contact_z",
    "wheel_curvature_long",
    "wheel_curvature_lat",
    "rail_curvature_lat",
)


@dataclass(frozen=True, eq=False)
class ContactTable:
    """Contact functions of a rigid wheelset (zero yaw) on a track, tabulated over shift ``y``.

    ``y`` (m) is uniform and increasing (index = (y - y[0]) / step for fast look-up).
    ``roll`` (rad), ``rise`` (m): wheelset roll and centre rise, shape (n,). Per-wheel arrays,
    shape (n, 2), columns LEFT/RIGHT: ``rolling_radius`` (m), ``contact_angle`` (rad),
    ``wheel_y`` / ``rail_y`` (m, contact point in wheel / rail profile coordinates),
    ``contact_y`` / ``contact_z`` (m, track frame), ``wheel_curvature_long``,
    ``wheel_curvature_lat``, ``rail_curvature_lat`` (1/m) and ``flange`` (bool: contact angle
    above ``meta['flange_angle']``). ``meta`` records the inputs (names, gauge, ...).

    Beyond the flangeway clearance the rigid wheelset can only go on by climbing the rail:
    there the table describes flange climb (the rise grows several mm per mm of shift, the
    contact runs over the flank onto the flange tip). A simulator should let the flange
    contact act through elastic penetration near the jump rather than follow that climb.
    """

    y: np.ndarray
    roll: np.ndarray
    rise: np.ndarray
    rolling_radius: np.ndarray
    contact_angle: np.ndarray
    wheel_y: np.ndarray
    rail_y: np.ndarray
    contact_y: np.ndarray
    contact_z: np.ndarray
    wheel_curvature_long: np.ndarray
    wheel_curvature_lat: np.ndarray
    rail_curvature_lat: np.ndarray
    flange: np.ndarray
    meta: dict[str, Any]

    @property
    def delta_r(self) -> np.ndarray:
        """Rolling radius difference r_L - r_R (m), shape (n,)."""
        return self.rolling_radius[:, LEFT] - self.rolling_radius[:, RIGHT]

    def flangeway_clearance(self) -> tuple[float, float]:
        """First shifts (m) with flange contact: (left wheel, y > 0; right wheel, y < 0).

        Resolved to the table step; NaN where the table range holds no flange contact.
        """
        left = self.y[(self.y > 0) & self.flange[:, LEFT]]
        right = self.y[(self.y < 0) & self.flange[:, RIGHT]]
        return (
            float(left.min()) if left.size else math.nan,
            float(right.max()) if right.size else math.nan,
        )

    def at(self, y: np.ndarray | float, *, clip: bool = False) -> ContactTable:
        """The table linearly interpolated at shifts ``y`` (m, 1-D or scalar).

        Across the flange jump the interpolation blends tread and flange values over one
        table step. Outside the table range a ValueError is raised, or with ``clip=True``
        the end values are held.
        """
        yq = np.atleast_1d(np.asarray(y, dtype=float)).ravel()
        if not clip and (yq.min() < self.y[0] - 1e-12 or yq.max() > self.y[-1] + 1e-12):
            raise ValueError(
                f"shift {yq.min() * 1e3:.3f}..{yq.max() * 1e3:.3f} mm outside the table range "
                f"{self.y[0] * 1e3:.3f}..{self.y[-1] * 1e3:.3f} mm"
            )
        cols = {"y": yq}
        for name in ("roll", "rise"):
            cols[name] = np.interp(yq, self.y, getattr(self, name))
        for name in _PER_WHEEL:
            arr = getattr(self, name)
            cols[name] = np.stack([np.interp(yq, self.y, arr[:, k]) for k in (0, 1)], axis=1)
        cols["flange"] = cols["contact_angle"] > self.meta["flange_angle"]
        return replace(self, **cols)

    def save(self, path: str | Path) -> Path:
        """Write the table to a ``.npz`` file (arrays plus JSON metadata)."""
        from railsusp.store import atomic_write_bytes

        path = Path(path)
        arrays = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "meta"}
        buf = io.BytesIO()
        np.savez(buf, meta=np.array(json.dumps(self.meta)), **arrays)
        return atomic_write_bytes(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> ContactTable:
        """Read a table written by :meth:`save`."""
        with np.load(Path(path), allow_pickle=False) as data:
            kw = {f.name: np.array(data[f.name]) for f in fields(cls) if f.name != "meta"}
            meta = json.loads(str(data["meta"]))
        return cls(meta=meta, **kw)

    def to_dataframe(self):
        """A pandas DataFrame, one row per shift; per-wheel columns end in _L / _R."""
        import pandas as pd

        cols: dict[str, np.ndarray] = {"y": self.y, "roll": self.roll, "rise": self.rise}
        for name in (*_PER_WHEEL, "flange"):
            arr = getattr(self, name)
            cols[f"{name}_L"] = arr[:, LEFT]
            cols[f"{name}_R"] = arr[:, RIGHT]
        return pd.DataFrame(cols)


def flange_split(table: ContactTable, min_jump: float = 0.005) -> float | None:
    """Wheel profile abscissa (m) that splits the tread from the flange for two-point contact.

    On the flange side of the left wheel (shifts y > 0) the rigid contact point runs up the
    tread and then jumps to the flange root or flank, skipping the stretch of profile between
    them: no point of that stretch is ever in contact alone. Its middle is the split, so a
    tread part and a flange part (``contact_table(..., wheel_range=...)``) each keep one
    contact point and both can touch at once (two-point contact). None when the largest jump
    is shorter than ``min_jump`` (m): a conformal profile with no distinct flange contact.
    """
    side = table.y > 0.0
    u = table.wheel_y[side, LEFT]
    if u.size < 2:
        return None
    jumps = u[:-1] - u[1:]  # the contact moves to -u (towards the flange) with growing y
    i = int(np.argmax(jumps))
    if not jumps[i] >= min_jump:
        return None
    return float(0.5 * (u[i] + u[i + 1]))


# --------------------------------------------------------------------------------------------
# equivalent conicity (EN 15302, harmonic linearisation)
# --------------------------------------------------------------------------------------------


def equivalent_conicity(
    table: ContactTable, amplitude: float | np.ndarray = 0.003, n_phase: int = 1440
) -> float | np.ndarray:
    """Equivalent conicity at lateral amplitude(s) ``amplitude`` (m), EN 15302 style.

    Harmonic linearisation of the rolling radius difference over a sinusoidal lateral
    motion y = A sin(theta): lambda_e(A) = c1 / (2 A), with c1 = (1/pi) * integral over one
    period of dr(A sin theta) sin(theta) d theta the first Fourier coefficient of
    dr = r_L - r_R. For a cone of slope tan(gamma) with dr = 2 tan(gamma) y this returns
    tan(gamma) exactly. A scalar amplitude gives a float, an array an array.
    """
    amp = np.asarray(amplitude, dtype=float)
    if np.any(amp <= 0.0):
        raise ValueError("conicity amplitude must be positive")
    if np.any(amp > min(-table.y[0], table.y[-1]) + 1e-12):
        raise ValueError(
            f"amplitude {amp.max() * 1e3:.2f} mm beyond the table range "
            f"{table.y[0] * 1e3:.2f}..{table.y[-1] * 1e3:.2f} mm"
        )
    theta = np.linspace(0.0, 2.0 * np.pi, n_phase, endpoint=False)
    s = np.sin(theta)
    dr = np.interp(amp[..., None] * s, table.y, table.delta_r)
    c1 = 2.0 * np.mean(dr * s, axis=-1)
    lam = c1 / (2.0 * amp)
    return float(lam) if lam.ndim == 0 else lam


def equivalent_conicity_curve(
    table: ContactTable, amplitudes: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(amplitudes, equivalent conicity) for amplitudes 1..10 mm unless given (m)."""
    amps = np.arange(1, 11) * 1e-3 if amplitudes is None else np.asarray(amplitudes, float)
    return amps, np.asarray(equivalent_conicity(table, amps))
