"""Several conditions in one integrator call: the same numbers as one condition at a time."""

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle.simulate import (
    SolverSettings,
    simulate_batch,
    simulate_conditions,
    simulate_requests,
)

SHORT = {"duration_s": 2.0, "n_steps": 100, "lead_in_m": 40.0}
SETS = np.array(
    [
        ParameterSet.nominal().to_array(),
        ParameterSet.nominal().replace({"X14": 6.0e6, "X18": 60e3}).to_array(),
    ]
)


def _same(a, b):
    for name in ("Y", "Q", "car_acc_y", "car_acc_z", "status", "fail_time", "settled_start"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.condition == b.condition and a.static_wheel_load == b.static_wheel_load


@pytest.mark.parametrize("start", ["lead-in", "settled"])
def test_three_study_conditions_share_one_call_with_unchanged_forces(integrator_calls, start):
    """The study's three conditions at 60 km/h: one call of 6 sets, and every set's series
    bit for bit what simulate_batch gives in its condition alone (3 calls of 2). Settled:
    with a lead-in long enough that the curve's record starts past its spiral."""
    settings = SolverSettings(start=start, run_in_m=30.0)
    short = SHORT | {"lead_in_m": 100.0} if start == "settled" else SHORT
    conds = [get_condition(n, **short) for n in ("straight", "curve", "uphill")]
    together = simulate_conditions(SETS, conds, settings=settings)
    assert integrator_calls == [6]
    alone = [simulate_batch(SETS, c, settings=settings) for c in conds]
    assert integrator_calls == [6, 2, 2, 2]
    for a, b in zip(together, alone, strict=True):
        _same(a, b)
        assert a.ok.all()
        assert a.settled_start.all() == (start == "settled")
    # the conditions differ, so a mix-up of tracks or constants would show
    assert np.abs(together[1].Y[0, 1].mean() - together[0].Y[0, 1].mean()) > 10e3


def test_conditions_the_integrator_cannot_share_run_in_their_own_calls(integrator_calls):
    """A different speed changes the steps before the record: two calls, same numbers."""
    slow = get_condition("straight", speed_kmh=40.0, **SHORT)
    conds = [get_condition("curve", **SHORT), slow, get_condition("straight", **SHORT)]
    seeds = [3, 4]
    together = simulate_conditions(SETS, conds, seeds=seeds)
    assert sorted(integrator_calls) == [2, 4]
    for a, c in zip(together, conds, strict=True):
        _same(a, simulate_batch(SETS, c, seeds=seeds))


def test_a_settled_and_a_lead_in_start_run_in_their_own_calls(integrator_calls):
    """The curve's record starts in its spiral 40 m in: it runs the lead-in, the tangent
    starts settled; each gets its own call and its own numbers."""
    settings = SolverSettings(start="settled", run_in_m=30.0)
    conds = [get_condition(n, **SHORT) for n in ("straight", "curve")]
    together = simulate_conditions(SETS, conds, settings=settings)
    assert integrator_calls == [2, 2]
    assert together[0].settled_start.all() and not together[1].settled_start.any()
    for a, c in zip(together, conds, strict=True):
        _same(a, simulate_batch(SETS, c, settings=settings))


def test_requests_of_their_own_sets_layouts_and_seeds_share_one_call(integrator_calls):
    """Two curves of another radius and cant, each with its own sets (over a subset of the
    parameters) and seeds, as a many-track campaign batch asks: one call of 3 sets, and
    each request's series bit for bit its own simulate_batch."""
    a = get_condition("curve", curve_radius_m=280.0, cant_mm=40.0, **SHORT)
    b = get_condition("curve", curve_radius_m=390.0, cant_mm=110.0, **SHORT)
    symbols = ("X14", "X18")
    xa, xb = np.array([[7.0e6, 45e3], [9.0e6, 55e3]]), np.array([[8.0e6, 50e3]])
    together = simulate_requests([(xa, a, [5, 6]), (xb, b, [7])], symbols=symbols)
    assert integrator_calls == [3]
    alone = [
        simulate_batch(xa, a, symbols=symbols, seeds=[5, 6]),
        simulate_batch(xb, b, symbols=symbols, seeds=[7]),
    ]
    for t, s in zip(together, alone, strict=True):
        _same(t, s)
        assert t.ok.all()
    np.testing.assert_array_equal(together[1].params[0, :], alone[1].params[0, :])
    # the layouts differ, so a mix-up of tracks or constants would show
    assert np.abs(together[1].Y[0, 1].mean() - together[0].Y[0, 1].mean()) > 1e3
    with pytest.raises(RailsuspInputError, match="requests: none given"):
        simulate_requests([])


def test_progress_counts_the_sets_of_every_condition():
    seen = []
    conds = [get_condition(n, **SHORT) for n in ("straight", "curve")]
    simulate_conditions(SETS, conds, progress=lambda d, t: seen.append((d, t)), chunk_size=3)
    assert seen == [(3, 4), (4, 4)]


def test_bad_requests_are_refused_in_one_line():
    with pytest.raises(RailsuspInputError, match="conditions: none given"):
        simulate_conditions(SETS, [])
    with pytest.raises(RailsuspInputError, match="seeds: 1 given for 2 parameter sets"):
        simulate_conditions(SETS, [get_condition("straight", **SHORT)], seeds=[1])


def test_two_threads_give_the_forces_of_one(tmp_path):
    """The suite's workers run Numba on one thread each (tests/conftest.py): a batch of
    four sets integrated on two threads, in a process of its own, gives the forces of the
    one-thread integration here bit for bit (each set is integrated on its own, whichever
    thread takes it)."""
    import os
    import subprocess
    import sys
    import textwrap

    sets = np.vstack([SETS, SETS[::-1] * 1.01])
    np.save(tmp_path / "sets.npy", sets)
    script = textwrap.dedent(
        f"""
        import numba, numpy as np
        from railsusp.conditions import get_condition
        from railsusp.vehicle.simulate import simulate_batch
        sets = np.load({str(tmp_path / "sets.npy")!r})
        res = simulate_batch(sets, get_condition("curve").with_changes(**{SHORT!r}))
        np.savez({str(tmp_path / "two.npz")!r}, Y=res.Y, Q=res.Q, threads=numba.get_num_threads())
        """
    )
    env = {**os.environ, "NUMBA_NUM_THREADS": "2"}
    subprocess.run([sys.executable, "-c", script], env=env, check=True, capture_output=True)
    two = np.load(tmp_path / "two.npz")
    one = simulate_batch(sets, get_condition("curve").with_changes(**SHORT))
    assert int(two["threads"]) == 2
    np.testing.assert_array_equal(two["Y"], one.Y)
    np.testing.assert_array_equal(two["Q"], one.Q)
