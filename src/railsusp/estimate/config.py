"""NSGA-II settings: the study's algorithm parameters, the objective definition and the
accepted range of each setting, checked before any work runs."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

from railsusp.errors import ParameterError, RailsuspInputError
from railsusp.estimate.statistics import ALIGNED, check_weighting, parse_statistics
from railsusp.numbers import is_whole
from railsusp.params import MAIN_SUSPENSION, spec

#: accepted range (inclusive) of each numeric NSGA-II setting, by :class:`NSGAConfig` field.
#: A population below 4 leaves the binary tournament nothing to choose from; pymoo's seed
#: is a 32-bit unsigned integer.
NSGA_RANGES: dict[str, tuple[float, float]] = {
    "pop_size": (4, 10_000),
    "n_gen": (1, 100_000),
    "crossover_prob": (0.0, 1.0),
    "mutation_prob": (0.0, 1.0),
    "seed": (0, 2**32 - 1),
    "expected_draws": (0, 64),
    "preview_generations": (0, 100_000),
    "preview_s": (1.0, 600.0),
}
#: the :data:`NSGA_RANGES` settings that count (a population, generations, draws) or seed a
#: generator: integers only. A fraction passed the range check and then failed deep inside
#: pymoo (``pop_size`` 10.5, ``seed`` 1.5) or was silently rounded up (``n_gen`` 3.5 ran 4)
NSGA_INTEGERS: tuple[str, ...] = (
    "pop_size",
    "n_gen",
    "seed",
    "expected_draws",
    "preview_generations",
)
#: independent NSGA-II runs for the seed spread
SEEDS_RANGE: tuple[int, int] = (1, 10)
#: simulator corrections of the surrogate's level error at NSGA-II's estimate
#: (:func:`~railsusp.estimate.level_correction.correct_by_simulator`; each: one simulation
#: of the estimate per recording and drawn track, and the surrogate's least squares again)
CORRECTIONS_RANGE: tuple[int, int] = (0, 5)
#: each key's step, as a fraction of its range, for the simulator's and the surrogate's
#: slopes at the estimate (inwards at the upper bound): the refinement's finite-difference
#: step (:data:`~railsusp.estimate.output_error.REFINE_STEP`, the same 5 %)
SLOPE_STEP = 0.05
#: how far, as a fraction of each range, a first-order correction's first least squares may
#: move each key from the point where the slopes were taken: three times their step. The box
#: then shrinks or grows by the simulator's check of each step
#: (:mod:`railsusp.estimate.trust_region`). One step without a box sent X19 from one bound
#: to near the other in one of issue 19's sets (bench/README.md, "First-order corrections")
TRUST_BOX = 0.15
#: the shortest step (Euclidean, as a fraction of each range) across which Broyden's update
#: changes the slopes (:func:`~railsusp.estimate.level_correction.broyden_slopes`): across a
#: shorter one the level's change is mostly the simulator's small-scale roughness, and the
#: secant divides it by the step's length
BROYDEN_MIN_STEP = 0.01
#: how a first-order correction gets the slopes at each later point it moves to: simulated
#: again (k more simulations per recording and drawn track), or Broyden's update from the
#: level corrections' change along the step (no simulation;
#: :func:`~railsusp.estimate.level_correction.broyden_slopes`); the first point's are always
#: simulated
SIMULATED, BROYDEN = "simulated", "broyden"
SLOPE_UPDATES: tuple[str, ...] = (SIMULATED, BROYDEN)

#: accepted range of each setting of the refinement (:func:`~railsusp.estimate.refine_estimate`)
REFINE_RANGES: dict[str, tuple[int, int]] = {
    "max_evaluations": (1, 500),
    "screen": (0, 10_000),
    "starts": (1, 20),
    "geometry_draws": (0, 100),
}


#: what the expected forces (``expected_draws``) can be compared by. By default they polish
#: NSGA-II's choice by the time-aligned least squares (the SIMEX step's place), which needs
#: the statistic ``aligned`` alone; in NSGA-II's generations (``expected_generations``)
#: also ``aligned`` with the mean, which is linear in the series. The spread statistics
#: (rms, std, percentiles) of a mean over draws are those of a smoothed series, lower than
#: a record's.
EXPECTED_STATISTICS_TEXT = {
    False: "'aligned' alone (the polish is the time-aligned least squares; 'aligned+mean' "
    "with expected_generations)",
    True: "'aligned', alone or with 'mean'",
}


def expected_statistics_ok(statistic: str, generations: bool = False) -> bool:
    """Whether expected forces can be compared by ``statistic``: ``aligned`` alone for the
    polish of NSGA-II's choice; in NSGA-II's ``generations`` also with ``mean`` beside it."""
    stats = set(parse_statistics(statistic))
    allowed = {ALIGNED, "mean"} if generations else {ALIGNED}
    return ALIGNED in stats and stats <= allowed


#: how the estimate is picked from the Pareto front, by name: the point closest to the ideal
#: point of the front normalised to [0, 1] (record statistics: relative errors of different
#: quantities, whose trade-off has no common scale), or the point of least time-aligned
#: cost, the sum over recordings and force channels of the squared time-aligned errors
#: (every error is in units of the measured force's standard deviation, so their squares
#: add up to the refinement's cost, and normalising a narrow front would weigh a trade-off
#: of 0.001 as much as one of 0.1). The cost is summed from each point's errors per
#: recording, not from its objectives: with ``per_condition`` off each objective is the mean
#: over recordings of a channel's error, and squared means do not add up to the cost
#: (:func:`~railsusp.estimate.nsga.choose`)
IDEAL_POINT = "ideal-point"
LEAST_SQUARES = "least-squares"
CHOICE_RULES: dict[str, str] = {
    IDEAL_POINT: "closest to the ideal point of the front normalised to [0, 1]",
    LEAST_SQUARES: "least sum of squared time-aligned errors over the recordings and force "
    "channels (in units of the measured force's standard deviation): the least "
    "time-aligned cost on the front",
}


def choice_rule(statistic: str) -> str:
    """The rule (:data:`CHOICE_RULES`) that picks the estimate on the Pareto front of an
    objective on ``statistic``: least squares for the time-aligned comparison alone, the
    normalised ideal point otherwise (record statistics, or a mixture with them)."""
    return LEAST_SQUARES if parse_statistics(statistic) == (ALIGNED,) else IDEAL_POINT


def _number(value: float) -> str:
    return str(value) if isinstance(value, int) else f"{value:g}"


def check_range(name: str, value: float, low: float, high: float) -> None:
    """A one-line :class:`~railsusp.errors.RailsuspInputError` naming the setting ``name``
    (an option such as ``--n-gen`` or a field such as ``n_gen``) and its accepted range,
    unless ``low <= value <= high`` (NaN is refused)."""
    if isinstance(value, bool) or not low <= value <= high:
        raise RailsuspInputError(
            f"{name} {_number(value)}: accepted {_number(low)} to {_number(high)}"
        )


def check_count(name: str, value: int, low: int, high: int) -> None:
    """:func:`check_range` for a setting that counts or seeds: also refuses, in the same one
    line, a value that is not an integer (a float such as 10.5 or 10.0, a boolean)."""
    if not is_whole(value):
        raise RailsuspInputError(f"{name} {value!r}: accepted an integer {low} to {high}")
    check_range(name, value, low, high)


def check_slope_update(update: str, slopes: bool, setting: str, slopes_setting: str) -> None:
    """Refuse, in one line naming the settings as the caller spells them (``setting``; the
    first-order switch ``slopes_setting``), a slope update not in :data:`SLOPE_UPDATES`, or
    Broyden's where no first-order corrections are asked for (it would change nothing)."""
    if update not in SLOPE_UPDATES:
        raise RailsuspInputError(
            f"{setting} {update!r}: accepted {', '.join(map(repr, SLOPE_UPDATES))}"
        )
    if update != SIMULATED and not slopes:
        raise RailsuspInputError(
            f"{setting} {update!r} updates the slopes of first-order corrections; "
            f"{slopes_setting} asks for none: accepted {SIMULATED!r} without them"
        )


