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

**Correction** (:class:`SpreadCorrection`): an over-confident estimator's draws are
widened per parameter about their median by a factor fitted on a *calibration* set of
held-out cases, separate from the cases that then check it. The factor is split conformal
(Vovk et al. 2005; Angelopoulos & Bates 2023, "A gentle introduction to conformal
prediction"): each calibration case's score is the smallest widening that puts its truth
inside the central interval, and the factor is the ceil((n + 1) level)-th smallest score,
so that on new cases drawn like the calibration ones the widened interval holds the truth
with probability at least ``level`` (and at most level + 1/(n + 1) for continuous
scores). It is never below 1: an interval wider than needed is honest and left as it is.
A factor above :data:`MAX_INFLATION` says the estimator's shape is wrong, not just its
spread, and the correction flags it (``excessive``) instead of hiding it.

Pure numpy/scipy: any sampler's output can be checked and corrected, which the tests do
with a conjugate Gaussian problem whose posterior is known. The widening acts on
unbounded coordinates; the caller maps bounded parameters there first (the posterior
uses the logit of the fraction of range).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.stats import binom, chi2

#: the credible level of the reported intervals
LEVEL = 0.90
#: a spread correction wider than this many times the estimator's own spread is flagged
MAX_INFLATION = 2.0


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


#: relative tolerance of an interval's ends in :func:`covered` (of the larger of the ends'
#: magnitudes and the interval's width): rounding only
END_TOLERANCE = 1e-9


def covered(samples: np.ndarray, truth: np.ndarray, level: float = LEVEL) -> np.ndarray:
    """(cases, d) booleans: truth inside the central ``level`` interval of the samples, its
    ends included to within rounding (:data:`END_TOLERANCE`). The spread correction puts
    the truth of the calibration case that defines its factor on the widened interval's
    end (:class:`SpreadCorrection`); computed again from the widened draws, that end
    differed from the truth in the last digits, and the case was counted outside about
    half the time (the calibration set's coverage after the correction one case short of
    what the factor holds)."""
    q = np.quantile(np.asarray(samples, float), [(1 - level) / 2, (1 + level) / 2], axis=1)
    tol = END_TOLERANCE * np.maximum(np.maximum(np.abs(q[0]), np.abs(q[1])), q[1] - q[0])
    return (truth >= q[0] - tol) & (truth <= q[1] + tol)


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


def inflation_scores(samples: np.ndarray, truth: np.ndarray, level: float = LEVEL) -> np.ndarray:
    """(cases, d) smallest factor by which each case's draws, widened about their median,
    put the truth inside their central ``level`` interval (0 for a truth at the median)."""
    samples = np.asarray(samples, float)
    truth = np.asarray(truth, float)
    lo, med, hi = np.quantile(samples, [(1 - level) / 2, 0.5, (1 + level) / 2], axis=1)
    tiny = 1e-12
    above = (truth - med) / np.maximum(hi - med, tiny)
    below = (med - truth) / np.maximum(med - lo, tiny)
    return np.where(truth >= med, above, below)


def widen(samples: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """Draws (cases, S, d) or (S, d) widened per parameter by ``factors`` (d,) about each
    case's median: its central intervals scale by the factor, its median stays."""
    samples = np.asarray(samples, float)
    med = np.median(samples, axis=-2, keepdims=True)
    return med + np.asarray(factors, float) * (samples - med)


@dataclass(frozen=True)
class SpreadCorrection:
    """Per-parameter widening factors fitted by split conformal on ``n`` calibration
    cases (module docstring)."""

    parameters: tuple[str, ...]
    factors: tuple[float, ...]
    n: int
    level: float = LEVEL
    max_inflation: float = MAX_INFLATION
    method: str = "split-conformal spread inflation about the median"
    raw_factors: tuple[float, ...] = field(default=())  # before the floor at 1

    def __post_init__(self) -> None:
        if len(self.factors) != len(self.parameters):
            raise ValueError(f"{len(self.factors)} factors for {len(self.parameters)} parameters")
        if not self.raw_factors:  # given directly: the factors are the raw ones
            object.__setattr__(self, "raw_factors", tuple(self.factors))

    @classmethod
    def fit(
        cls,
        samples: np.ndarray,
        truth: np.ndarray,
        names: list[str],
        *,
        level: float = LEVEL,
        max_inflation: float = MAX_INFLATION,
    ) -> SpreadCorrection:
        """Factors from calibration cases: draws (n, S, d) and truths (n, d)."""
        scores = inflation_scores(samples, truth, level)
        n, d = scores.shape
        if len(names) != d:
            raise ValueError(f"{len(names)} names for {d} parameters")
        k = int(np.ceil((n + 1) * level - 1e-9))
        if k > n:
            raise ValueError(
                f"{n} calibration cases: at least {int(np.ceil(level / (1 - level) - 1e-9))} are "
                f"needed for a {level:.0%} conformal factor"
            )
        raw = np.sort(scores, axis=0)[k - 1]
        return cls(
            tuple(names),
            tuple(float(max(1.0, r)) for r in raw),
            n,
            level,
            max_inflation,
            raw_factors=tuple(float(r) for r in raw),
        )

    def apply(self, samples: np.ndarray) -> np.ndarray:
        """The draws widened by the factors (:func:`widen`)."""
        return widen(samples, np.array(self.factors))

    @property
    def excessive(self) -> list[str]:
        """Parameters whose factor exceeds ``max_inflation``."""
        return [p for p, f in zip(self.parameters, self.factors, strict=True)
                if f > self.max_inflation]  # fmt: skip

    def to_dict(self) -> dict:
        d = asdict(self)
        d["parameters"] = list(self.parameters)
        d["factors"] = dict(zip(self.parameters, self.factors, strict=True))
        d["raw_factors"] = dict(zip(self.parameters, self.raw_factors, strict=True))
        d["excessive"] = self.excessive
        return d

    @classmethod
    def from_dict(cls, d: dict) -> SpreadCorrection:
        names = tuple(d["parameters"])
        return cls(
            names,
            tuple(float(d["factors"][p]) for p in names),
            int(d["n"]),
            float(d["level"]),
            float(d["max_inflation"]),
            d["method"],
            tuple(float(d["raw_factors"][p]) for p in names),
        )
