"""The output-error refinement's confidence intervals (:mod:`railsusp.estimate.intervals`).

The Gauss-Newton standard errors of :func:`railsusp.estimate.refine.refine` assume white
residuals; time-aligned force residuals are correlated over neighbouring samples (sensor
bandwidth, model error), and the refinement holds the other main-suspension parameters at
nominal. Here the standard errors are inflated by the residuals' integrated autocorrelation
time (their effective sample size), a Student-t quantile is taken on the effective degrees
of freedom, and the track-geometry error's spread and the linear response to the held
parameters are added in quadrature (docs/intervals.md).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.estimate.forces import SimulatorForces
from railsusp.estimate.intervals import LEVEL, REFINEMENT, Intervals, from_standard_errors
from railsusp.estimate.refine import OutputError, Refinement
from railsusp.params import MAIN_SUSPENSION, ParameterSet, bounds


def autocorrelation_time(r: np.ndarray) -> float:
    """Integrated autocorrelation time τ = 1 + 2 Σ ρ(l) of a series, ρ summed over Geyer's
    initial positive sequence (pairs ρ(2m) + ρ(2m+1) while positive): the factor by which
    correlation inflates the variance of an average, so a series of n samples carries the
    information of n / τ independent ones. 1 for white residuals, at least 1."""
    x = np.asarray(r, dtype=float)
    x = x - x.mean()
    n = x.size
    if n < 4 or not np.any(x):
        return 1.0
    f = np.fft.rfft(x, 2 * n)
    acov = np.fft.irfft(f * np.conj(f))[:n] / n
    rho = acov / acov[0]
    tau = -1.0  # 1 + 2 sum_{l >= 1} rho(l) = -1 + 2 sum over pairs from l = 0
    for m in range(n // 2):
        pair = rho[2 * m] + rho[2 * m + 1]
        if pair <= 0.0:
            break
        tau += 2.0 * pair
    return float(max(tau, 1.0))


def effective_sample_size(residuals: np.ndarray, blocks: Sequence[int]) -> tuple[float, float]:
    """(n_eff, τ) of residuals made of consecutive ``blocks`` (one per recording and
    channel): the sum of each block's length over its autocorrelation time, and the overall
    inflation n / n_eff."""
    r = np.asarray(residuals, dtype=float).ravel()
    sizes = [int(b) for b in blocks] if blocks else [r.size]
    if sum(sizes) != r.size:
        sizes = [r.size]
    n_eff, start = 0.0, 0
    for size in sizes:
        n_eff += size / autocorrelation_time(r[start : start + size])
        start += size
    return n_eff, r.size / max(n_eff, 1e-12)


def held_parameters(parameters: Sequence[str]) -> tuple[str, ...]:
    """The main-suspension parameters an estimate of ``parameters`` holds at nominal."""
    return tuple(p for p in MAIN_SUSPENSION if p not in set(parameters))


def held_parameter_variance(refinement: Refinement) -> np.ndarray | None:
    """(k,) variance, SI², of the refined estimate caused by the main-suspension parameters
    held at nominal, each uniform over its range (variance range²/12 in unit coordinates
    1/12): the estimate moves by -A·δh for a change δh of them, with A the least-squares
    response (J_e⁺ J_h) of the estimated parameters and channel gains to the held ones, the
    Jacobians taken at the estimate with the held parameters at nominal. None where it
    cannot be computed: no held parameter, or a force model other than the simulator (the
    surrogates know the key parameters only). One batch of k + h + 1 simulations."""
    prob, z = refinement.problem, refinement.solution
    if prob is None or z is None or not isinstance(prob.model, SimulatorForces):
        return None
    held = held_parameters(prob.parameters)
    if not held:
        return None
    k, h = prob.k, len(held)
    every = (*prob.parameters, *held)
    ext = OutputError(
        SimulatorForces(every, prob.model.wheel), prob.recordings, every, prob.step, prob.gains
    )
    nominal = ParameterSet.nominal()
    lo_h, hi_h = bounds(held)
    u_held = np.clip((np.array([nominal[p] for p in held]) - lo_h) / (hi_h - lo_h), 0.0, 1.0)
    zz = np.concatenate([z[:k], u_held, z[k:]])
    jac = ext.jacobian_of(ext.predictions(ext.steps(zz[: k + h])), zz)
    est_cols = np.r_[0:k, k + h : jac.shape[1]]
    j_e, j_h = jac[:, est_cols], jac[:, k : k + h]
    response = np.linalg.lstsq(j_e, j_h, rcond=None)[0][:k]  # (k, h), unit coordinates
    var_u = (response**2).sum(axis=1) / 12.0
    return var_u * (prob.hi - prob.lo) ** 2


def refinement_intervals(
    refinement: Refinement, level: float = LEVEL, held: bool = True
) -> Intervals:
    """The refinement's ``level`` confidence intervals (module docstring): Gauss-Newton
    standard errors inflated by the residuals' autocorrelation time, a Student-t quantile
    on n_eff - p degrees of freedom, and in quadrature the geometry-error spread and, with
    ``held``, the held parameters' part (:func:`held_parameter_variance`)."""
    ref = refinement
    k = len(ref.parameters)
    lo, hi = bounds(ref.parameters)
    span = hi - lo
    residuals = getattr(ref, "residuals", None)
    blocks = getattr(ref, "residual_blocks", ())
    if residuals is not None and np.size(residuals):
        n_eff, tau = effective_sample_size(residuals, blocks)  # type: ignore[assignment]
        n_fit = k + (len(ref.channel_gains) or 0)
        dof: float | None = max(n_eff - n_fit, 1.0)
    else:  # residuals not kept (a refinement read back): white, normal quantile
        n_eff, tau, dof = None, 1.0, None
    noise = np.sqrt(tau) * ref.standard_error_si
    geometry = ref.geometry_error_si
    held_var = held_parameter_variance(ref) if held else None
    held_sd = np.sqrt(held_var) if held_var is not None else np.zeros(k)
    total = np.sqrt(noise**2 + geometry**2 + held_sd**2)

    def pct(v: np.ndarray) -> dict[str, float]:
        return {p: float(100 * x / s) for p, x, s in zip(ref.parameters, v, span, strict=True)}

    details = {
        "residual_autocorrelation_time": tau,
        "effective_sample_size": n_eff,
        "degrees_of_freedom": dof,
        "noise_standard_error_pct_range": pct(noise),
        "geometry_error_pct_range": pct(geometry),
        "held_parameters": list(held_parameters(ref.parameters)) if held_var is not None else [],
        "held_parameters_error_pct_range": pct(held_sd),
        "total_standard_error_pct_range": pct(total),
    }
    return from_standard_errors(
        ref.parameters, ref.estimate_si, total, level, dof, REFINEMENT, details
    )
