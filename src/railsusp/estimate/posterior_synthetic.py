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
  (:func:`~railsusp.estimate.posterior_synthetic_model_error.fit_scales`), corrects the
  emulator's section scatter by the scatter of the records' own sections;
- S(u) A S(u), S the sections' standard deviations: the emulator's error that the
  bootstrap spread misses (its bias; the spread of 10 networks spans at most 9 of the D
  directions), a full D x D matrix A in the sections' units, estimated per direction on
  the same calibration records (:func:`~railsusp.estimate.posterior_synthetic_model_error.
  fit_model_error`: the records' mean residuals' excess covariance, Ledoit-Wolf shrunk
  towards the isotropic m R). Before stop 24 it was
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
posterior_synthetic_run`), with no widening fitted.

This module holds the likelihood and its sampling; c, m and A are fitted on calibration
records in :mod:`railsusp.estimate.posterior_synthetic_model_error`, and the Fisher
information, Cramer-Rao widths and informative projection that read the likelihood without
drawing from it are :mod:`railsusp.estimate.posterior_synthetic_information`.
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
    # J (N, D, sources) = fixed + the levels' terms: each term factor * w * mean_j adds to
    # one entry (i, s) of J, summed per entry (np.add.reduceat over the terms sorted by
    # entry); a Python loop over the statistics was a tenth of a posterior's time
    fixed = np.zeros((len(names), n_src))
    entry, column, coef = [], [], []
    for i, terms in enumerate(rows):
        for s, factor, scale in terms:
            if not scale:
                fixed[i, s] += factor
            for j, w in scale:
                entry.append(i * n_src + s)
                column.append(j)
                coef.append(factor * w)
    order = np.argsort(np.asarray(entry, dtype=np.int64), kind="stable")
    entries, starts = np.unique(np.asarray(entry, dtype=np.int64)[order], return_index=True)
    columns, coefs = np.asarray(column, dtype=np.int64)[order], np.asarray(coef, float)[order]

    def shared(mean: np.ndarray) -> np.ndarray:
        mean = np.atleast_2d(mean)
        jac = np.repeat(fixed[None], mean.shape[0], axis=0)
        if len(columns):
            levels = np.add.reduceat(mean[:, columns] * coefs, starts, axis=1)
            jac.reshape(mean.shape[0], len(names) * n_src)[:, entries] += levels
        return gain_error**2 * np.matmul(jac, jac.transpose(0, 2, 1))  # J J^T per point

    return shared


@dataclass
class SyntheticLikelihood:
    """The synthetic likelihood of the mean of k sections' statistics (module
    docstring); ``shared``: G(mean), or None when nothing is shared between sections.
    ``within_scale`` (at least 1) multiplies Sigma; ``model_error`` (at least 0) adds
    that fraction of Sigma as the emulator's error its bootstrap spread does not see
    (both fitted on held-out records of several sections,
    :func:`~railsusp.estimate.posterior_synthetic_model_error.fit_scales`; 1 and 0: as the
    emulator says); ``model_error_matrix`` A (D, D), when given, replaces m Sigma by S A S
    (:func:`~railsusp.estimate.posterior_synthetic_model_error.fit_model_error`).
    ``projected``, with a ``projection`` P: an
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
        standard deviations, with the fitted A
        (:func:`~railsusp.estimate.posterior_synthetic_model_error.fit_model_error`); without
        one, the isotropic m Sigma."""
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
