"""Wheel and rail transverse profiles: the :class:`Profile` type and profile files.

Profile coordinates (both wheel and rail, SI metres inside, millimetres in files):

* ``y`` runs along the axle, **positive towards the field side** (away from the flange on a
  wheel, away from the gauge face on a rail). It must be strictly increasing.
* ``z`` is **positive downwards**, i.e. towards the rail foot.

Reference points:

* wheel: ``y = 0`` at the taping line (nominal rolling circle), ``z = 0`` at the taping-line
  level, so the rolling radius at ``y`` is ``r0 + z(y)``; the flange has ``z > 0`` and lies
  at ``y < 0``.
* rail: ``y = 0`` on the rail-head centre line, ``z = 0`` at the crown top, in the rail's own
  axes (not inclined). :func:`railsusp.vehicle.profile_shapes.incline` turns it by the rail
  cant for use in a track.

The same profile describes the left and the right wheel (rail); the contact code mirrors it.

The profiles built from their dimensions (the LM-like worn tread, the CHN60 rail head, the
cone and round head of the checks) are :mod:`railsusp.vehicle.profile_shapes`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from railsusp.errors import RailsuspInputError

__all__ = ["Profile", "read_profile", "write_profile"]

_KINDS = ("wheel", "rail")


@dataclass(frozen=True, eq=False)
class Profile:
    """A transverse wheel or rail profile sampled as ``z(y)`` (m), conventions in module doc.

    ``y`` must be strictly increasing and finite, ``z`` finite and of the same length (at
    least 4 points, so that a cubic spline can give slope and curvature).
    """

    y: np.ndarray
    z: np.ndarray
    name: str = "profile"
    kind: str = "wheel"

    def __post_init__(self) -> None:
        y = np.array(self.y, dtype=float, copy=True)
        z = np.array(self.z, dtype=float, copy=True)
        who = f"profile {self.name!r}"
        if self.kind not in _KINDS:
            raise RailsuspInputError(f"{who}: kind {self.kind!r} not one of {_KINDS}")
        if y.ndim != 1 or z.ndim != 1:
            raise RailsuspInputError(f"{who}: y and z must be 1-D, got shapes {y.shape}, {z.shape}")
        if y.size != z.size:
            raise RailsuspInputError(f"{who}: y has {y.size} points but z has {z.size}")
        if y.size < 4:
            raise RailsuspInputError(f"{who}: needs at least 4 points, got {y.size}")
        for label, arr in (("y", y), ("z", z)):
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise RailsuspInputError(
                    f"{who}: {label} is not finite at index {bad[0]} ({arr[bad[0]]!r})"
                )
        step = np.diff(y)
        bad = np.flatnonzero(step <= 0.0)
        if bad.size:
            i = int(bad[0]) + 1
            raise RailsuspInputError(
                f"{who}: y is not strictly increasing at index {i} "
                f"(y = {y[i] * 1e3:.4f} mm after {y[i - 1] * 1e3:.4f} mm)"
            )
        y.flags.writeable = False
        z.flags.writeable = False
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "z", z)

    def __len__(self) -> int:
        return int(self.y.size)

    @cached_property
    def _bspline(self) -> BSpline:
        return make_interp_spline(self.y, self.z, k=3)

    def evaluate(self, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Height z (m), slope dz/dy (-) and curvature (1/m) at ``y`` (m), from a cubic spline.

        Curvature is z'' / (1 + z'^2)^(3/2) in the profile axes (z down): positive where the
        profile bends towards -z, i.e. convex for a rail head, concave (hollow) for a wheel.
        Outside the sampled range the spline extrapolates: callers mask that range. The
        spline interpolates the points, so a measured (noisy) profile should be smoothed
        before use or its curvature, and hence the Hertz patch, will be noisy.
        """
        spl = self._bspline
        y = np.asarray(y, dtype=float)
        z = spl(y)
        dz = spl(y, 1)
        d2z = spl(y, 2)
        return z, dz, d2z / (1.0 + dz * dz) ** 1.5

    def shifted(self, dy: float = 0.0, dz: float = 0.0, name: str | None = None) -> Profile:
        """The same profile with its origin moved: returns points (y + dy, z + dz), m."""
        return Profile(self.y + dy, self.z + dz, name or self.name, self.kind)


# --------------------------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------------------------


def read_profile(path: str | Path, *, name: str | None = None, kind: str = "wheel") -> Profile:
    """Read a profile file: two columns y, z in **millimetres** (module conventions).

    Columns are separated by commas, semicolons, tabs or spaces; blank lines and lines whose
    first non-blank character is ``#`` are skipped. Errors name the file, the line number
    (1-based) and the problem: a missing or extra column, a non-numeric or non-finite cell,
    a y value that does not increase, too few points.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise RailsuspInputError(f"profile file {path}: cannot be read ({exc})") from None
    except UnicodeDecodeError as exc:
        raise RailsuspInputError(
            f"profile file {path}: not text (byte {exc.start} is no UTF-8); accepted two "
            "columns y, z in mm"
        ) from None
    ys: list[float] = []
    zs: list[float] = []
    lines: list[int] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        cells = line.replace(",", " ").replace(";", " ").split()
        if len(cells) != 2:
            raise RailsuspInputError(
                f"{path}, line {number}: expected 2 columns (y z in mm), found {len(cells)}"
            )
        values = []
        for col, cell in zip(("y", "z"), cells, strict=True):
            try:
                v = float(cell)
            except ValueError:
                raise RailsuspInputError(
                    f"{path}, line {number}: {col} cell {cell!r} is not a number"
                ) from None
            if not math.isfinite(v):
                raise RailsuspInputError(f"{path}, line {number}: {col} cell {cell!r} not finite")
            values.append(v * 1e-3)
        if ys and values[0] <= ys[-1]:
            raise RailsuspInputError(
                f"{path}, line {number}: y = {cells[0]} mm does not increase "
                f"(previous point, line {lines[-1]}: {ys[-1] * 1e3:g} mm)"
            )
        ys.append(values[0])
        zs.append(values[1])
        lines.append(number)
    if len(ys) < 4:
        raise RailsuspInputError(f"{path}: needs at least 4 data lines, found {len(ys)}")
    return Profile(np.array(ys), np.array(zs), name=name or path.stem, kind=kind)


def write_profile(profile: Profile, path: str | Path) -> Path:
    """Write ``profile`` as a comma-separated y, z file in millimetres (nm resolution)."""
    path = Path(path)
    header = (
        f"# railsusp profile: {profile.name}\n# kind: {profile.kind}\n"
        "# y (mm, + towards the field side), z (mm, + downwards)\n"
    )
    body = "".join(
        f"{y:.6f},{z:.6f}\n" for y, z in zip(profile.y * 1e3, profile.z * 1e3, strict=True)
    )
    from railsusp.store import atomic_write_text

    return atomic_write_text(path, header + body)
