"""Output-error refinement of an estimate on recordings with measured track geometry.

NSGA-II on surrogates is global and fast but compares statistics; where the recordings carry
the geometry of the track they were made on, the simulator can be run on that track and
compared with them sample by sample. :func:`refine` runs bounded least squares on the
time-aligned residuals (the output-error method of system identification: Maine & Iliff,
*Identification of dynamic systems*, NASA RP-1168, 1986), estimating the gains of the force
channels alongside, and reports standard errors and the share of the uncertainty that the
track geometry's measurement error causes; :func:`refine_starts` refines several starts in
step, their simulations batched together. The problem itself (residuals, Jacobians, cached
simulations) is :class:`~railsusp.estimate.output_error.OutputError`. Screening the starts
and attaching the result to an NSGA-II estimate is
:func:`railsusp.estimate.polish.refine_estimate`.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from railsusp.estimate.comparison import GAIN_LIMIT
from railsusp.estimate.expected_forces import averaged_model
from railsusp.estimate.forces import ForceModel, SimulatorForces, SurrogateForces
from railsusp.estimate.geometry_bias import (
    GEOMETRY_DRAWS,
    less_bias,
    removable,
    simex_bias,
    simex_spread,
)
from railsusp.estimate.output_error import REFINE_STEP, OutputError
from railsusp.estimate.problem import display_values
from railsusp.estimate.residual_noise import PER_CHANNEL, noise_standard_errors
from railsusp.estimate.residual_noise import standard_errors as standard_errors  # re-export
from railsusp.measured import Recording
from railsusp.params import bounds

#: progress lines for the command line
log = logging.getLogger("railsusp.estimate")


#: the origin of a refinement's start that is NSGA-II's choice (:attr:`Refinement.start_origin`)
CHOICE = "NSGA-II's choice"
#: the origin of a start that is NSGA-II's estimate: its choice after the geometry
#: correction (less the geometry error's bias, or polished on expected forces;
#: :attr:`~railsusp.estimate.result.CalibrationResult.nsga_x`)
GEOMETRY_CORRECTED = "NSGA-II's estimate (its choice after its geometry correction)"


@dataclass
class Refinement:
    """Result of the output-error refinement of an estimate (see :func:`refine`)."""

    parameters: tuple[str, ...]
    start_si: np.ndarray
    x_si: np.ndarray
    cost_start: float
    cost: float
    n_evaluations: int
    n_jacobians: int
    message: str
    #: (k,) standard errors, SI, that the sensor noise causes: each recording's force
    #: channel with its own residual variance and autocorrelation time (the sandwich
    #: covariance, :func:`~railsusp.estimate.residual_noise.noise_standard_errors`),
    #: autocorrelation included; the intervals' noise part
    standard_error_si: np.ndarray
    history_si: np.ndarray  # (n_jacobians, k): the iterate at each Jacobian
    channel_gains: dict[str, float] = field(default_factory=dict)  # estimated, if any
    starts: list[dict] = field(default_factory=list)  # every start refined, when screened
    screened: int = 0  # candidate starts scored
    #: where the winning start came from (:data:`CHOICE`, "the nominal parameters", ...;
    #: "" where no starts were screened)
    start_origin: str = ""
    #: (draws, k) first-order shift of the estimate, SI, that each draw of geometry error of
    #: the stated accuracy causes (:func:`~railsusp.estimate.output_error.gauss_newton_step`);
    #: empty on exact geometry
    geometry_shifts_si: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    #: whether the estimate is the refined point less :attr:`geometry_bias_si`
    geometry_bias_removed: bool = False
    #: draws of the true geometry whose mean response was compared (expected forces, on
    #: recordings that state their geometry's accuracy; 0: the measured geometry itself)
    expected_draws: int = 0
    #: the least-squares problem solved, with its cache of simulated series, and its
    #: solution (unit parameters, then gains), for more work at the estimate (not saved)
    problem: OutputError | None = field(default=None, repr=False, compare=False)
    solution: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: residuals at the solution and their lengths per recording and channel, for the
    #: intervals' autocorrelation inflation (:mod:`railsusp.estimate.intervals`; not saved):
    #: the compared rows only, as the blocks count them (a washout's left-out leading rows
    #: are no residuals; kept, they pooled the channels into one block)
    residuals: np.ndarray | None = field(default=None, repr=False, compare=False)
    residual_blocks: tuple[int, ...] = field(default=(), repr=False, compare=False)
    #: the force model compared, in words (:func:`model_text`: "the simulator", a folder's
    #: surrogates, ...), for the route; "" where not known
    compared_model: str = ""

    @property
    def estimate_si(self) -> np.ndarray:
        """(k,) the estimate, SI: the refined point, less the geometry bias estimate where
        it is removed (kept within the ranges)."""
        if not self.geometry_bias_removed:
            return self.x_si
        return less_bias(self.parameters, self.x_si, self.geometry_shifts_si)

    @property
    def geometry_error_si(self) -> np.ndarray:
        """(k,) RMS shift of the estimate over the geometry-error draws, SI: the part of its
        uncertainty that the track geometry's measurement error causes (zeros if none;
        :func:`~railsusp.estimate.geometry_bias.simex_spread`)."""
        return simex_spread(self.geometry_shifts_si, len(self.parameters))

    @property
    def geometry_bias_si(self) -> np.ndarray:
        """(k,) mean shift of the estimate over the geometry-error draws, SI: the first
        SIMEX step (:func:`~railsusp.estimate.geometry_bias.simex_bias`; zeros if none)."""
        return simex_bias(self.geometry_shifts_si, len(self.parameters))

    @property
    def total_error_si(self) -> np.ndarray:
        """(k,) standard error from sensor noise and geometry error together, SI."""
        return np.hypot(self.standard_error_si, self.geometry_error_si)

    @property
    def from_choice(self) -> bool:
        """Whether the refinement started from NSGA-II's choice (or was not screened)."""
        return self.start_origin in ("", CHOICE)

    def to_dict(self) -> dict:
        lo, hi = bounds(self.parameters)

        def pct(values: np.ndarray) -> dict[str, float]:
            return {
                p: float(100 * v / (h - low))
                for p, v, low, h in zip(self.parameters, values, lo, hi, strict=True)
            }

        return {
            "method": "output-error least squares (scipy least_squares, trust-region "
            "reflective) on time-aligned series of recordings on measured track"
            + (
                f", the model's mean over {self.expected_draws} draws of the true geometry "
                "given the measured one (expected forces)"
                if self.expected_draws
                else ""
            ),
            "expected_draws": self.expected_draws,
            "compared_model": self.compared_model,  # the force model it compared (route)
            "start_display": display_values(self.parameters, self.start_si),
            "refined_display": display_values(self.parameters, self.x_si),
            "geometry_bias_removed": self.geometry_bias_removed,
            "cost_start": self.cost_start,
            "cost": self.cost,
            "n_evaluations": self.n_evaluations,
            "n_jacobians": self.n_jacobians,
            "message": self.message,
            "standard_error_pct_range": pct(self.total_error_si),
            "noise_standard_error_pct_range": pct(self.standard_error_si),
            "noise_standard_error_method": PER_CHANNEL,
            "geometry_error_pct_range": pct(self.geometry_error_si),
            "geometry_bias_pct_range": pct(self.geometry_bias_si),
            "geometry_bias_kept": [
                p
                for p, able in zip(
                    self.parameters,
                    removable(self.parameters, self.geometry_shifts_si),
                    strict=True,
                )
                if self.geometry_bias_removed and not able
            ],
            "geometry_draws": int(self.geometry_shifts_si.shape[0]),
            "channel_gains": self.channel_gains,
            "screened_starts": self.screened,
            "start_origin": self.start_origin,
            "starts": self.starts,
            "history_si": self.history_si,
        }


