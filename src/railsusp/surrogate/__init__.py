"""Surrogate ("proxy") models of the simulator: data windows, networks, training, evaluation.

``train_surrogate(run, condition)`` trains a network on a campaign run directory and saves it
under ``RUN/surrogates/<kind>/<condition>/`` (:mod:`~railsusp.surrogate.fit`); ``load(path)``
gives back a :class:`~railsusp.surrogate.bundle.Surrogate` whose ``predict`` returns force
series; :mod:`~railsusp.surrogate.keys`: the parameters the surrogates take as inputs.
"""

from __future__ import annotations

from railsusp.surrogate.bundle import Surrogate, load
from railsusp.surrogate.evaluate import evaluate
from railsusp.surrogate.fit import (
    check_conditions,
    check_unseen_tracks,
    check_window,
    feature_spec,
    replaced_settings,
    train_surrogate,
)
from railsusp.surrogate.keys import key_parameters, not_estimated, unexplained_parameters
from railsusp.surrogate.models import KINDS
from railsusp.surrogate.split import Split, campaign_split
from railsusp.surrogate.train import TrainConfig
from railsusp.variation import assumed_parameters

__all__ = [
    "KINDS",
    "Split",
    "Surrogate",
    "TrainConfig",
    "assumed_parameters",
    "campaign_split",
    "check_conditions",
    "check_unseen_tracks",
    "check_window",
    "evaluate",
    "feature_spec",
    "key_parameters",
    "load",
    "not_estimated",
    "replaced_settings",
    "train_surrogate",
    "unexplained_parameters",
]
