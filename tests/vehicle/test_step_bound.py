"""The RK4 step kept within its stability bound (:mod:`railsusp.vehicle.step_bound`).

The creep forces' damping grows as 1/speed; with the fixed 1 ms step the loaded wagon went
unstable below about 42 km/h and read 13 kN of lateral force on ideal straight track at
30 km/h, status ok (the physics audit of stop 59). These tests fail on the code before the
bound: the ideal-track test reads 13.2 kN there.
"""

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.params import ParameterSet
from railsusp.vehicle import step_bound
from railsusp.vehicle.simulate import SolverSettings, simulate
from railsusp.vehicle.step_bound import STEP_EIGEN_LIMIT, stable_step
from railsusp.vehicle.wagon import load_wagon


@pytest.mark.parametrize("speed", [5.0, 30.0])
def test_on_ideal_straight_track_at_low_speed_the_lateral_force_stays_static(speed):
    """At rest in static equilibrium on ideal straight track the wheels keep their static
    1.64 kN (conicity and spin creep) at any speed; the unstable step made it 13.2 kN at
    30 km/h and 44 kN at 5 km/h."""
    cond = get_condition(
        "straight", irregularity_class=None, speed_kmh=speed, lead_in_m=0.0, duration_s=2.0,
        name="slow",
    )  # fmt: skip
    res = simulate(None, cond)
    assert res.ok[0]
    Y = np.abs(res.Y[0]) / 1e3
    assert Y.max() == pytest.approx(1.64, abs=0.02)


def test_the_bound_follows_the_creep_eigenvalue_and_keeps_1_ms_at_60_km_h():
    """Below about 58 km/h the loaded wagon's bound is under 1 ms and falls as the speed
    (the creep damping's eigenvalue grows as 1/V); at 60 km/h, the study's speed, both
    wagons keep the 1 ms step, so the study's conditions are simulated as before, bit for
    bit."""
    P = ParameterSet.nominal().to_array()
    loaded, tare = load_wagon("loaded"), load_wagon("tare")
    assert stable_step(loaded, 60.0, P) > 1e-3 and stable_step(tare, 60.0, P) > 1e-3
    slow = [stable_step(loaded, v, P) for v in (10.0, 20.0, 40.0)]
    assert slow[0] < slow[1] < slow[2] < 1e-3
    assert slow[1] / slow[0] == pytest.approx(2.0, rel=0.05)  # h ~ V at low speed
    assert STEP_EIGEN_LIMIT < 2.785  # inside RK4's real-axis stability limit


def test_at_30_km_h_on_irregular_track_the_statistics_are_the_converged_ones():
    """Class 5 tangent at 30 km/h: the default settings' statistics within 0.5 % of a
    0.25 ms step's (the unstable 1 ms step gave Y mean 12.5 kN against 3.6)."""
    cond = get_condition("straight", speed_kmh=30.0, duration_s=6.0, name="slow")
    a = simulate(None, cond).statistics()
    b = simulate(None, cond, settings=SolverSettings(max_step=2.5e-4)).statistics()
    for k in ("Y_mean", "Y_p99", "Q_p99"):
        assert a[k] == pytest.approx(b[k], rel=5e-3), k


def test_a_batch_of_two_wheelset_masses_reads_dq_q_against_each_sets_static_load():
    """dQ/Q of every set was taken against the first set's static wheel load: at rest on
    ideal track a set of twice the wheelset mass read -4.8 % unloading instead of 0."""
    from railsusp.vehicle.simulate import simulate_batch

    P = np.tile(ParameterSet.nominal().to_array(), (2, 1))
    P[1, 0] = 2400.0  # X1, wheelset mass
    cond = get_condition(
        "straight", irregularity_class=None, lead_in_m=0.0, duration_s=1.0, name="rest"
    )
    res = simulate_batch(P, cond)
    assert np.shape(res.static_wheel_load) == (2,)
    assert np.abs(res.unloading_ratio[:, :, -10:]).max() < 1e-3


def test_statistics_of_a_record_with_fewer_samples_than_segments_are_numbers():
    """600 s in 20 samples: 30 statistic segments of 20 s for 20 samples left ten empty and
    every mean, RMS and p99 NaN, status ok; the segments are now at most the samples."""
    from railsusp.vehicle.simulation_result import statistic_segments

    assert statistic_segments(20, 30.0) == 20
    cond = get_condition("straight", duration_s=600.0, n_steps=20, name="sparse")
    stats = simulate(None, cond).statistics()
    assert all(np.isfinite(stats[k]) for k in ("Y_mean", "Y_rms", "Y_p99", "Q_mean"))


