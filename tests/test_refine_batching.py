"""The refinement's simulations in batches: solvers in lockstep, batched Jacobians, screened
series reused. Batching changes how simulations are grouped, never the numbers."""

import threading

import numpy as np
import pytest
from scipy.stats import qmc

from railsusp.conditions import get_condition
from railsusp.estimate import NSGAConfig, aligned_cost, estimate, refine_estimate
from railsusp.estimate.lockstep import Lockstep
from railsusp.estimate.output_error import OutputError
from railsusp.estimate.refine import refine, refine_starts
from railsusp.measured.synthetic import recording_from_simulation
from railsusp.params import ParameterSet, bounds
from railsusp.vehicle.simulate import simulate_batch
from railsusp.vehicle.track import synthesise
from railsusp.vehicle.track_geometry import write_track_geometry
from test_estimate import PARAMS, WaveForces, wave_recording

TRUTH = np.array([16.1e6, 8.3e6])


class Counting(WaveForces):
    """WaveForces that records every call: its parameter sets (bytes) and batch size."""

    def __init__(self):
        self.asked: list[bytes] = []
        self.sizes: list[int] = []
        self._lock = threading.Lock()

    def series(self, x_si, condition):
        with self._lock:  # the solvers' threads call it, one at a time by design
            rows = np.atleast_2d(x_si)
            self.asked += [row.tobytes() for row in rows]
            self.sizes.append(len(rows))
        return super().series(x_si, condition)


# ------------------------------------------------------------------ Lockstep
def test_lockstep_serves_the_requests_of_all_running_solvers_in_one_call():
    """Three solvers asking 3, 2 and 1 times: the rounds hold 3, 2, then 1 requests; each
    solver gets its own answers; a request outside a run is served alone at once."""
    answers: dict[tuple[int, int], int] = {}

    def serve(items):
        for solver, step in items:
            answers[(solver, step)] = 10 * solver + step

    lock = Lockstep(serve)

    def solver(i: int, steps: int):
        def run():
            got = []
            for s in range(steps):
                lock.request((i, s))
                got.append(answers[(i, s)])
            return got

        return run

    out = lock.run([solver(0, 3), solver(1, 2), solver(2, 1)])
    assert out == [[0, 1, 2], [10, 11], [20]]
    assert lock.batches == [3, 2, 1]
    lock.request((9, 0))
    assert answers[(9, 0)] == 90 and lock.batches == [3, 2, 1, 1]


def test_lockstep_hands_a_serving_error_to_every_solver_of_its_round():
    def serve(items):
        raise RuntimeError(f"simulator broke on {len(items)} requests")

    lock = Lockstep(serve)
    seen: list[str] = []

    def solver():
        try:
            lock.request(0)
        except RuntimeError as exc:
            seen.append(str(exc))
            raise

    with pytest.raises(RuntimeError, match="simulator broke on 2 requests"):
        lock.run([solver, solver])
    assert seen == ["simulator broke on 2 requests"] * 2
    # a solver failing on its own leaves the other to go on alone, then is raised
    lock = Lockstep(lambda items: None)

    def fails():
        raise ValueError("start 1 diverged")

    def goes_on():
        for _ in range(3):
            lock.request(0)
        return "done"

    with pytest.raises(ValueError, match="start 1 diverged"):
        lock.run([fails, goes_on])
    assert lock.batches == [1, 1, 1]


# ------------------------------------------------------------------ the simulator
@pytest.fixture(scope="module")
def on_measured_track(tmp_path_factory):
    """A short recording of the simulator on a measured track (nominal wagon, the truth)."""
    folder = tmp_path_factory.mktemp("track")
    geometry = write_track_geometry(
        folder / "g.csv", synthesise(100.0, 5, 3, start=-40.0, dx=0.125)
    )
    cond = get_condition(
        "straight", duration_s=1.0, n_steps=50, lead_in_m=20.0, track_geometry=str(geometry)
    )
    return recording_from_simulation(simulate_batch([ParameterSet.nominal()], cond))


def test_a_batched_jacobian_equals_the_column_by_column_one(on_measured_track):
    """The simulator integrates each set on its own, so k + 1 sets in one call give, bit for
    bit, the series of k + 1 calls of one set, and the Jacobian built from either is the
    same."""
    from railsusp.estimate import SimulatorForces

    rec = on_measured_track
    model = SimulatorForces(PARAMS)
    batched = OutputError(model, [rec], PARAMS, gains=True)
    single = OutputError(model, [rec], PARAMS, gains=True)
    z = np.array([0.3, 0.6, 1.0, 1.0])
    steps = batched.steps(z[:2])
    alone = [single.predictions(row) for row in steps]  # one simulation per call
    together = batched.predictions(steps)  # one call of k + 1 sets
    np.testing.assert_array_equal(together[0], np.concatenate([a[0] for a in alone]))
    assert single.lockstep.batches == [1, 1, 1] and batched.lockstep.batches == [1]
    np.testing.assert_array_equal(
        batched.jacobian_of(together, z), single.jacobian_of(single.predictions(steps), z)
    )
    raw = model.series(batched.lo + steps * (batched.hi - batched.lo), rec.condition)
    for i, row in enumerate(steps):
        np.testing.assert_array_equal(
            raw[i],
            model.series(batched.lo + row[None] * (batched.hi - batched.lo), rec.condition)[0],
        )


