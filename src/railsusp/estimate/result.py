"""The estimate, told and kept: its route in words, the study's Table 5 layout, and the run
directory's ``estimate/`` files.

:class:`CalibrationResult` is what :func:`railsusp.estimate.estimate` returns and what the
refinement (:func:`railsusp.estimate.refine_estimate`) completes; it writes the run
directory's ``estimate/`` files (``nsga_log.*``, ``estimate.csv``, ``estimate.json``, the
Pareto and convergence figures), each atomically. The estimate itself (the Pareto set and
front, the chosen point, the convergence, the steps after NSGA-II, the per-parameter
intervals) is its base, :class:`~railsusp.estimate.estimate_point.EstimatePoint`
(:mod:`railsusp.estimate.estimate_point`).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from railsusp.estimate.config import BROYDEN, CHOICE_RULES, SLOPE_STEP, TRUST_BOX
from railsusp.estimate.estimate_point import EstimatePoint
from railsusp.estimate.intervals import PARETO
from railsusp.estimate.problem import display_values
from railsusp.estimate.refine import SIMULATOR_TEXT, Refinement
from railsusp.estimate.statistics import ALIGNED, parse_statistics
from railsusp.params import spec
from railsusp.store import atomic_write_bytes, write_json, write_parquet

#: the route's words for a point that has the geometry error's bias taken off
LESS_GEOMETRY_BIAS = ", less the track geometry error's bias (first SIMEX step)"


class CalibrationResult(EstimatePoint):
    """One NSGA-II run's estimate (:class:`~railsusp.estimate.estimate_point.EstimatePoint`,
    whose fields it is built from) with how it is described and kept: its route, the study's
    Table 5 layout, the run directory's ``estimate/`` files."""

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
            text += LESS_GEOMETRY_BIAS
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
            if self.geometry_bias_removed:  # (level_correction: each step's least squares)
                text += ", each corrected point less the same bias"
        if self.refinement is None:
            return text
        ref = self.refinement
        drawn = ref.expected_draws
        on = f" on its mean over {drawn} draws of the true track geometry" if drawn else ""
        model = ref.compared_model or "an unnamed force model"  # the model it compared
        # its point less the geometry bias its draws estimate, as NSGA-II's above
        less = LESS_GEOMETRY_BIAS if ref.geometry_bias_removed else ""
        if self.refinement_is_polish:
            what = (
                "the simulator's output-error refinement"
                if model == SIMULATOR_TEXT
                else f"the output-error refinement with {model}"
            )
            return text + f"; {what}{on}{less} is a polish beside it"
        start = "" if ref.from_choice else f" from {ref.start_origin}"
        return text + f", then refined by output-error least squares with {model}{on}{start}{less}"

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
                "seeds": self.n_seeds,
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
                "held_at_display": {p: spec(p).to_display(v) for p, v in self.held_at_si.items()},
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
