"""The nominal wagon's forces on a track: an input that carries the track's whole effect.

A window network reads 0.4 s of track, but the lateral force on tangent remembers 3-5 s of
irregularities (the wheelsets' kinematic motion, 15-20 m wavelength): the study's window
CNN-GRU trained on 2048 tracks explains R² 0.54-0.56 of the tangent and grade lateral series
of held-out runs. The same wagon with every parameter at its nominal value, simulated on the
same track, explains 0.88-0.89 there (0.96 in the curve) with no network at all
(bench/README.md, Table 7 of the current model, row "nominal wagon alone"). A surrogate with
:attr:`~railsusp.surrogate.data.FeatureSpec.nominal_response` reads that nominal response as
one more input and learns only what the parameters change: its target is the force minus
the nominal force, added back when it predicts (measured: lateral R² 0.91 on tangent and
grade, 0.98 in the curve). The price is one simulation of the nominal wagon per track (per
recording and condition, seconds), not per parameter set.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.params import ParameterSet
from railsusp.vehicle.simulate import SolverSettings, measured_wheel_index, simulate_batch
from railsusp.vehicle.wagon import WagonData


def nominal_forces(
    condition: WorkingCondition,
    seed: int,
    wagon: WagonData,
    targets: Sequence[str] = ("Y", "Q"),
    settings: SolverSettings | None = None,
) -> np.ndarray:
    """(T, len(targets)) forces of the measured wheel (kN, the campaign's automatic choice
    of wheel) of the nominal wagon on ``condition``'s track with irregularity ``seed`` (its
    measured geometry where it carries one)."""
    r = simulate_batch(
        [ParameterSet.nominal()],
        condition.with_changes(seed=seed),
        seeds=[seed],
        wagon=wagon,
        settings=settings,
    )
    if int(r.status[0]) != 0:
        raise ValueError(
            f"the nominal wagon's simulation on condition {condition.name!r} failed "
            f"(status {int(r.status[0])}): no nominal response to read"
        )
    j = measured_wheel_index(condition, "auto")
    series = {"Y": r.Y[0, j], "Q": r.Q[0, j]}
    return np.stack([series[t] / 1e3 for t in targets], axis=1)
