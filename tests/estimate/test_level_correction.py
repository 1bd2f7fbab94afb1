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
    assert step["check"] is None and res.correction_checks == []  # zeroth order: no check


def test_with_a_slope_error_the_corrections_converge_on_the_truth(recording):
    """A surrogate that passes on 0.9 of b's effect, with a level error besides: each
    correction is exact at its start but keeps the surrogate's slope, so one step from
    NSGA-II's b0 leaves e0 = (1 - 0.1 b0) / 0.9 - 1 of b (about -2 %) and a second
    -e0 / 9 (the same map from 1 + e0)."""
    surrogate = Linear(slope=0.9, offset=-0.1)
    errors = []
    for steps in (1, 2):
        res = correct_by_simulator(
            _nsga(surrogate, recording), [recording], surrogate, steps, simulator=Linear()
        )
        errors.append(res.chosen_x[1] / 10e6 - 1.0)
    b0 = res.nsga_x[1] / 10e6
    assert errors[0] == pytest.approx((1.0 - 0.1 * b0) / 0.9 - 1.0, rel=0.05)
    assert abs(errors[0]) > 0.005
    assert errors[1] == pytest.approx(-errors[0] / 9.0, rel=0.05)


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
    first_order = _nsga(surrogate, recording)  # the same, first order: the step's extent
    first_order.geometry_shifts_si = res.geometry_shifts_si  # is the least squares' own
    first_order.geometry_bias_removed = True  # move, not the move of the biased point
    correct_by_simulator(first_order, [recording], surrogate, 1, simulator=Linear(), slopes=True)
    (step,), (check,) = first_order.corrections, first_order.correction_checks
    assert check.extent == pytest.approx(abs(step.x_si[1] - step.start_si[1]) / span[1])
    assert check.extent != pytest.approx(abs(step.estimate_si[1] - step.start_si[1]) / span[1])


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
    v = np.cos(2 * np.pi * 0.7 * t) + 0.5 * np.sin(2 * np.pi * 2.3 * t + 1.0)
    for key, n in ((condition_key(short), 500), (condition_key(recording.condition), 1000)):
        assert d[key].shape == (n, 2)  # the offset's 0.2 x 10 v(t) in Q, none in Y
        np.testing.assert_allclose(d[key][:500, 1], 2.0 * v, atol=1e-12)
        np.testing.assert_allclose(d[key][:, 0], 0.0, atol=1e-12)


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


def test_each_first_order_step_stays_in_its_trust_box_which_grows_after_good_steps(
    recording, tmp_path
):
    """A surrogate passing on 0.8 of b's effect, 0.3 low, puts NSGA-II's b at 1.5 (X14 on
    its upper bound, half the range from the truth), where the slopes are taken by a step
    inwards. The first correction may move X14 by TRUST_BOX of its range; the reference is
    linear, so the simulator confirms the corrected surrogate's predicted fall exactly
    (ratio 1) and, the step being on the box's edge, the box doubles: the second step moves
    by 2 TRUST_BOX (BOX_MAX) and the third reaches the truth. estimate.json records each
    step's box and check."""
    from railsusp.estimate.config import TRUST_BOX
    from railsusp.estimate.trust_region import BOX_MAX

    surrogate = Linear(slope=0.8, offset=-0.3)
    res = _nsga(surrogate, recording)
    assert res.nsga_x[1] / 10e6 == pytest.approx(1.5, abs=0.03)
    correct_by_simulator(res, [recording], surrogate, 3, simulator=Linear(), slopes=True)
    moves = [(c.estimate_si[1] - c.start_si[1]) / 10e6 for c in res.corrections]  # range 10
    boxes = [c.box for c in res.correction_checks]
    assert boxes == [TRUST_BOX, BOX_MAX, BOX_MAX] and BOX_MAX == pytest.approx(2 * TRUST_BOX)
    assert moves[:2] == pytest.approx([-TRUST_BOX, -BOX_MAX], abs=1e-6)
    assert [c.ratio for c in res.correction_checks[:2]] == pytest.approx([1.0, 1.0], abs=1e-6)
    assert [c.accepted for c in res.correction_checks] == [True, True, None]  # last: unchecked
    checks = res.correction_checks  # a kept point's simulated cost is the next step's start
    assert [c.cost_start for c in checks[1:]] == [c.cost_simulated for c in checks[:2]]
    assert checks[1].cost_start < 0.5 * checks[0].cost_start
    assert res.chosen_x[1] / 10e6 == pytest.approx(1.0, abs=0.002)
    res.save(tmp_path)
    doc = read_json(tmp_path / "estimate.json")
    assert doc["correction_slopes"] == {
        "step_of_range": 0.05,
        "trust_box_of_range": TRUST_BOX,
        "slope_update": "simulated",
    }
    first = doc["simulator_corrections"][0]
    assert "within a trust region" in first["method"]
    assert first["check"]["box"] == TRUST_BOX and first["check"]["accepted"] is True