def refine(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    start_si: np.ndarray,
    *,
    max_evaluations: int = 40,
    step: float = REFINE_STEP,
    gains: bool = True,
    geometry_draws: int = GEOMETRY_DRAWS,
    seed: int = 0,
    box: float | None = None,
) -> Refinement:
    """Refine an estimate by the output-error method: least squares on the time-aligned
    residuals of every recording (lateral and vertical force, each over the standard
    deviation of its measured series and the square root of its length, so that the cost is
    half the sum of the squared :func:`aligned_error`).

    Needs recordings on measured track geometry and a series model (the simulator by
    default in the CLI). The Jacobian is a forward difference of ``step`` of each range,
    computed as one batch of k + 1 parameter sets. With ``gains`` the gain of every force
    channel (its calibration factor, within ±:data:`GAIN_LIMIT`) is estimated alongside, as a
    nuisance parameter whose Jacobian column is analytic: a 1 % calibration error on Q is
    1.2 kN, more than most parameters change the vertical force. On geometry of stated
    accuracy the series are compared in the band where it is accurate
    (:func:`~railsusp.estimate.comparison_band_hz`) and the residuals taken at four samples
    per period of its upper frequency (:func:`~railsusp.estimate.comparison_samples`).
    The standard errors (:attr:`Refinement.standard_error_si`) are the sandwich covariance
    (J^T J)^-1 J^T Σ J (J^T J)^-1 with Σ each recording's channel's own residual variance
    times its integrated autocorrelation time
    (:func:`~railsusp.estimate.residual_noise.noise_standard_errors`): the channels are
    unequally noisy and their residuals correlated, so one pooled white-residual s^2 (J^T J)^-1
    would be 2-4 times too wide for parameters the lateral force fixes and optimistic where
    the residuals are correlated. Where the geometry has a stated accuracy, its measurement
    error is propagated too (:func:`~railsusp.estimate.output_error.gauss_newton_step` on
    ``geometry_draws`` draws seeded by ``seed``): on 0.5 mm geometry it, not the sensor
    noise, sets the uncertainty. The method is the classical one of system identification
    (Maine & Iliff, NASA RP-1168, 1986, including the scale-factor estimation of
    measurement channels). Several starts on one problem: :func:`refine_starts`.
    ``box``: each parameter kept within that fraction of its range about the start (a trust
    region for a model trusted only near it, :mod:`~railsusp.estimate.level_correction`);
    None: the whole range.
    """
    problem = OutputError(model, recordings, parameters, step, gains)
    result = least_squares_from(problem, start_si, max_evaluations, box=box)
    assert result.solution is not None
    result.geometry_shifts_si = problem.geometry_shifts(result.solution, geometry_draws, seed)
    return result


