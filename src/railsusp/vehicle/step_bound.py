"""The largest RK4 step at which the wagon's fastest decaying motion stays stable.

Why. The creep forces damp the wheelsets' lateral and yaw motion with coefficients f22 / V
and f11 b² / V (Kalker's linear theory: the creepages are velocities over the running
speed V), so the wagon's most negative eigenvalue grows as the speed falls: about
-1900 1/s at 60 km/h, -2700 at 42 km/h, -5500 at 20 km/h for the loaded C80 on ideal
straight track (linearised as :mod:`railsusp.vehicle.modes` does). Classic RK4 is stable
on the negative real axis only up to |h λ| = 2.785 (Hairer & Wanner, Solving Ordinary
Differential Equations II, section IV.2), so the fixed 1 ms step went unstable below about
42 km/h: the wheelsets' creep motion oscillated from step to step, the creep saturation
held it bounded and the anti-alias filter hid it, and the loaded wagon on ideal track read
13 kN of lateral force at 30 km/h against the converged 1.6 kN, with no failure flagged.

What. :func:`stable_step` linearises the wagon at the condition's speed (the static
equilibrium on ideal straight track, friction stuck) and returns ``STEP_EIGEN_LIMIT /
max |λ|``; the simulator takes the smaller of it and ``SolverSettings.max_step``. With the
limit at 2.0 (|R(hλ)| = 0.33 on the real axis, against e^-2 = 0.14 exact, so the mode
is damped, not ringing at the edge of stability) the 1 ms step is kept at 60 km/h and
above for the C80 and its forces there are unchanged bit for bit; it is shortened below
about 58 km/h. The bound is kept per wagon, speed and fixed (not sampled) parameters: the
masses and inertias it depends on are the fixed ones, and a campaign's sets share them.
"""

from __future__ import annotations

import warnings

import numpy as np

from railsusp.params import CATALOGUE
from railsusp.vehicle import layout as L
from railsusp.vehicle.wagon import WagonData

#: largest |h λ| accepted for the linearised wagon's eigenvalues (RK4's real-axis limit is
#: 2.785; its imaginary-axis limit 2.828)
STEP_EIGEN_LIMIT = 2.0

#: the parameters a bound is kept for: the fixed ones (masses, inertias, spans)
FIXED_PARAMETERS = np.array([not s.is_sampled for s in CATALOGUE])
_NOMINAL = np.array([s.nominal for s in CATALOGUE], dtype=float)

#: no step is shortened below this (s): the loaded C80 needs 1.9e-5 s at 1 km/h, the
#: slowest working condition; a set needing less is warned of (:func:`set_steps`)
STEP_FLOOR = 1e-5

_bounds: dict[tuple, float] = {}


def stable_step(wagon: WagonData, speed_kmh: float, P: np.ndarray) -> float:
    """The largest step (s) with |h λ| <= :data:`STEP_EIGEN_LIMIT` for every eigenvalue λ of
    the wagon linearised at ``speed_kmh`` with the fixed parameters of ``P`` (SI, catalogue
    order, as the simulator has them: unchecked) and the sampled ones nominal; inf where the
    linearisation fails (the simulator then reports the failure itself)."""
    from railsusp.vehicle.modes import default_steps, jacobian
    from railsusp.vehicle.operating_point import OperatingPointError, ideal_track, point_of

    # the sampled parameters at nominal: the bound is the same for every set of a campaign
    # whatever set comes first (they move max |λ| by under 2 %, inside the limit's margin
    # to RK4's 2.785), so a campaign's step does not depend on its batches' order
    P = np.where(FIXED_PARAMETERS, np.asarray(P, dtype=float), _NOMINAL)
    key = (wagon.model_dump_json(), float(speed_kmh), P[FIXED_PARAMETERS].tobytes())
    if key not in _bounds:
        try:
            point = point_of(P, wagon, ideal_track(float(speed_kmh)))
            A = jacobian(point.rhs, np.zeros(L.N_STATE), default_steps())
            fastest = float(np.abs(np.linalg.eigvals(A)).max())
        except (OperatingPointError, np.linalg.LinAlgError, ValueError):
            fastest = 0.0
        _bounds[key] = STEP_EIGEN_LIMIT / fastest if fastest > 0.0 else float("inf")
    return _bounds[key]


def set_steps(wagon: WagonData, speed_kmh: float, P: np.ndarray, max_step: float) -> np.ndarray:
    """Each set's step (s) of a batch ``P`` (n, 20): :func:`stable_step` of its fixed
    parameters (one linearisation per distinct row: one for a campaign, whose sets share
    them) and ``max_step``, the smaller, so that a set's forces do not depend on the other
    sets of its batch. Never below :data:`STEP_FLOOR`: a set that needs less (a wheelset
    of 1 g, or of 300 kg at 1 km/h) runs at the floor, where it may not converge, and is
    warned of (taking the full ``max_step`` instead gave 44 kN where 1.6 kN is right)."""
    fixed = np.asarray(P, dtype=float)[:, FIXED_PARAMETERS]
    _, first, inverse = np.unique(fixed, axis=0, return_index=True, return_inverse=True)
    bounds = np.array([stable_step(wagon, speed_kmh, P[i]) for i in first])
    short = np.flatnonzero(bounds < STEP_FLOOR)
    if short.size:
        sets = np.flatnonzero(np.isin(inverse.reshape(-1), short))
        warnings.warn(
            f"set(s) {', '.join(map(str, sets[:8]))}{' ...' if sets.size > 8 else ''}: at "
            f"{speed_kmh:g} km/h their masses need an RK4 step of {bounds[short].min():.3g} s, "
            f"below the {STEP_FLOOR:g} s floor: run at the floor, their forces may not "
            "converge (check the fixed parameters X1-X10)",
            stacklevel=3,
        )
    return np.minimum(max_step, np.maximum(bounds, STEP_FLOOR))[inverse.reshape(-1)]
