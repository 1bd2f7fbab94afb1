"""Free-decay analysis of the car-body modes on the nonlinear simulator, friction on.

The wagon runs over otherwise ideal straight, level track with one short input (a cosine
dip of one or both rails, a lateral kink of both rails; :data:`EXCITATIONS`) and then
rolls freely. Which modes: every mode below ``f_max`` whose kinetic energy is at least
:data:`CAR_BODY_SHARE` in the car body (the car-body modes and the bogie modes that carry
the body with them), whatever its name. Each such mode's coordinate is read from the whole
recorded state (displacements, velocities, friction states) with the mode's left
eigenvector of the linearised model (:mod:`railsusp.vehicle.modes`, same friction
variant): a modal filter, eta_i = w_i^H x with w_i^H v_i = 1, which separates modes of
nearby frequency (the body's lateral modes at 1.66-1.74 Hz) that the car body's five
displacements alone cannot. Its free decay, from the moment the last wheelset has left the
input, is fitted with one damped sinusoid plus offset, A exp(-σ t) cos(ω_d t + φ) + c
(nonlinear least squares, on Re eta). Frequency f_n = sqrt(σ² + ω_d²) / 2π and the
**equivalent damping ratio** ζ = σ / sqrt(σ² + ω_d²) describe the decay over the fitted
window: friction damping depends on amplitude (Coulomb friction takes a fixed amount off
every cycle, and a stuck slider only its pre-sliding loss), so ζ is that of the exponential
closest to the decay actually simulated, not a constant of the wagon. Each mode is
analysed in the run that excites it most (largest sqrt(2 T) of its part of the motion).

Fit quality (:attr:`DecayResult.unreliable`): R² of the fit at least :data:`FIT_R2_MIN`
and the fitted natural frequency within :data:`FREQUENCY_BAND` of the linearised mode's. A
decay that misses either is not that mode's (mixed with another, or the friction changes
state: wedges that slide move a mode from its stuck towards its sliding frequency).

A record that does not oscillate (an overdamped mode, a drift) has no frequency or damping
ratio: the fit gives NaN where the record neither crosses its offset three times nor is
fitted by one damped sinusoid markedly better than by the best non-oscillating decay with as many
parameters (:data:`OSCILLATION_EVIDENCE`), and its row is not ``fit_ok``.

The runs (:mod:`railsusp.vehicle.decay_runs`) use the simulator's equations and its
integrator in a loop that records the whole state.

Inputs are checked before anything runs (one-line :class:`RailsuspInputError` naming the
argument and its accepted range): :data:`AMPLITUDE_RANGE_M` (the command's ``--amplitude``
in mm), :data:`LENGTH_RANGE_M`, :data:`WINDOW_RANGE_S`, ``f_max`` up to
:data:`~railsusp.vehicle.modes.F_MAX_LIMIT_HZ`, the speed a working condition's, and a
``modal`` result must be the linearisation of the runs' own parameters, wagon, speed and
friction variant. A run the model stops (a flange climb of a large kink) raises
:class:`DecayRunError`, which names the amplitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import eig

from railsusp.errors import RailsuspInputError, repeated
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.decay_fit import FIT_MIN_SAMPLES, OSCILLATION_EVIDENCE, fit_damped_sinusoid
from railsusp.vehicle.decay_runs import (
    AMPLITUDE_RANGE_M,
    EXCITATIONS,
    LENGTH_RANGE_M,
    MAX_STEP_S,
    SAMPLE_DT,
    WINDOW_RANGE_S,
    DecayRun,
    DecayRunError,
    decay_run,
    input_passed_s,
)
from railsusp.vehicle.modes import (
    DOF_NAMES,
    F_MAX_LIMIT_HZ,
    FRICTION_MODES,
    Friction,
    LinearisationPoint,
    ModalResult,
    linearisation_point,
    modal_analysis,
)
from railsusp.vehicle.operating_point import check_real, check_speed
from railsusp.vehicle.step_bound import STEP_FLOOR, stable_step
from railsusp.vehicle.wagon import WagonData, load_wagon

#: a mode takes part in the decay analysis when the car body carries at least this share of
#: its kinetic energy. For the loaded wagon at 60 km/h the shares below 20 Hz are either
#: above 0.38 (the car-body modes, 0.90-0.99, and the bogies' kinematic modes at 2.3 Hz,
#: 0.39-0.41 with the wedges' warp friction) or below 0.05, so the choice is not on a
#: boundary.
CAR_BODY_SHARE = 0.2
#: least R² of the damped-sinusoid fit of a mode's free decay
FIT_R2_MIN = 0.99
#: largest relative difference of the fitted natural frequency from the linearised mode's
FREQUENCY_BAND = 0.05


# ---------------------------------------------------------------- estimation
@dataclass
class DecayResult:
    """Equivalent damping of the car-body modes from free-decay runs (module docstring).

    Per mode (``rows``): its name, car-body share of kinetic energy and linearised frequency
    and damping ratio, the run that excites it most, the fitted natural frequency (Hz),
    equivalent damping ratio, modal amplitude (sqrt(2 T) of the mode's part of the motion at
    its largest in the window, sqrt(J)), R² of the fit, the fitted over the linear frequency,
    and whether the fit meets :data:`FIT_R2_MIN` and :data:`FREQUENCY_BAND` (``fit_ok``).
    The linear figures are those of the linearisation with the runs' friction variant
    (``friction``: "stuck" for the modelled friction, whose sliders stick at small
    amplitude)."""

    speed_kmh: float
    rows: list[dict]
    runs: list[DecayRun]
    window_s: float
    friction: str = "stuck"

    def to_dataframe(self):
        """One row per mode, by linear frequency."""
        import pandas as pd

        return pd.DataFrame(self.rows)

    def row(self, name: str) -> dict:
        """The first mode whose name contains ``name``."""
        for row in self.rows:
            if name in row["mode"]:
                return row
        raise KeyError(f"no car-body mode named like {name!r}")

    def damping(self, name: str) -> float:
        """Equivalent damping ratio of the first mode whose name contains ``name``."""
        return self.row(name)["damping_ratio"]

    @property
    def unreliable(self) -> list[dict]:
        """The rows whose fit misses :data:`FIT_R2_MIN` or :data:`FREQUENCY_BAND`."""
        return [row for row in self.rows if not row["fit_ok"]]


def modal_filters(modal: ModalResult, modes: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Left and right eigenvectors (N_STATE, len(modes)) of the given modes of a modal
    result's state matrix, scaled so that w_i^H v_i = 1: eta_i = w_i^H x is mode i's
    coordinate in a state x (exactly, for the linear model)."""
    lam, left, right = eig(modal.jacobian, left=True, right=True)
    ws, vs = [], []
    for i in modes:
        j = int(np.argmin(np.abs(lam - modal.eigenvalues[i])))
        if abs(lam[j] - modal.eigenvalues[i]) > 1e-6 * abs(modal.eigenvalues[i]):
            raise RuntimeError(f"mode {modal.names[i]!r}: eigenvalue not found again")
        w, v = left[:, j], right[:, j]
        ws.append(w / np.conj(np.vdot(w, v)))
        vs.append(v)
    return np.array(ws).T, np.array(vs).T


