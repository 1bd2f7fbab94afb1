"""Energy audit of the equations of motion: work of the non-conservative forces against the
change of mechanical energy.

For the model's equations M a = F(q, v, z) (diagonal mass matrix M, friction states z),
split F into the conservative part F_c(q) (springs, bowl and bearer contacts with lift-off,
Hertz wheel-rail contact, stops: F at v = 0, z = 0 with creep switched off) and the rest
(dampers, friction, creep forces, rail damping). Then

    d/dt (T + V) = (F - F_c) . v,   T = v' M v / 2,   V(q) = -int_0^1 F_c(s q) . q ds,

where V is the potential of F_c along the straight path from the static equilibrium (q = 0).
The identity holds only if F_c really is a gradient field: a lever arm applied to one body
and not its reaction, or a stiffness that is not symmetric, breaks it. The audit integrates
the state and the non-conservative work W_nc together (RK4) on ideal straight track from a
perturbed state and compares W_nc with the change of T + V. Gyroscopic moments do no work.

The discrepancy is relative to the larger of |W_nc| and |change of T + V|
(:attr:`EnergyAudit.relative_error`), which in a damped run is the dissipated work: a drift
of the conservative part (the contact's normal force is not quite a gradient, docs/model.md)
is a fraction of that work, which heavy damping makes small enough to hide; a lightly damped
run shows it more plainly.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.operating_point import LinearisationPoint, check_real, linearisation_point
from railsusp.vehicle.step_bound import STEP_FLOOR, stable_step
from railsusp.vehicle.wagon import WagonData, load_wagon

NQ = L.N_DOF
#: Gauss-Legendre points per sub-interval and sub-intervals of the potential's path integral
_GL_X, _GL_W = np.polynomial.legendre.leggauss(6)
_PATH_PARTS = 8
#: accepted run length of an audit, s (a Python RK4 loop: a minute is 120000 steps)
DURATION_RANGE_S: tuple[float, float] = (0.0, 60.0)
#: accepted integration step, s (shortened further to RK4's stability bound where needed)
DT_RANGE_S: tuple[float, float] = (STEP_FLOOR, 1.0e-3)


@dataclass(frozen=True)
class EnergyAudit:
    """Result of :func:`energy_audit` (J): mechanical energy T + V at the start and end, the
    work of the non-conservative forces over the run, and the discrepancy."""

    energy_start: float
    energy_end: float
    work_nonconservative: float
    dissipated_fraction: float

    @property
    def change(self) -> float:
        return self.energy_end - self.energy_start

    @property
    def relative_error(self) -> float:
        """|change of T + V - W_nc| relative to the larger of |W_nc| and |change| (module
        docstring: under heavy damping that is the dissipated work)."""
        scale = max(abs(self.work_nonconservative), abs(self.change), 1e-12)
        return abs(self.change - self.work_nonconservative) / scale


class _Audit:
    def __init__(self, point: LinearisationPoint, creep: bool):
        self.M = point.dof_inertia()
        k_cons = point.K.copy()
        k_cons[L.K["creep_factor"]] = 0.0  # conservative part: no creep forces
        self.conservative_point = replace(point, K=k_cons)
        self.point = point if creep else self.conservative_point

    def conservative(self, q: np.ndarray) -> np.ndarray:
        x = np.zeros(L.N_STATE)
        x[:NQ] = q
        return self.M * self.conservative_point.rhs(x)[NQ : 2 * NQ]

    def potential(self, q: np.ndarray) -> float:
        total = 0.0
        for part in range(_PATH_PARTS):
            a = part / _PATH_PARTS
            for xg, wg in zip(_GL_X, _GL_W, strict=True):
                lam = a + (xg + 1.0) / (2.0 * _PATH_PARTS)
                total -= wg / (2.0 * _PATH_PARTS) * float(self.conservative(lam * q) @ q)
        return total

    def energy(self, x: np.ndarray) -> float:
        v = x[NQ : 2 * NQ]
        return 0.5 * float(self.M @ (v * v)) + self.potential(x[:NQ])

    def augmented(self, y: np.ndarray) -> np.ndarray:
        x = y[:-1]
        d = self.point.rhs(x)
        v = x[NQ : 2 * NQ]
        f_nc = self.M * d[NQ : 2 * NQ] - self.conservative(x[:NQ])
        return np.append(d, float(f_nc @ v))


def energy_audit(
    x0: np.ndarray,
    params: ParameterSet | None = None,
    *,
    speed_kmh: float = 60.0,
    duration_s: float = 3.0,
    dt: float = 5.0e-4,
    wagon: WagonData | None = None,
    creep: bool = True,
) -> EnergyAudit:
    """Run from state ``x0`` (layout.N_STATE; friction states usually 0) on ideal straight,
    level track and compare the work of the non-conservative forces with the change of
    mechanical energy (module docstring). ``creep=False`` switches the creep forces off.
    ``dt`` is shortened to RK4's stability bound where the speed needs it
    (:func:`~railsusp.vehicle.step_bound.stable_step`: below about 29 km/h for 0.5 ms).
    Accepted: ``x0`` a finite state of layout.N_STATE values, ``duration_s`` in
    :data:`DURATION_RANGE_S` (above 0), ``dt`` in :data:`DT_RANGE_S`, ``speed_kmh`` a
    working condition's 1-200 km/h (one-line :class:`RailsuspInputError` otherwise: a
    negative duration or step returned a passing audit of nothing, a zero step divided by
    zero)."""
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (L.N_STATE,):
        raise RailsuspInputError(f"x0: {x0.size} values given, the state has {L.N_STATE}")
    if not np.isfinite(x0).all():
        raise RailsuspInputError(
            f"x0: {int((~np.isfinite(x0)).sum())} values not finite; accepted a finite state"
        )
    duration_s = check_real("duration_s", duration_s, *DURATION_RANGE_S, "s", lo_open=True)
    dt = check_real("dt", dt, *DT_RANGE_S, "s")
    wagon = load_wagon(wagon)
    point = linearisation_point(params, wagon, speed_kmh)
    dt = min(dt, stable_step(wagon, speed_kmh, point.P))
    audit = _Audit(point, creep)
    y = np.append(x0, 0.0)
    e0 = audit.energy(y[:-1])
    for _ in range(round(duration_s / dt)):  # ideal straight track: the same everywhere
        k1 = audit.augmented(y)
        k2 = audit.augmented(y + 0.5 * dt * k1)
        k3 = audit.augmented(y + 0.5 * dt * k2)
        k4 = audit.augmented(y + dt * k3)
        y = y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    e1 = audit.energy(y[:-1])
    return EnergyAudit(float(e0), float(e1), float(y[-1]), float(-y[-1] / e0) if e0 else 0.0)
