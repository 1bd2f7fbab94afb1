"""The output-error refinement's confidence intervals (:mod:`railsusp.estimate.intervals`).

The Gauss-Newton standard errors of :func:`railsusp.estimate.refine.refine` assume white
residuals; time-aligned force residuals are correlated over neighbouring samples (sensor
bandwidth, model error), and the refinement holds the other main-suspension parameters at
nominal. Here the standard errors are inflated by the residuals' integrated autocorrelation
time (their effective sample size), a Student-t quantile is taken on the effective degrees
of freedom, and the track-geometry error's spread and the linear response to the held
parameters are added in quadrature (docs/intervals.md): each held parameter uniform over the
user's range (:class:`~railsusp.estimate.config.HeldPrior`, ``[estimate] held_prior``) or
else its whole Table 2 range, taken as its second moment about the value held.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.estimate.config import HeldPrior
from railsusp.estimate.forces import SimulatorForces
from railsusp.estimate.intervals import LEVEL, REFINEMENT, Intervals, from_standard_errors
from railsusp.estimate.refine import OutputError, Refinement
from railsusp.params import MAIN_SUSPENSION, ParameterSet, bounds, spec


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


def held_moments(
    held: Sequence[str], held_at_si: np.ndarray, prior: HeldPrior | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(variance, offset) of each ``held`` parameter about the value it is held at, in unit
    coordinates of its Table 2 range: uniform over the user's range [a, b] (``prior``) or
    else its whole Table 2 range, so variance (b - a)²/12 and offset (a + b)/2 - held value.
    The default holds at nominal, the centre of every Table 2 range (nominal ± 50 %), so
    its offsets are zero; a user's range off-centre, or one that leaves nominal out, has
    an offset, the mean of the error holding at nominal causes."""
    prior = prior or HeldPrior()
    if not len(held):
        return np.zeros(0), np.zeros(0)
    lo_t, hi_t = bounds(held)
    span = hi_t - lo_t
    ab = np.array([prior.range_si(p) for p in held], dtype=float)
    var = ((ab[:, 1] - ab[:, 0]) / span) ** 2 / 12.0
    offset = (ab.mean(axis=1) - np.asarray(held_at_si, dtype=float)) / span
    return var, offset


def held_error_variance(
    response: np.ndarray, variance: np.ndarray, offset: np.ndarray
) -> np.ndarray:
    """(k,) second moment E[e²] of the estimate's error e = R·δ that held parameters cause,
    with R (k, h) the estimate's response to them and δ their independent deviations from
    the held values, of ``variance`` and mean ``offset``: Σ_j R_ij² var_j + (Σ_j R_ij m_j)².
    The offsets shift the estimate coherently (a bias R·m), so their squares do not simply
    add per held parameter; with no offset this is the variance Σ R² var."""
    r = np.atleast_2d(np.asarray(response, dtype=float))
    return (r**2) @ np.asarray(variance, dtype=float) + (r @ np.asarray(offset, dtype=float)) ** 2


def held_parameter_variance(
    refinement: Refinement, prior: HeldPrior | None = None
) -> np.ndarray | None:
    """(k,) second moment, SI², of the refined estimate's error caused by the main-suspension
    parameters it holds (at nominal, or the force model's ``base``), each uniform over the
    user's range in ``prior`` or else its whole Table 2 range (:func:`held_moments`,
    :func:`held_error_variance`): the estimate moves by A·δh for a change δh of them, with
    A the least-squares response (J_e⁺ J_h) of the estimated parameters and channel gains
    to the held ones, the Jacobians taken at the estimate with the held parameters at the
    values held. None where it cannot be computed: no held parameter, or a force model
    other than the simulator (the surrogates know the key parameters only). One batch of
    k + h + 1 simulations."""
    prob, z = refinement.problem, refinement.solution
    if prob is None or z is None or not isinstance(prob.model, SimulatorForces):
        return None
    held = held_parameters(prob.parameters)
    if not held:
        return None
    k, h = prob.k, len(held)
    every = (*prob.parameters, *held)
    base = prob.model.base
    ext = OutputError(
        SimulatorForces(every, prob.model.wheel, base=base),
        prob.recordings,
        every,
        prob.step,
        prob.gains,
    )
    held_at = held_values(held, base)
    lo_h, hi_h = bounds(held)
    u_held = np.clip((held_at - lo_h) / (hi_h - lo_h), 0.0, 1.0)
    zz = np.concatenate([z[:k], u_held, z[k:]])
    jac = ext.jacobian_of(ext.predictions(ext.steps(zz[: k + h])), zz)
    est_cols = np.r_[0:k, k + h : jac.shape[1]]
    j_e, j_h = jac[:, est_cols], jac[:, k : k + h]
    response = np.linalg.lstsq(j_e, j_h, rcond=None)[0][:k]  # (k, h), unit coordinates
    var_u = held_error_variance(response, *held_moments(held, held_at, prior))
    return var_u * (prob.hi - prob.lo) ** 2


def held_values(held: Sequence[str], base: ParameterSet | None = None) -> np.ndarray:
    """(h,) SI values the ``held`` parameters are held at: ``base``'s, else nominal."""
    values = base or ParameterSet.nominal()
    return np.array([values[p] for p in held], dtype=float)


def held_assumptions(
    parameters: Sequence[str], prior: HeldPrior | None = None, base: ParameterSet | None = None
) -> dict[str, dict]:
    """What the intervals assume of each held parameter (display units): the value it is
    held at and the range it is taken uniform over, the user's (``"range": "prior"``) or
    Table 2's; for estimate.json and the report."""
    prior = prior or HeldPrior()
    held = held_parameters(parameters)
    out = {}
    for p, v in zip(held, held_values(held, base), strict=True):
        s = spec(p)
        lo, hi = prior.range_si(p)
        out[p] = {
            "held_at_display": s.to_display(v),
            "low_display": s.to_display(lo),
            "high_display": s.to_display(hi),
            "unit": s.display_unit,
            "range": "prior" if prior.given(p) else "Table 2",
        }
    return out


def refinement_intervals(
    refinement: Refinement,
    level: float = LEVEL,
    held: bool = True,
    prior: HeldPrior | None = None,
) -> Intervals:
    """The refinement's ``level`` confidence intervals (module docstring): Gauss-Newton
    standard errors inflated by the residuals' autocorrelation time, a Student-t quantile
    on n_eff - p degrees of freedom, and in quadrature the geometry-error spread and, with
    ``held``, the held parameters' part (:func:`held_parameter_variance`), each held one
    uniform over its range in ``prior`` or else over its whole Table 2 range."""
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
    held_var = held_parameter_variance(ref, prior) if held else None
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
        "held_parameters_assumed": held_assumptions(ref.parameters, prior, _base(ref))
        if held_var is not None
        else {},
        "held_prior_display": (prior or HeldPrior()).to_display(),
        "held_prior_unused": (prior or HeldPrior()).unused(ref.parameters),
        "total_standard_error_pct_range": pct(total),
    }
    return from_standard_errors(
        ref.parameters, ref.estimate_si, total, level, dof, REFINEMENT, details
    )


def _base(refinement: Refinement) -> ParameterSet | None:
    """The values the refinement's simulator holds the other parameters at (None: nominal)."""
    prob = refinement.problem
    return getattr(prob.model, "base", None) if prob is not None else None
