"""Simulation: parameter sets + working condition + wagon data -> wheel-rail force time series.

``simulate(params, condition)`` runs one set; ``simulate_batch(matrix, condition)`` runs many
at once in compiled, parallel code (one thread per core). Both return a
:class:`~railsusp.vehicle.simulation_result.SimulationResult` with, per wheel, the lateral
force Y and vertical force Q on the rail, and derived wheelset lateral force H, derailment
quotient Y/Q, wheel-unloading ratio dQ/Q and car-body accelerations, sampled at the
condition's output rate after a causal anti-alias filter. Sets that diverge or reach a
non-physical state are flagged with the reason and carry NaN series; they never disturb the
other sets of the batch.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_whole
from railsusp.params import SYMBOLS, ParameterSet, check_matrix, spec
from railsusp.vehicle import layout as L
from railsusp.vehicle.setup import SolverSettings, contact_arrays
from railsusp.vehicle.simulation_result import SimulationResult
from railsusp.vehicle.wagon import WagonData, load_wagon


# ---------------------------------------------------------------- entry points
def _param_matrix(sets: np.ndarray | Iterable[ParameterSet], symbols: Sequence[str] | None):
    """Full (n, 20) SI matrix from ParameterSets, or from a matrix over ``symbols``; other
    input (a dict, a list of lists, a matrix of other than 20 columns without ``symbols``)
    is a one-line error naming the argument."""
    accepted = "accepted ParameterSets, or an SI matrix (n_sets, len(symbols)) with symbols="
    if isinstance(sets, ParameterSet):
        sets = [sets]
    elif sets is None or isinstance(sets, Mapping | str | bytes):
        raise RailsuspInputError(
            f"sets: a {type(sets).__name__} is not a parameter set; {accepted} (a dict of "
            "display values: ParameterSet(values, units='display'))"
        )
    if isinstance(symbols, str) or (
        symbols is not None and not all(isinstance(s, str) for s in symbols)
    ):
        raise RailsuspInputError(f"symbols = {symbols!r}: accepted a list of symbols (X13, ...)")
    if isinstance(sets, np.ndarray) or (symbols is not None):
        syms = list(symbols) if symbols is not None else list(SYMBOLS)
        try:
            given = np.asarray(sets)
        except (TypeError, ValueError):
            raise RailsuspInputError(
                "sets: not a matrix of numbers (rows of unequal length?); " + accepted
            ) from None
        if given.dtype.kind not in "iuf":  # text ("1.61e7") or complex: not converted
            what = {"U": "text", "S": "bytes", "c": "complex numbers", "b": "booleans"}
            raise RailsuspInputError(
                f"sets: a matrix of {what.get(given.dtype.kind, str(given.dtype))}; accepted "
                "real numbers (SI), not converted. " + accepted
            )
        given = given.astype(float)
        shape = given.shape
        if symbols is None and (len(shape) not in (1, 2) or shape[-1] != len(SYMBOLS)):
            raise RailsuspInputError(
                f"sets: a matrix of shape {shape} without symbols=; a matrix of all "
                f"{len(SYMBOLS)} parameters X1..X20 has {len(SYMBOLS)} columns, others need "
                "symbols=[...] naming its columns"
            )
        if 0 in shape:
            raise RailsuspInputError("sets: no parameter sets given (an empty matrix)")
        x = (
            check_matrix(syms, np.atleast_2d(given))
            if syms != list(SYMBOLS)
            else np.atleast_2d(given)
        )
        full = np.tile(ParameterSet.nominal().to_array(), (x.shape[0], 1))
        for j, s in enumerate(syms):
            full[:, SYMBOLS.index(spec(s).symbol)] = x[:, j]
        if syms == list(SYMBOLS):
            for i in range(full.shape[0]):  # validate every row as a full set
                ParameterSet(dict(zip(SYMBOLS, full[i], strict=True)))
        return full
    rows = list(sets)
    if not rows:
        raise RailsuspInputError("no parameter sets given")
    wrong = next((r for r in rows if not isinstance(r, ParameterSet)), None)
    if wrong is not None:
        raise RailsuspInputError(f"sets: an item {wrong!r} is not a ParameterSet; {accepted}")
    return np.array([p.to_array() for p in rows])


def simulate_batch(
    sets: np.ndarray | Iterable[ParameterSet],
    condition: WorkingCondition,
    *,
    symbols: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    wagon: WagonData | None = None,
    settings: SolverSettings | None = None,
    progress: Callable[[int, int], None] | None = None,
    chunk_size: int = 32,
) -> SimulationResult:
    """Simulate N parameter sets in one condition, in parallel.

    ``sets``: ParameterSets, or an (N, len(symbols)) SI matrix of the parameters in
    ``symbols`` (others nominal), or (N, 20) for all. ``seeds``: one irregularity seed per
    set (default: the condition's seed for every set, i.e. common random numbers).
    ``progress(done, total)`` is called after each chunk of ``chunk_size`` sets.
    """
    return simulate_conditions(
        sets,
        [condition],
        symbols=symbols,
        seeds=seeds,
        wagon=wagon,
        settings=settings,
        progress=progress,
        chunk_size=chunk_size,
    )[0]


def simulate_conditions(
    sets: np.ndarray | Iterable[ParameterSet],
    conditions: Sequence[WorkingCondition],
    *,
    symbols: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    wagon: WagonData | None = None,
    settings: SolverSettings | None = None,
    progress: Callable[[int, int], None] | None = None,
    chunk_size: int = 32,
) -> list[SimulationResult]:
    """Simulate the same N parameter sets in each of several conditions, one result per
    condition, each equal to :func:`simulate_batch`'s in that condition.

    Conditions whose integrator settings agree (the study's three at 60 km/h do) share the
    compiled integrator's parallel calls (:mod:`railsusp.vehicle.batch_runs`), so a few sets
    in three conditions keep every core busy. Arguments as :func:`simulate_batch`; ``seeds``
    apply in every condition; ``progress`` counts the sets of all conditions;
    ``wall_time`` of each result is its preparation and the calls its sets were in.
    """
    if isinstance(conditions, WorkingCondition | str):
        raise RailsuspInputError(
            f"conditions = {conditions!r}: accepted a list of one or more WorkingConditions"
        )
    if not conditions:
        raise RailsuspInputError("conditions: none given, accepted at least one")
    P = np.ascontiguousarray(_param_matrix(sets, symbols))
    return _simulate_full(
        [(P, c, seeds) for c in conditions], wagon, settings, progress, chunk_size
    )


#: one request of :func:`simulate_requests`: parameter sets (ParameterSets or an SI matrix
#: over the call's ``symbols``), the condition they run in, their irregularity seeds or None
Request = tuple[np.ndarray | Iterable[ParameterSet], WorkingCondition, Sequence[int] | None]


def simulate_requests(
    requests: Sequence[Request],
    *,
    symbols: Sequence[str] | None = None,
    wagon: WagonData | None = None,
    settings: SolverSettings | None = None,
    progress: Callable[[int, int], None] | None = None,
    chunk_size: int = 32,
) -> list[SimulationResult]:
    """Simulate several requests, each its own (sets, condition, seeds), one result per
    request, each equal to :func:`simulate_batch`'s of that request.

    Requests whose integrator settings agree share the compiled integrator's parallel calls
    (:mod:`railsusp.vehicle.batch_runs`): the samples of a many-track campaign batch that
    each run on their own curve radius and cant (one request per layout) then keep every core
    busy, where one :func:`simulate_batch` per layout ran them one at a time. ``progress``
    counts the sets of all requests; ``wall_time`` of each result is its preparation and the
    calls its sets were in."""
    if not requests:
        raise RailsuspInputError("requests: none given, accepted at least one")
    prepared = [
        (np.ascontiguousarray(_param_matrix(sets, symbols)), cond, seeds)
        for sets, cond, seeds in requests
    ]
    return _simulate_full(prepared, wagon, settings, progress, chunk_size)


def _simulate_full(
    prepared: Sequence[tuple[np.ndarray, WorkingCondition, Sequence[int] | None]],
    wagon: WagonData | None,
    settings: SolverSettings | None,
    progress: Callable[[int, int], None] | None,
    chunk_size: int,
) -> list[SimulationResult]:
    """:func:`simulate_requests` of requests whose sets are full (n, 20) SI matrices; the
    conditions, ``wagon`` (a WagonData, a wagon file or None) and ``settings`` checked."""
    from railsusp.vehicle.batch_runs import integrate_conditions

    if progress is not None and not callable(progress):
        raise RailsuspInputError(f"progress = {progress!r}: accepted a function (done, total)")
    if not is_whole(chunk_size) or chunk_size < 1:
        raise RailsuspInputError(
            f"chunk_size = {chunk_size!r}: accepted a whole number >= 1 (sets per parallel call)"
        )
    for _, cond, _ in prepared:
        if not isinstance(cond, WorkingCondition):
            raise RailsuspInputError(
                f"condition {cond!r}: a WorkingCondition is needed "
                "(railsusp.get_condition('curve'), or a list of them where conditions go)"
            )
    wagon = load_wagon(wagon) if wagon is None or isinstance(wagon, str | Path) else wagon
    if not isinstance(wagon, WagonData):
        raise RailsuspInputError(f"wagon = {wagon!r}: accepted a WagonData, a wagon file or None")
    _warn_unmodelled([P for P, _, _ in prepared])
    settings = SolverSettings() if settings is None else settings
    if not isinstance(settings, SolverSettings):
        raise RailsuspInputError(
            f"settings = {settings!r}: accepted a railsusp.vehicle.setup.SolverSettings or None"
        )
    ca = contact_arrays(wagon)
    if ca.contact_points == 1 and settings.flange_substeps == 1:
        warnings.warn(
            "single-point wheel-rail contact with the plain step: its jump to the flange needs "
            "SolverSettings(flange_substeps=2) to stay numerically on the rail (docs/model.md)",
            stacklevel=3,
        )
    runs = integrate_conditions(prepared, wagon, settings, ca, progress, chunk_size)
    return [
        SimulationResult(
            condition=r.condition,
            params=P,
            time=np.arange(r.condition.n_steps) * r.condition.sample_interval,
            Y=r.out[:, L.OUT_Y : L.OUT_Y + 8],
            Q=r.out[:, L.OUT_Q : L.OUT_Q + 8],
            car_acc_y=r.out[:, L.OUT_ACC_Y],
            car_acc_z=r.out[:, L.OUT_ACC_Z],
            status=r.status,
            fail_time=r.fail_time,
            static_wheel_load=_static_load(r.K[:, L.K["Q0"]]),
            wall_time=r.wall_time,
            settings=settings,
            wagon_name=wagon.name,
            settled_start=r.settled,
        )
        for r, (P, _, _) in zip(runs, prepared, strict=True)
    ]


#: catalogue parameters the model does not read: the bearing adapter's mass and inertias
#: (the study's Table 1 lists them; the model has no adapter body, its seat is the
#: stiffness X20 between pad and side frame, docs/parameters.md)
UNMODELLED = ("X5", "X6", "X7", "X8")


def _warn_unmodelled(matrices: Sequence[np.ndarray]) -> None:
    """Warn where a set gives an unmodelled parameter (:data:`UNMODELLED`) another value
    than its nominal: it changes nothing, which an engineer setting X5 would not expect."""
    cols = [SYMBOLS.index(s) for s in UNMODELLED]
    nominal = ParameterSet.nominal().to_array()[cols]
    changed = sorted(
        {UNMODELLED[j] for P in matrices for j in np.flatnonzero((P[:, cols] != nominal).any(0))}
    )
    if changed:
        warnings.warn(
            f"{', '.join(changed)} changed from nominal: the model has no bearing-adapter "
            "body, so X5-X8 change no force (docs/parameters.md)",
            stacklevel=4,
        )


def _static_load(q0: np.ndarray) -> float | np.ndarray:
    """The sets' static wheel load (N): one number where they share it, else per set (a
    batch varying the wheelset mass X1: dQ/Q of every set was taken against the first's)."""
    return float(q0[0]) if np.all(q0 == q0[0]) else np.array(q0, dtype=float)


def simulate(
    params: ParameterSet | None, condition: WorkingCondition, **kwargs
) -> SimulationResult:
    """Simulate one parameter set (nominal if None) in one condition."""
    if params is not None and not isinstance(params, ParameterSet):
        raise RailsuspInputError(
            f"params: a {type(params).__name__} is not a ParameterSet; give "
            "ParameterSet(values) (SI) or ParameterSet(values, units='display'), or None"
        )
    return simulate_batch([params or ParameterSet.nominal()], condition, **kwargs)
