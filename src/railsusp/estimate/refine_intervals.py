"""The output-error refinement's confidence intervals (:mod:`railsusp.estimate.intervals`).

Time-aligned force residuals are correlated over neighbouring samples (sensor bandwidth,
model error), their channels are unequally noisy, and the refinement holds the other
main-suspension parameters at nominal (or, with a user's prior, at its range's centre:
:meth:`~railsusp.estimate.config.HeldPrior.held_at_si`). The noise part is the
refinement's own standard error
(:attr:`~railsusp.estimate.refine.Refinement.standard_error_si`: each recording's channel
with its own residual variance and integrated autocorrelation time, the sandwich
covariance of :func:`~railsusp.estimate.residual_noise.noise_standard_errors`), a Student-t
variable on the effective degrees of freedom; the track-geometry error's spread is normal;
the held parameters' part is their linear response, each held parameter uniform over the
user's range (:class:`~railsusp.estimate.config.HeldPrior`, ``[estimate] held_prior``) or
else its whole Table 2 range. The interval is the central quantiles of the sum of the three
(:mod:`railsusp.estimate.interval_distribution`, JCGM 101:2008), docs/intervals.md.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.estimate.config import HeldPrior
from railsusp.estimate.expected_forces import ExpectedForces, averaged_model
from railsusp.estimate.forces import ForceModel, SimulatorForces
from railsusp.estimate.interval_distribution import DRAWS, SEED, error_quantiles
from railsusp.estimate.intervals import (
    LEVEL,
    REFINEMENT,
    Intervals,
    from_error_quantiles,
    from_standard_errors,
)
from railsusp.estimate.refine import OutputError, Refinement
from railsusp.estimate.residual_noise import PER_CHANNEL
from railsusp.estimate.residual_noise import autocorrelation_time as autocorrelation_time
from railsusp.estimate.residual_noise import effective_sample_size as effective_sample_size
from railsusp.estimate.residual_noise import noise_standard_errors as noise_standard_errors
from railsusp.params import MAIN_SUSPENSION, ParameterSet, bounds, spec


def held_parameters(parameters: Sequence[str]) -> tuple[str, ...]:
    """The main-suspension parameters an estimate of ``parameters`` holds (at nominal, or
    at a held prior's centre)."""
    return tuple(p for p in MAIN_SUSPENSION if p not in set(parameters))


def held_moments(
    held: Sequence[str], held_at_si: np.ndarray, prior: HeldPrior | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(variance, offset) of each ``held`` parameter about the value it is held at, in unit
    coordinates of its Table 2 range: uniform over the user's range [a, b] (``prior``) or
    else its whole Table 2 range, so variance (b - a)²/12 and offset (a + b)/2 - held value.
    The default holds at nominal, the centre of every Table 2 range (nominal ± 50 %), so
    its offsets are zero; a user's range off-centre, or one that leaves nominal out, has
    an offset, the mean of the error holding at nominal causes (the estimate route holds a
    parameter with a prior at its centre since stop 78, so its offset there is zero)."""
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


def held_response(refinement: Refinement) -> tuple[tuple[str, ...], np.ndarray] | None:
    """(held, R): the main-suspension parameters the refined estimate holds (at nominal, or
    the force model's ``base``) and the estimate's linear response R (k, h) to them, unit
    coordinates of the Table 2 ranges: the estimate moves by R·δh for a change δh of them,
    R = J_e⁺ J_h the least-squares response of the estimated parameters and channel gains
    to the held ones, the Jacobians taken at the estimate with the held parameters at the
    values held. None where it cannot be computed: no held parameter, or a force model other
    than the simulator (the surrogates know the key parameters only). One batch of
    k + h + 1 simulations; where the refinement compared the simulator's expected forces
    (:class:`~railsusp.estimate.expected_forces.ExpectedForces`), the response is that of
    the same expected forces (the same draws: they are seeded by the tracks), that many
    times the simulations."""
    prob, z = refinement.problem, refinement.solution
    sim = _simulator(refinement)
    if prob is None or z is None or sim is None:
        return None
    held = held_parameters(prob.parameters)
    if not held:
        return None
    k, h = prob.k, len(held)
    every = (*prob.parameters, *held)
    model: ForceModel = SimulatorForces(every, sim.wheel, base=sim.base, wagon=sim.wagon)
    if isinstance(prob.model, ExpectedForces):
        expected = prob.model
        model = ExpectedForces(model, expected.draws, expected.seed, expected.antithetic)
    ext = OutputError(model, prob.recordings, every, prob.step, prob.gains)
    lo_h, hi_h = bounds(held)
    u_held = np.clip((held_values(held, sim.base) - lo_h) / (hi_h - lo_h), 0.0, 1.0)
    zz = np.concatenate([z[:k], u_held, z[k:]])
    try:
        jac = ext.jacobian_of(ext.predictions(ext.steps(zz[: k + h])), zz)
    finally:
        if isinstance(model, ExpectedForces):
            model.close()
    est_cols = np.r_[0:k, k + h : jac.shape[1]]
    j_e, j_h = jac[:, est_cols], jac[:, k : k + h]
    return held, np.linalg.lstsq(j_e, j_h, rcond=None)[0][:k]


def held_parameter_variance(
    refinement: Refinement,
    prior: HeldPrior | None = None,
    response: tuple[tuple[str, ...], np.ndarray] | None = None,
) -> np.ndarray | None:
    """(k,) second moment, SI², of the refined estimate's error caused by the main-suspension
    parameters it holds, each uniform over the user's range in ``prior`` or else its whole
    Table 2 range (:func:`held_response`, :func:`held_moments`, :func:`held_error_variance`).
    ``response``: :func:`held_response`'s answer where already computed (it costs a batch of
    simulations). None where the response cannot be computed."""
    got = held_response(refinement) if response is None else response
    if got is None:
        return None
    held, response = got
    moments = held_moments(held, held_values(held, _base(refinement)), prior)
    lo, hi = bounds(refinement.parameters)
    return held_error_variance(response, *moments) * (hi - lo) ** 2


def held_deviation_range(
    held: Sequence[str], held_at_si: np.ndarray, prior: HeldPrior | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of each ``held`` parameter's deviation from the value it is held at, unit
    coordinates of its Table 2 range: the user's range [a, b] (``prior``) or else Table 2's,
    less the value held. The support of the uniform δ whose moments :func:`held_moments`
    gives."""
    prior = prior or HeldPrior()
    lo_t, hi_t = bounds(held)
    ab = np.array([prior.range_si(p) for p in held], dtype=float).reshape(-1, 2)
    at = np.asarray(held_at_si, dtype=float)
    return (ab[:, 0] - at) / (hi_t - lo_t), (ab[:, 1] - at) / (hi_t - lo_t)


def solution_jacobian(refinement: Refinement) -> np.ndarray | None:
    """The refinement's Jacobian at its solution (unit parameters, then gains), from its
    problem's cache of simulations where the last step computed it; None for a refinement
    read back, which keeps no problem."""
    prob, z = refinement.problem, refinement.solution
    if prob is None or z is None:
        return None
    return prob.jacobian_of(prob.predictions(prob.steps(z[: prob.k])), z)


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


#: how the interval was formed from its parts (``interval_quantiles``)
MONTE_CARLO = "central quantiles of the error's distribution (JCGM 101:2008 Monte Carlo)"
STUDENT_T = "Student-t quantile times the total standard error"


def refinement_intervals(
    refinement: Refinement,
    level: float = LEVEL,
    held: bool = True,
    prior: HeldPrior | None = None,
) -> Intervals:
    """The refinement's ``level`` confidence intervals (module docstring). The noise part:
    the refinement's standard errors as they are (:attr:`Refinement.standard_error_si`,
    each recording's channel its own residual variance and autocorrelation time, so that
    the autocorrelation time is in them once), on n_eff - p degrees of freedom from its
    residuals (a normal quantile for one that keeps none). With ``held``, the held
    parameters' linear response (:func:`held_response`), each held one uniform over its
    range in ``prior`` or else over its whole Table 2 range, offsets from the value held
    included; the geometry error's spread. Where there is a held part, the interval is the
    central ``level`` quantiles of the sum of the three
    (:func:`~railsusp.estimate.interval_distribution.error_quantiles`: uniform, Student-t on
    n_eff - p degrees of freedom, normal), not a multiple of its standard deviation; without
    one the sum is Student-t and normal, and the interval the Student-t quantile times the
    total standard error, as before."""
    ref = refinement
    k = len(ref.parameters)
    lo, hi = bounds(ref.parameters)
    span = hi - lo
    residuals = getattr(ref, "residuals", None)
    if residuals is not None and np.size(residuals):
        blocks = getattr(ref, "residual_blocks", ())
        n_eff, tau = effective_sample_size(residuals, blocks)  # type: ignore[assignment]
        n_fit = k + (len(ref.channel_gains) or 0)
        dof: float | None = max(n_eff - n_fit, 1.0)
    else:  # residuals not kept: normal quantile
        n_eff, tau, dof = None, 1.0, None
    noise = np.asarray(ref.standard_error_si, dtype=float)  # τ included: not applied again
    geometry = ref.geometry_error_si
    response = held_response(ref) if held else None
    held_names: tuple[str, ...] = ()
    held_sd = np.zeros(k)
    if response is not None:
        held_names, r_unit = response
        held_at = held_values(held_names, _base(ref))
        held_sd = np.sqrt(held_parameter_variance(ref, prior, response))
    total = np.sqrt(noise**2 + geometry**2 + held_sd**2)

    def pct(v: np.ndarray) -> dict[str, float]:
        return {p: float(100 * x / s) for p, x, s in zip(ref.parameters, v, span, strict=True)}

    details = {
        "residual_autocorrelation_time": tau,
        "effective_sample_size": n_eff,
        "degrees_of_freedom": dof,
        "noise_standard_error_method": PER_CHANNEL,
        "noise_standard_error_pct_range": pct(noise),
        "geometry_error_pct_range": pct(geometry),
        "held_parameters": list(held_names),
        "held_parameters_error_pct_range": pct(held_sd),
        "held_parameters_assumed": held_assumptions(ref.parameters, prior, _base(ref))
        if response is not None
        else {},
        "held_prior_display": (prior or HeldPrior()).to_display(),
        "held_prior_unused": (prior or HeldPrior()).unused(ref.parameters),
        "total_standard_error_pct_range": pct(total),
    }
    if response is None:
        details["interval_quantiles"] = STUDENT_T
        return from_standard_errors(
            ref.parameters, ref.estimate_si, total, level, dof, REFINEMENT, details
        )
    low_u, high_u = held_deviation_range(held_names, held_at, prior)
    lower, upper = error_quantiles(
        r_unit, low_u, high_u, noise / span, dof, geometry / span, level, DRAWS, SEED
    )
    details.update(
        {
            "interval_quantiles": MONTE_CARLO,
            "monte_carlo_draws": DRAWS,
            "monte_carlo_seed": SEED,
            "error_quantiles_pct_range": {
                p: [float(100 * a), float(100 * b)]
                for p, a, b in zip(ref.parameters, lower, upper, strict=True)
            },
        }
    )
    return from_error_quantiles(
        ref.parameters, ref.estimate_si, lower * span, upper * span, level, REFINEMENT, details
    )


def _simulator(refinement: Refinement) -> SimulatorForces | None:
    """The simulator the refinement compared (itself, or averaged over drawn tracks by
    :class:`~railsusp.estimate.expected_forces.ExpectedForces`); None for another model."""
    prob = refinement.problem
    model = averaged_model(prob.model) if prob is not None else None
    return model if isinstance(model, SimulatorForces) else None


def _base(refinement: Refinement) -> ParameterSet | None:
    """The values the refinement's simulator holds the other parameters at (None: nominal)."""
    sim = _simulator(refinement)
    return sim.base if sim is not None else None
