"""The compiled equations at one operating point, callable from Python: the kernel inputs
of one parameter set on ideal straight, level track at one speed (the static equilibrium
is the zero state there), a checked ``rhs`` and the inertia of every degree of freedom.
The modal analysis linearises about it; the free-decay and energy-audit runs start from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from railsusp.conditions import WorkingCondition, field_range, make_condition
from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_real
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.model import rhs as model_rhs
from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays
from railsusp.vehicle.track_grid import track_arrays
from railsusp.vehicle.wagon import WagonData, load_wagon

Friction = Literal["stuck", "sliding"]
FRICTION_MODES: tuple[str, ...] = ("stuck", "sliding")

#: constants set to zero for the sliding linearisation: every friction limit of the
#: suspension (names starting "mu_"), never the wheel-rail friction coefficient "mu"
FRICTION_LIMIT_KEYS: tuple[str, ...] = tuple(n for n in L.K if n.startswith("mu_"))


def _speed_range() -> tuple[float, float]:
    lo, hi = field_range("speed_kmh")
    assert lo is not None and hi is not None  # a working condition bounds its speed
    return float(lo), float(hi)


#: the running speeds a linearisation accepts, km/h: a working condition's (one source)
SPEED_RANGE_KMH: tuple[float, float] = _speed_range()


def check_real(
    name: str, value: object, lo: float, hi: float, unit: str, *, lo_open: bool = False
) -> float:
    """``value`` as a float if it is a real number from ``lo`` to ``hi`` (``lo`` itself
    excluded where ``lo_open``); otherwise a one-line :class:`RailsuspInputError` naming
    ``name``, the value and the accepted range (``unit`` after the numbers). The API checks
    of the modal, free-decay and energy-audit functions, so that a bad number is refused
    before it reaches a division or the integrator."""
    low = f"({lo:g}, {hi:g}] {unit}" if lo_open else f"{lo:g} to {hi:g} {unit}"
    if not is_real(value):
        raise RailsuspInputError(f"{name} = {value!r}: a number is needed; accepted {low}")
    x = float(value)  # type: ignore[arg-type]
    inside = lo < x <= hi if lo_open else lo <= x <= hi
    if not (math.isfinite(x) and inside):
        raise RailsuspInputError(f"{name} = {x:g} {unit}: accepted {low}")
    return x


def check_speed(speed_kmh: object, name: str = "speed_kmh") -> float:
    """The running speed, checked against :data:`SPEED_RANGE_KMH` (a working condition's
    range) before anything divides by it."""
    return check_real(name, speed_kmh, *SPEED_RANGE_KMH, "km/h")


class OperatingPointError(RuntimeError):
    """The model fails at the state it is linearised about (a failure code of its right-hand
    side: a wheel through its rail, a state not finite), as wagon data far outside what a
    wagon is (a car body of 1e30 kg) make it."""


@dataclass(frozen=True)
class LinearisationPoint:
    """Everything ``model.rhs`` needs on ideal straight, level track at one speed: the
    parameter vector P (X1..X20, SI), constants K, track channels and contact table, and the
    track position of the leading wheelset (mid-section, away from the grid's ends)."""

    P: np.ndarray
    K: np.ndarray
    track: np.ndarray
    s0: float
    ds: float
    contact: object  # setup.ContactArrays
    s_front: float
    speed: float  # m/s
    friction: str

    def rhs(self, x: np.ndarray, s_front: float | None = None) -> np.ndarray:
        """d x / d t at state x (raises :class:`OperatingPointError` on a failure code of the
        model)."""
        dxdt = np.zeros(L.N_STATE)
        out = np.zeros(L.N_OUT_WORK)
        ca = self.contact
        code = model_rhs(
            np.ascontiguousarray(x, dtype=float), dxdt, self.P, self.K, self.track, self.s0,
            self.ds, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R,
            self.s_front if s_front is None else s_front, out,
        )  # fmt: skip
        if code != 0:
            raise OperatingPointError(f"model.rhs failed: {L.FAILURE_REASONS.get(code, code)}")
        return dxdt

    def dof_inertia(self) -> np.ndarray:
        """Mass or moment of inertia of each degree of freedom (kg, kg m²)."""
        return dof_inertia(self.K, self.P)


def linearisation_point(
    params: ParameterSet | None = None,
    wagon: WagonData | None = None,
    speed_kmh: float = 60.0,
    friction: Friction = "stuck",
    track_length_m: float = 200.0,
) -> LinearisationPoint:
    """Model inputs for ideal straight, level track at ``speed_kmh`` (validated as a working
    condition: 1-200 km/h), built the way :func:`railsusp.vehicle.simulate.simulate_batch`
    builds them. ``friction="sliding"`` zeros the friction limits (module docstring)."""
    if friction not in FRICTION_MODES:
        raise RailsuspInputError(f"friction = {friction!r}: accepted {', '.join(FRICTION_MODES)}")
    speed_kmh = check_speed(speed_kmh)
    wagon = load_wagon(wagon)
    cond = ideal_track(speed_kmh, track_length_m)
    P = (params or ParameterSet.nominal()).to_array()
    return point_of(P, wagon, cond, friction)


def ideal_track(speed_kmh: float, track_length_m: float = 200.0) -> WorkingCondition:
    """The working condition of a linearisation: ideal straight, level track at
    ``speed_kmh`` (validated: 1-200 km/h), no lead-in, ``track_length_m`` of record."""
    speed_kmh = check_speed(speed_kmh)
    return make_condition(
        {
            "name": "modal",
            "speed_kmh": speed_kmh,
            "irregularity_class": None,
            "lead_in_m": 0.0,
            "duration_s": min(600.0, max(1.0, track_length_m / (speed_kmh / 3.6))),
        }
    )


def point_of(
    P: np.ndarray, wagon: WagonData, cond: WorkingCondition, friction: Friction = "stuck"
) -> LinearisationPoint:
    """:func:`linearisation_point` of a parameter vector ``P`` (SI, catalogue order) as the
    simulator has it, unchecked, on the ideal straight track of condition ``cond``."""
    settings = SolverSettings()
    P = np.ascontiguousarray(P, dtype=float)
    ca = contact_arrays(wagon)
    K = constants(wagon, cond, P, ca, settings)
    if friction == "sliding":
        for name in FRICTION_LIMIT_KEYS:
            K[L.K[name]] = 0.0
    tracks, s0, ds = track_arrays(cond, [0], wagon, settings)
    return LinearisationPoint(
        P=P,
        K=np.ascontiguousarray(K),
        track=np.ascontiguousarray(tracks[0]),
        s0=s0,
        ds=ds,
        contact=ca,
        s_front=0.5 * cond.section_length_m,
        speed=cond.speed,
        friction=friction,
    )


def dof_inertia(K: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Mass or moment of inertia of each of the N_DOF displacements (kg, kg m²), read from
    the constants vector and the catalogue (wheelset mass and inertias are X1, X2, X4)."""
    k = L.K
    m = np.empty(L.N_DOF)
    m[L.CB_Y] = m[L.CB_Z] = K[k["m_c"]]
    m[L.CB_ROLL], m[L.CB_PITCH], m[L.CB_YAW] = K[k["Ix_c"]], K[k["Iy_c"]], K[k["Iz_c"]]
    for b in range(2):
        i = L.BOL0 + 4 * b
        m[i : i + 4] = K[k["m_b"]], K[k["m_b"]], K[k["Ix_b"]], K[k["Iz_b"]]
    for j in range(4):
        i = L.SF0 + 5 * j
        m[i : i + 5] = K[k["m_f"]], K[k["m_f"]], K[k["m_f"]], K[k["Iy_f"]], K[k["Iz_f"]]
    for w in range(4):
        i = L.WS0 + 4 * w
        m[i : i + 4] = P[0], P[0], P[1], P[3]
    return m
