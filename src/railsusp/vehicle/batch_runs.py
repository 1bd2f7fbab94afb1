"""The integrator's calls: the parameter sets of one or several working conditions in as few
parallel calls as their numerics allow.

The compiled integrator (:func:`~railsusp.vehicle.integrate.integrate_batch`) runs the sets of
one call in parallel, one per core, each on its own track (an index into a stack of track
channels) from its own initial state. Sets of *different* conditions can therefore share a
call whenever the integrator's scalars agree: internal step and sub-steps, output samples,
start position and steps before the record, the track grid and the output filter. The three
study conditions at 60 km/h with the same record length do. An estimate that simulates one
or two parameter sets on each of three recordings (a least-squares trial point) then keeps
both cores busy with three to six sets instead of one core with one or two.

Every set's numbers are those it gets alone: the integrator treats the sets of a call
independently (tests/vehicle/test_batch_runs.py compares bit for bit).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import butter

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.vehicle import layout as L
from railsusp.vehicle.settle import StartPlan, lead_in_plan, settled_states, start_plan
from railsusp.vehicle.setup import ContactArrays, SolverSettings, constants
from railsusp.vehicle.step_bound import set_steps
from railsusp.vehicle.track_grid import track_arrays
from railsusp.vehicle.wagon import WagonData


@dataclass
class ConditionRuns:
    """The integrator's output for the sets of one condition (SI), filled by
    :func:`integrate_conditions`: series (n, N_OUT, n_out), failure code and time (from the
    section start) per set, whether each set started settled, the wall time of the calls
    its sets were in."""

    condition: WorkingCondition
    P: np.ndarray  # (n, 20) parameter sets
    K: np.ndarray  # (n, N_K) constants
    out: np.ndarray
    status: np.ndarray
    fail_time: np.ndarray
    settled: np.ndarray
    wall_time: float = 0.0


@dataclass
class _Part:
    """Sets of one condition that start alike: what one integrator call needs for them."""

    runs: ConditionRuns
    sets: np.ndarray  # indices into runs
    X0: np.ndarray  # (len(sets), N_STATE) initial states
    tracks: np.ndarray  # (n_tracks, N_TR, n_s) track channels
    track_index: np.ndarray  # (len(sets),) into tracks
    s0: float
    ds: float
    start: StartPlan
    dt: float
    n_sub: int
    sos: np.ndarray

    def key(self) -> tuple:
        """Parts with equal keys can share one call: the integrator's scalar arguments."""
        return (
            self.dt,
            self.n_sub,
            self.runs.out.shape[2],
            self.start.s_start,
            self.start.n_pre,
            self.s0,
            self.ds,
            self.tracks.shape[1:],
            self.sos.tobytes(),
        )


def _track_seeds(
    condition: WorkingCondition, seeds: Sequence[int] | None, n: int
) -> tuple[list[int], np.ndarray]:
    """The distinct irregularity seeds and each set's index into them (default: the
    condition's seed for every set, i.e. common random numbers)."""
    if seeds is None:
        return [condition.seed], np.zeros(n, dtype=np.int64)
    given = np.asarray(seeds) if not isinstance(seeds, str | bytes) else np.asarray(None)
    if given.ndim != 1 or not (
        np.issubdtype(given.dtype, np.integer) and not np.issubdtype(given.dtype, np.bool_)
    ):
        raise RailsuspInputError(
            f"seeds = {seeds!r}: accepted a list of integers, one per parameter set"
        )
    if len(given) != n:
        raise RailsuspInputError(f"seeds: {len(given)} given for {n} parameter sets")
    if (given < 0).any():
        raise RailsuspInputError(f"seeds: {int(given.min())} given; accepted integers >= 0")
    distinct, inverse = np.unique(given.astype(np.int64), return_inverse=True)
    return list(distinct), inverse.astype(np.int64)


def _parts(
    P: np.ndarray,
    condition: WorkingCondition,
    seeds: Sequence[int] | None,
    wagon: WagonData,
    settings: SolverSettings,
    ca: ContactArrays,
) -> tuple[ConditionRuns, list[_Part]]:
    """One condition's sets prepared: their output arrays and their parts (the settled start
    for the sets whose steady state solves, where it applies; the lead-in for the rest)."""
    t0 = time.perf_counter()
    n = P.shape[0]
    K = np.ascontiguousarray(
        np.stack([constants(wagon, condition, P[i], ca, settings) for i in range(n)])
    )
    track_seeds, track_index = _track_seeds(condition, seeds, n)
    dt_out = condition.sample_interval
    runs = ConditionRuns(
        condition=condition,
        P=P,
        K=K,
        out=np.zeros((n, L.N_OUT, condition.n_steps)),
        status=np.zeros(n, dtype=np.int64),
        fail_time=np.zeros(n),
        settled=np.zeros(n, dtype=bool),
    )
    # each set at its own stable step (its masses'), the sets of one step in their parts:
    # a set's forces are those it gets alone, whatever else its batch holds
    steps = set_steps(wagon, condition.speed_kmh, P, settings.max_step)
    n_subs = np.maximum(1, np.ceil(dt_out / steps - 1e-9)).astype(np.int64)
    parts = []
    for n_sub in np.unique(n_subs):
        group = np.flatnonzero(n_subs == n_sub)
        dt = dt_out / int(n_sub)
        sos = np.ascontiguousarray(
            butter(
                settings.filter_order, settings.anti_alias * 0.5 / dt_out, fs=1.0 / dt, output="sos"
            )
        )
        plan = start_plan(condition, wagon, settings, dt)
        if plan.settled:
            tracks, s0, ds = track_arrays(
                condition, track_seeds, wagon, settings, **plan.track_options
            )
            X0, ok = settled_states(P[group], K[group], tracks[0], s0, ds, ca, plan.s_start)
            runs.settled[group] = ok
            idx = group[ok]
            parts.append(
                _Part(
                    runs, idx, X0[ok], tracks, track_index[idx], s0, ds, plan, dt, int(n_sub), sos
                )
            )
        rest = group[~runs.settled[group]]  # the lead-in, or where the solve failed
        if rest.size:
            tracks, s0, ds = track_arrays(condition, track_seeds, wagon, settings)
            X0 = np.zeros((rest.size, L.N_STATE))  # static equilibrium on straight track
            lead = lead_in_plan(condition, dt)
            parts.append(
                _Part(runs, rest, X0, tracks, track_index[rest], s0, ds, lead, dt, int(n_sub), sos)
            )
    runs.wall_time = time.perf_counter() - t0
    return runs, [p for p in parts if p.sets.size]


