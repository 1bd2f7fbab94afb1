"""NSGA-II settings: the study's algorithm parameters, the objective definition and the
accepted range of each setting, checked before any work runs."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from railsusp.errors import RailsuspInputError
from railsusp.estimate.statistics import ALIGNED, check_weighting, parse_statistics

#: accepted range (inclusive) of each numeric NSGA-II setting, by :class:`NSGAConfig` field.
#: A population below 4 leaves the binary tournament nothing to choose from; pymoo's seed
#: is a 32-bit unsigned integer.
NSGA_RANGES: dict[str, tuple[float, float]] = {
    "pop_size": (4, 10_000),
    "n_gen": (1, 100_000),
    "crossover_prob": (0.0, 1.0),
    "mutation_prob": (0.0, 1.0),
    "seed": (0, 2**32 - 1),
}
#: independent NSGA-II runs for the seed spread
SEEDS_RANGE: tuple[int, int] = (1, 10)
#: accepted range of each setting of the refinement (:func:`~railsusp.estimate.refine_estimate`)
REFINE_RANGES: dict[str, tuple[int, int]] = {
    "max_evaluations": (1, 500),
    "screen": (0, 10_000),
    "starts": (1, 20),
    "geometry_draws": (0, 100),
}


#: how the estimate is picked from the Pareto front, by name: the point closest to the ideal
#: point of the front normalised to [0, 1] (record statistics: relative errors of different
#: quantities, whose trade-off has no common scale), or the point of least summed squared
#: objectives (time-aligned errors: every objective is already in units of the measured
#: force's standard deviation, so their squares add up to the time-aligned cost, and
#: normalising a narrow front would weigh a trade-off of 0.001 as much as one of 0.1)
IDEAL_POINT = "ideal-point"
LEAST_SQUARES = "least-squares"
CHOICE_RULES: dict[str, str] = {
    IDEAL_POINT: "closest to the ideal point of the front normalised to [0, 1]",
    LEAST_SQUARES: "least sum of squared objectives (time-aligned errors in units of the "
    "measured force's standard deviation): the least time-aligned cost on the front",
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

    def __post_init__(self):
        for name, (low, high) in NSGA_RANGES.items():
            check_range(name, getattr(self, name), low, high)
        parse_statistics(self.statistic)  # fail early with the accepted values
        check_weighting(self.weighting)

    def to_dict(self) -> dict:
        return asdict(self)