def test_solver_settings_out_of_range_are_one_line_errors_and_unmodelled_x5_warns():
    from railsusp.errors import RailsuspInputError

    for bad, text in (
        ({"max_step": 0.0}, "max_step = 0.0 s: accepted 1e-06 to 0.01 s"),
        ({"max_step": -1e-3}, "max_step"),
        ({"track_step": 0.0}, "track_step = 0.0 m: accepted 0.005 to 1 m"),
        ({"anti_alias": 5.0}, "anti_alias = 5.0: accepted 0.05 to 1"),
        ({"filter_order": 0}, "filter_order = 0: accepted an integer 1 to 12"),
    ):
        with pytest.raises(RailsuspInputError, match=text):
            SolverSettings(**bad)
    cond = get_condition("straight", irregularity_class=None, duration_s=1.0, name="x5")
    with pytest.warns(UserWarning, match="X5 changed from nominal: the model has no bearing"):
        simulate(ParameterSet({"X5": 30.0}), cond)


def test_the_bound_does_not_depend_on_the_sampled_parameters():
    """A campaign's step must not depend on which of its sets comes first (the sampled
    parameters move max |λ| by under 2 %): the bound is taken with them nominal."""
    P = ParameterSet.nominal().to_array()
    stiff = ParameterSet(
        {"X13": 21e6, "X14": 15e6, "X15": 255e6, "X19": 45e6, "X20": 1.5e9}
    ).to_array()
    loaded = load_wagon("loaded")
    for speed in (30.0, 45.0):
        step_bound._bounds.clear()  # whichever set comes first in a fresh process
        first = stable_step(loaded, speed, stiff)
        step_bound._bounds.clear()
        assert first == stable_step(loaded, speed, P)


def test_a_sets_forces_do_not_depend_on_the_other_sets_of_its_batch():
    """The step was the batch's smallest: a nominal set beside one of 0.8 x the wheelset
    mass ran at 0.87 ms instead of 1 ms, its forces moved by 0.2 kN (the review of stop
    59). Each set now runs at its own step, the sets of one step together."""
    from railsusp.vehicle.simulate import simulate_batch

    cond = get_condition("straight", duration_s=2.0, n_steps=100)
    P = np.tile(ParameterSet.nominal().to_array(), (2, 1))
    P[1, 0] = 0.8 * 1200.0
    both = simulate_batch(P, cond)
    alone = simulate_batch(P[:1], cond)
    assert np.array_equal(both.Y[0], alone.Y[0]) and np.array_equal(both.Q[0], alone.Q[0])


def test_a_set_whose_masses_need_a_step_below_the_floor_is_warned_of_not_run_at_1_ms():
    """A wheelset of 150 kg at 3 km/h needs a step under the 1e-5 s floor; the batch took
    the whole 1 ms then and read 43.9 kN on ideal track, status ok. Now the floor, with a
    warning."""
    from railsusp.vehicle.step_bound import STEP_FLOOR, set_steps

    P = ParameterSet.nominal().to_array()
    light = P.copy()
    light[0] = 150.0
    with pytest.warns(UserWarning, match=r"set\(s\) 1: at 3 km/h .* below the 1e-05 s floor"):
        steps = set_steps(load_wagon("loaded"), 3.0, np.stack([P, light]), 1e-3)
    assert steps[1] == STEP_FLOOR and STEP_FLOOR < steps[0] < 1e-3


def test_the_free_decay_runs_keep_the_step_within_the_bound(monkeypatch):
    """modes --decay integrated its own fixed 1 ms step (damping ratios 0.445 against 0.404
    at 30 km/h, the review of stop 59); it takes the bound now, and at 60 km/h its 1 ms as
    before."""
    from railsusp.vehicle import decay

    taken = []

    def spy(*args, **kwargs):
        taken.append(kwargs["dt"])
        raise RuntimeError("enough")

    monkeypatch.setattr(decay, "decay_run", spy)
    wagon = load_wagon("loaded")
    P = ParameterSet.nominal().to_array()
    for speed in (30.0, 60.0):
        with pytest.raises(RuntimeError, match="enough"):
            decay.free_decay(None, wagon, speed)
    assert taken[0] <= stable_step(wagon, 30.0, P) and taken[1] == 1e-3
