"""The NSGA-II run (pymoo): population, operators, generation log, choice rule, seed spread.

Problem, algorithm, termination, one entry point (pymoo style): the problem is a
:class:`~railsusp.estimate.problem.CalibrationProblem`, the settings an
:class:`~railsusp.estimate.config.NSGAConfig` (the study's: population 50, crossover 0.9,
mutation 0.05, 100 generations), and :func:`estimate` returns a
:class:`~railsusp.estimate.result.CalibrationResult`.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.core.callback import Callback
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.sampling.rnd import FloatRandomSampling
from pymoo.optimize import minimize
from pymoo.util.display.multi import MultiObjectiveOutput

from railsusp.errors import RailsuspInputError
from railsusp.estimate.comparison import check_time_base
from railsusp.estimate.config import (
    CHOICE_RULES,
    IDEAL_POINT,
    LEAST_SQUARES,
    NSGA_RANGES,
    SEEDS_RANGE,
    NSGAConfig,
    check_count,
    choice_rule,
)
from railsusp.estimate.expected_forces import ExpectedForces, check_drawable
from railsusp.estimate.forces import ForceModel
from railsusp.estimate.identifiability import cramer_rao_pct_range
from railsusp.estimate.problem import ERRORS, CalibrationProblem
from railsusp.estimate.result import CalibrationResult
from railsusp.estimate.statistics import ALIGNED, parse_statistics
from railsusp.estimate.statistics_forces import StatisticsForces
from railsusp.interrupts import stop_if_interrupted
from railsusp.measured import Recording
from railsusp.params import bounds

#: progress lines for the command line (stage progress of long estimates)
log = logging.getLogger("railsusp.estimate")


class _Log(Callback):
    """Records pymoo's n_gen, n_eval, n_nds, eps, indicator (the study's Tables 3/4) and
    each generation's population, for the convergence history; says the progress on the
    ``railsusp`` logger every tenth of the run (the command line prints it)."""

    def __init__(self, n_gen: int = 0):
        super().__init__()
        self.n_gen = n_gen
        self.rows: list[dict] = []
        self.front_x: list[np.ndarray] = []
        self.front_f: list[np.ndarray] = []
        self.front_e: list[np.ndarray] = []  # the front's errors per recording and force
        self._out = MultiObjectiveOutput()
        self._ready = False

    def notify(self, algorithm):
        if not self._ready:
            self._out.initialize(algorithm)
            self._ready = True
        self._out.update(algorithm)
        row = {c.name: c.value for c in self._out.columns}
        row["eps"] = None if row.get("eps") is None else float(row["eps"])
        self.rows.append(row)
        self.front_x.append(algorithm.opt.get("X").copy())
        self.front_f.append(algorithm.opt.get("F").copy())
        self.front_e.append(np.asarray(algorithm.opt.get(ERRORS), dtype=float).copy())
        n = len(self.rows)
        if self.n_gen and (n % max(1, self.n_gen // 10) == 0 or n == self.n_gen):
            log.info(
                "NSGA-II generation %d of %d: %d evaluations, %d on the front",
                n, self.n_gen, row.get("n_eval", 0), len(self.front_f[-1]),
            )  # fmt: skip
        stop_if_interrupted()  # a swallowed Ctrl-C: no use finishing the run (none resumes)


def choose(front: np.ndarray, rule: str = IDEAL_POINT, errors: np.ndarray | None = None) -> int:
    """Index of the estimate on a Pareto front (n, n_obj) by a choice rule
    (:data:`~railsusp.estimate.config.CHOICE_RULES`): ``ideal-point``, the point closest to
    the ideal point after normalising each objective to [0, 1] over the front;
    ``least-squares``, the point of least time-aligned cost (ties: the first), the sum of
    each point's squared ``errors`` (n, ...: its time-aligned error per recording and force,
    :meth:`~railsusp.estimate.problem.CalibrationProblem.errors`). Without ``errors`` the
    cost is the sum of the squared objectives, which is it only where the objectives are
    those errors themselves (one recording, or ``per_condition``): objectives averaged over
    recordings are the mean of each force's errors, and the sum of squared means can rank
    the front otherwise: errors (0, 0.3) and (0.6, 0.3) in two recordings average to
    objectives (0.3, 0.3), squared 0.18, against 0.19 for errors (0.25, 0.36) in both, yet
    their sums of squared errors are 0.54 against 0.38."""
    if rule == LEAST_SQUARES:
        terms = np.asarray(front if errors is None else errors, dtype=float)
        return int(np.argmin((terms.reshape(len(terms), -1) ** 2).sum(axis=1)))
    if rule != IDEAL_POINT:
        raise ValueError(f"choice rule {rule!r}: accepted {', '.join(CHOICE_RULES)}")
    lo, hi = front.min(axis=0), front.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    return int(np.argmin(np.linalg.norm((front - lo) / span, axis=1)))


def estimate(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    config: NSGAConfig | None = None,
    initial_si: np.ndarray | None = None,
) -> CalibrationResult:
    """Run NSGA-II and pick the estimate; deterministic for a given seed.

    ``initial_si``: parameter sets (n, k), SI, to start the population from (e.g. the Pareto
    set of a cheaper estimate), topped up with random sets to the population size. With
    ``config.expected_generations`` the time-aligned comparison is with the model's mean
    over ``config.expected_draws`` draws of the true track geometry given each recording's
    measured one (:class:`~railsusp.estimate.expected_forces.ExpectedForces`, seeded by
    ``config.seed``; that many times the predictions); else on the measured geometry itself
    (the expected forces' polish of the choice comes after:
    :func:`~railsusp.estimate.nsga_geometry.polish_on_expected_forces`)."""
    cfg = NSGAConfig() if config is None else config
    check_drawable(model, recordings, cfg.expected_draws)  # before the generations
    if ALIGNED in parse_statistics(cfg.statistic):  # the whole records', before a preview's
        check_time_base(recordings, "the time-aligned comparison (statistic 'aligned')")
    if cfg.preview_generations:
        return _previewed(model, recordings, parameters, cfg, initial_si)
    return _search(model, recordings, parameters, cfg, initial_si)


def _search(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    cfg: NSGAConfig,
    initial_si: np.ndarray | None,
) -> CalibrationResult:
    """One NSGA-II search of ``cfg.n_gen`` generations on ``recordings``."""
    if cfg.expected_generations:  # on stated-accuracy geometry: the mean over drawn tracks
        with ExpectedForces(model, cfg.expected_draws, seed=cfg.seed) as expected:
            return _estimate(expected, recordings, parameters, cfg, initial_si)
    return _estimate(model, recordings, parameters, cfg, initial_si)


def _previewed(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    cfg: NSGAConfig,
    initial_si: np.ndarray | None,
) -> CalibrationResult:
    """:func:`estimate` with preview generations: the first ``cfg.preview_generations`` on
    each recording's first ``cfg.preview_s`` seconds, the rest on the whole records from
    the preview's Pareto set (same seed, operators and population). One result: the log
    and the choice's history run over all ``cfg.n_gen`` generations (the log's ``record``
    column says which records each compared: their objectives are not comparable across
    the switch), the front, choice and Cramér-Rao bounds are the whole records'. Where no
    recording is longer than the preview, there is none: one search of ``cfg.n_gen``
    generations (its ``config`` without the preview), said in a warning."""
    n_preview = cfg.preview_generations
    plain = replace(cfg, preview_generations=0)
    heads = [r.head(cfg.preview_s) for r in recordings]
    whole = [r for r, h in zip(recordings, heads, strict=True) if h is r]
    if len(whole) == len(recordings):  # nothing to preview: one search, not restarted from
        warnings.warn(  # the preview's Pareto set on the same records
            f"preview_s {cfg.preview_s:g}: no recording is longer ("
            + ", ".join(f"{r.condition.name!r} {r.condition.duration_s:g} s" for r in whole)
            + f"), so there is no preview: the {cfg.n_gen} generations compare the whole "
            "records in one search",
            stacklevel=3,
        )
        result = _search(model, recordings, parameters, plain, initial_si)
        result.log = result.log.assign(record="whole")
        return result
    if whole:  # said, not left to be found: the preview then saves nothing on them
        warnings.warn(
            f"preview_s {cfg.preview_s:g}: recording(s) "
            + ", ".join(f"{r.condition.name!r} ({r.condition.duration_s:g} s)" for r in whole)
            + f" are no longer, so the {n_preview} preview generation(s) compare the whole "
            "record there",
            stacklevel=3,
        )
    log.info(
        "NSGA-II preview: %d of %d generations on the records' first %g s",
        n_preview, cfg.n_gen, cfg.preview_s,
    )  # fmt: skip
    first = _search(model, heads, parameters, replace(plain, n_gen=n_preview), initial_si)
    rest = _search(
        model, recordings, parameters, replace(plain, n_gen=cfg.n_gen - n_preview), first.pareto_x
    )
    head_log = first.log.assign(record=f"first {cfg.preview_s:g} s")
    rest_log = rest.log.assign(record="whole")
    for column in ("n_gen", "n_eval"):  # counted on from the preview's
        if column in rest_log and column in head_log and len(head_log):
            rest_log[column] = rest_log[column] + head_log[column].iloc[-1]
    rest.log = pd.concat([head_log, rest_log], ignore_index=True)
    rest.history = np.vstack([first.history, rest.history])
    rest.config = cfg
    return rest


def _estimate(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    cfg: NSGAConfig,
    initial_si: np.ndarray | None,
) -> CalibrationResult:
    """:func:`estimate` with the model it compares (the expected forces, where asked)."""
    problem = CalibrationProblem(
        model,
        recordings,
        parameters,
        cfg.statistic,
        cfg.per_condition,
        cfg.weighting,
        cfg.channel_gains,
    )
    sampling: Any = FloatRandomSampling()
    if initial_si is not None:
        start = np.clip((np.atleast_2d(initial_si) - problem.lo) / (problem.hi - problem.lo), 0, 1)
        start = start[: cfg.pop_size]
        fill = np.random.default_rng(cfg.seed).random((cfg.pop_size - len(start), problem.n_var))
        sampling = np.vstack([start, fill])
    algo = NSGA2(
        pop_size=cfg.pop_size,
        sampling=sampling,
        crossover=SBX(prob=cfg.crossover_prob, eta=15),
        mutation=PM(prob_var=cfg.mutation_prob, eta=20),
        eliminate_duplicates=True,
    )
    progress = _Log(cfg.n_gen)
    res = minimize(
        problem, algo, ("n_gen", cfg.n_gen), seed=cfg.seed, verbose=False, callback=progress
    )
    x = np.atleast_2d(res.X)
    f = np.atleast_2d(res.F)
    e = np.asarray(res.opt.get(ERRORS), dtype=float).reshape(len(x), -1)
    order = np.argsort(f[:, 0])
    x, f, e = x[order], f[order], e[order]
    rule = choice_rule(cfg.statistic)
    history = np.array(
        [
            problem.to_si(fx[choose(ff, rule, fe)])
            for fx, ff, fe in zip(progress.front_x, progress.front_f, progress.front_e, strict=True)
        ]
    )
    result = CalibrationResult(
        tuple(parameters),
        problem.to_si(x),
        f,
        choose(f, rule, e),
        pd.DataFrame(progress.rows),
        history,
        cfg,
        choice_rule=rule,
    )
    if cfg.channel_gains:
        result.channel_gains = problem.channel_gains_at(result.pareto_x[result.chosen])
    if isinstance(model, StatisticsForces) and problem.stats:
        result.cramer_rao = cramer_rao_pct_range(
            model, problem.recordings, result.parameters, result.chosen_x, problem.stats
        )
    return result


def estimate_with_seeds(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    config: NSGAConfig | None = None,
    n_seeds: int = 3,
) -> CalibrationResult:
    """The estimate of the first seed, with the spread of the chosen estimate over
    ``n_seeds`` independent runs (in % of each parameter's range): run k has seed
    ``config.seed + k``, so the last seed is checked against pymoo's 32-bit range before
    the first run (not after it, as a seed one past the range failed)."""
    check_count("n_seeds", n_seeds, *SEEDS_RANGE)
    cfg = NSGAConfig() if config is None else config
    top = int(NSGA_RANGES["seed"][1])
    if cfg.seed + n_seeds - 1 > top:
        raise RailsuspInputError(
            f"seed {cfg.seed} with seeds {n_seeds}: accepted seed + seeds - 1 at most {top} "
            "(run k of the seed spread has seed + k)"
        )
    runs = [
        estimate(
            model, recordings, parameters, NSGAConfig(**{**cfg.to_dict(), "seed": cfg.seed + k})
        )
        for k in range(n_seeds)
    ]
    lo, hi = bounds(parameters)
    chosen = np.array([r.pareto_x[r.chosen] for r in runs])
    spread = (chosen.max(axis=0) - chosen.min(axis=0)) / (hi - lo) * 100
    first = runs[0]
    first.n_seeds = n_seeds
    if n_seeds > 1:  # one seed's "spread" of 0 would read as a reproducible search
        first.seeds_spread = {p: float(s) for p, s in zip(parameters, spread, strict=True)}
    return first
