"""One interval type for every estimation route: value, low and high of each parameter.

Every route that estimates the suspension parameters reports, per parameter, a point and an
interval in SI (shown in display units, e.g. ``X14 = 8.3 [7.6-9.1] MN/m``), with its
``level`` and the ``method`` that formed it:

- ``posterior``: the central ``level`` credible interval, quantiles of the simulation-based
  posterior's draws (:mod:`railsusp.estimate.posterior`); the point is the median.
- ``refinement``: the ``level`` confidence interval of the output-error refinement
  (:mod:`railsusp.estimate.refine`, formed in :mod:`railsusp.estimate.refine_intervals`):
  the least-squares covariance with each force channel's own residual variance, inflated by
  its residuals' integrated autocorrelation time (their effective sample size, Thiébaux &
  Zwiers 1984; Geyer 1992 for the truncation), Student-t on the effective degrees of
  freedom; the spread that the track geometry's stated error causes; and, where the
  simulator can tell it, the linear response of the estimate to the main-suspension
  parameters held at nominal, each uniformly unknown over the user's range
  (``[estimate] held_prior``) or its whole Table 2 range. The interval is the central
  ``level`` quantiles of the sum of these parts (JCGM 101:2008 Monte Carlo), or the
  Student-t quantile times the total standard error where nothing is held. Clipped to the
  parameter's range (the prior).
- ``standard-error``: an estimate.json written before intervals were stored: estimate ±
  z·standard error of the refinement (normal quantile), as optimistic as those errors were.
- ``pareto``: the range of NSGA-II's Pareto set: the parameter sets that trade the objectives
  off against each other. It is **not** a confidence interval (``level`` is None): a narrow
  Pareto set can sit far from the truth (on unknown track one did, at 25 % of the range).

:func:`identification` turns an interval into the "identified" verdict: identified only by
a statistical interval (not the Pareto range) no wider than :data:`IDENTIFIED_WIDTH_PCT` of
the parameter's range (docs/intervals.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from railsusp.numbers import sig3
from railsusp.params import ParameterSet, bounds, spec

#: the level of the reported intervals
LEVEL = 0.90
#: a parameter is identified when its interval at :data:`LEVEL` is at most this wide, % of
#: its range (± 10 %: a point estimate 25 % of the range off lies outside such an interval)
IDENTIFIED_WIDTH_PCT = 20.0

POSTERIOR = "posterior"
REFINEMENT = "refinement"
STANDARD_ERROR = "standard-error"
PARETO = "pareto"
#: methods whose intervals hold the truth with a stated probability
STATISTICAL = (POSTERIOR, REFINEMENT, STANDARD_ERROR)
#: what each method's interval is, for tables, reports and estimate.json
DESCRIPTIONS = {
    POSTERIOR: "central {pct} credible interval: quantiles of the simulation-based posterior",
    REFINEMENT: "{pct} confidence interval of the output-error refinement: least-squares "
    "covariance with each channel's residual variance, Student-t on the effective sample size "
    "of the correlated residuals, with the track geometry's stated error (none where the "
    "recordings state none) and the parameters held (at nominal or their held_prior's "
    "centre; quantiles of their sum)",
    STANDARD_ERROR: "{pct} interval from the refinement's standard errors (normal quantile; "
    "an estimate saved before intervals were stored)",
    PARETO: "range of the NSGA-II Pareto set (the trade-off between the objectives): not a "
    "confidence interval",
}


def describe(method: str, level: float | None) -> str:
    """What an interval of ``method`` at ``level`` is, in words."""
    return DESCRIPTIONS[method].format(pct=f"{100 * level:g} %" if level else "")


def _check_level(level: float) -> None:
    from railsusp.errors import RailsuspInputError

    if isinstance(level, bool) or not 0.5 <= level < 1.0:
        raise RailsuspInputError(f"interval level {level}: accepted 0.5 to below 1")


@dataclass(frozen=True)
class ParameterInterval:
    """One parameter's point and interval, SI (``level`` None: not a probability interval)."""

    parameter: str
    value_si: float
    low_si: float
    high_si: float
    level: float | None
    method: str

    @property
    def unit(self) -> str:
        return spec(self.parameter).display_unit

    @property
    def value(self) -> float:
        """The point, display units."""
        return spec(self.parameter).to_display(self.value_si)

    @property
    def low(self) -> float:
        return spec(self.parameter).to_display(self.low_si)

    @property
    def high(self) -> float:
        return spec(self.parameter).to_display(self.high_si)

    @property
    def width_pct_range(self) -> float:
        """Width of the interval, % of the parameter's range."""
        lo, hi = spec(self.parameter).bounds
        return 100.0 * (self.high_si - self.low_si) / (hi - lo)

    @property
    def span_pct_range(self) -> float:
        """Width of the smallest range holding the interval and the point, % of the
        parameter's range: the width where the point lies inside, more where it does not (a
        refinement's interval shifted by the held parameters' prior off nominal)."""
        lo, hi = spec(self.parameter).bounds
        low, high = min(self.low_si, self.value_si), max(self.high_si, self.value_si)
        return 100.0 * (high - low) / (hi - lo)

    @property
    def statistical(self) -> bool:
        """Whether the interval holds the truth with a stated probability."""
        return self.method in STATISTICAL and self.level is not None

    def contains(self, x_si: float) -> bool:
        return self.low_si <= x_si <= self.high_si

    def text(self) -> str:
        """``value [low-high] unit`` with three significant figures."""
        return f"{sig3(self.value)} [{sig3(self.low)}-{sig3(self.high)}] {self.unit}"

    def to_dict(self) -> dict[str, Any]:
        return {
            "value_si": self.value_si,
            "low_si": self.low_si,
            "high_si": self.high_si,
            "value_display": self.value,
            "low_display": self.low,
            "high_display": self.high,
            "unit": self.unit,
            "width_pct_range": self.width_pct_range,
        }


