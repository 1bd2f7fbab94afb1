"""What the mean of k sections' statistics can tell about the parameters, read through a
synthetic likelihood's emulator: the Fisher information J^T C_k^-1 J
(:func:`fisher_information`; J, the Jacobian of the emulated mean, by central differences,
:func:`mean_jacobian`), the Cramer-Rao bound of a 90 % interval's width
(:func:`cramer_rao_width`), and the informative projection, the few linear combinations of
the statistics that carry the most of that information (:func:`informative_projection`,
:func:`whitening`, :func:`top_directions`).

Apart from :mod:`railsusp.estimate.posterior_synthetic`, which draws the posterior: these
draw nothing; they bound what any posterior of these statistics can reach (the Cramer-Rao
tables of bench/posterior_synthetic.py and bench/information_estimate.py) and choose what
the likelihood reads (:mod:`railsusp.estimate.posterior_synthetic_fit` fits the
projection)."""

from __future__ import annotations

import numpy as np

from railsusp.estimate.posterior_synthetic import SyntheticLikelihood

#: z of a central 90 % interval: its width is 2 x 1.645 standard deviations
Z90 = 1.6448536269514722


def mean_jacobian(sl: SyntheticLikelihood, u: np.ndarray, step: float = 0.01) -> np.ndarray:
    """(N, dim, d) the Jacobian of mu (projected as ``sl`` reads it) at ``u`` (N, d) by
    central differences of ``step`` (a fraction of range)."""
    u = np.atleast_2d(np.asarray(u, float))
    n, d = u.shape
    jac = np.empty((n, sl.dim, d))
    for j in range(d):
        hi, lo = u.copy(), u.copy()
        hi[:, j] += step
        lo[:, j] -= step
        jac[:, :, j] = (sl.mean(hi) - sl.mean(lo)) / (2 * step)
    return jac


def fisher_information(
    sl: SyntheticLikelihood, u: np.ndarray, k: int, step: float = 0.01, emulator_error=True
) -> np.ndarray:
    """(N, d, d) Fisher information about u (fractions of range) of the mean of ``k``
    sections at ``u`` (N, d): J^T C_k^-1 J, J the Jacobian of the emulator's mu by central
    differences of ``step`` (a fraction of range). ``emulator_error``: C_k with the
    emulator's error (E and m Sigma or S A S: what this emulator can tell); False: G +
    (c Sigma - G) / k alone (what the statistics themselves hold, read by a perfect
    emulator). Only the mean's term: the covariance's own dependence on u is left out (its
    term does not grow with k, and Sigma(u) is a quadratic fit)."""
    u = np.atleast_2d(np.asarray(u, float))
    jac = mean_jacobian(sl, u, step)
    _, shared, section, emulator = sl.parts(u)
    cov = shared + (sl.within_scale * section - shared) / k
    if emulator_error:
        cov = cov + emulator + sl.model_error_cov(section)
    return np.einsum("nia,nij,njb->nab", jac, np.linalg.inv(cov), jac)


def cramer_rao_width(information: np.ndarray) -> np.ndarray:
    """(N, d) the narrowest 90 % interval an unbiased estimator can have, 2 x 1.645 x
    sqrt((I^-1)_jj), in the units of u (all d parameters unknown: the others are not
    held at their truths)."""
    inv = np.linalg.inv(np.atleast_3d(information))
    return 2.0 * Z90 * np.sqrt(np.diagonal(inv, axis1=1, axis2=2))


def informative_projection(
    sl: SyntheticLikelihood, u: np.ndarray, k: int, rank: int, step: float = 0.01
) -> tuple[np.ndarray, float]:
    """(P (rank, D), the fraction of the information kept): the ``rank`` linear
    combinations of the statistics that carry the most information about the parameters,
    on average over the points ``u`` (N, d; the training cases' parameters), for the mean
    of ``k`` sections.

    With C the covariance of that mean as the emulator says it (G + (Sigma - G) / k + E,
    averaged over ``u``) and J(u) the emulator's Jacobian, the whitened information
    W J J^T W (W = C^-1/2) averaged over ``u`` has eigenvectors V; P = V_r^T W keeps its
    ``rank`` largest. Where J spans at most ``rank`` directions for every u, P s carries all
    that s carries (a sufficient linear summary of a Gaussian with a mean linear in u); a
    likelihood of P s needs its covariance, the emulator's error and the model error only
    in ``rank`` dimensions, which the calibration records can estimate (150 records for 270
    statistics cannot: the posterior of all 270 held the truth in 54-78 % of 100 test
    records at 600 s, bench/README.md). Fitted on training cases only. The fraction kept is
    of the averaged information's trace, which the well-identified parameters dominate: a
    weakly identified one can lose more (compare the Cramer-Rao widths through the
    projection, :func:`fisher_information`, with those of all statistics)."""
    base = SyntheticLikelihood(sl.emulator, sl.shared)
    u = np.atleast_2d(np.asarray(u, float))
    _, shared, section, emulator = base.parts(u)
    whiten = whitening(np.mean(shared + (section - shared) / k + emulator, axis=0))
    return top_directions(whiten, mean_jacobian(base, u, step), rank)


def whitening(cov: np.ndarray) -> np.ndarray:
    """W = C^-1/2 (D, D) of a symmetric covariance ``cov``, its eigenvalues floored at
    1e-12 of the largest (directions of no variance are not amplified without bound)."""
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    return (vecs / np.sqrt(np.maximum(vals, 1e-12 * vals.max()))) @ vecs.T


def top_directions(whiten: np.ndarray, jac: np.ndarray, rank: int) -> tuple[np.ndarray, float]:
    """(P (rank, D), the fraction kept): P = V_r^T W, V_r the ``rank`` eigenvectors of
    largest eigenvalue of the whitened information W J J^T W averaged over the Jacobians
    ``jac`` (N, D, d; or one, (D, d)); the fraction is of its trace. Where W whitens J's
    statistics, these are the combinations that carry the most information about the
    parameters."""
    jac = np.asarray(jac, float)
    w = np.einsum("ij,njb->nib", whiten, jac[None] if jac.ndim == 2 else jac)  # whitened J
    m = np.einsum("nib,njb->ij", w, w) / len(w)
    vals, vecs = np.linalg.eigh(m)
    order = np.argsort(vals)[::-1][:rank]
    kept = float(np.sum(vals[order]) / np.sum(np.maximum(vals, 0.0)))
    return vecs[:, order].T @ whiten, kept
