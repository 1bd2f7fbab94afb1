"""Modal analysis of the wagon: the equations of :mod:`railsusp.vehicle.model` linearised about
the static equilibrium on ideal straight, level track, with natural frequencies, damping
ratios and mode names.

Method. The state x of ``model.rhs`` (displacements, velocities and the auxiliary friction
states, all deviations from static equilibrium) is zero at the static equilibrium on ideal
track: the constants vector K carries the static preloads of every interface, so
rhs(0) = 0 up to round-off (:attr:`ModalResult.equilibrium_residual` says how close).
The Jacobian A = d(rhs)/dx at x = 0 is taken by central finite differences over the full
first-order state (every column checked against a ten times smaller step), its eigenvalues
λ = -ζ ω_n ± i ω_n sqrt(1 - ζ²) give the natural frequency f_n = |λ| / 2π and the damping
ratio ζ = -Re λ / |λ|, and each mode is named from where its kinetic energy sits
(m_i |v_i|² per degree of freedom, v the velocity part of the eigenvector). A real
eigenvalue λ = -σ is an overdamped mode: it does not oscillate, so it has no natural
frequency; it decays as exp(-t / τ) with the time constant τ = 1 / σ
(:attr:`ModalResult.overdamped`, :attr:`ModalResult.time_constant_s`).

Friction. A Coulomb slider linearised at zero state is **stuck**: inside its limit the
friction force follows its stick stiffness, so the wedges act as springs in parallel with
the spring nests and the body-bolster yaw friction as a yaw spring, and none of them
dissipates energy (``friction="stuck"``, the default). The **sliding** variant sets every
friction limit to zero through K (the constants named ``mu_*``: wedge ratio, centre-plate
and side-bearer friction coefficients; never the wheel-rail ``mu``): a slider that slides
passes a force of constant magnitude whose increment is zero, so its linearisation has no
stiffness and no damping, which is what zero limits give. Neither variant shows friction
damping, which is amplitude dependent; the free-decay analysis
(:mod:`railsusp.vehicle.decay`) measures it on the nonlinear simulator.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.mode_names import (
    DOF_NAMES,
    GROUPS,
    NO_MOTION_GROUP,
    NO_MOTION_NAME,
    distinct_names,
    name_mode,
)
from railsusp.vehicle.operating_point import (
    FRICTION_LIMIT_KEYS,
    FRICTION_MODES,
    Friction,
    LinearisationPoint,
    check_real,
    dof_inertia,
    linearisation_point,
)
from railsusp.vehicle.wagon import WagonData

__all__ = [
    "DOF_NAMES",
    "FRICTION_LIMIT_KEYS",
    "FRICTION_MODES",
    "F_MAX_LIMIT_HZ",
    "GROUPS",
    "NO_MOTION_GROUP",
    "NO_MOTION_NAME",
    "STEP_RANGE",
    "Friction",
    "LinearisationPoint",
    "ModalResult",
    "default_steps",
    "distinct_names",
    "dof_inertia",
    "jacobian",
    "linearisation_point",
    "modal_analysis",
    "modes_of",
    "name_mode",
    "stiffness_and_damping",
]

#: the highest frequency a mode table or a free-decay analysis may be asked to list up to,
#: Hz (``--fmax``, ``f_max``): the wagon's modes end near 1 kHz (wheelset on the rail)
F_MAX_LIMIT_HZ = 1000.0
#: accepted finite-difference steps of the displacements and velocities (m, rad, m/s): the
#: Jacobian's columns are refined down to a millionth of the step, so below 1e-9 they reach
#: round-off, and above 1e-4 the contact's nonlinearity shows
STEP_RANGE: tuple[float, float] = (1e-9, 1e-4)
#: relative agreement asked of a Jacobian column between step h and h/10
_FD_TOL = 1e-3
#: an eigenvalue whose imaginary part is below this share of its magnitude is real (the
#: finite-difference Jacobian leaves 1e-16 relative on roots that are real)
_REAL_TOL = 1e-8


def real_roots(lam: np.ndarray) -> np.ndarray:
    """Per eigenvalue, whether it is real (an overdamped mode): its imaginary part below
    :data:`_REAL_TOL` of its magnitude."""
    return np.abs(lam.imag) <= _REAL_TOL * np.abs(lam)


# ---------------------------------------------------------------- linearisation
def jacobian(
    f: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, steps: np.ndarray
) -> np.ndarray:
    """Central-difference Jacobian of f at x0. Each column starts at its step and is taken
    ten times smaller while it changes by more than 0.1 % (up to six times): the steps
    are small enough for the contact nonlinearity and large enough for round-off."""
    n = x0.size
    J = np.empty((n, n))
    for j in range(n):
        h = steps[j]
        col = _central(f, x0, j, h)
        for _ in range(6):
            finer = _central(f, x0, j, h / 10.0)
            scale = max(np.abs(finer).max(), 1e-12)
            if np.abs(finer - col).max() <= _FD_TOL * scale:
                break
            h, col = h / 10.0, finer
        J[:, j] = col
    return J


def _central(f, x0, j, h):
    xp = x0.copy()
    xm = x0.copy()
    xp[j] += h
    xm[j] -= h
    return (f(xp) - f(xm)) / (2.0 * h)


def default_steps(step: float = 1e-6, aux_step: float = 1.0) -> np.ndarray:
    """Finite-difference steps over the state: ``step`` for displacements (m, rad) and
    velocities, ``aux_step`` for the auxiliary friction states (forces, N, and moments,
    N m; a stuck slider is linear in its state, so any step inside its limit serves)."""
    h = np.full(L.N_STATE, step)
    h[2 * L.N_DOF :] = aux_step
    return h


# ---------------------------------------------------------------- result
@dataclass
class ModalResult:
    """Eigen-analysis of the linearised wagon.

    Per mode (one per complex-conjugate pair, or one real root): eigenvalue (1/s), |λ| / 2π
    (Hz: the natural frequency of an oscillating mode; for an overdamped real root λ = -σ
    the corner frequency σ / 2π of its first-order decay, not a frequency it moves at, see
    :attr:`overdamped` and :attr:`time_constant_s`), damping ratio (1 for a real root),
    name, the body group carrying most kinetic energy, the car body's share of kinetic
    energy, the share per degree of freedom (``energy``, rows sum to 1) and the
    displacement part of the eigenvector (``shapes``).
    ``equilibrium_residual``: max |rhs(0)| over the accelerations (m/s², rad/s²): the
    linearisation point is an equilibrium to that accuracy. ``parameters`` and
    ``constants``: the point's P and K (the parameter set, wagon, speed and friction variant
    it was linearised with), so that a user of the result (the free decay's modal filters)
    can tell whether it is the linearisation of its own runs; None where not recorded.
    """

    speed_kmh: float
    friction: str
    eigenvalues: np.ndarray
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    names: list[str]
    groups: list[str]
    car_body_share: np.ndarray
    energy: np.ndarray
    shapes: np.ndarray
    equilibrium_residual: float
    jacobian: np.ndarray = field(repr=False)
    parameters: np.ndarray | None = field(default=None, repr=False)
    constants: np.ndarray | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return self.eigenvalues.size

    @property
    def overdamped(self) -> np.ndarray:
        """Per mode, whether its eigenvalue is real: an overdamped mode, which decays without
        oscillating (a stuck slider's stiffness against a damper, or a light body on stiff
        pads and much damping)."""
        return real_roots(self.eigenvalues)

    @property
    def time_constant_s(self) -> np.ndarray:
        """Per mode, the time constant τ = 1 / σ (s) of an overdamped mode's decay
        exp(-t / τ) (λ = -σ); NaN for an oscillating mode."""
        return np.where(self.overdamped, -1.0 / self.eigenvalues.real, np.nan)

    def to_dataframe(self, f_max: float | None = None):
        """Modes as a pandas DataFrame in the order of |λ| (optionally up to ``f_max`` Hz of
        |λ| / 2π). An oscillating mode has its natural frequency and damping ratio; an
        overdamped one its time constant, its frequency and damping ratio blank (NaN): it
        has no frequency, and one real root does not define a damping ratio."""
        import pandas as pd

        real = self.overdamped
        df = pd.DataFrame(
            {
                "mode": self.names,
                "frequency_Hz": np.where(real, np.nan, self.frequency_hz),
                "damping_ratio": np.where(real, np.nan, self.damping_ratio),
                "time_constant_s": self.time_constant_s,
                "group": self.groups,
                "car_body_energy": self.car_body_share,
            }
        )
        if f_max is not None:
            df = df[self.frequency_hz <= f_max]
        return df.reset_index(drop=True)

    def car_body_modes(self, f_max: float = 20.0, min_share: float = 0.5) -> np.ndarray:
        """Indices of the oscillating modes below ``f_max`` Hz whose kinetic energy is mostly
        (at least ``min_share``) in the car body (an overdamped mode has no frequency to
        compare, nor a decay to fit a damped sinusoid to)."""
        sel = (self.frequency_hz <= f_max) & (self.car_body_share >= min_share) & ~self.overdamped
        return np.flatnonzero(sel)

    def car_body_kinds(self, f_max: float = 20.0) -> dict[str, int]:
        """The car-body modes below ``f_max`` Hz, one per kind (bounce, pitch, yaw, lower
        sway, upper sway, lateral): where the coupling with the bogies' lateral dynamics
        gives two modes of one kind, the one with the larger car-body energy share. At most
        five (the car body's five freedoms), those with the largest shares. Kinematic
        (hunting-like) body modes ride on the wheelsets, not on the suspension, and are
        left out."""
        best: dict[str, int] = {}
        for i in self.car_body_modes(f_max):
            if "kinematic" in self.names[i]:
                continue
            kind = self.names[i].split(" (")[0].split(",")[0].removeprefix("car body ")
            if kind not in best or self.car_body_share[i] > self.car_body_share[best[kind]]:
                best[kind] = i
        top = sorted(best.items(), key=lambda kv: -self.car_body_share[kv[1]])[:5]
        return dict(sorted(top, key=lambda kv: self.frequency_hz[kv[1]]))

    def find(self, name: str) -> int:
        """Index of the lowest-frequency mode whose name contains ``name``."""
        hits = [i for i, n in enumerate(self.names) if name in n]
        if not hits:
            raise KeyError(f"no mode named like {name!r}; modes: {sorted(set(self.names))}")
        return hits[0]


def modal_analysis(
    params: ParameterSet | None = None,
    wagon: WagonData | None = None,
    speed_kmh: float = 60.0,
    friction: Friction = "stuck",
    step: float = 1e-6,
) -> ModalResult:
    """Linearise the wagon about its static equilibrium on ideal straight, level track at
    ``speed_kmh`` (1-200 km/h, a working condition's range) and return its modes (module
    docstring: method, friction variants); ``step``: the finite-difference step
    (:data:`STEP_RANGE`)."""
    step = check_real("step", step, *STEP_RANGE, "m")
    point = linearisation_point(params, wagon, speed_kmh, friction)
    x0 = np.zeros(L.N_STATE)
    residual = float(np.abs(point.rhs(x0)[L.N_DOF : 2 * L.N_DOF]).max())
    A = jacobian(point.rhs, x0, default_steps(step))
    return modes_of(A, point, speed_kmh, residual)


def modes_of(
    A: np.ndarray, point: LinearisationPoint, speed_kmh: float, residual: float = 0.0
) -> ModalResult:
    """Modes of the state matrix A at a linearisation point, sorted by frequency. A root in
    which no body moves (the sliding variant's zero-limit friction states relaxing) is
    named :data:`NO_MOTION_NAME` in the group :data:`NO_MOTION_GROUP`, with no car-body
    share."""
    lam, vec = np.linalg.eig(A)
    mag = np.abs(lam)
    # zero eigenvalues: the stuck sliders' conserved combinations and neutral motions
    keep = (mag > 1e-6 * max(mag.max(), 1.0)) & (lam.imag >= 0.0)
    lam, vec = lam[keep], vec[:, keep]
    order = np.argsort(np.abs(lam))
    lam, vec = lam[order], vec[:, order]
    inertia = point.dof_inertia()
    q = vec[: L.N_DOF]
    v = vec[L.N_DOF : 2 * L.N_DOF]
    ke = inertia * np.abs(v.T) ** 2
    ke_sum = ke.sum(axis=1, keepdims=True)
    energy = np.divide(ke, ke_sum, out=np.zeros_like(ke), where=ke_sum > 0)
    h_cg = point.K[L.K["h_cg_c"]]
    l_c = point.K[L.K["l_c"]]
    h_cp = point.K[L.K["h_cp"]]
    names, groups = [], []
    real = real_roots(lam)  # overdamped modes are named so
    for i in range(lam.size):
        group, name = name_mode(energy[i], q[:, i], h_cg, l_c, point.speed, h_cp, bool(real[i]))
        groups.append(group)
        names.append(name)
    names = distinct_names(names)
    mag = np.abs(lam)
    return ModalResult(
        speed_kmh=speed_kmh,
        friction=point.friction,
        eigenvalues=lam,
        frequency_hz=mag / (2.0 * np.pi),
        damping_ratio=-lam.real / mag,
        names=names,
        groups=groups,
        car_body_share=energy[:, GROUPS["car body"]].sum(axis=1),
        energy=energy,
        shapes=q.T,
        equilibrium_residual=residual,
        jacobian=A,
        parameters=point.P.copy(),
        constants=point.K.copy(),
    )


def stiffness_and_damping(A: np.ndarray, inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and damping matrices (N/m, N s/m and their rotational forms) of the
    displacement-velocity part of a state matrix: acceleration rows = -M^-1 (K q + C v)."""
    n = L.N_DOF
    Kq = -inertia[:, None] * A[n : 2 * n, :n]
    Cv = -inertia[:, None] * A[n : 2 * n, n : 2 * n]
    return Kq, Cv
