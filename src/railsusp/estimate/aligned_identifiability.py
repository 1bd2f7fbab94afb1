"""How precisely can time-aligned forces fix each key parameter? A Cramér-Rao bound.

The time-aligned counterpart of :mod:`railsusp.estimate.identifiability` (which bounds what
record statistics can tell): for recordings on measured track compared sample by sample
(:func:`~railsusp.estimate.comparison.aligned_error`), the Fisher information about the key
parameters in unit-range coordinates is JᵀJ / σ², with J the forward-difference Jacobian of
the scaled residuals of every recording's lateral and vertical force
(:class:`~railsusp.estimate.output_error.OutputError`, the refinement's problem, without
channel gains) and σ² their variance, inflated by the residuals' integrated autocorrelation
time (:func:`~railsusp.estimate.refine_intervals.effective_sample_size`: filtered residuals
are not independent). The square roots of the diagonal of its inverse are the smallest
standard deviations any unbiased estimator can reach from these recordings; a parameter
whose bound exceeds :data:`~railsusp.estimate.identifiability.BOUND_LIMIT_PCT` of its range
is not identifiable to that precision.

:func:`jacobian_agreement` compares two force models' Jacobians on the same recordings:
whether a surrogate makes the forces depend on each parameter as the simulator does, which
is what inverting it needs.

Evaluated at a given point (for synthetic recordings, the truth: a property of the
recordings and the force model, not of any estimate), with whatever force model is given
(a surrogate, or the simulator); local and linearised, so a guide, not a guarantee.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np

from railsusp.estimate.forces import ForceModel
from railsusp.estimate.identifiability import BOUND_LIMIT_PCT
from railsusp.estimate.output_error import OutputError
from railsusp.estimate.refine import standard_errors
from railsusp.estimate.refine_intervals import effective_sample_size
from railsusp.measured import Recording


def aligned_jacobian(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The time-aligned comparison's scaled residuals at ``x_si`` (SI) and their
    forward-difference Jacobian in unit-range parameters
    (:class:`~railsusp.estimate.output_error.OutputError` without channel gains), and the
    number of compared samples of each recording's lateral and vertical force, in order."""
    problem = OutputError(model, recordings, parameters, gains=False)
    unit = np.clip((np.asarray(x_si, dtype=float) - problem.lo) / (problem.hi - problem.lo), 0, 1)
    preds = problem.predictions(problem.steps(unit))
    jac = problem.jacobian_of(preds, unit)
    r = problem.residuals(preds, np.ones(0))[0]
    blocks = [u[c].size for u in problem.samples for c in range(2)]
    return r, jac, blocks


def bounds_pct_range(r: np.ndarray, jac: np.ndarray, blocks: Sequence[int]) -> np.ndarray:
    """Cramér-Rao bounds (% of range) from residuals ``r`` and their Jacobian ``jac`` in
    unit-range parameters (:func:`aligned_jacobian`): σ² is the residual variance times
    the residuals' integrated autocorrelation time over ``blocks``."""
    _, tau = effective_sample_size(r, list(blocks))
    s2 = float(r @ r) / max(r.size - jac.shape[1], 1) * tau
    return 100.0 * standard_errors(jac, s2)


def aligned_cramer_rao_pct_range(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
) -> dict[str, float]:
    """Cramér-Rao bound of each key parameter at ``x_si`` (SI) from the time-aligned
    comparison of ``model`` with ``recordings``, in % of its range; infinite for a parameter
    the residuals do not depend on. σ² is the residual variance at ``x_si`` (measurement
    noise, geometry error and model error alike), times the autocorrelation time."""
    bound = bounds_pct_range(*aligned_jacobian(model, recordings, parameters, x_si))
    return {p: float(b) for p, b in zip(parameters, bound, strict=True)}


def _agreement(col: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """Least-squares gain of ``col`` on ``ref``, their cosine, and the norm ratio."""
    nc, nr = float(np.linalg.norm(col)), float(np.linalg.norm(ref))
    dot = float(col @ ref)
    return {
        "gain": dot / nr**2 if nr > 0 else float("nan"),
        "cosine": dot / (nc * nr) if nc > 0 and nr > 0 else float("nan"),
        "norm_ratio": nc / nr if nr > 0 else float("inf"),
    }


def block_slices(blocks: Sequence[int]) -> list[slice]:
    """The rows of each block of :func:`aligned_jacobian`'s residuals and Jacobian (one
    recording's lateral or vertical force), in order."""
    edges = np.cumsum([0, *blocks])
    return [slice(int(a), int(b)) for a, b in pairwise(edges)]


def agreement_of(
    jac: np.ndarray,
    reference: np.ndarray,
    blocks: Sequence[int],
    channels: Sequence[str],
    parameters: Sequence[str],
) -> dict[str, dict]:
    """Per parameter the agreement of Jacobian ``jac``'s column with ``reference``'s
    (:func:`jacobian_agreement`), overall and per block of rows (``channels`` names them)."""
    rows = block_slices(blocks)
    out: dict[str, dict] = {}
    for j, p in enumerate(parameters):
        row: dict = _agreement(jac[:, j], reference[:, j])
        row["by_channel"] = {
            name: _agreement(jac[r, j], reference[r, j])
            for name, r in zip(channels, rows, strict=True)
        }
        out[p] = row
    return out


def channel_names(recordings: Sequence[Recording]) -> list[str]:
    """``"<condition>:Y"``, ``"<condition>:Q"`` per recording: the row blocks of
    :func:`aligned_jacobian`, in order."""
    return [f"{rec.condition.name}:{f}" for rec in recordings for f in ("Y", "Q")]


def jacobian_agreement(
    model: ForceModel,
    reference: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
) -> dict[str, dict]:
    """How well ``model`` (a surrogate) reproduces how ``reference`` (the simulator) makes the
    time-aligned forces depend on each key parameter at ``x_si``: per parameter the
    least-squares gain of the model's Jacobian column on the reference's (1: the right
    size), their cosine (1: the right shape in time), the norm ratio, and the same per
    recording and force (``by_channel``, keyed ``"<condition>:Y"`` / ``":Q"``).

    A surrogate to be inverted needs gains near 1 and cosines near 1 for the parameters it
    is to identify; its held-out error says nothing about either (issue 19). Both Jacobians
    are forward differences of :data:`~railsusp.estimate.output_error.REFINE_STEP` of the
    range, on the same recordings and samples."""
    _, jm, blocks = aligned_jacobian(model, recordings, parameters, x_si)
    _, jr, _ = aligned_jacobian(reference, recordings, parameters, x_si)
    return agreement_of(jm, jr, blocks, channel_names(recordings), parameters)


def identifiable(bounds_pct: dict[str, float], limit_pct: float = BOUND_LIMIT_PCT) -> list[str]:
    """The parameters whose bound is at most ``limit_pct`` of their range."""
    return [p for p, b in bounds_pct.items() if b <= limit_pct]
