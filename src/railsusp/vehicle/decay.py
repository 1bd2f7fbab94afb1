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

The runs use the simulator's equations (``model.rhs``) and its integrator (fixed-step
classical RK4, the simulator's 1 ms step), here in a loop that records the state, so that
the whole state is available and any initial state can be given.

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

import numba as nb
import numpy as np
from scipy.linalg import eig

from railsusp.errors import RailsuspInputError, repeated
from railsusp.numbers import is_real
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.decay_fit import FIT_MIN_SAMPLES, OSCILLATION_EVIDENCE, fit_damped_sinusoid
from railsusp.vehicle.kernel_cache import FASTMATH  # (sets the kernel cache before any compiles)
from railsusp.vehicle.model import rhs
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

#: the track inputs: a cosine dip of both rails (bounce, pitch), of the left rail only
#: (cross-level: roll and sway, with bounce and pitch), a lateral kink of both rails
#: (lateral, yaw, sway)
EXCITATIONS: tuple[str, ...] = ("dip", "cross-level", "kink")

#: where the input starts on the track, m ahead of the leading wheelset's start
INPUT_START_M = 5.0

CAR_BODY = np.arange(L.CB_Y, L.CB_YAW + 1)
I_V = L.K["V"]

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

#: accepted depth of the dips and offset of the kink, m (the command's --amplitude, 0.5-50
#: mm): below 0.5 mm the decay is lost in the settling of the contact, and from 15 mm the
#: loaded wagon's wedges slide (docs/model.md)
AMPLITUDE_RANGE_M: tuple[float, float] = (0.5e-3, 50e-3)
#: accepted length of the cosine input, m: at least eight steps of the track grid (0.125 m),
#: a short input next to the wagon's 10 m from first to last wheelset
LENGTH_RANGE_M: tuple[float, float] = (1.0, 20.0)
#: accepted free-decay window after the input has passed, s: a second holds a cycle of the
#: slowest car-body mode (about 1 Hz); a minute is 10 km of track at 60 km/h
WINDOW_RANGE_S: tuple[float, float] = (1.0, 60.0)
#: largest integration step of a decay run, s: the simulator's 1 ms (RK4's stability bound
#: is shorter below about 42 km/h: :func:`free_decay` takes it)
MAX_STEP_S = 1.0e-3


class DecayRunError(RuntimeError):
    """A free-decay run that the model stopped (a failure code: a flange climb, a wheel
    lift beyond the flange), as too large an input makes it; names the excitation, the
    amplitude and the reason."""

    def __init__(self, excitation: str, amplitude_m: float, reason: str):
        self.excitation = excitation
        self.amplitude_m = amplitude_m
        self.reason = reason
        super().__init__(
            f"amplitude_m = {amplitude_m:g} m: the free-decay run over the {excitation} "
            f"stopped ({reason}); accepted a smaller amplitude_m for this wagon and speed "
            f"(from {AMPLITUDE_RANGE_M[0]:g} m)"
        )


# ---------------------------------------------------------------- integration
@nb.njit(cache=True, fastmath=FASTMATH)
def run_states(x, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, dt, n_steps, every, idx, out):
    """Integrate from state x (changed in place) for n_steps RK4 steps of dt, the leading
    wheelset at s = V t; every ``every`` steps store x[idx] in the next row of ``out``
    (the first row is the initial state). Returns (failure code, rows written)."""
    ns = x.size
    ks = np.empty((4, ns))
    xt = np.empty(ns)
    o = np.zeros(L.N_OUT_WORK)
    V = K[I_V]
    rows = 0
    for n in range(n_steps + 1):
        if n % every == 0:
            for c in range(idx.size):
                out[rows, c] = x[idx[c]]
            rows += 1
        if n == n_steps:
            break
        s = V * n * dt
        code = rhs(x, ks[0], P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s, o)
        if code != 0:
            return code, rows
        for j in range(1, 4):
            c = 1.0 if j == 3 else 0.5
            for i in range(ns):
                xt[i] = x[i] + c * dt * ks[j - 1, i]
            code = rhs(xt, ks[j], P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s + c * V * dt, o)
            if code != 0:
                return code, rows
        acc = 0.0
        for i in range(ns):
            x[i] += dt / 6.0 * (ks[0, i] + 2.0 * ks[1, i] + 2.0 * ks[2, i] + ks[3, i])
            acc += x[i]
        if not math.isfinite(acc):
            return L.FAIL_NAN, rows
    return L.OK, rows


def track_with_input(
    point: LinearisationPoint, excitation: str, amplitude_m: float, length_m: float
) -> np.ndarray:
    """The point's ideal track with one cosine-shaped input of depth/offset
    ``amplitude_m`` (:data:`AMPLITUDE_RANGE_M`) over ``length_m`` (:data:`LENGTH_RANGE_M`)
    starting :data:`INPUT_START_M` ahead."""
    if excitation not in EXCITATIONS:
        raise RailsuspInputError(f"excitation {excitation!r}: accepted {', '.join(EXCITATIONS)}")
    amplitude_m = check_real("amplitude_m", amplitude_m, *AMPLITUDE_RANGE_M, "m")
    length_m = check_real("length_m", length_m, *LENGTH_RANGE_M, "m")
    trk = point.track.copy()
    s = point.s0 + point.ds * np.arange(trk.shape[1])
    u = (s - INPUT_START_M) / length_m
    bump = np.where((u > 0) & (u < 1), 0.5 * (1.0 - np.cos(2.0 * np.pi * u)), 0.0) * amplitude_m
    if excitation == "dip":
        trk[L.TR_ZL] -= bump
        trk[L.TR_ZR] -= bump
    elif excitation == "cross-level":
        trk[L.TR_ZL] -= bump
    else:
        trk[L.TR_YL] += bump
        trk[L.TR_YR] += bump
    return np.ascontiguousarray(trk)


