"""Checks that a posterior is honest: simulation-based calibration and expected coverage.

For held-out cases whose true parameters were drawn from the prior, a calibrated posterior
(Talts et al. 2018, "Validating Bayesian inference algorithms with simulation-based
calibration") puts the truth at a uniformly distributed rank among its samples, and its
central 90 % interval holds the truth in 90 % of cases. Two checks per parameter:

- **coverage**: the fraction of cases whose truth lies in the central interval; failed
  when it is below the nominal level beyond what chance explains (one-sided binomial test
  at ``alpha``), i.e. when the intervals are too narrow (over-confident). A too wide
  interval is reported (``coverage`` above nominal) but not failed: it is honest, if
  wasteful.
- **rank uniformity** (SBC): a chi-square test of the ranks in ``bins`` equal bins; a
  biased or over-confident posterior piles ranks at the ends or to one side, a too wide
  one in the middle. Reported (``sbc_p``), not a pass/fail criterion: with a few hundred
  cases it is the weaker test of the two, and a low value asks for the rank histogram.

Pure numpy/scipy: any sampler's output can be checked, which the tests use with a
conjugate Gaussian problem whose posterior is known.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.stats import binom, chi2

#: the credible level of the reported intervals
LEVEL = 0.90


@dataclass(frozen=True)
class ParameterCalibration:
    """Calibration of one parameter's posterior over ``n`` held-out cases."""

    parameter: str
    n: int
    coverage: float  # fraction of truths inside the central LEVEL interval
    coverage_p: float  # one-sided binomial p-value of a coverage this low at LEVEL
    sbc_p: float  # chi-square p-value of rank uniformity
    passed: bool  # coverage not significantly below the nominal level

    def to_dict(self) -> dict:
        return asdict(self)


def ranks(samples: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """SBC rank of each truth among its posterior samples: ``samples`` (cases, S, d),
    ``truth`` (cases, d) -> (cases, d) integers 0..S (number of samples below the truth)."""
    samples = np.asarray(samples, dtype=float)
    truth = np.asarray(truth, dtype=float)
    return np.sum(samples < truth[:, None, :], axis=1)


def covered(samples: np.ndarray, truth: np.ndarray, level: float = LEVEL) -> np.ndarray:
    """(cases, d) booleans: truth inside the central ``level`` interval of the samples."""
    q = np.quantile(np.asarray(samples, float), [(1 - level) / 2, (1 + level) / 2], axis=1)
    return (truth >= q[0]) & (truth <= q[1])


def check(
    samples: np.ndarray,
    truth: np.ndarray,
    names: list[str],
    *,
    level: float = LEVEL,
    alpha: float = 0.01,
    bins: int = 10,
) -> list[ParameterCalibration]:
    """Coverage and SBC rank check of every parameter (see the module docstring)."""
    samples = np.asarray(samples, float)
    truth = np.asarray(truth, float)
    if samples.ndim != 3 or truth.shape != (samples.shape[0], samples.shape[2]):
        raise ValueError(f"samples {samples.shape} and truth {truth.shape}: need (n, S, d), (n, d)")
    n, s, d = samples.shape
    if len(names) != d:
        raise ValueError(f"{len(names)} names for {d} parameters")
    inside = covered(samples, truth, level)
    r = ranks(samples, truth)
    bins = max(2, min(bins, n // 5, s + 1))  # at least about 5 cases per bin expected
    out = []
    for j, name in enumerate(names):
        k = int(inside[:, j].sum())
        p_cov = float(binom.cdf(k, n, level))  # P(K <= k) at the nominal level
        counts = np.bincount(np.minimum(r[:, j] * bins // (s + 1), bins - 1), minlength=bins)
        expected = n / bins
        stat = float(np.sum((counts - expected) ** 2 / expected))
        p_sbc = float(chi2.sf(stat, bins - 1))
        out.append(ParameterCalibration(name, n, k / n, p_cov, p_sbc, p_cov >= alpha))
    return out
