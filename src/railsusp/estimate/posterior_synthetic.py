"""Posterior of a long recording by a Gaussian synthetic likelihood of the MEAN of its
section statistics (Wood 2010, "Statistical inference for noisy nonlinear ecological
dynamic systems"; Price, Drovandi, Lee & Nott 2018, "Bayesian synthetic likelihood").

A recording of k sections gives k summary vectors x_1..x_k (:mod:`railsusp.estimate.
summaries`); their mean s_k is, by the central limit theorem over nearly independent
sections of stationary random track, Gaussian about mu(u) with covariance

    C_k(u) = G(u) + (c Sigma(u) - G(u)) / k + E(u) + m Sigma(u)

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
- c >= 1 and m >= 0, two numbers for every length, fitted once on held-out calibration
  records of the longest checked length (:func:`fit_scales`): c corrects the emulator's
  section scatter by the scatter of the records' own sections, m adds the emulator's
  error that the bootstrap spread misses (its bias, and the directions 10 networks do not
  span), so that the records' means lie as far from mu as C_k says. 1 / m is the number
  of sections the emulator is worth. Measured at the issue's scale: c = 1.12, m = 0.020.

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
    ``names`` (``condition:channel_statistic``, :func:`railsusp.estimate.summaries.
    summary_names`). Percentiles of Y and Q scale with their channel's gain, those of Y/Q
    with the difference of the two, those of the wheelset sum of Y with the mean of its two
    wheels' gains; a log10 band RMS shifts by its channel's gain / ln 10."""
    sources: dict[str, int] = {}
    rows: list[list[tuple[int, float, bool]]] = []  # (source, factor, times the value)

    def src(cond: str, ch: str) -> int:
        return sources.setdefault(f"{cond}:{ch}", len(sources))

    for name in names:
        cond, stat = name.split(":", 1) if ":" in name else ("", name)
        channel, kind = stat.split("_", 1)
        band = kind.startswith("band")
        if channel == "YQ":
            rows.append([(src(cond, "Y"), 1.0, True), (src(cond, "Q"), -1.0, True)])
        elif channel == "sumY":
            rows.append([(src(cond, "Y"), 0.5, True), (src(cond, "partner"), 0.5, True)])
        else:
            rows.append([(src(cond, channel), 1.0 / np.log(10.0) if band else 1.0, not band)])
    n_src = len(sources)

    def shared(mean: np.ndarray) -> np.ndarray:
        mean = np.atleast_2d(mean)
        jac = np.zeros((mean.shape[0], len(names), n_src))
        for i, terms in enumerate(rows):
            for s, factor, scaled in terms:
                jac[:, i, s] += factor * (mean[:, i] if scaled else 1.0)
        return gain_error**2 * np.einsum("nis,njs->nij", jac, jac)

    return shared


@dataclass
class SyntheticLikelihood:
    """The synthetic likelihood of the mean of k sections' statistics (module
    docstring); ``shared``: G(mean), or None when nothing is shared between sections.
    ``within_scale`` (at least 1) multiplies Sigma; ``model_error`` (at least 0) adds
    that fraction of Sigma as the emulator's error its bootstrap spread does not see
    (both fitted on held-out records of several sections, :func:`fit_scales`; 1 and 0:
    as the emulator says)."""

    emulator: StatisticsEmulator
    shared: SharedCovariance | None = None
    emulator_variance: bool = True  # False only to show what leaving E(u) out does
    within_scale: float = 1.0
    model_error: float = 0.0

    def parts(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """At ``u``: mu (N, D), G, Sigma and E (as the emulator says, unscaled)."""
        mean, section, emulator = self.emulator.moments(u)
        shared = self.shared(mean) if self.shared is not None else np.zeros_like(section)
        return mean, shared, section, emulator

    def mean_and_covariance(self, u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """mu(u) (N, D) and C_k(u) (N, D, D) for the mean of ``k`` sections."""
        mean, shared, section, emulator = self.parts(u)
        # G + (c Sigma - G) / k = G (1 - 1/k) + c Sigma / k: PSD for k >= 1 and c >= 1
        cov = shared + (self.within_scale * section - shared) / k
        if self.emulator_variance:
            cov = cov + emulator + self.model_error * section
        return mean, cov

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
        the emulator's inputs) of the sections ``sections`` (k, D), from their mean."""
        x = np.atleast_2d(np.asarray(sections, float))
        if x.ndim != 2 or x.shape[1] != self.emulator.dim or not np.all(np.isfinite(x)):
            raise RailsuspInputError(
                f"sections {x.shape}: accepted finite summaries (k, {self.emulator.dim})"
            )
        s, k = x.mean(axis=0), x.shape[0]
        d = self.emulator.weights[0][0][0].shape[0]
        rng = np.random.default_rng(seed)
        return smc_sample(lambda u: self.log_likelihood(u, s, k), d, n, rng)


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
    x = np.asarray(records, float)
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