class Kinked(Linear):
    """The reference, with the wheel load's response to b flat above the truth and steep
    below it: Q = 120 + 10 (1 + psi(b - 1)) v(t), psi(e) = tanh(15 e) / 15 for e >= 0,
    4 e below. From b = 1.1 the slope there (0.1 of the linear model's) asks for a step far
    past the truth, which the box cuts to b = 0.95, where the cost is 11 times that at
    1.1. ``derail_below``: b under which the simulation stops (NaN series)."""

    def __init__(self, derail_below: float = 0.0):
        super().__init__()
        self.derail_below = derail_below

    def series(self, x_si, condition):
        out = super().series(x_si, condition)
        e = x_si[:, 1] / 10e6 - 1.0
        psi = np.where(e >= 0.0, np.tanh(15.0 * e) / 15.0, 4.0 * e)
        t = np.arange(condition.n_steps) * condition.sample_interval
        v = np.cos(2 * np.pi * 0.7 * t) + 0.5 * np.sin(2 * np.pi * 2.3 * t + 1.0)
        out[:, :, 1] = 120.0 + 10.0 * (1.0 + psi)[:, None] * v
        out[x_si[:, 1] / 10e6 < self.derail_below] = np.nan
        return out


def test_a_step_that_raises_the_simulators_cost_is_rejected_and_the_next_starts_where_it_did(
    recording, tmp_path
):
    """On the kinked reference the first first-order step from b = 1.1 lands at 0.95, where
    the simulator's cost is higher than at its start: the step is rejected (negative
    ratio), the second least squares starts from the first's start again, with the same
    corrected surrogate, in a box of a quarter of the rejected step's extent, and that
    step (kept: the cost falls more than predicted) brings b closer to the truth. Without
    the check (before it) the second step started at the rejected point. The route,
    estimate.json and the report say it."""
    from railsusp.estimate.trust_region import SHRINK
    from railsusp.report_doc import Doc
    from railsusp.report_estimate import estimate_section

    surrogate = Linear(offset=-0.1)  # NSGA-II's b at 1.1
    res = _nsga(surrogate, recording)
    assert res.nsga_x[1] / 10e6 == pytest.approx(1.1, abs=0.01)
    correct_by_simulator(res, [recording], surrogate, 3, simulator=Kinked(), slopes=True)
    first, second, _ = res.correction_checks
    assert first.accepted is False and first.ratio < 0.0
    assert first.cost_simulated > 5.0 * first.cost_start
    step1, step2, _ = res.corrections
    np.testing.assert_array_equal(step2.start_si, step1.start_si)
    extent = abs(step1.estimate_si[1] - step1.start_si[1]) / 10e6
    assert extent == pytest.approx(0.15, abs=1e-6)
    assert second.box == pytest.approx(SHRINK * extent)
    assert second.accepted is True and second.cost_simulated < first.cost_start
    assert second.cost_start == first.cost_start  # a rejected point is no start
    assert abs(step2.estimate_si[1] / 10e6 - 1.0) < abs(res.nsga_x[1] / 10e6 - 1.0)
    assert "1 proposed point rejected" in res.route
    res.save(tmp_path)
    records = read_json(tmp_path / "estimate.json")["simulator_corrections"]
    assert [r["check"]["accepted"] for r in records] == [False, True, None]
    doc = Doc(tmp_path)
    estimate_section(doc, tmp_path)
    text = "\n".join(doc.md)
    assert "1 of 2 kept" in text and "Trust boxes, % of each range: 15, 3.75, 7.5" in text
    assert "(a rejected one from one)" in text


