"""The track geometry's measurement error in an estimate on time-aligned forces: its spread
and its bias (the first SIMEX step), for NSGA-II's choice as for the refinement.

A force model that reads the recording's measured track (the simulator, or a network
reading the nominal wagon's response on it) takes the geometry's measurement error in as an
input error: the compared forces then carry a part that no parameter explains, and least
squares on them is biased, not only scattered (errors in variables). On 0.5 mm geometry
the simulator's own output-error fit started at the truth lands 10-14 % of X18's range
too high on every one of four parameter sets, and within 1.5 % on exact geometry
(bench/README.md, "The geometry's error biases every estimate on time-aligned forces").

SIMEX (simulation-extrapolation, Cook & Stefanski, JASA 89, 1994) measures that bias by
adding more of the same error: each draw of error of the stated accuracy added to the
measured geometry moves the estimate by a shift
(:meth:`~railsusp.estimate.output_error.OutputError.geometry_shifts`: a Gauss-Newton step
with the perturbed geometry's residuals and Jacobian, with the same force model). Their
mean is the bias that doubling the error variance causes, and the estimate less it is the
linear extrapolation to no error; their RMS is the part of the uncertainty the geometry
causes. The functions here serve both the refinement
(:class:`~railsusp.estimate.refine.Refinement`) and NSGA-II's estimate
(:class:`~railsusp.estimate.result.CalibrationResult`,
:func:`~railsusp.estimate.nsga_geometry.remove_nsga_geometry_bias`), which keep the shifts
themselves.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.estimate.comparison import channel_gains
from railsusp.estimate.forces import ForceModel
from railsusp.estimate.output_error import OutputError
from railsusp.measured import Recording
from railsusp.params import bounds

#: draws of track-geometry measurement error propagated into an estimate, where the
#: recordings state their geometry's accuracy
GEOMETRY_DRAWS = 8
#: largest RMS shift over the draws, share of the range, of a parameter whose bias is taken off
MAX_SCATTER = 0.5


def simex_bias(shifts_si: np.ndarray, k: int) -> np.ndarray:
    """(k,) mean shift over the geometry-error draws ``shifts_si`` (draws, k), SI: the first
    SIMEX step. Doubling the error variance moves the estimate by about the bias the error
    already caused, so the estimate less this approximates the estimate on exact geometry
    (linear extrapolation in the error variance; zeros without draws)."""
    return shifts_si.mean(axis=0) if shifts_si.size else np.zeros(k)


def simex_spread(shifts_si: np.ndarray, k: int) -> np.ndarray:
    """(k,) RMS shift over the draws, SI: the part of the estimate's uncertainty that the
    geometry's measurement error causes (zeros without draws)."""
    return np.sqrt(np.mean(shifts_si**2, axis=0)) if shifts_si.size else np.zeros(k)


def removable(parameters: Sequence[str], shifts_si: np.ndarray) -> np.ndarray:
    """(k,) whether each parameter's SIMEX bias can be taken off: its draws move it by at most
    :data:`MAX_SCATTER` of its range (RMS). A parameter the draws throw further is not fixed by
    the compared forces (a network that hardly responds to it gives steps of many ranges),
    and a linear step that long says nothing of its bias: it keeps its estimate. Where it
    can, the draws' mean shift is consistent with their scatter in practice (on the bench's
    12 sets the key parameters' scatter is 1.0-1.5 times their bias, X19's 12-34 % of
    range)."""
    lo, hi = bounds(parameters)
    return simex_spread(shifts_si, len(parameters)) <= MAX_SCATTER * (hi - lo)


def less_bias(parameters: Sequence[str], x_si: np.ndarray, shifts_si: np.ndarray) -> np.ndarray:
    """``x_si`` (one set, or rows of sets) less the SIMEX bias of ``shifts_si`` of the
    :func:`removable` parameters, kept within the ranges."""
    lo, hi = bounds(parameters)
    bias = np.where(removable(parameters, shifts_si), simex_bias(shifts_si, len(parameters)), 0.0)
    return np.clip(np.asarray(x_si, float) - bias, lo, hi)


def stated_accuracy(recordings: Sequence[Recording]) -> bool:
    """Whether any recording states its track geometry's accuracy (the draws need one)."""
    return any(rec.condition.track_accuracy_mm for rec in recordings)


def geometry_shifts_at(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
    draws: int = GEOMETRY_DRAWS,
    seed: int = 0,
    gains: bool = False,
) -> np.ndarray:
    """(draws, k) shift, SI, of an estimate ``x_si`` of the time-aligned least squares
    that each draw of the recordings' stated geometry error causes, computed with ``model``,
    the force model that made the estimate (each draw: the model on the perturbed geometry
    at ``x_si`` and k forward steps). ``gains``: the least squares profiled each channel's
    gain out, as NSGA-II's comparison with channel gains does
    (:func:`~railsusp.estimate.comparison.channel_gains`): the shifts are then the
    parameters' part of the step with the gains estimated alongside, from the gains at
    ``x_si``. Empty where no recording states an accuracy or ``draws`` is 0."""
    problem = OutputError(model, recordings, parameters, gains=gains)
    unit = np.clip((np.asarray(x_si, dtype=float) - problem.lo) / (problem.hi - problem.lo), 0, 1)
    z = unit
    if gains:  # the step's batch (the point first), which the shifts then reuse from cache
        blocks = [b[:1] for b in problem.blocks(problem.predictions(problem.steps(unit)))]
        g = [channel_gains(b, t)[0] for b, t in zip(blocks, problem.targets, strict=True)]
        z = np.concatenate([unit, g])
    return problem.geometry_shifts(z, draws, seed)