def free_decay(
    params: ParameterSet | None = None,
    wagon: WagonData | None = None,
    speed_kmh: float = 60.0,
    *,
    excitations: tuple[str, ...] = EXCITATIONS,
    amplitude_m: float = 0.005,
    length_m: float = 2.0,
    window_s: float = 6.0,
    f_max: float = 20.0,
    friction: Friction = "stuck",
    modal: ModalResult | None = None,
) -> DecayResult:
    """Free-decay frequency and equivalent damping ratio of every mode below ``f_max`` Hz
    with at least :data:`CAR_BODY_SHARE` of its kinetic energy in the car body (module
    docstring): one run per excitation, each ``window_s`` of free decay after the input has
    passed. ``friction``: the simulator's friction ("stuck" = as modelled; "sliding" zeroes
    the friction limits, for comparison); ``modal``: the linearisation whose left
    eigenvectors read the modal coordinates (default: the same friction variant's; one
    given must be of the same parameters, wagon, speed and friction).

    Accepted (checked before anything runs): ``excitations`` a non-empty tuple of
    :data:`EXCITATIONS`, each once; ``amplitude_m`` :data:`AMPLITUDE_RANGE_M`; ``length_m``
    :data:`LENGTH_RANGE_M`; ``window_s`` :data:`WINDOW_RANGE_S`; ``f_max`` (0,
    :data:`~railsusp.vehicle.modes.F_MAX_LIMIT_HZ`] Hz with a mode to analyse below it;
    ``speed_kmh`` a working condition's 1-200 km/h. A run the model stops raises
    :class:`DecayRunError` (naming the amplitude)."""
    excitations = _check_excitations(excitations)
    amplitude_m = check_real("amplitude_m", amplitude_m, *AMPLITUDE_RANGE_M, "m")
    length_m = check_real("length_m", length_m, *LENGTH_RANGE_M, "m")
    window_s = check_real("window_s", window_s, *WINDOW_RANGE_S, "s")
    f_max = check_real("f_max", f_max, 0.0, F_MAX_LIMIT_HZ, "Hz", lo_open=True)
    speed_kmh = check_speed(speed_kmh)
    if friction not in FRICTION_MODES:
        raise RailsuspInputError(f"friction = {friction!r}: accepted {', '.join(FRICTION_MODES)}")
    wagon = load_wagon(wagon)
    point = linearisation_point(params, wagon, speed_kmh, friction)
    if modal is None:
        modal = modal_analysis(params, wagon, speed_kmh, friction)
    else:
        _check_modal(modal, point, speed_kmh)
    chosen = [int(i) for i in modal.car_body_modes(f_max, CAR_BODY_SHARE)]
    if not chosen:
        every = modal.car_body_modes(math.inf, CAR_BODY_SHARE)
        lowest = f"{modal.frequency_hz[every].min():.3g} Hz" if every.size else "none"
        raise RailsuspInputError(
            f"f_max = {f_max:g} Hz: no oscillating mode below it has {CAR_BODY_SHARE:.0%} of "
            f"its kinetic energy in the car body (the lowest: {lowest}); accepted f_max "
            f"above that, up to {F_MAX_LIMIT_HZ:g} Hz"
        )
    filters, vectors = modal_filters(modal, chosen)
    # the mode's part of the motion, 2 Re(eta v): its kinetic energy at |eta| = 1
    inertia = point.dof_inertia()
    vel = vectors[L.N_DOF : 2 * L.N_DOF]
    unit_energy = np.sqrt((inertia[:, None] * np.abs(2.0 * vel) ** 2).sum(axis=0))
    runs, coords = [], []
    free = input_passed_s(point, length_m)
    # 1 ms, or RK4's stability bound where the speed makes it shorter (the fixed 1 ms went
    # unstable below about 42 km/h: damping ratios 0.445 against 0.404 at 30 km/h)
    stable = min(MAX_STEP_S, stable_step(wagon, speed_kmh, point.P))
    if stable < STEP_FLOOR:
        raise RailsuspInputError(
            f"speed_kmh = {speed_kmh:g} km/h: this wagon needs RK4 steps of {stable:.2g} s "
            f"here, below the {STEP_FLOOR:g} s floor; accepted a higher speed"
        )
    dt = SAMPLE_DT / math.ceil(SAMPLE_DT / stable - 1e-9)
    for ex in excitations:
        run = decay_run(  # a run the model stops raises DecayRunError
            point,
            ex,
            amplitude_m=amplitude_m,
            length_m=length_m,
            duration_s=free + window_s,
            dt=dt,
            sample_dt=SAMPLE_DT,
        )
        runs.append(run)
        sel = run.time >= run.free_from
        coords.append((run.time[sel], run.state[sel] @ np.conj(filters)))
    rows = []
    for m, i in enumerate(chosen):
        amps = [np.abs(eta[:, m]).max() * unit_energy[m] for _, eta in coords]
        r = int(np.argmax(amps))
        t, eta = coords[r]
        f_n, zeta, _, r2 = fit_damped_sinusoid(t, eta[:, m].real)
        f_lin = float(modal.frequency_hz[i])
        ratio = f_n / f_lin
        rows.append(
            {
                "mode": modal.names[i],
                "car_body_energy": float(modal.car_body_share[i]),
                "linear_frequency_Hz": f_lin,
                "linear_damping_ratio": float(modal.damping_ratio[i]),
                "excitation": runs[r].excitation,
                "frequency_Hz": f_n,
                "damping_ratio": zeta,
                "amplitude": float(amps[r]),
                "fit_R2": r2,
                "frequency_ratio": ratio,
                "fit_ok": bool(r2 >= FIT_R2_MIN and abs(ratio - 1.0) <= FREQUENCY_BAND),
            }
        )
    return DecayResult(
        speed_kmh=speed_kmh, rows=rows, runs=runs, window_s=window_s, friction=friction
    )