@pytest.mark.parametrize("update", ["simulated", "broyden"])
def test_a_proposed_point_that_derails_is_rejected_and_the_corrections_go_on(recording, update):
    """If the simulation of a first-order step's point stops (here: derails below b =
    0.97), that point is rejected as one that raised the cost, and the corrections go on
    from the last point simulated whole; before, they stopped there and the derailed point
    became the estimate. With Broyden's update the same holds: the derailed point has no
    simulated level, and no secant is taken to it (one would fail on the missing level)."""
    surrogate = Linear(offset=-0.1)
    res = _nsga(surrogate, recording)
    correct_by_simulator(
        res,
        [recording],
        surrogate,
        3,
        simulator=Kinked(derail_below=0.97),
        slopes=True,
        slope_update=update,
    )
    assert res.corrections_stopped == ""
    assert len(res.corrections) == 3
    first = res.correction_checks[0]
    assert first.accepted is False and "stopped in straight" in first.stopped
    assert res.chosen_x[1] / 10e6 > 0.97
    assert abs(res.chosen_x[1] / 10e6 - 1.0) < abs(res.nsga_x[1] / 10e6 - 1.0)


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


def test_broyden_slopes_carry_the_level_change_along_the_step_and_nothing_across():
    """Broyden's update makes the slope corrections reproduce the level correction's change
    along the step (the secant condition) and leaves their action on a direction
    orthogonal to the step (in range units) unchanged."""
    from railsusp.estimate.level_correction import broyden_slopes

    rng = np.random.default_rng(0)
    span = np.array([20e6, 10e6])
    g = {j: {"c": rng.normal(size=(50, 2)) * 1e-6} for j in range(2)}
    before, after = {"c": rng.normal(size=(50, 2))}, {"c": rng.normal(size=(50, 2))}
    step = np.array([0.1, -0.05]) * span
    new = broyden_slopes(g, before, after, step, span)
    carried = sum(new[j]["c"] * step[j] for j in range(2))
    np.testing.assert_allclose(carried, after["c"] - before["c"], rtol=1e-12, atol=1e-12)
    across = np.array([0.05, 0.1]) * span  # orthogonal to the step in range units
    np.testing.assert_allclose(
        sum(new[j]["c"] * across[j] for j in range(2)),
        sum(g[j]["c"] * across[j] for j in range(2)),
        rtol=1e-12,
        atol=1e-12,
    )
    assert broyden_slopes(g, before, after, np.zeros(2), span) is g


def test_broyden_slopes_are_kept_across_a_step_shorter_than_the_floor():
    """A step of 0.72 % of range (under BROYDEN_MIN_STEP, 1 %) leaves the slopes as they
    were, so that the simulator's roughness across the small steps near convergence does
    not enter them; the same step with no floor updates them (the secant holds), and so do
    a step of exactly the floor along one key and a diagonal one whose length (Euclidean,
    in range units) passes the floor though no key's move does."""
    from types import SimpleNamespace

    from railsusp.estimate.config import BROYDEN_MIN_STEP
    from railsusp.estimate.level_correction import _broyden_at, broyden_slopes

    rng = np.random.default_rng(1)
    span = np.array([20e6, 10e6])
    g = {j: {"c": rng.normal(size=(50, 2)) * 1e-6} for j in range(2)}
    before, after = {"c": rng.normal(size=(50, 2))}, {"c": rng.normal(size=(50, 2))}

    def carried(slopes, step):
        return sum(slopes[j]["c"] * step[j] for j in range(2))

    change = after["c"] - before["c"]
    short = np.array([0.006, -0.004]) * span
    assert broyden_slopes(g, before, after, short, span) is g
    unfloored = broyden_slopes(g, before, after, short, span, min_step=0.0)
    np.testing.assert_allclose(carried(unfloored, short), change, atol=1e-12)
    assert broyden_slopes(g, before, after, np.zeros(2), span, min_step=0.0) is g
    along = np.array([BROYDEN_MIN_STEP, 0.0]) * span
    np.testing.assert_allclose(
        carried(broyden_slopes(g, before, after, along, span), along), change, atol=1e-12
    )
    x0 = np.array([14e6, 10e6])  # and so inside the corrections, for a kept or rejected point
    made_at = SimpleNamespace(slopes=g, corrections=before)
    assert _broyden_at(made_at, after, x0 + short, x0, span, BROYDEN_MIN_STEP) is g
    assert _broyden_at(made_at, after, x0 + along, x0, span, BROYDEN_MIN_STEP) is not g
    diagonal = np.array([0.008, 0.008]) * span  # 1.13 % long, though no key moves 1 %
    np.testing.assert_allclose(
        carried(broyden_slopes(g, before, after, diagonal, span), diagonal), change, atol=1e-12
    )


class Counting(Linear):
    """The reference, counting the parameter sets it simulates."""

    def __init__(self, base):
        self.base, self.sets = base, 0
        self.parameters = base.parameters

    def series(self, x_si, condition):
        self.sets += len(x_si)
        return self.base.series(x_si, condition)


