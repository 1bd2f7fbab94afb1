"""How precisely can time-aligned forces fix each key parameter? A Cramér-Rao bound.

The time-aligned counterpart of :mod:`railsusp.estimate.identifiability` (which bounds what
record statistics can tell): for recordings on measured track compared sample by sample
(:func:`~railsusp.estimate.comparison.aligned_error`), the residuals r are the scaled
differences of every recording's lateral and vertical force
(:class:`~railsusp.estimate.output_error.OutputError`, the refinement's problem, without
channel gains), J their forward-difference Jacobian in unit-range parameters. The noise
model is the refinement's (:func:`~railsusp.estimate.residual_noise.channel_variances`):
each recording's force channel b its own variance s_b² and integrated autocorrelation time
τ_b (filtered residuals are not independent), Σ diagonal with s_b² τ_b. For Gaussian noise
of covariance Σ about a mean that depends on θ, the Fisher information is

    F = Jᵀ Σ⁻¹ J                                                       (Kay 1993, eq. 3.31)

(Kay, *Fundamentals of Statistical Signal Processing: Estimation Theory*, §3.9, the
general Gaussian case, the covariance not depending on θ), and the square roots of the
diagonal of F⁻¹ are the smallest standard deviations any unbiased estimator can reach from
these recordings. Σ⁻¹ with s_b² τ_b on its diagonal is the autocorrelated noise's
information counted in white-equivalent samples: exact where the parameters' effects on a
channel are slow beside the residuals' correlation (its spectrum near zero frequency,
§3.10), a guide otherwise, as τ was before.

Why this and not the sandwich (JᵀJ)⁻¹ Jᵀ Σ J (JᵀJ)⁻¹ of
:func:`~railsusp.estimate.residual_noise.noise_standard_errors`: that is the noise error of
one estimator, unweighted least squares (the refinement), and it is at least F⁻¹ (Aitken:
least squares weighted by Σ⁻¹ is the best linear unbiased estimator), equal where every
channel is equally noisy. The bound decides which key parameters are identifiable
(:func:`identifiable`; bench/estimate_tracks.py scores "identifiable keys within 5 %" with
it, for an estimator, NSGA-II on a surrogate, that is neither least squares;
bench/jacobian_check.py compares a surrogate's bound with the simulator's), so it must be a
property of the recordings and the force model, not of an estimator: a wider,
estimator-specific bound would let a poorer estimator shrink the set it is scored on.
Before 2026-11-24 (stop 24) the bound was s² (JᵀJ)⁻¹ with one residual variance pooled over
all channels times the overall autocorrelation inflation. The vertical forces' residual
variance is 10-40 times the lateral ones' on the demo's recordings, and the pooled variance,
mostly theirs, made the bounds of parameters the lateral force fixes (X11, X13) too wide
and of those the vertical force alone fixes too narrow (a parameter seen equally by a
channel and by one 40 times noisier: 3.24 times too wide,
tests/estimate/test_aligned_identifiability.py). With equal noise in every channel the two
agree.

A parameter whose bound exceeds :data:`~railsusp.estimate.identifiability.BOUND_LIMIT_PCT`
of its range is not identifiable to that precision.

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

from railsusp.estimate.comparison import comparison_filter
from railsusp.estimate.forces import ForceModel, series_in_conditions
from railsusp.estimate.identifiability import BOUND_LIMIT_PCT
from railsusp.estimate.output_error import REFINE_STEP, OutputError
from railsusp.estimate.residual_noise import channel_variances, standard_errors
from railsusp.measured import Recording


def aligned_jacobian(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
    *,
    defined_from: Sequence[int] | None = None,
    step: float = REFINE_STEP,
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The time-aligned comparison's scaled residuals at ``x_si`` (SI) and their
    forward-difference Jacobian in unit-range parameters (steps of ``step`` of the range,
    inwards at the upper bound)
    (:class:`~railsusp.estimate.output_error.OutputError` without channel gains), and the
    number of compared samples of each recording's lateral and vertical force, in order.

    Only samples where the model's prediction is defined are compared: a surrogate's first
    steps (a window network's window, a sequence network's washout, through the
    comparison's filter) are undefined, and the refinement's problem counts them as zero
    force, which would make a 100 kN wheel load look like a residual of several standard
    deviations. ``defined_from`` (per recording, the first step to compare, e.g. another
    model's :func:`defined_from`) leaves out more, so that two models are compared on the
    same samples. Each block stays scaled so that its norm is the RMS residual over the
    measured force's standard deviation."""
    problem = OutputError(model, recordings, parameters, gains=False, step=step)
    unit = np.clip((np.asarray(x_si, dtype=float) - problem.lo) / (problem.hi - problem.lo), 0, 1)
    base = problem.lo + unit * (problem.hi - problem.lo)
    series = series_in_conditions(model, base[None], [rec.condition for rec in recordings])
    problem.remember(base[None], series)  # the base point is not predicted twice
    first = [_first_defined(s, rec) for s, rec in zip(series, recordings, strict=True)]
    if defined_from is not None:
        first = [max(a, int(b)) for a, b in zip(first, defined_from, strict=True)]
    preds = problem.predictions(problem.steps(unit))
    jac = problem.jacobian_of(preds, unit)
    r = problem.residuals(preds, np.ones(0))[0]
    # the problem itself leaves out the samples no set defines, scaled for the rest
    # (:meth:`OutputError.compared_rows`); rescale for those ``defined_from`` leaves out too
    _, own = problem.compared_rows()
    keep, scale = [], []
    counts = iter(own)
    for u, start in zip(problem.samples, first, strict=True):
        for c in range(2):
            used = u[c] >= start
            keep.append(used)
            n = max(int(used.sum()), 1)
            scale.append(np.full(int(used.sum()), np.sqrt(next(counts) / n)))
    rows = np.concatenate(keep)
    factor = np.concatenate(scale)
    blocks = [int(k.sum()) for k in keep]
    return r[rows] * factor, jac[rows] * factor[:, None], blocks