def _check_excitations(excitations: object) -> tuple[str, ...]:
    """The excitations of :func:`free_decay` as a tuple: a non-empty tuple or list of
    :data:`EXCITATIONS`, each once (a bare string is refused: iterated, "dip" was read as
    the excitations 'd', 'i', 'p')."""
    accepted = f"accepted a non-empty tuple of {', '.join(EXCITATIONS)}, each once"
    if not isinstance(excitations, tuple | list) or not excitations:
        raise RailsuspInputError(f"excitations = {excitations!r}: {accepted} (e.g. ('dip',))")
    for ex in excitations:
        if ex not in EXCITATIONS:
            raise RailsuspInputError(f"excitations: {ex!r} unknown; {accepted}")
    twice = repeated(list(excitations))
    if twice:
        raise RailsuspInputError(f"excitations: {', '.join(twice)} given twice; {accepted}")
    return tuple(excitations)


def _check_modal(modal: ModalResult, point: LinearisationPoint, speed_kmh: float) -> None:
    """Refuse a ``modal`` result that is not the linearisation of the runs at ``point``:
    its left eigenvectors would read the state of another wagon (another speed, friction
    variant, parameter set or wagon data) and its modes would be compared with decays they
    are not (measured: every row's fit failed, R² down to -675, silently)."""
    if not isinstance(modal, ModalResult):
        raise RailsuspInputError(
            f"modal: a {type(modal).__name__}; accepted a ModalResult of modal_analysis"
        )
    runs = f"the runs are at {speed_kmh:g} km/h, friction {point.friction}"
    if modal.speed_kmh != speed_kmh or modal.friction != point.friction:
        raise RailsuspInputError(
            f"modal: linearised at {modal.speed_kmh:g} km/h, friction {modal.friction}; "
            f"{runs}: accepted the modal result of the same speed and friction (or none)"
        )
    if (
        modal.constants is not None
        and modal.parameters is not None
        and not (
            np.array_equal(modal.constants, point.K) and np.array_equal(modal.parameters, point.P)
        )
    ):
        raise RailsuspInputError(
            "modal: linearised with other parameters or wagon data than the runs'; accepted "
            "the modal result of the same parameter set and wagon (or none)"
        )


__all__ = [
    "AMPLITUDE_RANGE_M",
    "CAR_BODY_SHARE",
    "DOF_NAMES",
    "FIT_MIN_SAMPLES",
    "FIT_R2_MIN",
    "FREQUENCY_BAND",
    "OSCILLATION_EVIDENCE",
    "DecayResult",
    "DecayRunError",
    "decay_run",
    "fit_damped_sinusoid",
    "free_decay",
    "modal_filters",
]