#: why a preview needs the time-aligned comparison (its refusal, here and in the pipeline's
#: configuration check)
PREVIEW_NEEDS_ALIGNED = (
    "record statistics alone: accepted only with the time-aligned comparison (a statistic "
    "with 'aligned'); a record's statistics are predicted at the training length whatever the "
    "record's, so the preview saves nothing and compares a short record's statistics with "
    "the whole record's"
)


@dataclass(frozen=True)
class NSGAConfig:
    """NSGA-II settings (the study's defaults) and the objective definition.

    Refuses a setting outside :data:`NSGA_RANGES` (a one-line input error naming the field),
    so that a bad setting fails before the recordings are read or a generation runs."""

    pop_size: int = 50
    n_gen: int = 100
    crossover_prob: float = 0.9
    mutation_prob: float = 0.05
    seed: int = 0
    statistic: str = "mean"
    per_condition: bool = False
    weighting: str = "relative"
    #: the time-aligned comparison profiles each channel's gain out
    #: (:func:`~railsusp.estimate.comparison.channel_gains`)
    channel_gains: bool = False
    #: on recordings whose geometry states its accuracy, NSGA-II's choice is polished by the
    #: model's time-aligned least squares on its mean over this many draws of the true track
    #: geometry given the measured one
    #: (:class:`~railsusp.estimate.expected_forces.ExpectedForces`,
    #: :func:`~railsusp.estimate.nsga_geometry.polish_on_expected_forces`), instead of the
    #: first SIMEX step; 0: neither polish nor expected forces
    expected_draws: int = 0
    #: NSGA-II's generations compare the expected forces too (``expected_draws`` times the
    #: predictions in every generation: on the shipped networks 8x the time, landing where
    #: the polish alone does, bench/README.md)
    expected_generations: bool = False
    #: the first this many of the ``n_gen`` generations compare only each recording's first
    #: ``preview_s`` seconds (:meth:`~railsusp.measured.Recording.head`), the rest start
    #: from their Pareto set on the whole records: the front's coarse search costs the
    #: predictions of a short record. Issue 19's bench, 60 of 100 generations on 20 s of
    #: 60 s records: 57.5 s per estimate against 91.0 s, 33 of 44 identifiable keys within
    #: 5 % of range against 30 (bench/README.md, "Preview generations"); 0: none
    preview_generations: int = 0
    preview_s: float = 20.0

    def __post_init__(self):
        for name, (low, high) in NSGA_RANGES.items():
            if name in NSGA_INTEGERS:
                check_count(name, getattr(self, name), int(low), int(high))
                # a numpy integer kept as Python's: seed + k and the saved config stay exact
                object.__setattr__(self, name, int(getattr(self, name)))
            else:
                check_range(name, getattr(self, name), low, high)
        if self.preview_generations >= self.n_gen:
            raise RailsuspInputError(
                f"preview_generations {self.preview_generations}: accepted 0 to n_gen - 1 "
                f"({self.n_gen - 1}; the generations after the preview compare the whole "
                "records)"
            )
        parse_statistics(self.statistic)  # fail early with the accepted values
        check_weighting(self.weighting)
        if self.preview_generations and ALIGNED not in parse_statistics(self.statistic):
            raise RailsuspInputError(f"preview_generations with {PREVIEW_NEEDS_ALIGNED}")
        if self.channel_gains and ALIGNED not in parse_statistics(self.statistic):
            raise RailsuspInputError(
                f"channel_gains with statistic {self.statistic!r}: accepted only with the "
                "time-aligned comparison (a statistic with 'aligned')"
            )
        if self.expected_generations and not self.expected_draws:
            raise RailsuspInputError(
                "expected_generations needs expected_draws 1 or more (the draws they compare)"
            )
        if self.expected_draws and not expected_statistics_ok(
            self.statistic, self.expected_generations
        ):
            raise RailsuspInputError(
                f"expected_draws {self.expected_draws} with statistic {self.statistic!r}: "
                f"accepted only with {EXPECTED_STATISTICS_TEXT[self.expected_generations]}"
            )

    def to_dict(self) -> dict:
        return asdict(self)


