"""The damped-sinusoid fit of a free decay (:func:`fit_damped_sinusoid`): the natural
frequency and damping ratio of one car-body mode's modal coordinate, as the log decrement
reads them but from the whole window (least squares, several starts), and NaN where the
record does not show an oscillation (an overdamped mode, a drift). Used by
:func:`railsusp.vehicle.decay.free_decay`."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from railsusp.errors import RailsuspInputError

#: least number of samples of a record :func:`fit_damped_sinusoid` fits: its five
#: parameters and one more
FIT_MIN_SAMPLES = 6
#: a record that crosses its fitted offset fewer than three times (beyond the fit's RMS
#: residual; two exponentials cross any level at most twice) still oscillates when one
#: damped sinusoid plus offset fits it with at most 1/4 of the squared residual of the best
#: non-oscillating decay with as many parameters (two exponentials plus offset: an
#: overdamped mode, or a drift). The loaded wagon's bogie kinematic modes at 60 km/h (ζ
#: 0.89, gone within one cycle, about two crossings) pass by 42, the other car-body modes by
#: 1e4-1e9 and with 4-50 crossings; a decaying exponential or a ramp fails by 1e-7 or less;
#: a decay with ζ above about 0.95 that carries noise of 1e-4 of its amplitude fails
#: (1.3-3): there the oscillation is not shown. A stick-slip decay (a 30 mm dip: R² 0.87,
#: two exponentials 0.54) crosses dozens of times and is kept, for its fit check to flag.
OSCILLATION_EVIDENCE = 4.0


def fit_damped_sinusoid(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """Fit A exp(-σ t) cos(ω_d t + φ) + c to y(t). Returns (natural frequency Hz, damping
    ratio, amplitude at the window start, R² of the fit).

    NaNs (amplitude 0 for a constant record) when y does not oscillate: constant, or a
    record that neither crosses the fitted offset three times (beyond the fit's RMS
    residual: a sum of two exponentials, what an overdamped mode gives, rises or falls to
    one extreme at most, so it crosses any level at most twice) nor is fitted
    :data:`OSCILLATION_EVIDENCE` times better by the damped sinusoid than by two
    exponentials plus offset, the non-oscillating decay with as many parameters (a heavily
    damped mode, gone within a cycle, crosses visibly once or twice but is told by its
    shape). Without that test an exponential decay came out as a 0.5 Hz mode with ζ 0.98
    and R² 0.9999, a ramp as a 0.09 Hz mode. The record is scaled to its largest deviation
    from its mean before fitting, so that the fit's tolerances do not depend on its units
    (a record of 1e-12 m fitted as well as one of 1 m). ``t``: uniformly spaced,
    increasing, at least :data:`FIT_MIN_SAMPLES` samples; ``t`` and ``y`` finite (one-line
    :class:`RailsuspInputError` otherwise: a NaN sample made LAPACK print to stderr and
    raise LinAlgError)."""
    t, y = _check_record(t, y)
    t = t - t[0]
    mean = float(y.mean())
    scale = float(np.abs(y - mean).max())
    if not scale > 64 * np.finfo(float).eps * abs(mean):  # constant to round-off
        return math.nan, math.nan, 0.0, math.nan
    y = (y - mean) / scale  # mean 0, largest deviation 1
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
    spec = np.abs(np.fft.rfft(y * np.hanning(t.size), n))
    freqs = np.fft.rfftfreq(n, dt)
    spec[freqs < 1.0 / t[-1]] = 0.0  # less than one cycle in the window: not a mode
    f0 = freqs[int(np.argmax(spec))]
    if f0 > 0:
        starts += [(2 * np.pi * f0, z0 * 2 * np.pi * f0) for z0 in (0.002, 0.02, 0.1, 0.3)]
    if not starts:
        return math.nan, math.nan, math.nan, math.nan
    best = None
    for w0, s0 in starts:
        for phase in (0.0, np.pi / 2, np.pi, -np.pi / 2):
            res = least_squares(
                lambda p: p[0] * np.exp(-p[1] * t) * np.cos(p[2] * t + p[3]) + p[4] - y,
                [1.0, s0, w0, phase, 0.0],
                bounds=(
                    [0, -5.0, 0.5 * w0, -10, -np.inf],
                    [np.inf, 50.0 * w0, 2.0 * w0, 10, np.inf],
                ),
            )
            if best is None or res.cost < best.cost:
                best = res
    amp, sigma, wd, _, offset = best.x
    noise = math.sqrt(float(np.mean(best.fun**2)))  # the fit's residual, RMS
    if _crossings(y - offset, noise) < 3 and not (
        best.cost * OSCILLATION_EVIDENCE < _exponential_cost(t, y, sigma)
    ):
        return math.nan, math.nan, math.nan, math.nan
    wn = math.hypot(sigma, wd)
    r2 = 1.0 - 2.0 * best.cost / float(np.sum(y * y))
    return wn / (2 * np.pi), sigma / wn, amp * scale, r2


def _check_record(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t and y as float arrays, checked for :func:`fit_damped_sinusoid` (its docstring)."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.shape != y.shape:
        raise RailsuspInputError(
            f"t, y: shapes {t.shape} and {y.shape}; accepted two 1-D records of one length"
        )
    if t.size < FIT_MIN_SAMPLES:
        raise RailsuspInputError(
            f"t, y: {t.size} samples; accepted at least {FIT_MIN_SAMPLES} (five parameters)"
        )
    for name, v in (("t", t), ("y", y)):
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise RailsuspInputError(
                f"{name}: {bad.size} of {v.size} samples not finite (the first at index "
                f"{bad[0]}); accepted a finite record"
            )
    step = np.diff(t)
    mean = float(step.mean())
    if not (mean > 0 and np.abs(step - mean).max() <= 1e-6 * mean):
        raise RailsuspInputError(
            f"t: steps from {step.min():g} to {step.max():g} s; accepted uniformly spaced, "
            "increasing times"
        )
    return t, y


def _crossings(d: np.ndarray, band: float) -> int:
    """How often d changes sign, counting only samples beyond ±band (hysteresis: noise
    inside the band around zero makes no crossing)."""
    side = np.sign(d[np.abs(d) > band])
    return int(np.count_nonzero(side[1:] != side[:-1]))


def _exponential_cost(t: np.ndarray, y: np.ndarray, sigma: float) -> float:
    """Least half sum of squared residuals of A1 exp(-s1 t) + A2 exp(-s2 t) + c fitted to
    y (mean 0, largest deviation 1): the best non-oscillating decay with the damped
    sinusoid's five parameters, started from rates around the sinusoid's σ and the window's
    1 / T (the decay rates bounded below as the sinusoid's σ is, -5 1/s)."""
    T = float(t[-1])
    sig = max(float(sigma), 1.0 / T)
    span = float(y[0] - y[-1]) or 1.0
    best = math.inf
    for s1, s2 in ((sig / 2, 2 * sig), (sig, 4 * sig), (0.5 / T, sig), (sig / 4, sig),
                   (0.1 / T, 10 / T), (1 / T, 30 / T)):  # fmt: skip
        for sign in (1.0, -1.0):
            res = least_squares(
                lambda p: p[0] * np.exp(-p[1] * t) + p[2] * np.exp(-p[3] * t) + p[4] - y,
                [sign * span, s1, -0.1 * sign * span, s2, float(y[-1])],
                bounds=([-np.inf, -5.0, -np.inf, -5.0, -np.inf], np.inf),
            )
            best = min(best, float(res.cost))
    return best
