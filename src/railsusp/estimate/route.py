"""The estimate's steps in their order: one definition for ``railsusp estimate`` and the
pipeline's estimate stage.

An estimate is NSGA-II on the force model (:func:`~railsusp.estimate.nsga.estimate_with_seeds`),
then the recordings' stated geometry error (the expected-forces polish or the first SIMEX
step, :func:`~railsusp.estimate.nsga_geometry.account_for_geometry`), then the simulator's
level corrections of a surrogate (:func:`~railsusp.estimate.level_correction.correct_by_simulator`),
then, optionally, the output-error refinement with the simulator
(:func:`~railsusp.estimate.polish.refine_estimate`). Each step reads what the one before it
left in the :class:`~railsusp.estimate.result.CalibrationResult`, so the order is part of the
method; until stop 51 the command line and the pipeline each wrote it out, with the checks
that must come before NSGA-II. :class:`EstimateRoute` holds the settings of every step and
:meth:`EstimateRoute.check` refuses, before any work and naming the setting as its caller
spells it (``--refine`` or ``estimate.refine``), what a later step cannot take.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass

from railsusp.estimate.config import SIMULATED, HeldPrior, NSGAConfig, check_slope_update
from railsusp.estimate.forces import ForceModel, SimulatorForces
from railsusp.estimate.level_correction import check_correctable, correct_by_simulator
from railsusp.estimate.nsga import estimate_with_seeds
from railsusp.estimate.nsga_geometry import (
    account_for_geometry,
    takes_expected_polish,
    takes_geometry_bias,
)
from railsusp.estimate.polish import check_refinable, refine_estimate
from railsusp.estimate.result import CalibrationResult
from railsusp.measured import Recording
from railsusp.params import ParameterSet

#: what shows a step while it runs: given the step's description, a context manager
#: (the command line's spinner, ``rich.console.Console.status``); none by default
Progress = Callable[[str], AbstractContextManager]


def _quiet(_: str) -> AbstractContextManager:
    return nullcontext()


@dataclass(frozen=True)
class EstimateRoute:
    """Every step's settings (NSGA-II's in ``nsga``) and how the caller names the two
    settings whose refusals depend on the recordings: ``refine_setting`` and
    ``corrections_setting``."""

    nsga: NSGAConfig
    seeds: int
    geometry_draws: int
    remove_geometry_bias: bool
    simulator_corrections: int
    refine: bool
    refine_evaluations: int
    refine_screen: int
    refine_starts: int
    held_prior: HeldPrior | None = None
    correction_slopes: bool = False
    slope_update: str = SIMULATED
    refine_setting: str = "refine"
    corrections_setting: str = "simulator_corrections"
    held_prior_setting: str = "held_prior"

    def check(self, recordings: Sequence[Recording], model: ForceModel) -> None:
        """Refuse, in one line naming the setting, a refinement the recordings cannot take
        (no measured track) and simulator corrections that the recordings, the comparison
        or ``model`` cannot: before NSGA-II runs, not after it."""
        if self.refine:
            check_refinable(recordings, self.refine_setting)
        if self.simulator_corrections:
            check_correctable(recordings, self.nsga.statistic, self.corrections_setting, model)
        check_slope_update(
            self.slope_update, self.correction_slopes, "slope_update", "correction_slopes off"
        )

    def run(
        self,
        model: ForceModel,
        recordings: Sequence[Recording],
        parameters: Sequence[str],
        progress: Progress = _quiet,
        simulator: ForceModel | None = None,
    ) -> CalibrationResult:
        """The estimate of ``parameters`` from ``recordings`` with ``model``: the checks
        (:meth:`check`), then each step in order, each shown by ``progress`` while it runs.
        ``simulator``: the corrections' and the refinement's reference model (default the
        simulator of the packaged wagon, :class:`~railsusp.estimate.forces.SimulatorForces`;
        give one with ``wagon=`` for another wagon's data)."""
        self.check(recordings, model)
        unused = self.held_prior.unused(parameters) if self.held_prior is not None else []
        if unused:  # a pipeline's key parameters are found after its configuration is read
            warnings.warn(
                f"{self.held_prior_setting}: {', '.join(unused)} estimated, so its range is not "
                "used (the refined intervals take a prior for held parameters only)",
                stacklevel=2,
            )
        # the parameters the user gave a range for, held at its centre wherever the
        # simulator runs: NSGA-II on it, its corrections, the refinement
        held_at: dict[str, float] = {}
        if self.refine or self.simulator_corrections or isinstance(model, SimulatorForces):
            simulator, held_at = held_simulator(simulator, self.held_prior, parameters)
        if held_at and isinstance(model, SimulatorForces):
            model, _ = held_simulator(model, self.held_prior, parameters)
        cfg = self.nsga
        with progress(f"NSGA-II {cfg.pop_size} x {cfg.n_gen} on {len(recordings)} recording(s)"):
            res = estimate_with_seeds(model, recordings, parameters, cfg, n_seeds=self.seeds)
        if takes_expected_polish(cfg, recordings):
            doing = f"polishing on the mean over {cfg.expected_draws} drawn true tracks"
        elif takes_geometry_bias(cfg, self.geometry_draws, recordings):
            doing = f"{self.geometry_draws} draws of the track geometry's error"
        else:
            doing = ""
        if doing:
            with progress(doing):
                account_for_geometry(
                    res,
                    recordings,
                    model,
                    self.geometry_draws,
                    cfg.seed,
                    self.remove_geometry_bias,
                )
        if self.simulator_corrections:
            order = "first-order " if self.correction_slopes else ""
            n = self.simulator_corrections
            with progress(f"{n} {order}simulator correction(s) of the estimate"):
                correct_by_simulator(
                    res,
                    recordings,
                    model,
                    self.simulator_corrections,
                    simulator=simulator,
                    slopes=self.correction_slopes,
                    slope_update=self.slope_update,
                )
        if self.refine:
            with progress("refining on the measured track (simulator, output error)"):
                refine_estimate(
                    res,
                    recordings,
                    max_evaluations=self.refine_evaluations,
                    screen=self.refine_screen,
                    starts=self.refine_starts,
                    seed=cfg.seed,
                    geometry_draws=self.geometry_draws,
                    remove_geometry_bias=self.remove_geometry_bias,
                    expected_draws=cfg.expected_draws,
                    model=simulator,
                )
            res.held_prior = self.held_prior
        res.held_at_si = held_at  # (the validation simulates the estimate there too)
        return res


def held_simulator(
    simulator: ForceModel | None, prior: HeldPrior | None, parameters: Sequence[str]
) -> tuple[ForceModel | None, dict[str, float]]:
    """(the reference simulator, the values it holds parameters at off nominal): with a
    user's ``prior`` for parameters not estimated, the simulator (default the packaged
    wagon's) holding each at the centre of its range (:meth:`HeldPrior.held_at_si`), and
    those values (SI); else ``simulator`` as given and none. A reference model that is not
    the simulator is left as it is, and holds nothing off nominal."""
    held = prior.held_at_si(parameters) if prior is not None else {}
    sim = SimulatorForces(parameters) if simulator is None else simulator
    if not held or not isinstance(sim, SimulatorForces):
        return simulator, {}
    base = (sim.base or ParameterSet.nominal()).replace(held)
    return SimulatorForces(sim.parameters, sim.wheel, base=base, wagon=sim.wagon), held
