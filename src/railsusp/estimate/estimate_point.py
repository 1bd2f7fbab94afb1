"""Which point of one NSGA-II run is the estimate, and how sure it is: the Pareto set and
front, the choice on it, and what the steps after NSGA-II left (the geometry error's shifts or
the expected-forces polish, the simulator's corrections, the refinement); from them the
estimate (SI and display units), its per-parameter intervals and its spreads in % of range.
The intervals (:mod:`railsusp.estimate.intervals`) are the refinement's confidence intervals
when refined, else the Pareto set's range moved as the choice was, labelled as not a
confidence interval.

A module of its own because this is the estimate itself, which each step after NSGA-II
reads and completes; how it is described and kept (the route in words, the study's Table 5
layout, the run directory's ``estimate/`` files) is
:class:`~railsusp.estimate.result.CalibrationResult`, which adds that to
:class:`EstimatePoint` and is what the steps are given.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from railsusp.estimate.config import IDEAL_POINT, SIMULATED, HeldPrior, NSGAConfig
from railsusp.estimate.geometry_bias import less_bias, removable, simex_bias, simex_spread
from railsusp.estimate.intervals import LEVEL, Intervals, from_pareto
from railsusp.estimate.problem import display_values
from railsusp.estimate.refine import Refinement
from railsusp.estimate.refine_intervals import refinement_intervals
from railsusp.estimate.trust_region import StepCheck
from railsusp.params import ParameterSet, bounds
from railsusp.vehicle.revision import this_revision


@dataclass
class EstimatePoint:
    """Pareto set/front, chosen estimate, convergence history and log of one NSGA-II run."""

    parameters: tuple[str, ...]
    pareto_x: np.ndarray  # (n_pareto, k) SI
    pareto_f: np.ndarray  # (n_pareto, n_obj)
    chosen: int
    log: pd.DataFrame
    history: np.ndarray  # (n_gen, k) SI: per generation, the choice rule on its front
    config: NSGAConfig
    seeds_spread: dict[str, float] = field(default_factory=dict)
    #: independent NSGA-II runs behind ``seeds_spread`` (seeds ``config.seed`` on; the
    #: estimate is the first's: :func:`~railsusp.estimate.nsga.estimate_with_seeds`)
    n_seeds: int = 1
    refinement: Refinement | None = None
    #: Cramér-Rao bound of each parameter at NSGA-II's choice, % of range (statistics GPs)
    cramer_rao: dict[str, float] = field(default_factory=dict)
    #: how ``chosen`` was picked on the front (:data:`~railsusp.estimate.config.CHOICE_RULES`)
    choice_rule: str = IDEAL_POINT
    #: the refinement is a polish shown beside NSGA-II's estimate, which stays the estimate
    #: (time-aligned objectives: the surrogate on the recordings' track gives the answer),
    #: rather than the estimate itself (record statistics, which it corrects)
    refinement_is_polish: bool = False
    #: the user's ranges of the parameters the refinement holds, for its intervals (None:
    #: each held one over its whole Table 2 range)
    held_prior: HeldPrior | None = None
    #: the parameters not estimated that the estimate's simulations held off nominal, SI:
    #: at the centre of the user's ``held_prior`` range (the validation holds them there too)
    held_at_si: dict[str, float] = field(default_factory=dict)
    #: (draws, k) shift of NSGA-II's choice, SI, that each draw of the recordings' stated
    #: geometry error causes, with the model NSGA-II ran on (time-aligned forces only;
    #: :func:`~railsusp.estimate.nsga_geometry.remove_nsga_geometry_bias`); empty if none
    geometry_shifts_si: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    #: whether NSGA-II's estimate is its choice less the mean of those shifts (first SIMEX
    #: step; its Pareto range, the interval, moves with it; ``pareto_x`` stays NSGA-II's)
    geometry_bias_removed: bool = False
    #: the force model's own time-aligned least squares on its expected forces (mean over
    #: ``config.expected_draws`` draws of the true geometry given the measured one), from
    #: NSGA-II's choice: NSGA-II's estimate where present (in the SIMEX step's place;
    #: :func:`~railsusp.estimate.nsga_geometry.polish_on_expected_forces`), its Pareto
    #: range moved with it
    expected_polish: Refinement | None = None
    #: the simulator's corrections of the surrogate's level error at NSGA-II's estimate, each
    #: the surrogate's least squares again with it (output space mapping,
    #: :func:`~railsusp.estimate.level_correction.correct_by_simulator`); the last one's
    #: point is the estimate where present (:attr:`corrected_x`)
    corrections: list[Refinement] = field(default_factory=list)
    #: why the corrections stopped before the steps asked (a simulation of the estimate
    #: that derailed or diverged); empty if they did not
    corrections_stopped: str = ""
    #: whether each correction matched the simulator's slopes too (first order, in a trust
    #: region; :func:`~railsusp.estimate.level_correction.correct_by_simulator`)
    correction_slopes: bool = False
    #: the simulator's check of the point each first-order correction proposed (kept or
    #: rejected, and the trust box; :mod:`~railsusp.estimate.trust_region`), one per step of
    #: :attr:`corrections`; empty for zeroth-order corrections
    correction_checks: list[StepCheck] = field(default_factory=list)
    #: how the first-order corrections got the slopes at each later point: simulated again,
    #: or Broyden's update (:data:`~railsusp.estimate.config.SLOPE_UPDATES`)
    correction_slope_update: str = SIMULATED
    #: each recording's channel gain at the estimate (NSGA-II's choice, or the last of the
    #: expected-forces polish and the simulator corrections, which estimate them again), by
    #: "<condition>:<Y|Q>_<wheel>",
    #: where the time-aligned comparison profiled them out (``config.channel_gains``)
    channel_gains: dict[str, float] = field(default_factory=dict)
    #: the force laws' revision (:data:`railsusp.vehicle.MODEL_REVISION`) the estimate was
    #: made with, recorded in ``estimate.json`` for validate, which re-simulates it with its
    #: own force laws and refuses an estimate of others. This railsusp's: every force model
    #: an estimate runs on is refused when it records another (the surrogates' bundles, a
    #: network set's manifest), and the simulator corrections and refinement are its own
    model_revision: str = field(default_factory=this_revision)
    #: intervals computed, by level and refinement (a refinement attached later recomputes)
    _intervals: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def refined(self) -> bool:
        """Whether the refinement made the estimate (not when it is a polish beside it)."""
        return self.refinement is not None and not self.refinement_is_polish

    @property
    def chosen_x(self) -> np.ndarray:
        """The estimate, SI: the refined one when the refinement makes the estimate, else
        NSGA-II's corrected by the simulator (:attr:`corrected_x`) where it was, else
        NSGA-II's (:attr:`nsga_x`; also when the refinement is a polish: :attr:`polished_x`)."""
        if self.refinement is not None and self.refined:
            return self.refinement.estimate_si
        if self.corrections:
            return self.corrected_x
        return self.nsga_x

    @property
    def corrected_x(self) -> np.ndarray:
        """NSGA-II's estimate after the simulator's corrections of the surrogate's level
        error, SI (:attr:`nsga_x` where none was made)."""
        return self.corrections[-1].estimate_si if self.corrections else self.nsga_x

    @property
    def nsga_x(self) -> np.ndarray:
        """NSGA-II's estimate, SI: its choice on the front, polished on expected forces
        (:attr:`expected_polish`) or less the geometry error's bias where that is removed
        (:attr:`geometry_bias_removed`)."""
        if self.expected_polish is not None:
            return self.expected_polish.x_si
        return self._geometry_moved(self.pareto_x[self.chosen])

    def _moved(self, x_si: np.ndarray) -> np.ndarray:
        """``x_si`` (one set or rows of them) moved as NSGA-II's choice is to the estimate
        it makes (:meth:`_geometry_moved`, then by the simulator corrections' step); within
        the ranges."""
        moved = self._geometry_moved(x_si)
        if not self.corrections:
            return moved
        lo, hi = bounds(self.parameters)
        return np.clip(moved + (self.corrected_x - self.nsga_x), lo, hi)

    def _geometry_moved(self, x_si: np.ndarray) -> np.ndarray:
        """``x_si`` (one set or rows of them) moved as NSGA-II's choice is to its estimate:
        by the expected-forces polish's step, or less the geometry bias if removed; within
        the ranges."""
        if self.expected_polish is not None:
            # clipped: points moved past a bound sit on it, and the range narrows there
            lo, hi = bounds(self.parameters)
            step = self.expected_polish.x_si - self.expected_polish.start_si
            return np.clip(np.asarray(x_si, float) + step, lo, hi)
        if not self.geometry_bias_removed:
            return x_si
        return less_bias(self.parameters, x_si, self.geometry_shifts_si)

    @property
    def polished_x(self) -> np.ndarray | None:
        """The simulator polish of NSGA-II's estimate, SI, when the refinement is one."""
        if self.refinement is None or self.refined:
            return None
        return self.refinement.estimate_si

    @property
    def estimate(self) -> dict[str, float]:
        """The estimate, display units."""
        return display_values(self.parameters, self.chosen_x)

    def intervals(self, level: float = LEVEL) -> Intervals:
        """Per-parameter intervals of the estimate: the refinement's ``level`` confidence
        intervals when refined (computed once; with the simulator this includes one batch of
        simulations for the parameters held at nominal), else the Pareto set's range."""
        key = (
            level,
            id(self.refinement),
            self.refinement_is_polish,
            id(self.held_prior),
            self.geometry_bias_removed,
            id(self.geometry_shifts_si),
            id(self.expected_polish),
            tuple(id(c) for c in self.corrections),
        )
        if key not in self._intervals:
            if self.refinement is not None and self.refined:
                self._intervals[key] = refinement_intervals(
                    self.refinement, level, prior=self.held_prior
                )
            else:
                got = from_pareto(self.parameters, self._moved(self.pareto_x), self.chosen_x)
                if self.cramer_rao:
                    got = Intervals(
                        got.method, got.level, got.items, {"cramer_rao_pct_range": self.cramer_rao}
                    )
                self._intervals[key] = got
        return self._intervals[key]

    def pareto_spread(self) -> dict[str, float]:
        """Spread (max - min) of each parameter over the Pareto set, in % of its range."""
        return self._pct_range(self.pareto_x.max(axis=0) - self.pareto_x.min(axis=0))

    def nsga_geometry_pct_range(self) -> dict[str, dict[str, float]]:
        """NSGA-II's geometry error in % of each range: ``bias`` (the mean shift, removed or
        not) and ``scatter`` (the RMS shift); empty without draws."""
        if self.geometry_shifts_si.size == 0:
            return {}
        k = len(self.parameters)
        return {
            "bias": self._pct_range(simex_bias(self.geometry_shifts_si, k)),
            "scatter": self._pct_range(simex_spread(self.geometry_shifts_si, k)),
        }

    def bias_kept(self) -> list[str]:
        """The parameters whose geometry bias is not taken off although it is removed: their
        draws move them by more than half their range
        (:func:`~railsusp.estimate.geometry_bias.removable`)."""
        if not self.geometry_bias_removed:
            return []
        able = removable(self.parameters, self.geometry_shifts_si)
        return [p for p, a in zip(self.parameters, able, strict=True) if not a]

    def _pct_range(self, values_si: np.ndarray) -> dict[str, float]:
        """Per parameter, ``values_si`` in % of its range."""
        lo, hi = bounds(self.parameters)
        return {
            p: float(100 * v / (h - low))
            for p, v, low, h in zip(self.parameters, values_si, lo, hi, strict=True)
        }

    def estimate_set(self, base: ParameterSet | None = None) -> ParameterSet:
        """The chosen estimate as a full ParameterSet (others from ``base`` or nominal)."""
        base = base or ParameterSet.nominal()
        return base.replace(dict(zip(self.parameters, self.chosen_x, strict=True)))
