"""Output-error refinement of an estimate on recordings with measured track geometry.

NSGA-II on surrogates is global and fast but compares statistics; where the recordings carry
the geometry of the track they were made on, the simulator can be run on that track and
compared with them sample by sample. :func:`refine` runs bounded least squares on the
time-aligned residuals (the output-error method of system identification: Maine & Iliff,
*Identification of dynamic systems*, NASA RP-1168, 1986), estimating the gains of the force
channels alongside, and reports standard errors and the share of the uncertainty that the
track geometry's measurement error causes. Screening the starts and attaching the result to
an NSGA-II estimate is :func:`railsusp.estimate.polish.refine_estimate`.
"""

from __future__ import annotations

import logging
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from railsusp.estimate.comparison import (
    compared_measurement,
    comparison_filter,
    comparison_samples,
)
from railsusp.estimate.forces import ForceModel
from railsusp.estimate.problem import check_aligned, display_values
from railsusp.measured import Recording
from railsusp.params import bounds
from railsusp.vehicle import track

#: progress lines for the command line
log = logging.getLogger("railsusp.estimate")

#: forward-difference step of the refinement's Jacobian, share of each parameter's range:
#: wider than the small-scale roughness of the time-aligned cost (wedge friction, contact
#: tables), on which a 2 % step stalled in flat valleys 3-5 % of the range from the optimum
REFINE_STEP = 0.05


#: the refinement's channel gains stay within 1 ± this (instrumented-wheelset calibration)
GAIN_LIMIT = 0.1


