"""Posterior of a long recording by a Gaussian synthetic likelihood of the MEAN of its
section statistics (Wood 2010, "Statistical inference for noisy nonlinear ecological
dynamic systems"; Price, Drovandi, Lee & Nott 2018, "Bayesian synthetic likelihood").

A recording of k sections gives k summary vectors x_1..x_k (:mod:`railsusp.estimate.
summaries`); their mean s_k is, by the central limit theorem over nearly independent
sections of stationary random track, Gaussian about mu(u) with covariance

    C_k(u) = G(u) + (c Sigma(u) - G(u)) / k + E(u) + S(u) A S(u)

- Sigma(u): one section's covariance of the statistics; it shrinks with k;
- G(u): the part every section of one record shares, which does NOT average out: the
  instrument's gain error (one per channel and record, :data:`railsusp.estimate.
  posterior_data.GAIN_ERROR`), propagated to the statistics by their derivative with
  respect to the gain (percentiles scale with it, log band RMS shift by it / ln 10);
- E(u): the emulator's uncertainty about mu(u) (the bagged ensemble's spread,
  :mod:`railsusp.estimate.posterior_emulator`). It does not shrink with k either, so the
  posterior of a long record cannot narrow below what the emulator knows, and its error is
  counted once, not once per section as in the fusion of per-section posteriors
  (:mod:`railsusp.estimate.posterior_fusion`, whose widening grew to 2.5 at 30 sections);
- c >= 1, fitted once on held-out calibration records of the longest checked length
  (:func:`fit_scales`), corrects the emulator's section scatter by the scatter of the
  records' own sections;
- S(u) A S(u), S the sections' standard deviations: the emulator's error that the
  bootstrap spread misses (its bias; the spread of 10 networks spans at most 9 of the D
  directions), a full D x D matrix A in the sections' units, estimated per direction on
  the same calibration records (:func:`fit_model_error`: the records' mean residuals'
  excess covariance, Ledoit-Wolf shrunk towards the isotropic m R). Before stop 24 it was
  the isotropic m Sigma (m = 0.020 at the issue's scale), which fixes the residuals'
  average distance but not its direction: at 30 sections the calibration records'
  excess ran from 0.47 of a section's variance in one direction to nothing in most (raw,
  50 records; A on 150 records: 0.39, 0.18, 0.12, ... down to 0). ``model_error_matrix``
  None keeps m Sigma.
- C_k is held at a first posterior's mean when drawing (:meth:`SyntheticLikelihood.
  plug_in_log_likelihood`): the emulated covariance's dependence on u carries no
  information into the posterior.

The posterior is the uniform prior on the box of all ten parameters times this
likelihood, drawn by tempered SMC (:mod:`railsusp.estimate.posterior_smc`): no new
simulation at inference. The estimated parameters' columns are reported; the others are
marginalised. The emulator learns from the estimator's own training cases; its check is
coverage on the held-out records of several sections (:mod:`railsusp.estimate.
posterior_synthetic_check`), with no widening fitted.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.posterior_emulator import StatisticsEmulator
from railsusp.estimate.posterior_smc import smc_sample
from railsusp.estimate.statistic_families import gain_dependence

#: the ``long_record`` methods of a recording's posterior of several sections
LONG_RECORD_METHODS = ("fusion", "synthetic-likelihood")

SharedCovariance = Callable[[np.ndarray], np.ndarray]


def check_long_record(method: str) -> str:
    """The method's name, or a one-line error naming the accepted ones."""
    if method not in LONG_RECORD_METHODS:
        raise RailsuspInputError(
            f"long_record = {method!r}: accepted {', '.join(LONG_RECORD_METHODS)}"
        )
    return method


def gain_covariance(names: list[str], gain_error: float) -> SharedCovariance:
    """G(mean): the statistics' covariance (N, D, D) from independent relative gain errors
    of standard deviation ``gain_error``, one per channel and condition, for the summary
    ``names`` (``condition:channel_statistic``, :func:`railsusp.estimate.
    statistic_families.statistic_names`), each statistic's dependence on the gains as
    :func:`~railsusp.estimate.statistic_families.gain_dependence` gives it: percentiles of
    Y and Q scale with their channel's gain, those of Y/Q with the difference of the two,
    those of the wheelset's force sumY = Y - Yp with each wheel's level (the partner's
    with its sign) times its gain; a log10 band
    RMS shifts by its channel's gain / ln 10; coherencies and correlations do not move."""
    sources: dict[str, int] = {}
    index = {name: i for i, name in enumerate(names)}
    rows: list[list[tuple[int, float, list[tuple[int, float]]]]] = []
    for name in names:
        cond, stat = name.split(":", 1) if ":" in name else ("", name)
        prefix = f"{cond}:" if ":" in name else ""
        terms = []
        for channel, factor, scale in gain_dependence(stat):
            s = sources.setdefault(f"{cond}:{channel}", len(sources))
            terms.append((s, factor, [(index[prefix + n], w) for n, w in scale]))
        rows.append(terms)
    n_src = len(sources)

    def shared(mean: np.ndarray) -> np.ndarray:
        mean = np.atleast_2d(mean)
        jac = np.zeros((mean.shape[0], len(names), n_src))
        for i, terms in enumerate(rows):
            for s, factor, scale in terms:
                level = sum(w * mean[:, j] for j, w in scale) if scale else 1.0
                jac[:, i, s] += factor * level
        return gain_error**2 * np.einsum("nis,njs->nij", jac, jac)

    return shared


