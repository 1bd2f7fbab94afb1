"""The simulator's correction of a surrogate's level error at the estimate
(railsusp.estimate.level_correction): output space mapping on analytic force models."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.errors import RailsuspInputError
from railsusp.estimate import NSGAConfig, estimate
from railsusp.estimate.level_correction import correct_by_simulator
from railsusp.measured import Recording
from railsusp.store import read_json
from test_estimate import COND

PARAMS = ("X13", "X14")
TRUTH = np.array([14e6, 10e6])


class Linear:
    """Forces linear in a = X13 / 14 MN/m and b = X14 / 10 MN/m on two fixed shapes:
    Y = a u(t), Q = 120 + slope b v(t) + offset v(t) (kN). With slope 1 and offset 0 it is
    the reference ("simulator"); a surrogate with an offset has a level error along b's own
    column, with a slope other than 1 a slope error too."""

    parameters = PARAMS

    def __init__(self, slope: float = 1.0, offset: float = 0.0):
        self.slope, self.offset = slope, offset

    def series(self, x_si, condition):
        t = np.arange(condition.n_steps) * condition.sample_interval
        u = np.sin(2 * np.pi * 1.3 * t) + 0.4 * np.sin(2 * np.pi * 3.1 * t)
        v = np.cos(2 * np.pi * 0.7 * t) + 0.5 * np.sin(2 * np.pi * 2.3 * t + 1.0)
        a = (x_si[:, 0] / 14e6)[:, None]
        b = (x_si[:, 1] / 10e6)[:, None]
        q = 120.0 + (self.slope * b + self.offset) * 10.0 * v
        return np.stack([3.0 * a * u, q], axis=2)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """The reference model's forces at the truth on an exactly measured track (a track
    file, accuracy 0: the time-aligned comparison needs one; nothing is drawn)."""
    from railsusp.vehicle.track import synthesise
    from railsusp.vehicle.track_geometry import write_track_geometry

    folder = tmp_path_factory.mktemp("level")
    cond = COND.with_changes(duration_s=20.0, n_steps=1000)
    track = write_track_geometry(folder / "t.csv", synthesise(400.0, 5, 1, dx=0.25))
    cond = cond.with_changes(track_geometry=str(track))
    s = Linear().series(TRUTH[None], cond)[0]
    t = np.arange(cond.n_steps) * cond.sample_interval
    return Recording(t, {"w1L": s[:, 0]}, {"w1L": s[:, 1]}, cond)


def _nsga(model, rec):
    cfg = NSGAConfig(pop_size=12, n_gen=10, seed=3, statistic="aligned")
    return estimate(model, [rec], PARAMS, cfg)


def test_one_correction_removes_a_level_error_the_surrogate_has_along_a_column(recording, tmp_path):
    """A surrogate whose wheel load carries a level error along b's own column (offset
    -0.2) puts b 0.2 too high by least squares, whatever NSGA-II does; with its slopes
    right, one simulation at the estimate makes it exact there and everywhere, and the
    corrected least squares lands on the truth (within 0.5 %). The route, the table and
    estimate.json say what was done, and NSGA-II's own estimate is kept beside it."""
    surrogate = Linear(offset=-0.2)
    res = _nsga(surrogate, recording)
    assert res.nsga_x[1] / 10e6 == pytest.approx(1.2, abs=0.03)
    correct_by_simulator(res, [recording], surrogate, 1, simulator=Linear())
    assert len(res.corrections) == 1
    assert res.chosen_x[1] / 10e6 == pytest.approx(1.0, abs=0.005)
    assert res.chosen_x[0] / 14e6 == pytest.approx(1.0, abs=0.005)
    assert res.nsga_x[1] / 10e6 == pytest.approx(1.2, abs=0.03)  # kept
    assert "corrected for the surrogate's level error by 1 simulation" in res.route
    iv = res.intervals()["X14"]
    # the Pareto range moved with it: down by the correction's -0.2 of b
    assert iv.high_si == pytest.approx(res.pareto_x[:, 1].max() - 0.2 * 10e6, rel=0.03)
    assert "nsga_estimate" in res.table().columns
    res.save(tmp_path)
    doc = read_json(tmp_path / "estimate.json")
    assert doc["estimate_source"] == "nsga-ii, simulator-corrected"
    (step,) = doc["simulator_corrections"]
    assert step["corrected_display"]["X14"] == pytest.approx(res.estimate["X14"])
    assert step["step_pct_range"]["X14"] < -15.0  # from 1.2 down to 1.0: -20 % of range


