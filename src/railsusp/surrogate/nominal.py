"""The nominal wagon's forces on a track: an input that carries the track's whole effect.

A window network reads 0.4 s of track, but the lateral force on tangent remembers 3-5 s of
irregularities (the wheelsets' kinematic motion, 15-20 m wavelength): the study's window
CNN-GRU trained on 2048 tracks explains R² 0.54-0.56 of the tangent and grade lateral series
of held-out runs. The same wagon with every parameter at its nominal value, simulated on the
same track, explains 0.88-0.89 there (0.96 in the curve) with no network at all
(bench/README.md, Table 7 of the current model, row "nominal wagon alone"). A surrogate with
:attr:`~railsusp.surrogate.features.FeatureSpec.nominal_response` reads that nominal response as
one more input and learns only what the parameters change: its target is the force minus
the nominal force, added back when it predicts (measured: lateral R² 0.91 on tangent and
grade, 0.98 in the curve). The price is one simulation of the nominal wagon per track (per
recording and condition, seconds), not per parameter set.

:attr:`~railsusp.surrogate.features.FeatureSpec.nominal_context` adds more of the nominal
wagon's response as inputs (the forces at all eight wheels and the car body's
accelerations, :data:`CONTEXT_CHANNELS`): what a parameter changes depends on the bogie's
motion (a yaw resistance acts on the bogie's yaw, a primary stiffness on the wheelset's
displacement in the frame), which the measured wheel's two forces show only in part, and
the other wheelsets' forces show more of it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from railsusp.campaign.design import CHANNELS
from railsusp.conditions import WorkingCondition
from railsusp.params import ParameterSet
from railsusp.vehicle.simulate import SolverSettings, simulate_requests
from railsusp.vehicle.simulation_result import WHEEL_NAMES, measured_wheel_index
from railsusp.vehicle.wagon import WagonData

#: the nominal wagon's channels a network may read as context: every channel a campaign
#: (and so its nominal twins) stores, kN for forces, m/s² for accelerations
CONTEXT_CHANNELS = CHANNELS


def check_context(channels: Sequence[str]) -> tuple[str, ...]:
    """The context channels as a tuple, refused in one line where one is not a channel."""
    bad = [c for c in channels if c not in CONTEXT_CHANNELS]
    if bad:
        raise ValueError(f"nominal_context {bad}: accepted channels {', '.join(CONTEXT_CHANNELS)}")
    return tuple(channels)


def nominal_forces(
    condition: WorkingCondition,
    seed: int,
    wagon: WagonData,
    targets: Sequence[str] = ("Y", "Q"),
    settings: SolverSettings | None = None,
    context: Sequence[str] = (),
) -> np.ndarray:
    """(T, len(context) + len(targets)): the ``context`` channels (:data:`CONTEXT_CHANNELS`,
    kN and m/s²), then the forces of the measured wheel (kN, the campaign's automatic choice
    of wheel), of the nominal wagon on ``condition``'s track with irregularity ``seed`` (its
    measured geometry where it carries one)."""
    return nominal_forces_many([(condition, seed)], wagon, targets, settings, context)[0]


def nominal_forces_many(
    tracks: Sequence[tuple[WorkingCondition, int]],
    wagon: WagonData,
    targets: Sequence[str] = ("Y", "Q"),
    settings: SolverSettings | None = None,
    context: Sequence[str] = (),
) -> list[np.ndarray]:
    """:func:`nominal_forces` on each (condition, seed) of ``tracks``, the simulations in as
    few parallel calls as their integrator settings allow
    (:func:`~railsusp.vehicle.simulate.simulate_requests`): the draws of a measured
    geometry's error, each its own track, keep every core busy instead of one."""
    names = (*check_context(context), *targets)
    results = simulate_requests(
        [
            ([ParameterSet.nominal()], condition.with_changes(seed=seed), [seed])
            for condition, seed in tracks
        ],
        wagon=wagon,
        settings=settings,
    )
    out = []
    for (condition, _), r in zip(tracks, results, strict=True):
        if int(r.status[0]) != 0:
            raise ValueError(
                f"the nominal wagon's simulation on condition {condition.name!r} failed "
                f"(status {int(r.status[0])}): no nominal response to read"
            )
        j = measured_wheel_index(condition, "auto")
        series = {"Y": r.Y[0, j] / 1e3, "Q": r.Q[0, j] / 1e3}
        for i, w in enumerate(WHEEL_NAMES):
            series[f"Y_{w}"], series[f"Q_{w}"] = r.Y[0, i] / 1e3, r.Q[0, i] / 1e3
        series["car_acc_y"], series["car_acc_z"] = r.car_acc_y[0], r.car_acc_z[0]
        out.append(np.stack([np.asarray(series[c], dtype=float) for c in names], axis=1))
    return out
