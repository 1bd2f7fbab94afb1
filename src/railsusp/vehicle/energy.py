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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.model import rhs
from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays, track_arrays
from railsusp.vehicle.wagon import WagonData, load_wagon

NQ = L.N_DOF
#: Gauss-Legendre points per sub-interval and sub-intervals of the potential's path integral
_GL_X, _GL_W = np.polynomial.legendre.leggauss(6)
_PATH_PARTS = 8


@dataclass(frozen=True)
class ModelInputs:
    """Everything :func:`railsusp.vehicle.model.rhs` needs for one set on one track."""

    P: np.ndarray
    K: np.ndarray
    track: np.ndarray
    s0: float
    ds: float
    table: np.ndarray
    y0: float
    dy: float
    H0L: float
    H0R: float

    def derivative(self, x: np.ndarray, s_front: float, K: np.ndarray | None = None):
        """(dx/dt, failure code) at state x with the leading wheelset at s_front."""
        dxdt = np.zeros_like(x)
        out = np.zeros(L.N_OUT_WORK)
        code = rhs(
            x, dxdt, self.P, self.K if K is None else K, self.track, self.s0, self.ds,
            self.table, self.y0, self.dy, self.H0L, self.H0R, s_front, out,
        )  # fmt: skip
        return dxdt, int(code)

    def masses(self) -> np.ndarray:
        """Inertia of each degree of freedom (kg or kg m^2), in the layout's order."""
        k = self.K
        g = L.K
        m = np.empty(NQ)
        m[L.CB_Y : L.CB_YAW + 1] = [
            k[g["m_c"]], k[g["m_c"]], k[g["Ix_c"]], k[g["Iy_c"]], k[g["Iz_c"]],
        ]  # fmt: skip
        for b in range(2):
            m[L.BOL0 + 4 * b : L.BOL0 + 4 * b + 4] = [
                k[g["m_b"]], k[g["m_b"]], k[g["Ix_b"]], k[g["Iz_b"]],
            ]  # fmt: skip
        for j in range(4):
            m[L.SF0 + 5 * j : L.SF0 + 5 * j + 5] = [
                k[g["m_f"]], k[g["m_f"]], k[g["m_f"]], k[g["Iy_f"]], k[g["Iz_f"]],
            ]  # fmt: skip
        for w in range(4):
            m[L.WS0 + 4 * w : L.WS0 + 4 * w + 4] = [
                self.P[0], self.P[0], self.P[1], self.P[3],
            ]  # fmt: skip
        return m


def model_inputs(
    params: ParameterSet | None,
    condition: WorkingCondition,
    wagon: WagonData | None = None,
    settings: SolverSettings | None = None,
    seed: int | None = None,
) -> ModelInputs:
    """The kernel's inputs for one parameter set in one condition (one track realisation)."""
    wagon = load_wagon() if wagon is None else wagon
    settings = SolverSettings() if settings is None else settings
    p = (params or ParameterSet.nominal()).to_array()
    ca = contact_arrays(wagon)
    k = constants(wagon, condition, p, ca, settings)
    tracks, s0, ds = track_arrays(
        condition, [condition.seed if seed is None else seed], wagon, settings
    )
    return ModelInputs(
        np.ascontiguousarray(p), k, np.ascontiguousarray(tracks[0]), s0, ds, ca.table, ca.y0,
        ca.dy, ca.H0L, ca.H0R,
    )  # fmt: skip


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
        """|change of T + V - W_nc| relative to the larger of |W_nc| and |change|."""
        scale = max(abs(self.work_nonconservative), abs(self.change), 1e-12)
        return abs(self.change - self.work_nonconservative) / scale


class _Audit:
    def __init__(self, mi: ModelInputs, creep: bool):
        self.mi = mi
        self.M = mi.masses()
        self.Kc = mi.K.copy()
        self.Kc[L.K["creep_factor"]] = 0.0  # conservative part: no creep forces
        self.K = mi.K if creep else self.Kc

    def conservative(self, q: np.ndarray, s: float) -> np.ndarray:
        x = np.zeros(L.N_STATE)
        x[:NQ] = q
        d, code = self.mi.derivative(x, s, self.Kc)
        if code:
            raise RuntimeError(f"conservative force evaluation failed: {L.FAILURE_REASONS[code]}")
        return self.M * d[NQ : 2 * NQ]

    def potential(self, q: np.ndarray, s: float) -> float:
        total = 0.0
        for part in range(_PATH_PARTS):
            a = part / _PATH_PARTS
            for xg, wg in zip(_GL_X, _GL_W, strict=True):
                lam = a + (xg + 1.0) / (2.0 * _PATH_PARTS)
                total -= wg / (2.0 * _PATH_PARTS) * float(self.conservative(lam * q, s) @ q)
        return total

    def energy(self, x: np.ndarray, s: float) -> float:
        v = x[NQ : 2 * NQ]
        return 0.5 * float(self.M @ (v * v)) + self.potential(x[:NQ], s)

    def augmented(self, y: np.ndarray, s: float) -> np.ndarray:
        x = y[:-1]
        d, code = self.mi.derivative(x, s, self.K)
        if code:
            raise RuntimeError(f"simulation failed: {L.FAILURE_REASONS[code]}")
        v = x[NQ : 2 * NQ]
        f_nc = self.M * d[NQ : 2 * NQ] - self.conservative(x[:NQ], s)
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
    mechanical energy (module docstring). ``creep=False`` switches the creep forces off."""
    cond = WorkingCondition(
        name="energy-audit", speed_kmh=speed_kmh, duration_s=max(duration_s, 1.0),
        irregularity_class=None, lead_in_m=0.0,
    )  # fmt: skip
    mi = model_inputs(params, cond, wagon)
    audit = _Audit(mi, creep)
    V = cond.speed
    y = np.append(np.asarray(x0, dtype=float), 0.0)
    e0 = audit.energy(y[:-1], 0.0)
    n = round(duration_s / dt)
    for i in range(n):
        s = V * i * dt
        k1 = audit.augmented(y, s)
        k2 = audit.augmented(y + 0.5 * dt * k1, s + 0.5 * V * dt)
        k3 = audit.augmented(y + 0.5 * dt * k2, s + 0.5 * V * dt)
        k4 = audit.augmented(y + dt * k3, s + V * dt)
        y = y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    e1 = audit.energy(y[:-1], V * n * dt)
    return EnergyAudit(e0, e1, float(y[-1]), float(-y[-1] / e0) if e0 else 0.0)