def _integrate(
    parts: list[_Part],
    ca: ContactArrays,
    flange_substeps: int,
    chunk: int | None,
    on_chunk: Callable[[int], None],
) -> None:
    """Integrate parts of equal key in one call per chunk of their concatenated sets and
    write each set's results into its condition's arrays."""
    from railsusp.vehicle.integrate import integrate_batch

    first = parts[0]
    P = np.concatenate([p.runs.P[p.sets] for p in parts])
    K = np.concatenate([p.runs.K[p.sets] for p in parts])
    X0 = np.concatenate([p.X0 for p in parts])
    offsets = np.cumsum([0] + [p.tracks.shape[0] for p in parts[:-1]])
    tracks = np.ascontiguousarray(np.concatenate([p.tracks for p in parts]))
    track_index = np.concatenate([p.track_index + o for p, o in zip(parts, offsets, strict=True)])
    n, n_out = P.shape[0], first.runs.out.shape[2]
    out, status = unfinished(n, n_out)
    fail_time = np.zeros(n)
    step = n if chunk is None else max(1, chunk)
    for lo in range(0, n, step):
        sl = slice(lo, min(n, lo + step))
        o, st, ft = out[sl], status[sl], fail_time[sl]  # views: the call fills them
        integrate_batch(
            np.ascontiguousarray(P[sl]),
            np.ascontiguousarray(K[sl]),
            np.ascontiguousarray(X0[sl]),
            tracks,
            np.ascontiguousarray(track_index[sl]),
            first.s0,
            first.ds,
            ca.table,
            ca.y0,
            ca.dy,
            ca.H0L,
            ca.H0R,
            first.dt,
            first.start.s_start,
            first.start.n_pre,
            first.n_sub,
            n_out,
            first.sos,
            flange_substeps,
            o,
            st,
            ft,
        )
        on_chunk(sl.stop - sl.start)
    lo = 0
    for p in parts:
        sl = slice(lo, lo + p.sets.size)
        runs = p.runs
        runs.out[p.sets], runs.status[p.sets] = out[sl], status[sl]
        # from the section start, whichever start the set had
        runs.fail_time[p.sets] = fail_time[sl] + p.start.s_start / runs.condition.speed
        lo = sl.stop


def unfinished(n: int, n_out: int) -> tuple[np.ndarray, np.ndarray]:
    """The outputs (NaN) and statuses (``FAIL_UNFINISHED``) of ``n`` sets before the
    integrator's call, which writes each set's own on finishing it: a set it did not finish
    (an error inside its parallel loop, not passed on by Numba) reads as failed."""
    return np.full((n, L.N_OUT, n_out), np.nan), np.full(n, L.FAIL_UNFINISHED, dtype=np.int64)


def integrate_conditions(
    requests: Sequence[tuple[np.ndarray, WorkingCondition, Sequence[int] | None]],
    wagon: WagonData,
    settings: SolverSettings,
    ca: ContactArrays,
    progress: Callable[[int, int], None] | None = None,
    chunk_size: int = 32,
) -> list[ConditionRuns]:
    """Integrate every request, (P (n, 20) SI, condition, seeds or None), in as few calls as
    the integrator allows (module docstring); one :class:`ConditionRuns` per request.

    ``progress(done, total)`` is called after each chunk of ``chunk_size`` sets (without
    it, each call takes all its sets at once)."""
    prepared = [_parts(np.ascontiguousarray(P), c, s, wagon, settings, ca) for P, c, s in requests]
    groups: dict[tuple, list[_Part]] = {}
    for _, parts in prepared:
        for part in parts:
            groups.setdefault(part.key(), []).append(part)
    total = sum(r.P.shape[0] for r, _ in prepared)
    done = 0

    def on_chunk(size: int) -> None:
        nonlocal done
        done += size
        if progress is not None:
            progress(done, total)

    chunk = None if progress is None else chunk_size
    for parts in groups.values():
        t0 = time.perf_counter()
        _integrate(parts, ca, settings.flange_substeps, chunk, on_chunk)
        wall = time.perf_counter() - t0
        for runs in {id(p.runs): p.runs for p in parts}.values():
            runs.wall_time += wall
    return [r for r, _ in prepared]