@dataclass(frozen=True)
class Intervals:
    """The intervals of one estimate: one per parameter, one method and level for all, and
    the method's own figures per parameter (``details``, e.g. the error components)."""

    method: str
    level: float | None
    items: tuple[ParameterInterval, ...]
    details: Mapping[str, Any] = field(default_factory=dict)

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(i.parameter for i in self.items)

    @property
    def description(self) -> str:
        return describe(self.method, self.level)

    def __getitem__(self, parameter: str) -> ParameterInterval:
        for item in self.items:
            if item.parameter == parameter:
                return item
        raise KeyError(parameter)

    def __contains__(self, parameter: object) -> bool:
        return parameter in self.parameters

    def to_dict(self) -> dict[str, Any]:
        """The ``intervals`` record of a result JSON (SI and display units)."""
        return {
            "method": self.method,
            "level": self.level,
            "description": self.description,
            "parameters": {i.parameter: i.to_dict() for i in self.items},
            "details": dict(self.details),
        }

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> Intervals:
        """The inverse of :meth:`to_dict` (the SI values are the record)."""
        method, level = str(doc["method"]), doc.get("level")
        level = None if level is None else float(level)
        items = tuple(
            ParameterInterval(
                p, float(v["value_si"]), float(v["low_si"]), float(v["high_si"]), level, method
            )
            for p, v in doc["parameters"].items()
        )
        return cls(method, level, items, dict(doc.get("details") or {}))

    def table(self) -> list[dict[str, Any]]:
        """One row per parameter: value, low, high (display), unit, width and the text."""
        return [
            {
                "parameter": i.parameter,
                "unit": i.unit,
                "value": i.value,
                "low": i.low,
                "high": i.high,
                "width_pct_range": i.width_pct_range,
                "shown": i.text(),
            }
            for i in self.items
        ]


def _clip(parameters: Sequence[str], low: np.ndarray, high: np.ndarray):
    lo, hi = bounds(parameters)
    return np.clip(low, lo, hi), np.clip(high, lo, hi)


def from_samples(
    parameters: Sequence[str], samples_si: np.ndarray, level: float = LEVEL
) -> Intervals:
    """Central ``level`` credible intervals and medians of posterior draws (S, k), SI."""
    _check_level(level)
    s = np.asarray(samples_si, dtype=float)
    q = np.quantile(s, [0.5, (1 - level) / 2, (1 + level) / 2], axis=0)
    items = tuple(
        ParameterInterval(p, float(q[0, j]), float(q[1, j]), float(q[2, j]), level, POSTERIOR)
        for j, p in enumerate(parameters)
    )
    return Intervals(POSTERIOR, level, items)


def from_pareto(parameters: Sequence[str], pareto_x: np.ndarray, chosen_x: np.ndarray) -> Intervals:
    """The Pareto set's range of each parameter around the chosen point (SI)."""
    px = np.atleast_2d(np.asarray(pareto_x, dtype=float))
    chosen = np.asarray(chosen_x, dtype=float)
    low = np.minimum(px.min(axis=0), chosen)
    high = np.maximum(px.max(axis=0), chosen)
    items = tuple(
        ParameterInterval(p, float(chosen[j]), float(low[j]), float(high[j]), None, PARETO)
        for j, p in enumerate(parameters)
    )
    return Intervals(PARETO, None, items)