@dataclass
class SyntheticLikelihood:
    """The synthetic likelihood of the mean of k sections' statistics (module
    docstring); ``shared``: G(mean), or None when nothing is shared between sections.
    ``within_scale`` (at least 1) multiplies Sigma; ``model_error`` (at least 0) adds
    that fraction of Sigma as the emulator's error its bootstrap spread does not see
    (both fitted on held-out records of several sections, :func:`fit_scales`; 1 and 0:
    as the emulator says); ``model_error_matrix`` A (D, D), when given, replaces m Sigma
    by S A S (:func:`fit_model_error`). ``projected``, with a ``projection`` P: an
    emulator of P x itself (fitted on the projected training statistics, on more cases
    than the emulator of all D statistics can take), which then gives mu, Sigma and E;
    ``emulator`` still gives the statistics' levels that the gain model G reads."""

    emulator: StatisticsEmulator
    shared: SharedCovariance | None = None
    emulator_variance: bool = True  # False only to show what leaving E(u) out does
    within_scale: float = 1.0
    model_error: float = 0.0
    model_error_matrix: np.ndarray | None = None  # A (D, D): S A S replaces m Sigma
    plug_in_covariance: bool = True  # C_k fixed at a first posterior's mean (sample)
    first_pass_at_centre: bool = False  # that first posterior with C_k at the box's centre
    projection: np.ndarray | None = None  # P (r, D): the likelihood of P s (informative_projection)
    projected: StatisticsEmulator | None = None  # an emulator of P x itself (r outputs)

    def __post_init__(self) -> None:
        if self.projected is not None and (
            self.projection is None or self.projected.dim != self.projection.shape[0]
        ):
            raise RailsuspInputError(
                f"projected emulator of {self.projected.dim} statistics: accepted only with "
                "a projection of as many combinations"
            )

    @property
    def dim(self) -> int:
        """The number of statistics the likelihood reads (r with a projection, else D)."""
        return self.emulator.dim if self.projection is None else self.projection.shape[0]

    def project(self, x: np.ndarray) -> np.ndarray:
        """Statistics ``x`` (..., D) as the likelihood reads them: P x with a projection."""
        x = np.asarray(x, float)
        return x if self.projection is None else x @ self.projection.T

    def mean(self, u: np.ndarray) -> np.ndarray:
        """mu(u) (N, dim), projected."""
        if self.projected is not None:
            return self.projected.mean(u)
        return self.project(self.emulator.mean(u))

    def parts(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """At ``u``: mu (N, dim), G, Sigma and E (as the emulator says, unscaled), projected
        (G from the full statistics' mean: the gain model reads their values)."""
        if self.projected is not None:
            mean, section, emulator = self.projected.moments(u)
            if self.shared is None:
                return mean, np.zeros_like(section), section, emulator
            p = self.projection
            return mean, p @ self.shared(self.emulator.mean(u)) @ p.T, section, emulator
        mean, section, emulator = self.emulator.moments(u)
        shared = self.shared(mean) if self.shared is not None else np.zeros_like(section)
        if self.projection is None:
            return mean, shared, section, emulator
        p = self.projection
        return (self.project(mean), *(p @ c @ p.T for c in (shared, section, emulator)))

    def mean_and_covariance(self, u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """mu(u) (N, D) and C_k(u) (N, D, D) for the mean of ``k`` sections."""
        mean, shared, section, emulator = self.parts(u)
        # G + (c Sigma - G) / k = G (1 - 1/k) + c Sigma / k: PSD for k >= 1 and c >= 1
        cov = shared + (self.within_scale * section - shared) / k
        if self.emulator_variance:
            cov = cov + emulator + self.model_error_cov(section)
        return mean, cov

    def model_error_cov(self, section: np.ndarray) -> np.ndarray:
        """The emulator's error that its spread misses (N, D, D): S A S, S the section's
        standard deviations, with the fitted A (:func:`fit_model_error`); without one, the
        isotropic m Sigma."""
        if self.model_error_matrix is None:
            return self.model_error * section
        sd = np.sqrt(np.diagonal(section, axis1=1, axis2=2))
        return sd[:, :, None] * self.model_error_matrix * sd[:, None, :]

    def log_likelihood(self, u: np.ndarray, s: np.ndarray, k: int) -> np.ndarray:
        """(N,) log N(s; mu(u), C_k(u)) of the mean ``s`` (D,) of ``k`` sections."""
        mean, cov = self.mean_and_covariance(u, k)
        d = mean.shape[1]
        cov = cov + 1e-10 * np.trace(cov, axis1=1, axis2=2)[:, None, None] / d * np.eye(d)
        chol = np.linalg.cholesky(cov)
        r = np.linalg.solve(chol, (np.asarray(s, float) - mean)[:, :, None])[:, :, 0]
        logdet = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), axis=1)
        return -0.5 * (np.sum(r**2, axis=1) + logdet + d * np.log(2.0 * np.pi))

    def sample(self, sections: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
        """(n, d) draws on the unit box of the posterior (uniform prior on the box of
        the emulator's inputs) of the sections ``sections`` (k, D), from their mean:
        with ``plug_in_covariance``, a first posterior with C_k(u) gives the point u0 at
        which a second holds C_k (:meth:`plug_in_log_likelihood`); two SMC runs. With
        ``first_pass_at_centre`` (the statistics families beyond the EN 14363 summary) the
        first posterior holds C_k at the box's centre too: C_k(u) for every particle costs
        N D^3 / 3 per call (1000 particles of 270 statistics: 6.6 GFLOP and 0.6 GB a call,
        hundreds of calls)."""
        s, k = self.reading(sections)
        d = self.emulator.inputs
        rng = np.random.default_rng(seed)
        draws = smc_sample(self.first_log_likelihood(s, k), d, n, rng)
        if not self.plug_in_covariance:
            return draws
        return smc_sample(self.second_log_likelihood(draws.mean(axis=0), s, k), d, n, rng)

    def reading(self, sections: np.ndarray) -> tuple[np.ndarray, int]:
        """(s, k): the mean of the sections ``sections`` (k, D) as the likelihood reads it
        (projected) and their number; a one-line error for another width or a non-finite
        statistic."""
        x = np.atleast_2d(np.asarray(sections, float))
        if x.ndim != 2 or x.shape[1] != self.emulator.dim or not np.all(np.isfinite(x)):
            raise RailsuspInputError(
                f"sections {x.shape}: accepted finite summaries (k, {self.emulator.dim})"
            )
        return self.project(x.mean(axis=0)), x.shape[0]

    def first_log_likelihood(self, s: np.ndarray, k: int):
        """The first of :meth:`sample`'s two SMC runs' log-likelihood of the reading ``s``
        of ``k`` sections: C_k(u), or C_k held at the box's centre with
        ``first_pass_at_centre``."""
        if self.plug_in_covariance and self.first_pass_at_centre:
            return self.plug_in_log_likelihood(np.full(self.emulator.inputs, 0.5), s, k)
        return lambda u: self.log_likelihood(u, s, k)

    def second_log_likelihood(self, u0: np.ndarray, s: np.ndarray, k: int):
        """The second run's, C_k held at the first run's mean ``u0`` (with
        ``plug_in_covariance``; without, C_k(u) as in the first)."""
        if not self.plug_in_covariance:
            return lambda u: self.log_likelihood(u, s, k)
        return self.plug_in_log_likelihood(u0, s, k)

    def plug_in_log_likelihood(self, u0: np.ndarray, s: np.ndarray, k: int):
        """log N(s; mu(u), C_k(u0)) up to a constant, C_k held at ``u0``: the mean alone
        carries the information (fixed-covariance synthetic likelihood). Why: with C_k(u)
        the term -log|C_k(u)| / 2 pulls a weakly identified parameter towards where the
        emulated covariance is small, and that dependence (a quadratic fit of the log
        section variance, the gain error, E and the model error) is not checked anywhere.
        Measured at the issue's scale at 600 s on the 100 test records: with C_k(u) X15,
        X16, X19, X20 covered 0.73-0.80; with C_k held at the truth 0.80-0.84, held at a
        first posterior's mean (:meth:`sample`) 0.82-0.88."""
        _, cov = self.mean_and_covariance(np.atleast_2d(u0), k)
        d = cov.shape[1]
        cov = cov[0] + 1e-10 * np.trace(cov[0]) / d * np.eye(d)
        chol = np.linalg.cholesky(cov)
        s = np.asarray(s, float)

        def loglik(u: np.ndarray) -> np.ndarray:
            r = np.linalg.solve(chol, (s - self.mean(u)).T)
            return -0.5 * np.sum(r**2, axis=0)

        return loglik


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