def refine_starts(
    problem: OutputError, starts_si: Sequence[np.ndarray], max_evaluations: int = 40
) -> list[Refinement]:
    """:func:`refine` (without the geometry-error draws) from each of ``starts_si`` on one
    problem, the starts in step (:attr:`OutputError.lockstep`): each trial point and
    Jacobian of one start is simulated in the same batch as those of the others, so that
    the simulator's parallel sets fill the cores, and a set that two starts need is
    simulated once. Each start's result is the one it gets alone, bit for bit, as the
    simulations are independent per set."""
    solvers = [
        partial(least_squares_from, problem, s, max_evaluations, f"start {i + 1}: ")
        for i, s in enumerate(starts_si)
    ]
    if len(solvers) == 1:
        return [solvers[0]()]
    return problem.lockstep.run(solvers)


def least_squares_from(
    problem: OutputError,
    start_si: np.ndarray,
    max_evaluations: int = 40,
    label: str = "",
    box: float | None = None,
) -> Refinement:
    """The bounded least squares of :func:`refine` from one start (SI) on ``problem``
    (scipy's trust-region reflective method, forward-difference Jacobians); ``label``
    prefixes its progress lines; ``box`` as :func:`refine`'s."""
    from scipy.optimize import least_squares

    k, n_gain = problem.k, problem.n_gain
    lo, hi = problem.lo, problem.hi
    history: list[np.ndarray] = []

    def fun(z: np.ndarray) -> np.ndarray:
        return problem.residuals(problem.predictions(z[:k]), z[k:])[0]

    def jacobian(z: np.ndarray) -> np.ndarray:
        history.append(lo + z[:k] * (hi - lo))
        log.info(
            "%srefinement step %d (at most %d evaluations): %d simulations of %d parameters",
            label, len(history), max_evaluations, k + 1, k,
        )  # fmt: skip
        return problem.jacobian_of(problem.predictions(problem.steps(z[:k])), z)

    u0 = np.clip((np.asarray(start_si, dtype=float) - lo) / (hi - lo), 0.0, 1.0)
    z0 = np.concatenate([u0, np.ones(n_gain)])
    r0 = fun(z0)
    low, high = np.zeros(k), np.ones(k)
    if box is not None:
        low, high = np.maximum(low, u0 - box), np.minimum(high, u0 + box)
    sol = least_squares(
        fun,
        z0,
        jac=jacobian,
        bounds=(
            np.concatenate([low, np.full(n_gain, 1.0 - GAIN_LIMIT)]),
            np.concatenate([high, np.full(n_gain, 1.0 + GAIN_LIMIT)]),
        ),
        x_scale=np.concatenate([np.ones(k), np.full(n_gain, GAIN_LIMIT)]),
        max_nfev=max_evaluations,
        method="trf",
    )
    keep, blocks = problem.compared_rows()  # a washout's rows are no residuals
    se = noise_standard_errors(sol.jac[keep], sol.fun[keep], blocks, k + n_gain)  # at sol.x
    return Refinement(
        problem.parameters,
        lo + u0 * (hi - lo),
        lo + sol.x[:k] * (hi - lo),
        float(0.5 * r0 @ r0),
        float(sol.cost),
        int(sol.nfev),
        int(sol.njev or 0),
        str(sol.message),
        se[:k] * (hi - lo),
        np.array(history).reshape(-1, k),
        {
            f"{rec.condition.name}:{force}_{rec.wheels[0]}": float(sol.x[k + 2 * i + c])
            for i, rec in enumerate(problem.recordings)
            for c, force in enumerate(("Y", "Q"))
        }
        if problem.gains
        else {},
        problem=problem,
        solution=sol.x,
        residuals=sol.fun[keep],
        residual_blocks=blocks,
        compared_model=model_text(problem.model),
    )


#: :func:`model_text` of the simulator
SIMULATOR_TEXT = "the simulator"


def compared_model_of(refinement: dict | None) -> str:
    """The force model a refinement recorded in an ``estimate.json`` compared (its
    ``compared_model``, :func:`model_text`): older files name none, and theirs compared
    the simulator."""
    return (refinement or {}).get("compared_model") or SIMULATOR_TEXT


def model_text(model: ForceModel) -> str:
    """The force model a refinement compares, in words for the route: "the simulator", the
    window surrogates of a folder, else the model's class. A model averaged over drawn
    tracks (expected forces) is named as the model it averages; the route says the draws."""
    inner = averaged_model(model)
    if isinstance(inner, SimulatorForces):
        return SIMULATOR_TEXT
    if isinstance(inner, SurrogateForces):
        return f"the window surrogates in {inner.folder}"
    return f"the force model {type(inner).__name__}"
