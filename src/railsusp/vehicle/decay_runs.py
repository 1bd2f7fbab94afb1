"""Free-decay runs: the nonlinear simulator over one short track input, its state recorded.

The wagon runs over otherwise ideal straight, level track with one short input (a cosine
dip of one or both rails, a lateral kink of both rails; :data:`EXCITATIONS`) and then
rolls freely (or, with an initial state, rolls from it on ideal track). The runs use the
simulator's equations (``model.rhs``) and its integrator (fixed-step classical RK4, the
simulator's 1 ms step), here in a loop that records the state, so that the whole state is
available and any initial state can be given. They are the records that the free-decay
analysis of the car-body modes (:mod:`railsusp.vehicle.decay`) reads its modal
coordinates from; the loop is a compiled kernel (:func:`run_states`), cached by its source
(:mod:`railsusp.vehicle.kernel_cache`).

Inputs are checked before anything runs (one-line :class:`RailsuspInputError` naming the
argument and its accepted range): :data:`AMPLITUDE_RANGE_M` (the command's ``--amplitude``
in mm), :data:`LENGTH_RANGE_M`, :data:`WINDOW_RANGE_S`, the step up to :data:`MAX_STEP_S`.
A run the model stops (a flange climb of a large kink) raises :class:`DecayRunError`, which
names the amplitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_real
from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH  # (sets the kernel cache before any compiles)
from railsusp.vehicle.model import rhs
from railsusp.vehicle.modes import LinearisationPoint
from railsusp.vehicle.operating_point import check_real
from railsusp.vehicle.step_bound import STEP_FLOOR

#: the track inputs: a cosine dip of both rails (bounce, pitch), of the left rail only
#: (cross-level: roll and sway, with bounce and pitch), a lateral kink of both rails
#: (lateral, yaw, sway)
EXCITATIONS: tuple[str, ...] = ("dip", "cross-level", "kink")

#: where the input starts on the track, m ahead of the leading wheelset's start
INPUT_START_M = 5.0

CAR_BODY = np.arange(L.CB_Y, L.CB_YAW + 1)
I_V = L.K["V"]

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
#: is shorter below about 42 km/h: :func:`~railsusp.vehicle.decay.free_decay` takes it)
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


__all__ = [
    "AMPLITUDE_RANGE_M",
    "EXCITATIONS",
    "INPUT_START_M",
    "LENGTH_RANGE_M",
    "MAX_STEP_S",
    "SAMPLE_DT",
    "WINDOW_RANGE_S",
    "DecayRun",
    "DecayRunError",
    "decay_run",
    "input_passed_s",
    "run_states",
    "track_with_input",
]