def test_with_a_slope_error_the_corrections_converge_on_the_truth(recording):
    """A surrogate that passes on 0.9 of b's effect, with a level error besides: each
    correction is exact at its start but keeps the surrogate's slope, so one step leaves
    (1 - 0.1 b0) / 0.9 - 1 of b (about 2 %) and a second about a tenth of that."""
    surrogate = Linear(slope=0.9, offset=-0.1)
    errors = []
    for steps in (1, 2):
        res = correct_by_simulator(
            _nsga(surrogate, recording), [recording], surrogate, steps, simulator=Linear()
        )
        errors.append(abs(res.chosen_x[1] / 10e6 - 1.0))
    assert 0.005 < errors[0] < 0.05
    assert errors[1] < 0.3 * errors[0]


def test_after_the_simex_step_each_corrected_point_has_the_same_bias_taken_off(recording):
    """Where NSGA-II's estimate is its choice less the geometry error's bias (first SIMEX
    step), the corrected least squares lands on the biased point again, so the same bias
    comes off it: here a bias of +5 % of X14's range set by hand (the analytic model does
    not read the track), and the corrected estimate is the truth less it."""
    from railsusp.params import bounds

    surrogate = Linear(offset=-0.2)
    res = _nsga(surrogate, recording)
    span = np.diff(bounds(PARAMS), axis=0)[0]
    res.geometry_shifts_si = np.tile([0.0, 0.05 * span[1]], (4, 1))
    res.geometry_bias_removed = True
    correct_by_simulator(res, [recording], surrogate, 1, simulator=Linear())
    assert res.chosen_x[1] == pytest.approx(TRUTH[1] - 0.05 * span[1], rel=0.005)
    assert res.corrections[0].x_si[1] == pytest.approx(TRUTH[1], rel=0.005)
    assert "first SIMEX step), then corrected" in res.route


def test_a_stopped_simulation_keeps_the_estimate_and_says_why(recording):
    """A simulation of the estimate that stops (NaN series: derailment, divergence) takes
    no correction: NSGA-II's estimate stands, and the reason is kept for estimate.json."""

    class Derails(Linear):
        def series(self, x_si, condition):
            out = super().series(x_si, condition)
            out[:, 500:] = np.nan
            return out

    surrogate = Linear(offset=-0.2)
    res = _nsga(surrogate, recording)
    correct_by_simulator(res, [recording], surrogate, 2, simulator=Derails())
    assert res.corrections == [] and np.array_equal(res.chosen_x, res.nsga_x)
    assert "stopped in straight" in res.corrections_stopped


def test_two_recordings_of_one_name_keep_their_own_correction(recording):
    """The corrections are kept by the whole condition: two recordings named alike on
    tracks of other lengths each get theirs (by name they would share one, or fail)."""
    from railsusp.estimate.level_correction import condition_key, level_corrections

    short = recording.condition.with_changes(duration_s=10.0, n_steps=500)
    s = Linear().series(TRUTH[None], short)[0]
    t = np.arange(short.n_steps) * short.sample_interval
    other = Recording(t, {"w1L": s[:, 0]}, {"w1L": s[:, 1]}, short)
    d = level_corrections(Linear(offset=-0.2), Linear(), [recording, other], TRUTH)
    assert len(d) == 2
    assert d[condition_key(short)].shape == (500, 2)
    assert d[condition_key(recording.condition)].shape == (1000, 2)


def test_refusals(recording):
    """Corrections need the time-aligned least squares alone, and 0-5 steps; with 0 the
    estimate is NSGA-II's untouched; the simulator is not corrected by itself."""
    from railsusp.estimate import SimulatorForces
    from railsusp.estimate.expected_forces import ExpectedForces

    res = _nsga(Linear(offset=-0.2), recording)
    with pytest.raises(RailsuspInputError, match="simulator_corrections 6: accepted 0 to 5"):
        correct_by_simulator(res, [recording], Linear(), 6, simulator=Linear())
    before = res.chosen_x.copy()
    correct_by_simulator(res, [recording], Linear(), 0, simulator=Linear())
    assert res.corrections == [] and np.array_equal(res.chosen_x, before)
    mean = estimate(Linear(), [recording], PARAMS, NSGAConfig(pop_size=4, n_gen=1))
    with pytest.raises(RailsuspInputError, match="accepted 'aligned' alone"):
        correct_by_simulator(mean, [recording], Linear(), 1, simulator=Linear())
    for itself in (SimulatorForces(PARAMS), ExpectedForces(SimulatorForces(PARAMS), 2)):
        with pytest.raises(RailsuspInputError, match="the force model is the simulator itself"):
            correct_by_simulator(res, [recording], itself, 1)


