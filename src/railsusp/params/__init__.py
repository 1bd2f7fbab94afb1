"""The wagon's parameters: the catalogue of Tables 1 and 2 of the reference study
(:mod:`~railsusp.params.catalogue`), a validated set of them
(:mod:`~railsusp.params.parameter_set`) and the text users type for them
(:mod:`~railsusp.params.parsing`). Everything public is importable from here."""

from railsusp.errors import ParameterError
from railsusp.params.catalogue import (
    CATALOGUE,
    FIXED_FACTOR,
    MAIN_SUSPENSION,
    STUDY_KEY_PARAMETERS,
    SYMBOLS,
    ParameterSpec,
    bounds,
    spec,
)
from railsusp.params.parameter_set import ParameterSet, Units
from railsusp.params.parsing import check_matrix, parse_overrides, parse_sampled

__all__ = [
    "CATALOGUE",
    "FIXED_FACTOR",
    "MAIN_SUSPENSION",
    "STUDY_KEY_PARAMETERS",
    "SYMBOLS",
    "ParameterError",
    "ParameterSet",
    "ParameterSpec",
    "Units",
    "bounds",
    "check_matrix",
    "parse_overrides",
    "parse_sampled",
    "spec",
]