def _three_first_order_steps(recording, surrogate, reference, update):
    """Three first-order corrections of NSGA-II's estimate on ``surrogate`` against the
    ``reference`` (counted), slopes updated by ``update``: the result and the sets it
    simulated."""
    ref = Counting(reference)
    res = correct_by_simulator(
        _nsga(surrogate, recording),
        [recording],
        surrogate,
        3,
        simulator=ref,
        slopes=True,
        slope_update=update,
    )
    return res, ref.sets


def test_broyden_updates_take_the_slopes_once_and_match_the_simulated_ones_on_a_linear_model(
    recording,
):
    """With slope_update = 'broyden' only the first point's slopes are simulated (k + 1
    sets, then one per step): here 3 + 1 + 1 against 3 + 3 + 3. On the linear reference the
    slope correction is the same everywhere, so the update leaves it as simulated and both
    land on the same points. An unknown update, or Broyden's without slopes, is refused."""
    surrogate = Linear(slope=0.8, offset=-0.3)
    runs = {
        update: _three_first_order_steps(recording, surrogate, Linear(), update)
        for update in ("simulated", "broyden")
    }
    assert {u: sets for u, (_, sets) in runs.items()} == {"simulated": 9, "broyden": 5}
    np.testing.assert_allclose(
        [c.estimate_si for c in runs["simulated"][0].corrections],
        [c.estimate_si for c in runs["broyden"][0].corrections],
        rtol=1e-9,
    )
    res = _nsga(surrogate, recording)
    needle = "slope_update 'broyden' updates the slopes of first-order corrections; slopes = F"
    with pytest.raises(RailsuspInputError, match=needle):
        correct_by_simulator(res, [recording], surrogate, 1, slope_update="broyden")
    with pytest.raises(RailsuspInputError, match="slope_update 'newton': accepted"):
        correct_by_simulator(res, [recording], surrogate, 1, slopes=True, slope_update="newton")


def test_broyden_after_a_rejection_takes_the_rejected_points_secant(recording):
    """With Broyden's update a rejected point's simulation is not thrown away: the slopes
    at the start take the secant to it, so on the kinked reference (linear on either side
    of the truth) the corrected surrogate's next point is where that secant crosses the
    measurement, at predicted cost 0, where the simulated slopes (kept after a rejection)
    predict a cost well above it. The simulator runs 3 + 1 + 1 sets against 3 + 1 + 3."""
    surrogate = Linear(offset=-0.1)
    second, counts = {}, {}
    for update in ("simulated", "broyden"):
        res, counts[update] = _three_first_order_steps(recording, surrogate, Kinked(), update)
        assert res.correction_checks[0].accepted is False
        second[update] = res.correction_checks[1]
    assert second["broyden"].cost_predicted < 1e-12 * second["broyden"].cost_start
    assert second["simulated"].cost_predicted > 0.5 * second["simulated"].cost_start
    assert counts == {"simulated": 7, "broyden": 5}


def test_the_check_keeps_a_converged_point_and_the_box_never_shrinks_below_its_floor():
    """StepCheck's rules: falls of the cost within rounding of it are convergence (kept,
    box unchanged); with no predicted fall a point is kept if the cost did not rise (no
    ratio); a kept point with a poor ratio still shrinks the box; no box goes below BOX_MIN
    or above BOX_MAX."""
    from railsusp.estimate.trust_region import BOX_MAX, BOX_MIN, StepCheck

    flat = StepCheck(box=0.15, cost_start=4.0, cost_predicted=4.0 - 1e-12, extent=1e-7)
    flat.judge(4.0 + 1e-12)
    assert flat.accepted is True and flat.ratio is None and flat.next_box() == 0.15
    uphill = StepCheck(box=0.15, cost_start=4.0, cost_predicted=4.1, extent=0.1)
    uphill.judge(3.9)
    assert uphill.accepted is True and uphill.ratio is None and uphill.next_box() == 0.15
    uphill.judge(4.2)
    assert uphill.accepted is False and uphill.next_box() == pytest.approx(0.025)
    poor = StepCheck(box=0.15, cost_start=4.0, cost_predicted=3.0, extent=0.15)
    poor.judge(3.8)  # a fifth of the predicted fall: kept, box shrunk
    assert poor.accepted is True and poor.ratio == pytest.approx(0.2)
    assert poor.next_box() == pytest.approx(0.0375)
    tiny = StepCheck(box=0.15, cost_start=4.0, cost_predicted=3.0, extent=1e-6)
    tiny.judge(4.5)
    assert tiny.accepted is False and tiny.next_box() == BOX_MIN
    good = StepCheck(box=BOX_MAX, cost_start=4.0, cost_predicted=3.0, extent=BOX_MAX)
    good.judge(3.0)
    assert good.ratio == pytest.approx(1.0) and good.next_box() == BOX_MAX
    assert good.to_dict()["accepted"] is True