#: where a configuration gives the held parameters' prior (error messages)
HELD_PRIOR_FIELD = "estimate.held_prior"


@dataclass(frozen=True)
class HeldPrior:
    """The user's knowledge of main-suspension parameters an estimate may hold at nominal:
    per parameter the range ``[low, high]`` (SI) it is known to lie in, within its Table 2
    range. The refinement's intervals take each held parameter uniform over this range
    instead of its whole Table 2 range (:func:`~railsusp.estimate.refine_intervals.
    held_parameter_variance`). A parameter the estimate estimates uses its prior nowhere
    (its search range stays Table 2's); a parameter without a prior keeps Table 2's range.

    Build it from a configuration's display units with :meth:`from_display`, which refuses
    an unknown or fixed parameter, a non-number, ``low >= high`` and a range outside Table 2
    with a one-line error naming the field and the accepted range."""

    ranges_si: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    @classmethod
    def from_display(
        cls, ranges: Mapping[str, Any] | None, where: str = HELD_PRIOR_FIELD
    ) -> HeldPrior:
        """The prior of ``{symbol or name: [low, high]}`` in each parameter's display unit
        (MN/m, kN/m, kN·s/m, mm, m: docs/parameters.md), checked; ``where`` names the field
        in the errors."""
        out: dict[str, tuple[float, float]] = {}
        for key, pair in (ranges or {}).items():
            try:
                s = spec(str(key))
            except ParameterError:
                raise RailsuspInputError(
                    f"{where}.{key}: unknown parameter; accepted the main-suspension "
                    f"parameters {MAIN_SUSPENSION[0]}..{MAIN_SUSPENSION[-1]} or their names"
                ) from None
            name = f"{where}.{key}"
            if not s.is_sampled:
                raise RailsuspInputError(
                    f"{name}: {s.symbol} is fixed and never held with a range; accepted "
                    f"{MAIN_SUSPENSION[0]}..{MAIN_SUSPENSION[-1]}"
                )
            if s.symbol in out:
                raise RailsuspInputError(f"{name}: {s.symbol} is given twice")
            lo_t, hi_t = s.bounds_display  # type: ignore[misc]
            accepted = (
                f"accepted [low, high] with {lo_t:g} <= low < high <= {hi_t:g} {s.display_unit}"
            )
            lo, hi = _pair(pair, f"{name} = {pair!r}: {accepted}")
            shown = f"{name} = [{lo:g}, {hi:g}] {s.display_unit}"
            if not lo < hi:
                raise RailsuspInputError(f"{shown}: low must be below high; {accepted}")
            tol = 1e-9 * max(abs(lo_t), abs(hi_t))
            if lo < lo_t - tol or hi > hi_t + tol:
                raise RailsuspInputError(
                    f"{shown} reaches outside {s.symbol}'s Table 2 range; {accepted}"
                )
            out[s.symbol] = (max(lo, lo_t) * s.scale, min(hi, hi_t) * s.scale)
        return cls(out)

    def range_si(self, symbol: str) -> tuple[float, float]:
        """The range (SI) a held ``symbol`` is taken uniform over: the user's, or Table 2's."""
        got = self.ranges_si.get(symbol)
        return got if got is not None else spec(symbol).bounds  # type: ignore[return-value]

    def given(self, symbol: str) -> bool:
        """Whether the user gave ``symbol``'s range (else Table 2's is taken)."""
        return symbol in self.ranges_si

    def held_at_si(self, estimated: Iterable[str]) -> dict[str, float]:
        """The value (SI) the estimate's simulations hold each parameter at that the user
        gave a range for and that is not ``estimated``: the centre of that range, the mean
        of the uniform prior the intervals take it over. Holding such a parameter at
        nominal instead put the point beside its own interval, which took the offset in
        (X14 = 10.13 MN/m with 6.06-7.79, stop 77), and at a value outside a range that
        leaves nominal out. The others stay at nominal, the centre of Table 2's range."""
        est = set(estimated)
        return {p: 0.5 * (lo + hi) for p, (lo, hi) in self.ranges_si.items() if p not in est}

    def unused(self, estimated: Iterable[str]) -> list[str]:
        """The parameters with a prior that the estimate estimates (the prior is not used)."""
        est = set(estimated)
        return [p for p in self.ranges_si if p in est]

    def to_display(self) -> dict[str, list[float]]:
        """``{symbol: [low, high]}`` in display units (estimate.json, reports)."""
        return {
            p: [spec(p).to_display(lo), spec(p).to_display(hi)]
            for p, (lo, hi) in self.ranges_si.items()
        }


