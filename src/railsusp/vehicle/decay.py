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

The runs use the simulator's equations (``model.rhs``) and its integrator (fixed-step
classical RK4, the simulator's 1 ms step), here in a loop that records the state, so that
the whole state is available and any initial state can be given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np
from scipy.linalg import eig
from scipy.optimize import least_squares

from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH  # (sets the kernel cache before any compiles)
from railsusp.vehicle.model import rhs
from railsusp.vehicle.modes import (
    DOF_NAMES,
    Friction,
    LinearisationPoint,
    ModalResult,
    linearisation_point,
    modal_analysis,
)
from railsusp.vehicle.setup import axle_spread
from railsusp.vehicle.step_bound import stable_step
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
    ``amplitude_m`` over ``length_m`` starting :data:`INPUT_START_M` ahead."""
    if excitation not in EXCITATIONS:
        raise RailsuspInputError(f"excitation {excitation!r}: accepted {', '.join(EXCITATIONS)}")
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
    state on ideal track: ``excitation="none"``) and record the state."""
    if excitation == "none":
        trk = point.track
        free_from = 0.0
    else:
        trk = track_with_input(point, excitation, amplitude_m, length_m)
        spread = point.K[L.K["l_c"]] * 2 + point.K[L.K["a"]] * 2
        free_from = (INPUT_START_M + length_m + spread) / point.speed + 0.2
    if not 0 < free_from < duration_s - 1.0:
        raise RailsuspInputError(
            f"duration_s = {duration_s:g}: the input has passed only at {free_from:.1f} s; "
            "accepted a duration at least 1 s longer"
        )
    x = np.zeros(L.N_STATE) if x0 is None else np.array(x0, dtype=float)
    if x.shape != (L.N_STATE,):
        raise RailsuspInputError(f"x0: {x.size} values given, the state has {L.N_STATE}")
    every = max(1, round(sample_dt / dt))
    n_steps = round(duration_s / dt)
    out = np.zeros((n_steps // every + 1, L.N_STATE))
    ca = point.contact
    code, rows = run_states(
        x, point.P, point.K, trk, point.s0, point.ds, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R,
        dt, n_steps, every, np.arange(L.N_STATE, dtype=np.int64), out,
    )  # fmt: skip
    if code != L.OK:
        raise RuntimeError(f"free-decay run ({excitation}): {L.FAILURE_REASONS[code]}")
    return DecayRun(excitation, np.arange(rows) * every * dt, out[:rows], free_from)


# ---------------------------------------------------------------- estimation
def fit_damped_sinusoid(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """Fit A exp(-σ t) cos(ω_d t + φ) + c to y(t). Returns (natural frequency Hz, damping
    ratio, amplitude at the window start, R² of the fit); NaNs when y does not oscillate."""
    t = t - t[0]
    yc = y - y.mean()
    if not np.any(yc):
        return math.nan, math.nan, 0.0, math.nan
    dt = t[1] - t[0]
    starts = []  # (ω_d, σ) first guesses
    # linear prediction of a damped sinusoid with offset: x[n+2] = a1 x[n+1] + a2 x[n] + b
    # (exact for one mode); its poles z = exp(λ dt)
    M = np.column_stack([y[1:-1], y[:-2], np.ones(y.size - 2)])
    a1, a2, _ = np.linalg.lstsq(M, y[2:], rcond=None)[0]
    z = np.roots([1.0, -a1, -a2]).astype(complex)
    lam = np.log(z[np.argmax(z.imag)]) / dt
    if lam.imag > 0:
        starts.append((lam.imag, max(-lam.real, 0.0)))
    # and the spectrum's peak (more robust with several modes present)
    n = 8 * t.size
    spec = np.abs(np.fft.rfft(yc * np.hanning(t.size), n))
    freqs = np.fft.rfftfreq(n, dt)
    spec[freqs < 1.0 / t[-1]] = 0.0  # less than one cycle in the window: not a mode
    f0 = freqs[int(np.argmax(spec))]
    if f0 > 0:
        starts += [(2 * np.pi * f0, z0 * 2 * np.pi * f0) for z0 in (0.002, 0.02, 0.1, 0.3)]
    if not starts:
        return math.nan, math.nan, 0.0, math.nan
    best = None
    for w0, s0 in starts:
        for phase in (0.0, np.pi / 2, np.pi, -np.pi / 2):
            res = least_squares(
                lambda p: p[0] * np.exp(-p[1] * t) * np.cos(p[2] * t + p[3]) + p[4] - y,
                [np.abs(yc).max(), s0, w0, phase, y.mean()],
                bounds=(
                    [0, -5.0, 0.5 * w0, -10, -np.inf],
                    [np.inf, 50.0 * w0, 2.0 * w0, 10, np.inf],
                ),
            )
            if best is None or res.cost < best.cost:
                best = res
    amp, sigma, wd, _, _ = best.x
    wn = math.hypot(sigma, wd)
    r2 = 1.0 - 2.0 * best.cost / float(np.sum(yc * yc))
    return wn / (2 * np.pi), sigma / wn, amp, r2


@dataclass
class DecayResult:
    """Equivalent damping of the car-body modes from free-decay runs (module docstring).

    Per mode (``rows``): its name, car-body share of kinetic energy and linearised frequency
    and damping ratio, the run that excites it most, the fitted natural frequency (Hz),
    equivalent damping ratio, modal amplitude (sqrt(2 T) of the mode's part of the motion at
    its largest in the window, sqrt(J)), R² of the fit, the fitted over the linear frequency,
    and whether the fit meets :data:`FIT_R2_MIN` and :data:`FREQUENCY_BAND` (``fit_ok``)."""

    speed_kmh: float
    rows: list[dict]
    runs: list[DecayRun]
    window_s: float

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
    eigenvectors read the modal coordinates (default: the same friction variant's)."""
    wagon = load_wagon(wagon)
    if not 1.0 <= window_s <= 60.0:
        raise RailsuspInputError(f"window_s = {window_s:g}: accepted 1 to 60 s")
    point = linearisation_point(params, wagon, speed_kmh, friction)
    modal = modal_analysis(params, wagon, speed_kmh, friction) if modal is None else modal
    chosen = [int(i) for i in modal.car_body_modes(f_max, CAR_BODY_SHARE)]
    filters, vectors = modal_filters(modal, chosen)
    # the mode's part of the motion, 2 Re(eta v): its kinetic energy at |eta| = 1
    inertia = point.dof_inertia()
    vel = vectors[L.N_DOF : 2 * L.N_DOF]
    unit_energy = np.sqrt((inertia[:, None] * np.abs(2.0 * vel) ** 2).sum(axis=0))
    runs, coords = [], []
    free = (INPUT_START_M + length_m + axle_spread(wagon)) / point.speed + 0.2
    # 1 ms, or RK4's stability bound where the speed makes it shorter (the fixed 1 ms went
    # unstable below about 42 km/h: damping ratios 0.445 against 0.404 at 30 km/h)
    stable = min(1.0e-3, stable_step(wagon, speed_kmh, point.P))
    dt = SAMPLE_DT / math.ceil(SAMPLE_DT / stable - 1e-9)
    for ex in excitations:
        run = decay_run(
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
    return DecayResult(speed_kmh=speed_kmh, rows=rows, runs=runs, window_s=window_s)


__all__ = [
    "CAR_BODY_SHARE",
    "DOF_NAMES",
    "EXCITATIONS",
    "FIT_R2_MIN",
    "FREQUENCY_BAND",
    "DecayResult",
    "DecayRun",
    "decay_run",
    "fit_damped_sinusoid",
    "free_decay",
    "modal_filters",
    "track_with_input",
]