@pytest.mark.parametrize(
    ("box", "predicted", "extent", "simulated", "accepted", "ratio", "next_box"),
    [
        (0.15, 4.0, 0.01, 4.4, False, None, 0.0025),  # no fall predicted, the cost rose
        (0.15, 3.0, 0.02, 4.5, False, -0.5, 0.005),  # rejected: a quarter of the extent
        (0.15, 3.0, 2e-4, 4.5, False, -0.5, 1e-4),  # ... never under 0.01 % of range
        (0.15, 3.0, 0.15, 3.95, False, 0.05, 0.0375),  # under 0.1 of the fall: rejected
        (0.15, 3.0, 0.15, 3.85, True, 0.15, 0.0375),  # kept, under 0.25: box shrunk
        (0.15, 3.0, 0.15, 3.5, True, 0.5, 0.15),  # kept, box as it was
        (0.15, 3.0, 0.15, 3.2, True, 0.8, 0.3),  # over 0.75 on the edge: doubled
        (0.15, 3.0, 0.149, 3.0, True, 1.0, 0.3),  # 0.99 of the box is its edge
        (0.15, 3.0, 0.148, 3.0, True, 1.0, 0.15),  # inside the box: as it was
        (0.3, 3.0, 0.3, 3.2, True, 0.8, 0.3),  # never over 30 % of range
        (0.15, 3.99, 0.01, 3.9999, False, 0.01, 0.0025),  # a small fall is judged
    ],
)
def test_the_checks_rules_in_numbers(box, predicted, extent, simulated, accepted, ratio, next_box):
    """StepCheck's verdicts and next boxes, from a start cost of 4, against the numbers of
    Nocedal & Wright's Algorithm 4.1 as set in trust_region (eta 0.1, shrink below 0.25 to a
    quarter of the step's extent, at least 1e-4; double above 0.75 on the edge, at most
    0.3), written out rather than read from the module's constants."""
    from railsusp.estimate.trust_region import StepCheck

    check = StepCheck(box=box, cost_start=4.0, cost_predicted=predicted, extent=extent)
    check.judge(simulated)
    assert check.accepted is accepted
    assert check.ratio == (None if ratio is None else pytest.approx(ratio))
    assert check.next_box() == pytest.approx(next_box)


def test_convergence_is_judged_relative_to_the_cost():
    """Falls within 1e-9 of a cost of 4e6 (here 1e-4, a rise in the simulator's) are
    convergence: kept, no ratio, the box as it was; the same falls on a cost of 4 are
    judged, and the rise rejects the point."""
    from railsusp.estimate.trust_region import StepCheck

    big = StepCheck(box=0.15, cost_start=4e6, cost_predicted=4e6 - 1e-4, extent=1e-7)
    big.judge(4e6 + 1e-4)
    assert big.accepted is True and big.ratio is None and big.next_box() == 0.15
    small = StepCheck(box=0.15, cost_start=4.0, cost_predicted=4.0 - 1e-4, extent=1e-3)
    small.judge(4.0 + 1e-4)
    assert small.accepted is False and small.ratio == pytest.approx(-1.0)


def test_a_derailing_stepped_set_at_a_kept_point_stops_the_corrections_there(recording):
    """If a slope's stepped set derails at a point the check kept (here b in 1.38-1.42: the
    point 1.35 is kept, its step to 1.40 derails), no corrected surrogate can be made
    there: the corrections stop with the reason, and the kept point is the estimate."""

    class DerailsInBand(Linear):
        def series(self, x_si, condition):
            out = super().series(x_si, condition)
            b = x_si[:, 1] / 10e6
            out[(b > 1.38) & (b < 1.42)] = np.nan
            return out

    surrogate = Linear(slope=0.8, offset=-0.3)
    res = _nsga(surrogate, recording)
    correct_by_simulator(res, [recording], surrogate, 3, simulator=DerailsInBand(), slopes=True)
    assert "the estimate's slopes stopped in straight" in res.corrections_stopped
    assert len(res.corrections) == 1 and res.correction_checks[0].accepted is True
    assert res.chosen_x[1] / 10e6 == pytest.approx(res.nsga_x[1] / 10e6 - 0.15, abs=1e-6)
