"""The estimate: Pareto set and front, chosen point, convergence, refinement, intervals; save
and table.

:class:`CalibrationResult` is what :func:`railsusp.estimate.estimate` returns and what the
refinement (:func:`railsusp.estimate.refine_estimate`) completes; it writes the run
directory's ``estimate/`` files (``nsga_log.*``, ``estimate.csv``, ``estimate.json``, the
Pareto and convergence figures), each atomically. Its per-parameter intervals
(:mod:`railsusp.estimate.intervals`) are the refinement's confidence intervals when refined,
else the Pareto set's range, labelled as not a confidence interval.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.estimate.config import (
    BROYDEN,
    CHOICE_RULES,
    IDEAL_POINT,
    SIMULATED,
    SLOPE_STEP,
    TRUST_BOX,
    HeldPrior,
    NSGAConfig,
)
from railsusp.estimate.geometry_bias import less_bias, removable, simex_bias, simex_spread
from railsusp.estimate.intervals import LEVEL, PARETO, Intervals, from_pareto
from railsusp.estimate.problem import display_values
from railsusp.estimate.refine import SIMULATOR_TEXT, Refinement
from railsusp.estimate.refine_intervals import refinement_intervals
from railsusp.estimate.statistics import ALIGNED, parse_statistics
from railsusp.estimate.trust_region import StepCheck
from railsusp.params import ParameterSet, bounds, spec
from railsusp.store import atomic_write_bytes, write_json, write_parquet
from railsusp.vehicle import MODEL_REVISION


@dataclass
class CalibrationResult:
    """Pareto set/front, chosen estimate, convergence history and log of one NSGA-II run."""

    parameters: tuple[str, ...]
    pareto_x: np.ndarray  # (n_pareto, k) SI
    pareto_f: np.ndarray  # (n_pareto, n_obj)
    chosen: int
    log: pd.DataFrame
    history: np.ndarray  # (n_gen, k) SI: per generation, the choice rule on its front
    config: NSGAConfig
    seeds_spread: dict[str, float] = field(default_factory=dict)
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
    model_revision: str = MODEL_REVISION
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
    def route(self) -> str:
        """How the estimate was made, in words (estimate.json, reports)."""
        aligned = ALIGNED in parse_statistics(self.config.statistic)
        on = "time-aligned forces on measured track" if aligned else "record statistics"
        text = f"NSGA-II against {on} ({self.config.statistic})"
        if self.config.channel_gains:
            text += ", each force channel's gain profiled out"
        if self.config.preview_generations:
            text += (
                f", its first {self.config.preview_generations} of {self.config.n_gen} "
                f"generations on each record's first {self.config.preview_s:g} s"
            )
        if self.config.expected_generations:
            text += (
                f", predicted as the mean over {self.config.expected_draws} draws of the true "
                "track geometry given the measured one where its accuracy is stated"
            )
        if self.expected_polish is not None:
            text += (
                ", then polished by the same model's time-aligned least squares on its mean "
                f"over {self.config.expected_draws} draws of the true track geometry given the "
                "measured one (expected forces)"
            )
        if self.geometry_bias_removed:
            text += ", less the track geometry error's bias (first SIMEX step)"
        if self.corrections:
            n = len(self.corrections)
            if self.correction_slopes:
                text += (
                    f", then corrected by {n} first-order correction{'s' if n > 1 else ''}"
                    " (the simulator's forces and their slopes at the estimate added to the "
                    "surrogate's, its least squares repeated within a trust region: output "
                    "space mapping)"
                )
                if self.correction_slope_update == BROYDEN and n > 1:
                    text += ", the slopes after the first point by Broyden's update"
                rejected = sum(c.accepted is False for c in self.correction_checks)
                if rejected:
                    text += (
                        f", {rejected} proposed point{'s' if rejected > 1 else ''} rejected "
                        "by the simulator's check (its cost there, or a stopped simulation)"
                    )
            else:
                text += (
                    f", then corrected for the surrogate's level error by {n} simulation"
                    f"{'s' if n > 1 else ''} of the estimate, its least squares repeated with "
                    "each (output space mapping)"
                )
        if self.refinement is None:
            return text
        ref = self.refinement
        drawn = ref.expected_draws
        on = f" on its mean over {drawn} draws of the true track geometry" if drawn else ""
        model = ref.compared_model or "an unnamed force model"  # the model it compared
        if self.refinement_is_polish:
            what = (
                "the simulator's output-error refinement"
                if model == SIMULATOR_TEXT
                else f"the output-error refinement with {model}"
            )
            return text + f"; {what}{on} is a polish beside it"
        start = "" if ref.from_choice else f" from {ref.start_origin}"
        return text + f", then refined by output-error least squares with {model}{on}{start}"

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

    def table(self) -> pd.DataFrame:
        """The study's Table 5 layout: initial (nominal) and estimated value, display units,
        with the Pareto and seed spreads."""
        ps = self.pareto_spread()
        iv = self.intervals()
        shown = "Pareto range" if iv.method == PARETO else f"{100 * (iv.level or 0):g} % interval"
        nsga = display_values(self.parameters, self.nsga_x)
        refined = self.refinement.to_dict() if self.refinement else {}
        geometry = self.nsga_geometry_pct_range()
        rows = []
        for k, (p, v) in enumerate(self.estimate.items()):
            row = {
                "parameter": p,
                "unit": spec(p).display_unit,
                "initial": spec(p).nominal_display,
                "estimated": v,
                f"estimate [{shown}]": iv[p].text(),
                "pareto_spread_pct_range": ps[p],
            }
            if self.seeds_spread:  # one seed has no spread to show (it read 0)
                row["seed_spread_pct_range"] = self.seeds_spread[p]
            if self.refinement and self.refinement_is_polish:
                row["polished"] = spec(p).to_display(self.refinement.estimate_si[k])
                row["polish_standard_error_pct_range"] = refined["standard_error_pct_range"][p]
            elif self.refinement:
                row["nsga_estimate"] = nsga[p]
                # the interval's standard error (with the held parameters' part, where the
                # intervals take one), as the API's ``standard_error``; the refinement's own
                # (noise and geometry) beside it
                total = iv.details.get("total_standard_error_pct_range", {})
                own = refined["standard_error_pct_range"][p]
                row["standard_error_pct_range"] = total.get(p, own)
                if p in total:
                    row["refinement_standard_error_pct_range"] = own
                if refined["geometry_draws"]:
                    row["geometry_error_pct_range"] = refined["geometry_error_pct_range"][p]
            if self.corrections and not self.refined:
                row["nsga_estimate"] = nsga[p]
            if (geometry or self.expected_polish is not None) and not self.refined:
                row["nsga_choice"] = spec(p).to_display(self.pareto_x[self.chosen][k])
            if geometry and not self.refined:
                row["geometry_bias_pct_range"] = geometry["bias"][p]
                row["geometry_scatter_pct_range"] = geometry["scatter"][p]
            if self.cramer_rao:
                row["cramer_rao_pct_range"] = self.cramer_rao[p]
            rows.append(row)
        return pd.DataFrame(rows)

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

    def save(self, out: str | Path, extra: dict | None = None) -> Path:
        """Write the log, the Table 5 layout, the JSON record (with ``extra`` provenance such
        as the recordings folder) and the Pareto and convergence figures."""
        out = Path(out)
        write_parquet(out / "nsga_log.parquet", self.log)
        atomic_write_bytes(out / "nsga_log.csv", self.log.to_csv(index=False).encode())
        atomic_write_bytes(out / "estimate.csv", self.table().to_csv(index=False).encode())
        write_json(
            out / "estimate.json",
            {
                "parameters": list(self.parameters),
                "estimate_display": self.estimate,
                "pareto_x_si": self.pareto_x,
                "pareto_f": self.pareto_f,
                "chosen": self.chosen,
                "history_si": self.history,
                "config": self.config.to_dict(),
                "pareto_spread_pct_range": self.pareto_spread(),
                "seed_spread_pct_range": self.seeds_spread,
                "choice_rule": CHOICE_RULES[self.choice_rule]
                + (", then refined by output-error least squares" if self.refined else ""),
                "choice": self.choice_rule,
                "route": self.route,
                "estimate_source": "refinement"
                if self.refined
                else "nsga-ii, simulator-corrected"
                if self.corrections
                else "nsga-ii",
                "polished_display": None
                if self.polished_x is None
                else display_values(self.parameters, self.polished_x),
                "nsga_estimate_display": display_values(self.parameters, self.nsga_x),
                "nsga_choice_display": display_values(self.parameters, self.pareto_x[self.chosen]),
                "nsga_geometry": {
                    "draws": int(self.geometry_shifts_si.shape[0]),
                    "bias_removed": self.geometry_bias_removed,
                    "bias_kept": self.bias_kept(),
                    **{f"{n}_pct_range": v for n, v in self.nsga_geometry_pct_range().items()},
                },
                "channel_gains": self.channel_gains,
                "expected_polish": self._expected_polish_record(),
                "simulator_corrections": [
                    self._correction_record(i, c) for i, c in enumerate(self.corrections)
                ],
                "simulator_corrections_stopped": self.corrections_stopped,
                "correction_slopes": (
                    {
                        "step_of_range": SLOPE_STEP,
                        "trust_box_of_range": TRUST_BOX,
                        "slope_update": self.correction_slope_update,
                    }
                    if self.correction_slopes
                    else None
                ),
                "refinement": self.refinement.to_dict() if self.refinement else None,
                "cramer_rao_pct_range": self.cramer_rao,
                "intervals": self.intervals().to_dict(),
                "model_revision": self.model_revision,
                **(extra or {}),
            },
        )
        from railsusp.report import plot_convergence, plot_pareto

        plot_pareto(self, out / "pareto.png")
        plot_convergence(self, out / "convergence.png")
        return out

    def _expected_polish_record(self) -> dict | None:
        """estimate.json's account of the expected-forces polish (None without one)."""
        pol = self.expected_polish
        if pol is None:
            return None
        return {
            "method": "the force model's own time-aligned least squares (scipy least_squares, "
            "trust-region reflective) on its mean over draws of the true track geometry "
            "given the measured one, from NSGA-II's choice",
            "draws": self.config.expected_draws,
            "start_display": display_values(self.parameters, pol.start_si),
            "polished_display": display_values(self.parameters, pol.x_si),
            "step_pct_range": self._pct_range(pol.x_si - pol.start_si),
            "cost_start": pol.cost_start,
            "cost": pol.cost,
            "n_evaluations": pol.n_evaluations,
            "n_jacobians": pol.n_jacobians,
            "message": pol.message,
            "channel_gains": pol.channel_gains,
        }

    def _correction_record(self, i: int, step: Refinement) -> dict:
        """estimate.json's account of simulator correction step ``i``: with slopes, its
        trust box and the simulator's check of the point it proposed (``check``: its
        costs, ratio, whether kept; None without slopes)."""
        check = self.correction_checks[i] if i < len(self.correction_checks) else None
        return {
            "method": (
                "the surrogate plus its level error and its slopes' error at the start "
                "(simulator minus surrogate there, per recording; "
                + (
                    "the slopes simulated at the first start, carried by Broyden's update after"
                    if self.correction_slope_update == BROYDEN
                    else "the slopes simulated at each start"
                )
                + "), its time-aligned least squares from there within a trust region"
                if self.correction_slopes
                else "the surrogate plus its level error at the start (simulator minus "
                "surrogate there, per recording), its time-aligned least squares from there"
            ),
            "expected_draws": step.expected_draws,
            "start_display": display_values(self.parameters, step.start_si),
            "corrected_display": display_values(self.parameters, step.estimate_si),
            "geometry_bias_removed": step.geometry_bias_removed,
            "step_pct_range": self._pct_range(step.estimate_si - step.start_si),
            "cost_start": step.cost_start,
            "cost": step.cost,
            "n_evaluations": step.n_evaluations,
            "n_jacobians": step.n_jacobians,
            "message": step.message,
            "channel_gains": step.channel_gains,
            "check": None if check is None else check.to_dict(),
        }

    def estimate_set(self, base: ParameterSet | None = None) -> ParameterSet:
        """The chosen estimate as a full ParameterSet (others from ``base`` or nominal)."""
        base = base or ParameterSet.nominal()
        return base.replace(dict(zip(self.parameters, self.chosen_x, strict=True)))
