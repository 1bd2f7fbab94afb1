"""railsusp: estimate suspension parameters of heavy-haul freight wagons from wheel-rail forces.

The public API re-exports the pieces a user combines: the parameter catalogue, the working
conditions and the track input. Later stages (simulator, campaign, sensitivity, surrogate,
estimation) are added as they land.
"""

from railsusp.conditions import STANDARD_CONDITIONS, WorkingCondition, get_condition
from railsusp.errors import ConditionError, ParameterError, RailsuspInputError
from railsusp.params import CATALOGUE, MAIN_SUSPENSION, ParameterSet, parse_overrides

__version__ = "0.1.0"

__all__ = [
    "CATALOGUE",
    "MAIN_SUSPENSION",
    "STANDARD_CONDITIONS",
    "ConditionError",
    "ParameterError",
    "ParameterSet",
    "RailsuspInputError",
    "WorkingCondition",
    "__version__",
    "get_condition",
    "parse_overrides",
]