def from_standard_errors(
    parameters: Sequence[str],
    x_si: np.ndarray,
    se_si: np.ndarray,
    level: float = LEVEL,
    dof: float | None = None,
    method: str = STANDARD_ERROR,
    details: Mapping[str, Any] | None = None,
) -> Intervals:
    """x ± q·se, clipped to the ranges: q the Student-t quantile on ``dof`` degrees of
    freedom (normal when None); an infinite error gives the whole range."""
    from scipy.stats import norm, t

    _check_level(level)
    x = np.asarray(x_si, dtype=float)
    se = np.asarray(se_si, dtype=float)
    p = (1 + level) / 2
    q = float(norm.ppf(p) if dof is None else t.ppf(p, max(dof, 1.0)))
    half = np.where(np.isfinite(se), q * se, np.inf)
    low, high = _clip(parameters, x - half, x + half)
    items = tuple(
        ParameterInterval(par, float(x[j]), float(low[j]), float(high[j]), level, method)
        for j, par in enumerate(parameters)
    )
    return Intervals(method, level, items, dict(details or {}))


def from_error_quantiles(
    parameters: Sequence[str],
    x_si: np.ndarray,
    lower_si: np.ndarray,
    upper_si: np.ndarray,
    level: float = LEVEL,
    method: str = REFINEMENT,
    details: Mapping[str, Any] | None = None,
) -> Intervals:
    """[x - upper, x - lower], clipped to the ranges: the ``level`` interval for the truth
    of an estimate ``x_si`` whose error (estimate less truth) has the (1 - level)/2 and
    (1 + level)/2 quantiles ``lower_si`` and ``upper_si`` (an infinite one: the range's end)."""
    _check_level(level)
    x = np.asarray(x_si, dtype=float)
    low, high = _clip(parameters, x - np.asarray(upper_si), x - np.asarray(lower_si))
    items = tuple(
        ParameterInterval(par, float(x[j]), float(low[j]), float(high[j]), level, method)
        for j, par in enumerate(parameters)
    )
    return Intervals(method, level, items, dict(details or {}))


def intervals_of(doc: Mapping[str, Any], level: float = LEVEL) -> Intervals:
    """The intervals of a result JSON (estimate.json, a posterior result): its stored
    ``intervals``; for an estimate.json saved before they were, the refinement's standard
    errors at ``level`` (normal quantile; such files hold the pooled white-residual ones,
    which :class:`~railsusp.estimate.refine.Refinement` no longer reports) or else the
    Pareto set's range."""
    from railsusp.errors import RailsuspInputError

    kept = doc.get("intervals")
    if kept is not None and not (isinstance(kept, Mapping) and kept):
        # every writer stores a whole record; an empty one read as a file saved before
        # intervals were, its interval formed again from the noise part alone (4 x narrower)
        raise RailsuspInputError(
            f"intervals = {kept!r:.60}: accepted the record the estimate stored (method, "
            "level, parameters): the result file was edited or damaged; estimate again"
        )
    if kept:
        stored = Intervals.from_dict(kept)
        lacking = [p for p in doc.get("parameters", ()) if p not in stored]
        if lacking:
            raise RailsuspInputError(
                f"intervals: none of {', '.join(lacking)}, estimated (parameters "
                f"{', '.join(doc['parameters'])}): the result file was edited or damaged; "
                "estimate again"
            )
        return stored
    params = list(doc["parameters"])
    x = ParameterSet(doc["estimate_display"], units="display")
    x_si = np.array([x[p] for p in params])
    refined = doc.get("refinement") or {}
    se_pct = refined.get("standard_error_pct_range")
    if se_pct and doc.get("estimate_source", "refinement") == "refinement":  # not a polish
        lo, hi = bounds(params)
        se = np.array([float(se_pct.get(p, np.inf)) for p in params]) / 100.0 * (hi - lo)
        geometry = refined.get("geometry_error_pct_range") or {}
        return from_standard_errors(
            params, x_si, se, level, details={"geometry_error_pct_range": geometry}
        )
    pareto = np.asarray(doc.get("pareto_x_si") or [x_si], dtype=float)
    return from_pareto(params, pareto, x_si)


def identification(interval: ParameterInterval, limit_pct: float = IDENTIFIED_WIDTH_PCT) -> str:
    """Why the parameter is not identified by its interval ('' when it is): identified only
    by a statistical interval at most ``limit_pct`` % of its range wide that, with the point
    estimate, spans at most that (a refinement's interval lies beside its point where the
    held parameters' prior is off nominal: a value 25 % of the range from the estimate may
    then lie inside it)."""
    width = interval.width_pct_range
    if not interval.statistical:
        return (
            f"no confidence interval: the NSGA-II Pareto set spans {width:.0f} % of range, "
            "which does not bound the error (refine on measured track, or use the posterior)"
        )
    pct = f"{100 * (interval.level or 0.0):g} %"
    if width >= 100.0 - 1e-9:
        return f"its {pct} interval is the whole range: the recordings do not fix it"
    if width > limit_pct:
        return f"{pct} interval {width:.1f} % of range wide"
    span = interval.span_pct_range
    if span > limit_pct:  # the point outside its interval: judged by both together
        return (
            f"the estimate lies outside its {pct} interval ({width:.1f} % of range wide), "
            f"together {span:.1f} % of range (a value that far from the estimate is not ruled "
            "out)"
        )
    return ""