#: draws of track-geometry measurement error propagated into the refined estimate's
#: uncertainty, where the recordings state their geometry's accuracy
GEOMETRY_DRAWS = 8


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
    standard_error_si: np.ndarray  # white-residual standard errors, SI
    history_si: np.ndarray  # (n_jacobians, k): the iterate at each Jacobian
    channel_gains: dict[str, float] = field(default_factory=dict)  # estimated, if any
    starts: list[dict] = field(default_factory=list)  # every start refined, when screened
    screened: int = 0  # candidate starts scored
    #: (draws, k) first-order shift of the estimate, SI, that each draw of geometry error of
    #: the stated accuracy causes (:func:`gauss_newton_step`); empty on exact geometry
    geometry_shifts_si: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    #: whether the estimate is the refined point less :attr:`geometry_bias_si`
    geometry_bias_removed: bool = False
    #: the least-squares problem solved, with its cache of simulated series, and its
    #: solution (unit parameters, then gains), for more work at the estimate (not saved)
    problem: OutputError | None = field(default=None, repr=False, compare=False)
    solution: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: residuals at the solution and their lengths per recording and channel, for the
    #: intervals' autocorrelation inflation (:mod:`railsusp.estimate.intervals`; not saved)
    residuals: np.ndarray | None = field(default=None, repr=False, compare=False)
    residual_blocks: tuple[int, ...] = field(default=(), repr=False, compare=False)

    @property
    def estimate_si(self) -> np.ndarray:
        """(k,) the estimate, SI: the refined point, less the geometry bias estimate where
        it is removed (kept within the ranges)."""
        if not self.geometry_bias_removed:
            return self.x_si
        lo, hi = bounds(self.parameters)
        return np.clip(self.x_si - self.geometry_bias_si, lo, hi)

    @property
    def geometry_error_si(self) -> np.ndarray:
        """(k,) RMS shift of the estimate over the geometry-error draws, SI: the part of its
        uncertainty that the track geometry's measurement error causes (zeros if none)."""
        if self.geometry_shifts_si.size == 0:
            return np.zeros(len(self.parameters))
        return np.sqrt(np.mean(self.geometry_shifts_si**2, axis=0))

    @property
    def geometry_bias_si(self) -> np.ndarray:
        """(k,) mean shift of the estimate over the geometry-error draws, SI: the first
        SIMEX step (Cook & Stefanski, 1994). Doubling the error variance moves the estimate
        by about the bias the error already caused, so the refined point less this
        approximates the estimate on exact geometry (linear extrapolation in the error
        variance; zeros if none)."""
        if self.geometry_shifts_si.size == 0:
            return np.zeros(len(self.parameters))
        return self.geometry_shifts_si.mean(axis=0)

    @property
    def total_error_si(self) -> np.ndarray:
        """(k,) standard error from sensor noise and geometry error together, SI."""
        return np.hypot(self.standard_error_si, self.geometry_error_si)

    def to_dict(self) -> dict:
        lo, hi = bounds(self.parameters)

        def pct(values: np.ndarray) -> dict[str, float]:
            return {
                p: float(100 * v / (h - low))
                for p, v, low, h in zip(self.parameters, values, lo, hi, strict=True)
            }

        return {
            "method": "output-error least squares (scipy least_squares, trust-region "
            "reflective) on time-aligned series of recordings on measured track",
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
            "geometry_error_pct_range": pct(self.geometry_error_si),
            "geometry_bias_pct_range": pct(self.geometry_bias_si),
            "geometry_draws": int(self.geometry_shifts_si.shape[0]),
            "channel_gains": self.channel_gains,
            "screened_starts": self.screened,
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
    Standard errors are s^2 (J^T J)^-1 with white residuals, so they are optimistic where the
    residuals are correlated. Where the geometry has a stated accuracy, its measurement
    error is propagated too (:func:`gauss_newton_step` on ``geometry_draws`` draws seeded by
    ``seed``): on 0.5 mm geometry it, not the sensor noise, sets the uncertainty. The method
    is the classical one of system identification (Maine & Iliff, NASA RP-1168, 1986,
    including the scale-factor estimation of measurement channels).
    """
    from scipy.optimize import least_squares

    problem = OutputError(model, recordings, parameters, step, gains)
    k, n_gain = problem.k, problem.n_gain
    lo, hi = problem.lo, problem.hi
    history: list[np.ndarray] = []

    def fun(z: np.ndarray) -> np.ndarray:
        return problem.residuals(problem.predictions(z[:k]), z[k:])[0]

    def jacobian(z: np.ndarray) -> np.ndarray:
        history.append(lo + z[:k] * (hi - lo))
        log.info(
            "refinement step %d (at most %d evaluations): %d simulations of %d parameters",
            len(history), max_evaluations, k + 1, k,
        )  # fmt: skip
        return problem.jacobian_of(problem.predictions(problem.steps(z[:k])), z)

    u0 = np.clip((np.asarray(start_si, dtype=float) - lo) / (hi - lo), 0.0, 1.0)
    z0 = np.concatenate([u0, np.ones(n_gain)])
    r0 = fun(z0)
    sol = least_squares(
        fun,
        z0,
        jac=jacobian,
        bounds=(
            np.concatenate([np.zeros(k), np.full(n_gain, 1.0 - GAIN_LIMIT)]),
            np.concatenate([np.ones(k), np.full(n_gain, 1.0 + GAIN_LIMIT)]),
        ),
        x_scale=np.concatenate([np.ones(k), np.full(n_gain, GAIN_LIMIT)]),
        max_nfev=max_evaluations,
        method="trf",
    )
    dof = max(sol.fun.size - k - n_gain, 1)
    se = standard_errors(sol.jac, 2.0 * sol.cost / dof)
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
        if gains
        else {},
        geometry_shifts_si=problem.geometry_shifts(sol.x, geometry_draws, seed),
        problem=problem,
        solution=sol.x,
        residuals=sol.fun,
        residual_blocks=tuple(u[c].size for u in problem.samples for c in range(2)),
    )


class OutputError:
    """The time-aligned least-squares problem of :func:`refine` in unit parameters (and
    channel gains): the compared measurement and its scale per recording and channel,
    predictions with a cache, residuals and forward-difference Jacobians."""

    def __init__(
        self,
        model: ForceModel,
        recordings: Sequence[Recording],
        parameters: Sequence[str],
        step: float = REFINE_STEP,
        gains: bool = True,
    ):
        self.model = model
        self.parameters = tuple(parameters)
        self.recordings = list(recordings)
        check_aligned(model, self.recordings)
        self.lo, self.hi = bounds(self.parameters)
        self.k = len(self.parameters)
        self.step = step
        self.gains = gains
        self.n_gain = 2 * len(self.recordings) if gains else 0
        # per recording and channel (Y, Q): the compared measurement at the samples compared
        # and its scale, so that each channel's part of the cost is half its squared
        # aligned_error
        self.samples = [comparison_samples(rec) for rec in self.recordings]
        self.scales: list[list[float]] = []
        self.targets: list[np.ndarray] = []  # scaled measurement per recording and channel
        for rec, used in zip(self.recordings, self.samples, strict=True):
            meas = compared_measurement(rec)
            self.scales.append([meas[:, c].std() * np.sqrt(used[c].size) for c in range(2)])
            self.targets += [meas[used[c], c] / self.scales[-1][c] for c in range(2)]
        self._cache: dict[bytes, list[np.ndarray]] = {}

    def predictions(self, unit: np.ndarray) -> list[np.ndarray]:
        """Compared series (n, T, 2) per recording; undefined leading steps count zero.
        Parameter sets already simulated (the start, the base point of each Jacobian) are
        taken from a cache, the others simulated in one batch."""
        rows = np.atleast_2d(unit)
        cache = self._cache
        new = [i for i, u in enumerate(rows) if u.tobytes() not in cache]
        if new:
            x = self.lo + rows[new] * (self.hi - self.lo)
            series = [
                np.nan_to_num(comparison_filter(self.model.series(x, rec.condition), rec))
                for rec in self.recordings
            ]
            for j, i in enumerate(new):
                cache[rows[i].tobytes()] = [s[j] for s in series]
        return [
            np.stack([cache[u.tobytes()][r] for u in rows]) for r in range(len(self.recordings))
        ]

    def blocks(self, preds: list[np.ndarray]) -> list[np.ndarray]:
        """(n, T_c) scaled prediction per recording and channel, the gains' Jacobian too."""
        return [
            p[:, used[c], c] / sc[c]
            for p, used, sc in zip(preds, self.samples, self.scales, strict=True)
            for c in range(2)
        ]

    def residuals(self, preds: list[np.ndarray], g: np.ndarray) -> np.ndarray:
        g = g if self.gains else np.ones(2 * len(self.recordings))
        return np.concatenate(
            [b * gc - t for b, gc, t in zip(self.blocks(preds), g, self.targets, strict=True)],
            axis=1,
        )

    def steps(self, unit: np.ndarray) -> np.ndarray:
        """(k + 1, k) the point and its forward-difference neighbours, stepping inwards at
        the upper bound."""
        h = np.where(unit + self.step <= 1.0, self.step, -self.step)
        return np.vstack([unit, unit + np.diag(h)])

    def jacobian_of(self, preds: list[np.ndarray], z: np.ndarray) -> np.ndarray:
        """Jacobian at ``z`` from the predictions at :meth:`steps` of ``z``."""
        k = self.k
        h = np.diag(self.steps(z[:k])[1:] - z[:k])
        r = self.residuals(preds, z[k:])
        jac = np.zeros((r.shape[1], k + self.n_gain))
        jac[:, :k] = ((r[1:] - r[0]) / h[:, None]).T
        if self.gains:  # d r / d gain of a channel: its scaled prediction, in its rows only
            row = 0
            for j, b in enumerate(self.blocks(preds)):
                jac[row : row + b.shape[1], k + j] = b[0]
                row += b.shape[1]
        return jac

    def geometry_shifts(self, z: np.ndarray, draws: int, seed: int) -> np.ndarray:
        """(draws, k) shift of the estimate ``z``, SI, that each draw of geometry error of
        the recordings' stated accuracy causes: a :func:`gauss_newton_step` on the residuals
        and Jacobian with the perturbed geometry (:func:`geometry_error_series`), less the
        step on the measured geometry itself (zero at a converged interior optimum).
        Empty where no recording states an accuracy or ``draws`` is 0."""
        k = self.k
        if draws <= 0 or not any(rec.condition.track_accuracy_mm for rec in self.recordings):
            return np.zeros((0, k))
        batch = self.steps(z[:k])
        base = self.predictions(batch)
        drawn = geometry_error_series(
            self.model, self.recordings, self.lo + batch * (self.hi - self.lo), draws, seed
        )

        def shift(preds: list[np.ndarray]) -> np.ndarray:
            jac = self.jacobian_of(preds, z)
            return gauss_newton_step(jac, self.residuals(preds, z[k:])[0])[:k]

        unmoved = shift(base)
        return np.stack(
            [
                shift([b if d is None else d for b, d in zip(base, draw, strict=True)]) - unmoved
                for draw in drawn
            ]
        ) * (self.hi - self.lo)


def geometry_error_series(
    model: ForceModel,
    recordings: Sequence[Recording],
    x_si: np.ndarray,
    draws: int,
    seed: int,
) -> list[list[np.ndarray | None]]:
    """Per draw and recording, the compared series (n, T, 2) of the parameter sets ``x_si``
    (n, k) with the recording's measured geometry perturbed by a fresh draw of its stated
    measurement error (:func:`~railsusp.vehicle.track.with_measurement_error`:
    ``track_accuracy_mm`` RMS, down to ``wavelength_min_m``); None for recordings on exact
    geometry. The perturbed geometries go to a temporary folder, as the simulator reads
    geometry files."""
    rng = np.random.default_rng(seed)
    out: list[list[np.ndarray | None]] = [[None] * len(recordings) for _ in range(draws)]
    with tempfile.TemporaryDirectory(prefix="railsusp-geometry-") as tmp:
        for i, rec in enumerate(recordings):
            cond = rec.condition
            if not cond.track_accuracy_mm:
                continue
            irr = track.read_track_geometry(cond.track_geometry)
            rms_m = cond.track_accuracy_mm * 1e-3
            for d in range(draws):
                path = Path(tmp) / f"{i}-{d}.parquet"
                noisy = track.with_measurement_error(irr, rms_m, cond.wavelength_min_m, rng)
                track.write_track_geometry(path, noisy)
                series = model.series(x_si, cond.with_changes(track_geometry=str(path)))
                out[d][i] = np.nan_to_num(comparison_filter(series, rec))
    return out


def gauss_newton_step(jac: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The Gauss-Newton step -(JᵀJ)⁻¹Jᵀr of least squares with Jacobian ``jac`` and
    residuals ``r``; columns the residuals do not depend on stay put. At an estimate, with
    the Jacobian and residuals of perturbed input data, it is the estimate's shift that the
    perturbation causes (exact where the residuals are linear in the parameters), the
    propagation of errors-in-variables used by SIMEX (Cook & Stefanski, JASA 89, 1994)."""
    d = np.einsum("ij,ij->j", jac, jac)
    active = d > 1e-12 * max(float(d.max()), 1e-300)
    out = np.zeros(jac.shape[1])
    out[active] = -np.linalg.lstsq(jac[:, active], r, rcond=None)[0]
    return out


def standard_errors(jac: np.ndarray, s2: float) -> np.ndarray:
    """Standard errors sqrt(diag(s² (JᵀJ)⁻¹)) of least-squares estimates; a column the
    residuals do not depend on at all (e.g. a stop clearance never reached) gets an
    infinite error without spoiling the others."""
    jtj = jac.T @ jac
    d = np.diag(jtj)
    active = d > 1e-12 * max(float(d.max()), 1e-300)
    se = np.full(d.size, np.inf)
    try:
        cov = s2 * np.linalg.inv(jtj[np.ix_(active, active)])
        se[active] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        pass
    return se