@dataclass
class DecayRun:
    """The state (n_t, N_STATE) of one run, sampled every ``dt`` s, and the time from which
    it decays freely (the input has passed)."""

    excitation: str
    time: np.ndarray
    state: np.ndarray
    free_from: float

    @property
    def car_body(self) -> np.ndarray:
        """Car-body displacements (n_t, 5: y, z, roll, pitch, yaw; m, rad)."""
        return self.state[:, CAR_BODY]


#: the free-decay runs' state sampling interval, s
SAMPLE_DT = 0.01


def input_passed_s(point: LinearisationPoint, length_m: float) -> float:
    """Time (s) from which a run over an input of ``length_m`` decays freely: the last
    wheelset has left the input (it starts :data:`INPUT_START_M` ahead of the leading
    wheelset, which the trailing one follows at the wagon's axle spread), and 0.2 s more."""
    spread = point.K[L.K["l_c"]] * 2 + point.K[L.K["a"]] * 2
    return (INPUT_START_M + length_m + spread) / point.speed + 0.2


def decay_run(
    point: LinearisationPoint,
    excitation: str = "dip",
    *,
    amplitude_m: float = 0.005,
    length_m: float = 2.0,
    duration_s: float = 8.0,
    dt: float = 1.0e-3,
    sample_dt: float = SAMPLE_DT,
    x0: np.ndarray | None = None,
) -> DecayRun:
    """Run the nonlinear model over one track input (or, with ``x0``, from that initial
    state on ideal track: ``excitation="none"``) and record the state.

    ``duration_s``: over an input, from the moment the input has passed
    (:func:`input_passed_s`) plus :data:`WINDOW_RANGE_S` (a free decay of 1 to 60 s); with
    ``excitation="none"`` the decay is free from the start, so (0, 60] s. ``dt``: RK4's
    step, :data:`~railsusp.vehicle.step_bound.STEP_FLOOR` to :data:`MAX_STEP_S`;
    ``sample_dt``: the recording interval, from ``dt`` to 1 s."""
    lo_w, hi_w = WINDOW_RANGE_S
    dt = check_real("dt", dt, STEP_FLOOR, MAX_STEP_S, "s")
    sample_dt = check_real("sample_dt", sample_dt, dt, 1.0, "s")
    if excitation == "none":
        trk = point.track
        free_from = 0.0
        duration_s = check_real("duration_s", duration_s, 0.0, hi_w, "s", lo_open=True)
    else:
        trk = track_with_input(point, excitation, amplitude_m, length_m)
        free_from = input_passed_s(point, length_m)
        # the window check with a margin of round-off: free_decay asks free_from + window_s
        lo, hi = free_from + lo_w - 1e-9, free_from + hi_w + 1e-9
        if not (_is_number(duration_s) and lo <= float(duration_s) <= hi):
            shown = f"{float(duration_s):g} s" if is_real(duration_s) else repr(duration_s)
            raise RailsuspInputError(
                f"duration_s = {shown}: the {excitation} has passed at {free_from:.2f} s; "
                f"accepted {free_from + lo_w:.2f} to {free_from + hi_w:.2f} s (a free decay "
                f"of {lo_w:g} to {hi_w:g} s after it)"
            )
        duration_s = float(duration_s)
    x = np.zeros(L.N_STATE) if x0 is None else np.array(x0, dtype=float)
    if x.shape != (L.N_STATE,):
        raise RailsuspInputError(f"x0: {x.size} values given, the state has {L.N_STATE}")
    if not np.isfinite(x).all():
        raise RailsuspInputError(
            f"x0: {int((~np.isfinite(x)).sum())} values not finite; accepted a finite state"
        )
    every = max(1, round(sample_dt / dt))
    n_steps = round(duration_s / dt)
    out = np.zeros((n_steps // every + 1, L.N_STATE))
    ca = point.contact
    code, rows = run_states(
        x, point.P, point.K, trk, point.s0, point.ds, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R,
        dt, n_steps, every, np.arange(L.N_STATE, dtype=np.int64), out,
    )  # fmt: skip
    if code != L.OK:  # over an input: too large an input for the wagon, named
        if excitation == "none":
            raise RuntimeError(f"free-decay run ({excitation}): {L.FAILURE_REASONS[code]}")
        raise DecayRunError(excitation, float(amplitude_m), L.FAILURE_REASONS[code])
    return DecayRun(excitation, np.arange(rows) * every * dt, out[:rows], free_from)


def _is_number(value: object) -> bool:
    """A finite real number (not a boolean, not text)."""
    return is_real(value) and math.isfinite(float(value))  # type: ignore[arg-type]


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
    "EXCITATIONS",
    "FIT_MIN_SAMPLES",
    "FIT_R2_MIN",
    "FREQUENCY_BAND",
    "LENGTH_RANGE_M",
    "MAX_STEP_S",
    "OSCILLATION_EVIDENCE",
    "WINDOW_RANGE_S",
    "DecayResult",
    "DecayRun",
    "DecayRunError",
    "decay_run",
    "fit_damped_sinusoid",
    "free_decay",
    "input_passed_s",
    "modal_filters",
    "track_with_input",
]
