"""railsusp: estimate suspension parameters of heavy-haul freight wagons from wheel-rail forces.

The public API: ``railsusp.run(config, out=...)`` runs the whole method and
``railsusp.open_run(path)`` opens a run directory, both giving a :class:`RunResult` (the
estimate with intervals and verdicts, validation, sensitivity, surrogate accuracy, report;
docs/api.md); and the pieces a user combines: the parameter catalogue, the working
conditions. Each loads on first use, so that ``import railsusp`` loads the standard
library only (the console script's start, :mod:`railsusp.command`).
"""

import importlib as _importlib
import importlib.util as _importlib_util
from typing import TYPE_CHECKING

from railsusp._version import __version__
from railsusp.errors import ConditionError, ParameterError, RailsuspInputError

if TYPE_CHECKING:  # what type checkers and editors see; at run time, __getattr__ below
    from railsusp.api import OutdatedModelWarning, RunResult, Tolerances, open_run, run
    from railsusp.conditions import STANDARD_CONDITIONS, WorkingCondition, get_condition
    from railsusp.params import CATALOGUE, MAIN_SUSPENSION, ParameterSet, parse_overrides

__all__ = [
    "CATALOGUE",
    "MAIN_SUSPENSION",
    "STANDARD_CONDITIONS",
    "ConditionError",
    "OutdatedModelWarning",
    "ParameterError",
    "ParameterSet",
    "RailsuspInputError",
    "RunResult",
    "Tolerances",
    "WorkingCondition",
    "__version__",
    "get_condition",
    "open_run",
    "parse_overrides",
    "run",
]

#: the public names loaded on first use, by the module that holds each: ``import railsusp``
#: loads the standard library only (the console script's Ctrl-C guard, railsusp.command,
#: comes after it; NumPy and pydantic took 0.2 s of it before stop 76)
_LAZY = {
    **dict.fromkeys(("OutdatedModelWarning", "RunResult", "Tolerances", "open_run", "run"), "api"),
    **dict.fromkeys(("STANDARD_CONDITIONS", "WorkingCondition", "get_condition"), "conditions"),
    **dict.fromkeys(("CATALOGUE", "MAIN_SUSPENSION", "ParameterSet", "parse_overrides"), "params"),
}


def __getattr__(name: str):
    """The lazily imported API, and railsusp's modules by attribute as the docs name them
    (``railsusp.api.OutdatedModelWarning``, ``railsusp.vehicle.MODEL_REVISION``): after a
    plain ``import railsusp`` they raised AttributeError (the docs audit of stop 72)."""
    if name in _LAZY:
        value = getattr(_importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value  # once loaded, an attribute like any other
        return value
    # a plain name only: a dotted one ("vehicle.model") gave the submodule, and one of no
    # module (hasattr(railsusp, "a.b")) raised ModuleNotFoundError (the review of stop 72)
    submodule = name.isidentifier() and not name.startswith("_")
    if submodule and _importlib_util.find_spec(f"{__name__}.{name}") is not None:
        return _importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'railsusp' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The lazily imported API too (tab completion in a notebook)."""
    return sorted({*globals(), *__all__})
