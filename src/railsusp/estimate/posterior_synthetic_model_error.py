"""The synthetic likelihood's corrections for what its emulator gets wrong, fitted on held-out
calibration records of several sections: the scale c of the emulator's section scatter and
the isotropic model error m (:func:`fit_scales`), and the model error per direction A
(:func:`fit_model_error`: the records' mean residuals' excess covariance, shrunk as Ledoit
& Wolf shrink a sample covariance, :func:`shrunk_excess_covariance`).

Apart from :mod:`railsusp.estimate.posterior_synthetic`, whose
:class:`~railsusp.estimate.posterior_synthetic.SyntheticLikelihood` reads c, m and A: these
estimate them, once per estimator, on calibration records only (never the test records or
the sets); :mod:`railsusp.estimate.posterior_synthetic_fit` fits and caches them."""

from __future__ import annotations

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.posterior_synthetic import SyntheticLikelihood


def fit_scales(sl: SyntheticLikelihood, u: np.ndarray, records: np.ndarray) -> tuple[float, float]:
    """(within_scale, model_error) from held-out records ``records`` (n, k, D) of k
    consecutive sections at parameters ``u`` (n, d), k >= 2:

    - within_scale c: the sections' scatter about their record's mean, whose covariance
      is c Sigma - G (its expected quadratic form in Sigma^-1 is (k - 1) (c D -
      tr(Sigma^-1 G)));
    - model_error m: the fraction of Sigma added to E that makes the records' means' mean
      Mahalanobis distance from mu(u), under C_k, equal to D (its expectation): the
      emulator's error that its bootstrap spread does not see (the fitted mean's bias;
      the spread of 10 networks spans at most 9 of the D directions), measured where it
      matters most, on the longest records. 1 / m is the number of sections the emulator
      is worth: a record far longer cannot narrow the posterior further.

    A model that already covers the records is left as it is (c = 1, m = 0)."""
    x = sl.project(records)
    _, k, d = x.shape
    if k < 2:
        raise RailsuspInputError(f"records of {k} section: accepted at least 2 for the scales")
    mean, shared, section, emulator = sl.parts(u)
    section_inv = np.linalg.inv(section)
    w = x - x.mean(axis=1, keepdims=True)
    seen = np.einsum("nki,nij,nkj->", w, section_inv, w) / (k - 1)
    gain = np.einsum("nij,nji->", section_inv, shared)
    within_scale = max(1.0, float((seen + gain) / (len(x) * d)))
    r = x.mean(axis=1) - mean

    def mahalanobis(m: float) -> float:
        cov = shared + (within_scale * section - shared) / k + emulator + m * section
        return float(np.mean(np.einsum("ni,nij,nj->n", r, np.linalg.inv(cov), r)))

    if mahalanobis(0.0) <= d:
        return within_scale, 0.0
    lo, hi = 0.0, 1.0 / k
    while mahalanobis(hi) > d and hi < 1e3:
        hi *= 2.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mahalanobis(mid) > d else (lo, mid)
    return within_scale, float(hi)


def shrunk_excess_covariance(
    z: np.ndarray, base: np.ndarray, target: np.ndarray
) -> tuple[np.ndarray, float]:
    """(A, rho): the covariance A of what the vectors ``z`` (n, D) hold beyond their
    known covariance ``base`` (n, D, D; E[z z^T] = base_i + A), shrunk towards a
    multiple of ``target`` (D, D) and kept positive semi-definite.

    Each z_i z_i^T - base_i is an unbiased estimate of A; their mean A^ is full of
    sampling noise when n is not much larger than D (50 records, 34 statistics: its
    eigenvalues spread by a factor of ~100 about the truth, Marchenko-Pastur), so it is
    shrunk as Ledoit & Wolf (2004, "A well-conditioned estimator for large-dimensional
    covariance matrices") shrink a sample covariance: A = rho F + (1 - rho) A^, with F =
    tr(A^) / tr(target) target and rho = min(1, b^2 / d^2), where b^2 = sum ||W_i - A^||^2
    / n^2 estimates A^'s sampling error and d^2 = ||A^ - F||^2 how far A^ is from F (the
    Frobenius norm). rho is 1 where the data cannot tell A from F, and falls towards 0 as
    n grows. Negative eigenvalues (noise; the model already covers that direction) are set
    to 0."""
    z = np.asarray(z, float)
    w = z[:, :, None] * z[:, None, :] - np.asarray(base, float)
    n = len(w)
    a_hat = 0.5 * (w.mean(axis=0) + w.mean(axis=0).T)
    f = np.trace(a_hat) / np.trace(target) * np.asarray(target, float)
    b2 = float(np.sum((w - a_hat) ** 2)) / n**2
    d2 = float(np.sum((a_hat - f) ** 2))
    rho = 1.0 if d2 <= 0.0 else min(1.0, b2 / d2)
    vals, vecs = np.linalg.eigh(rho * f + (1.0 - rho) * a_hat)
    return (vecs * np.maximum(vals, 0.0)) @ vecs.T, rho


def fit_model_error(
    sl: SyntheticLikelihood, u: np.ndarray, records: np.ndarray, within_scale: float
) -> tuple[np.ndarray, float]:
    """(A, rho): the emulator's error per direction, S(u) A S(u), from held-out records
    ``records`` (n, k, D) at ``u`` (n, d) and the fitted ``within_scale``.

    The record means' residuals r = s_k - mu(u) have covariance G + (c Sigma - G) / k + E
    plus the emulator's error that its spread misses; in units of the sections' standard
    deviations S (z = r / S) that error is A, estimated per direction by
    :func:`shrunk_excess_covariance` towards the isotropic m R (R the sections'
    correlation; the model of :func:`fit_scales`). Why per direction: at the issue's scale
    the eigenvalues of A^ on 50 calibration records of 30 sections ran from 0.47 down to
    noise, against m = 0.020 on average: a few directions (the band RMS of Q among
    them) hold most of the emulator's bias. Why on
    records of several sections and not on the training cases' out-of-bag residuals: a
    training case is one section, whose residual is Sigma plus the emulator's error, and
    that error is about 2 % of Sigma on average: 2000 cases estimate a variance to sqrt(2
    / 2000) = 3 %, and Sigma itself is fitted to the same residuals, so the excess cannot be
    told from Sigma there; in the mean of 30 sections it is half the residual's variance.
    Only calibration records are used, never the test records or the sets."""
    x = sl.project(records)
    k = x.shape[1]
    mean, shared, section, emulator = sl.parts(u)
    sd = np.sqrt(np.diagonal(section, axis1=1, axis2=2))
    outer = sd[:, :, None] * sd[:, None, :]
    base = (shared + (within_scale * section - shared) / k + emulator) / outer
    z = (x.mean(axis=1) - mean) / sd
    return shrunk_excess_covariance(z, base, np.mean(section / outer, axis=0))