def defined_from(model: ForceModel, recordings: Sequence[Recording], x_si: np.ndarray) -> list[int]:
    """Per recording, the first step from which ``model``'s prediction at ``x_si`` (SI) is
    defined through the time-aligned comparison's filter (0 for the simulator)."""
    x = np.atleast_2d(np.asarray(x_si, dtype=float))
    series = series_in_conditions(model, x, [rec.condition for rec in recordings])
    return [_first_defined(s, rec) for s, rec in zip(series, recordings, strict=True)]


def _first_defined(series: np.ndarray, rec: Recording) -> int:
    """The first step from which every set of ``series`` (n, T, 2) is defined after the
    comparison's filter (T where one never is)."""
    ok = np.isfinite(comparison_filter(series, rec)).all(axis=-1)  # (n, T)
    if not ok.any(axis=1).all():
        return ok.shape[1]
    return int(np.argmax(ok, axis=1).max())


#: a channel whose residual vanishes (a noiseless synthetic record at its truth) is given
#: this share of the largest channel's variance: its parameters' bounds come out near zero
#: rather than 0 / 0
NOISELESS_SHARE = 1e-9


def bounds_pct_range(r: np.ndarray, jac: np.ndarray, blocks: Sequence[int]) -> np.ndarray:
    """Cramér-Rao bounds (% of range), sqrt(diag((Jᵀ Σ⁻¹ J)⁻¹)), from residuals ``r`` at the
    point and their Jacobian ``jac`` in unit-range parameters (:func:`aligned_jacobian`),
    ``blocks`` the lengths of their consecutive channels (one recording's lateral or
    vertical force each): Σ diagonal with each channel's residual variance times its
    autocorrelation time (:func:`~railsusp.estimate.residual_noise.channel_variances`, the
    refinement's noise model; the module docstring says why the inverse of the weighted
    information and not the least-squares sandwich). Infinite for a parameter the residuals
    do not depend on; with every residual zero, zero for the others."""
    r = np.asarray(r, dtype=float).ravel()
    variance = channel_variances(r, blocks, jac.shape[1])
    top = float(variance.max()) if variance.size else 0.0
    if top <= 0.0:
        return 100.0 * standard_errors(jac, 0.0)
    whiten = 1.0 / np.sqrt(np.maximum(variance, NOISELESS_SHARE * top))
    return 100.0 * standard_errors(jac * whiten[:, None], 1.0)


def aligned_cramer_rao_pct_range(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
) -> dict[str, float]:
    """Cramér-Rao bound of each key parameter at ``x_si`` (SI) from the time-aligned
    comparison of ``model`` with ``recordings``, in % of its range; infinite for a parameter
    the residuals do not depend on. Each force channel's noise is its residual variance at
    ``x_si`` (measurement noise, geometry error and model error alike) times its
    autocorrelation time (:func:`bounds_pct_range`)."""
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
    lead = defined_from(model, recordings, x_si)
    _, jm, blocks = aligned_jacobian(model, recordings, parameters, x_si, defined_from=lead)
    _, jr, _ = aligned_jacobian(reference, recordings, parameters, x_si, defined_from=lead)
    return agreement_of(jm, jr, blocks, channel_names(recordings), parameters)


def identifiable(bounds_pct: dict[str, float], limit_pct: float = BOUND_LIMIT_PCT) -> list[str]:
    """The parameters whose bound is at most ``limit_pct`` of their range."""
    return [p for p, b in bounds_pct.items() if b <= limit_pct]