def test_first_order_corrections_take_the_simulators_slope_and_land_on_the_truth(recording):
    """A surrogate that passes on 0.8 of b's effect with a level error besides (NSGA-II's b
    about 1.125, inside the trust box): the zeroth-order correction keeps its slope and
    leaves about 3 % of b; one correction with slopes makes the corrected surrogate the
    reference itself here (linear), and its least squares lands on the truth within
    0.2 %. The route says which."""
    surrogate = Linear(slope=0.8, offset=0.1)
    plain = correct_by_simulator(
        _nsga(surrogate, recording), [recording], surrogate, 1, simulator=Linear()
    )
    first = correct_by_simulator(
        _nsga(surrogate, recording), [recording], surrogate, 1, simulator=Linear(), slopes=True
    )
    assert abs(plain.chosen_x[1] / 10e6 - 1.0) > 0.015
    assert first.chosen_x[1] / 10e6 == pytest.approx(1.0, abs=0.002)
    assert first.chosen_x[0] / 14e6 == pytest.approx(1.0, abs=0.002)
    assert "first-order correction" in first.route and "first-order" not in plain.route


def test_each_first_order_step_stays_in_its_trust_box_and_the_steps_walk_to_the_truth(
    recording, tmp_path
):
    """A surrogate passing on 0.8 of b's effect, 0.3 low, puts NSGA-II's b at 1.5 (X14 on
    its upper bound, half the range from the truth), where the slopes are taken by a step
    inwards. With slopes each correction may move X14 by at most TRUST_BOX of its range:
    three steps leave it 5 % of range short, the fourth reaches the truth; estimate.json
    records the step and the box."""
    from railsusp.estimate.config import TRUST_BOX

    surrogate = Linear(slope=0.8, offset=-0.3)
    res = _nsga(surrogate, recording)
    assert res.nsga_x[1] / 10e6 == pytest.approx(1.5, abs=0.03)
    correct_by_simulator(res, [recording], surrogate, 4, simulator=Linear(), slopes=True)
    moves = [c.estimate_si[1] - c.start_si[1] for c in res.corrections]
    span = 10e6  # X14's range, 5-15 MN/m
    assert all(abs(m) <= TRUST_BOX * span * (1 + 1e-9) for m in moves)
    assert res.corrections[2].estimate_si[1] / 10e6 == pytest.approx(
        res.nsga_x[1] / 10e6 - 3 * TRUST_BOX, abs=1e-6
    )
    assert res.chosen_x[1] / 10e6 == pytest.approx(1.0, abs=0.005)
    res.save(tmp_path)
    doc = read_json(tmp_path / "estimate.json")
    assert doc["correction_slopes"] == {"step_of_range": 0.05, "trust_box_of_range": TRUST_BOX}
    assert "within a trust region" in doc["simulator_corrections"][0]["method"]


def test_slope_corrections_are_the_analytic_slope_difference_on_and_off_the_upper_bound(
    recording,
):
    """d(reference - surrogate)/dX14 of the linear models is (1 - 0.8) 10 v(t) / (10 MN/m)
    in the wheel load and nothing in the lateral force, nor along X13 (which both models
    share): so the slopes, taken by a forward step mid-range and by a step inwards where
    X14 sits on its upper bound, must be exactly that."""
    from railsusp.estimate.level_correction import (
        condition_key,
        level_corrections,
        slope_corrections,
    )

    surrogate, reference = Linear(slope=0.8), Linear()
    key = condition_key(recording.condition)
    t = np.arange(recording.condition.n_steps) * recording.condition.sample_interval
    v = np.cos(2 * np.pi * 0.7 * t) + 0.5 * np.sin(2 * np.pi * 2.3 * t + 1.0)
    for x14 in (10e6, 15e6):  # mid-range, and on the upper bound (5-15 MN/m)
        x = np.array([14e6, x14])
        level = level_corrections(surrogate, reference, [recording], x)
        slopes = slope_corrections(surrogate, reference, [recording], x, level)
        np.testing.assert_allclose(slopes[1][key][:, 1], 0.2 * 10.0 * v / 10e6, atol=1e-15)
        np.testing.assert_allclose(slopes[1][key][:, 0], 0.0, atol=1e-15)
        np.testing.assert_allclose(slopes[0][key], 0.0, atol=1e-15)
