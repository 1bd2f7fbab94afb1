"""What an estimator learnt from: the range and standard deviation of each summary statistic
over its training cases (:class:`TrainingSupport`), and the warning that a recording's
statistics lie outside that range, where the posterior extrapolates and is reported NOT
calibrated (docs/posterior.md, "The result").

Why a module of its own: the comparison works on the statistics alone, for every kind of
estimator and for a joint of several; reading the cached training cases for it is
:func:`railsusp.estimate.posterior_data.training_support`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from railsusp.errors import first_listed

#: a recording's statistic is outside what the estimator learnt from where the mean of its
#: sections lies beyond the range of the training cases by more than this many of their
#: standard deviations (docs/posterior.md, "The result"). Measured: the statistics of
#: recordings of the trained conditions lay within 0.2 standard deviations beyond that range
#: (inside it for most); a recording low-passed at 4 Hz 24 beyond, a curve recorded from its
#: entry spiral 9 beyond
OUTSIDE_MARGIN_SD = 1.0
#: fewer training cases than this, and the statistics are not compared with their range:
#: its extremes are too close in (measured on the 34 EN 14363 statistics of stop 63's
#: estimator, held-out simulations, each section compared: 20 cases flagged 30 % of
#: one-section simulations and 73 % of six-section ones, 100 cases 1.5 % and 7.5 %, 2000
#: cases 0.03 % per section, so 11 % of a 2 h recording's 360 sections; the review of stop
#: 65). The sections' mean is compared, which lies inside whatever its sections do
MIN_SUPPORT_CASES = 100


@dataclass(frozen=True)
class TrainingSupport:
    """The range (``low``, ``high``) and standard deviation ``sd`` of each statistic
    (``names``) over an estimator's ``n`` training cases (those with every statistic
    defined), against which a recording's sections are compared (:meth:`outside`)."""

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    sd: np.ndarray
    n: int

    @classmethod
    def of(cls, names, x: np.ndarray) -> TrainingSupport | None:
        """The support of the training cases ``x`` (n, D); None without two usable cases."""
        x = np.asarray(x, float)
        x = x[np.all(np.isfinite(x), axis=1)]
        if len(x) < 2 or x.shape[1] != len(names):
            return None
        return cls(tuple(names), x.min(axis=0), x.max(axis=0), x.std(axis=0), len(x))

    @classmethod
    def joined(cls, parts) -> TrainingSupport | None:
        """The supports of estimators whose statistics stand one after the other (a joint
        posterior's parts; as many cases as the smallest); None where any part has none."""
        if any(p is None for p in parts):
            return None
        return cls(
            tuple(n for p in parts for n in p.names),
            *(np.concatenate([getattr(p, k) for p in parts]) for k in ("low", "high", "sd")),
            min(p.n for p in parts),
        )

    def outside(self, x: np.ndarray) -> list[str]:
        """The statistics whose mean over the sections ``x`` (k, D) lies beyond the
        training range by more than :data:`OUTSIDE_MARGIN_SD` of their standard deviation
        (each section compared, a long recording's many sections flagged in-distribution
        ones: :data:`MIN_SUPPORT_CASES`)."""
        mean = np.atleast_2d(np.asarray(x, float)).mean(axis=0)
        margin = OUTSIDE_MARGIN_SD * self.sd
        beyond = (mean < self.low - margin) | (mean > self.high + margin)
        return [n for n, b in zip(self.names, beyond, strict=True) if b]


def support_notes(support: TrainingSupport | None, x: np.ndarray) -> tuple[list[str], list[str]]:
    """(the statistics of the sections ``x`` outside the training cases' ``support``, the
    warning that says so); a warning that nothing was compared where there is no support."""
    if support is None:
        return [], [
            "the recording's statistics were not compared with the range of the "
            "estimator's training cases (not at hand: its folder holds no cached training "
            "cases): whether they lie inside what it learnt from is unknown"
        ]
    if support.n < MIN_SUPPORT_CASES:
        return [], [
            f"the recording's statistics were not compared with the range of the "
            f"estimator's {support.n} training cases (fewer than {MIN_SUPPORT_CASES}: their "
            "extremes flag recordings like them): whether they lie inside what it learnt "
            "from is unknown"
        ]
    outside = support.outside(x)
    if not outside:
        return [], []
    shown = first_listed(outside, 4)
    return outside, [
        f"the recording's statistics {shown} lie outside the range of the estimator's "
        f"training cases (their mean over the sections, by more than {OUTSIDE_MARGIN_SD:g} "
        "of their standard deviation): "
        "the posterior extrapolates beyond what it learnt and is NOT calibrated; check the "
        "recording's condition and instrument against the trained ones"
    ]