def test_starts_refined_in_step_with_the_simulator_match_each_start_alone(on_measured_track):
    """Two starts in lockstep (their simulations in shared batches, from solver threads)
    end exactly where each ends refined alone."""
    from railsusp.estimate import SimulatorForces

    rec = on_measured_track
    model = SimulatorForces(PARAMS)
    lo, hi = bounds(PARAMS)
    starts = [lo + 0.3 * (hi - lo), lo + [0.7, 0.4] * (hi - lo)]
    problem = OutputError(model, [rec], PARAMS, gains=False)
    together = refine_starts(problem, starts, max_evaluations=3)
    assert max(problem.lockstep.batches) == 2  # the starts' requests went out together
    for start, run in zip(starts, together, strict=True):
        alone = refine(model, [rec], PARAMS, start, max_evaluations=3, gains=False)
        np.testing.assert_array_equal(run.x_si, alone.x_si)
        np.testing.assert_array_equal(run.standard_error_si, alone.standard_error_si)
        assert (run.cost, run.n_evaluations, run.n_jacobians) == (
            alone.cost,
            alone.n_evaluations,
            alone.n_jacobians,
        )


# ------------------------------------------------------------------ refine_estimate
def test_refine_estimate_batches_its_starts_and_simulates_no_set_twice():
    """The screen simulates each distinct candidate once (the chosen point is also on the
    Pareto set), the starts' own series come from the screen, and the two starts' trial
    points share calls; the refined results are those of the starts refined one by one."""
    rec = wave_recording(TRUTH, noise=0.05, seed=3)
    res = estimate(
        WaveForces(), [rec], PARAMS, NSGAConfig(pop_size=10, n_gen=3, statistic="aligned")
    )
    counting = Counting()
    refine_estimate(res, [rec], counting, gains=False, screen=16, starts=2, geometry_draws=0)
    ref = res.refinement
    assert len(counting.asked) == len(set(counting.asked))  # no set simulated twice
    candidates = np.vstack([res.pareto_x[res.chosen][None], res.pareto_x])
    assert counting.sizes[0] == len(np.unique(candidates, axis=0)) + 1 + 16  # + nominal, LHS
    assert 2 in counting.sizes[1:]  # trial points of both starts in one call
    # the same starts, screened and refined one by one as before the batching
    lo, hi = bounds(PARAMS)
    nominal = np.array([ParameterSet.nominal()[p] for p in PARAMS])
    lhs = qmc.LatinHypercube(d=2, seed=0).random(16)
    everything = np.vstack([candidates, nominal[None], lo + lhs * (hi - lo)])
    first = np.sort(np.unique(everything, axis=0, return_index=True)[1])
    everything = everything[first]  # each distinct start once (the choice is on the Pareto set)
    costs = aligned_cost(WaveForces(), [rec], PARAMS, everything)
    assert [st["screened_cost"] for st in ref.starts] == sorted(costs)[:2]
    for i, st in zip(np.argsort(costs, kind="stable")[:2], ref.starts, strict=True):
        alone = refine(WaveForces(), [rec], PARAMS, everything[i], gains=False, geometry_draws=0)
        assert alone.cost == st["cost"]
        assert alone.to_dict()["refined_display"] == st["refined_display"]
    assert ref.cost == min(st["cost"] for st in ref.starts)
    assert np.all(np.abs(ref.x_si - TRUTH) / (hi - lo) < 0.01)


def test_screened_series_are_reused_only_where_they_are_exact():
    """remember() keeps a screened set only where the unit coordinates map back to it bit
    for bit (what the refinement would simulate), and the screen's cost is aligned_cost's."""
    rec = wave_recording(TRUTH)
    lo, hi = bounds(PARAMS)
    problem = OutputError(WaveForces(), [rec], PARAMS, gains=False)
    inside = lo + np.array([[0.25, 0.5], [0.1, 0.9]]) * (hi - lo)
    outside = hi[None] * 1.5  # clipped to the range: not the set simulated
    x = np.vstack([inside, outside])
    exact = np.all(lo + (x - lo) / (hi - lo) * (hi - lo) == x, axis=1)
    kept = problem.remember(x, [WaveForces().series(x, rec.condition)])
    assert kept == int(exact[:2].sum()) and kept >= 1
    assert problem.remember(x, [WaveForces().series(x, rec.condition)]) == 0  # once only
    u = np.clip((x - lo) / (hi - lo), 0, 1)
    counting = Counting()
    problem.model = counting
    problem.predictions(u)
    assert len(counting.asked) == len(x) - kept
    cost = aligned_cost(WaveForces(), [rec], PARAMS, inside)
    r = problem.residuals(problem.predictions(u[:2]), np.ones(2))
    np.testing.assert_allclose(0.5 * (r**2).sum(axis=1), cost, rtol=1e-12)