def held_at_of(doc: Mapping[str, Any], where: str) -> dict[str, float]:
    """An estimate.json's ``held_at_display`` (the parameters not estimated that the
    estimate held off nominal, display units; absent or empty: none), checked: an object of
    main-suspension symbols not among its ``parameters``, each a finite number inside its
    Table 2 range; else a one-line input error naming ``where`` and the field (a hand-edited
    file gave a TypeError's or an AttributeError's traceback)."""
    held = doc.get("held_at_display") or {}
    estimated = set(doc.get("parameters") or ())
    accepted = (
        "accepted an object {symbol: value} of main-suspension parameters not estimated, "
        "each inside its Table 2 range in its display unit"
    )
    if not isinstance(held, Mapping):
        raise RailsuspInputError(f"{where}: held_at_display = {held!r:.60}: {accepted}")
    out = {}
    for key, value in held.items():
        ok = key in MAIN_SUSPENSION and key not in estimated
        if ok and not isinstance(value, bool) and isinstance(value, int | float):
            lo, hi = spec(key).bounds_display  # type: ignore[misc]
            tol = 1e-9 * max(abs(lo), abs(hi))
            ok = math.isfinite(value) and lo - tol <= value <= hi + tol
        else:
            ok = False
        if not ok:
            raise RailsuspInputError(f"{where}: held_at_display.{key} = {value!r:.40}: {accepted}")
        out[key] = float(value)
    return out


def _pair(value: Any, message: str) -> tuple[float, float]:
    """``value`` as two finite numbers (not booleans), else a RailsuspInputError(message)."""
    if isinstance(value, str | bytes | Mapping) or not isinstance(value, Iterable):
        raise RailsuspInputError(message)
    items = list(value)
    if len(items) != 2 or any(isinstance(v, bool) for v in items):
        raise RailsuspInputError(message)
    try:
        lo, hi = (float(v) for v in items)
    except (TypeError, ValueError):
        raise RailsuspInputError(message) from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise RailsuspInputError(message)
    return lo, hi
