"""The track geometry's measurement error in NSGA-II's time-aligned estimate: its bias (the
first SIMEX step) and scatter, with the model NSGA-II ran on.

The analytic case: forces proportional to the track irregularity under the wheel
(``TrackForces``: Y = 3 (X13 / 14 MN/m) x alignment, Q = 120 + 5 (X14 / 10 MN/m) x
profile), recorded on the true track and predicted on a measured geometry with 2 mm of
error. Least squares on an input with error attenuates the fitted gain (errors in
variables: by var(e) / (var(x) + var(e)) in the compared band), so on a long record both
estimates come out low; one more draw of the same error attenuates them further, and the
estimate less that further shift is the linear extrapolation to no error.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from railsusp.estimate import NSGAConfig, estimate
from railsusp.estimate.geometry_bias import MAX_SCATTER, less_bias, simex_bias, simex_spread
from railsusp.estimate.nsga_geometry import remove_nsga_geometry_bias
from railsusp.measured import Recording
from railsusp.params import bounds
from railsusp.vehicle.track import synthesise
from railsusp.vehicle.track_geometry import with_measurement_error, write_track_geometry
from test_estimate import COND, PARAMS, TrackForces

TRUTH = np.array([16.1e6, 8.3e6])
LO, HI = bounds(PARAMS)


def pct(x_si: np.ndarray) -> np.ndarray:
    """Error against the truth, % of each range."""
    return 100.0 * (np.asarray(x_si) - TRUTH) / (HI - LO)


@pytest.fixture(scope="module")
def long_record(tmp_path_factory):
    """200 s recorded on the true track (3 % noise), and its measured geometry with 2 mm of
    error stated as its accuracy; the same recording on exact geometry."""
    tmp = tmp_path_factory.mktemp("geometry")
    true_track = synthesise(3500.0, 5, 1, dx=0.125)
    cond = COND.with_changes(duration_s=200.0, n_steps=10000)
    exact = write_track_geometry(tmp / "exact.csv", true_track)
    on_exact = cond.with_changes(track_geometry=str(exact))
    s = TrackForces().series(TRUTH[None], on_exact)[0]
    s = s + 0.03 * s.std(axis=0) * np.random.default_rng(4).standard_normal(s.shape)
    t = np.arange(cond.n_steps) * cond.sample_interval
    measured = with_measurement_error(true_track, 2e-3, 1.0, np.random.default_rng(9))
    path = write_track_geometry(tmp / "measured.csv", measured)
    on_measured = cond.with_changes(track_geometry=str(path), track_accuracy_mm=2.0)
    return {
        "measured": Recording(t, {"w1L": s[:, 0]}, {"w1L": s[:, 1]}, on_measured),
        "exact": Recording(t, {"w1L": s[:, 0]}, {"w1L": s[:, 1]}, on_exact),
    }


def nsga(rec: Recording):
    return estimate(
        TrackForces(), [rec], PARAMS, NSGAConfig(pop_size=20, n_gen=30, statistic="aligned")
    )


def test_the_bias_of_an_attenuated_estimate_is_taken_off(long_record, tmp_path):
    res = nsga(long_record["measured"])
    choice = res.pareto_x[res.chosen].copy()
    raw = pct(choice)
    assert raw[0] < -0.7 and raw[1] < -0.15, raw  # both gains attenuated by the error
    remove_nsga_geometry_bias(res, [long_record["measured"]], TrackForces(), draws=8, seed=3)
    assert res.geometry_shifts_si.shape == (8, 2) and res.geometry_bias_removed
    # one more error attenuates further: the mean shift is downwards in both parameters
    bias = simex_bias(res.geometry_shifts_si, 2)
    assert np.all(bias < 0), bias
    corrected = pct(res.chosen_x)
    assert np.all(np.abs(corrected) < 0.5 * np.abs(raw)), (raw, corrected)
    np.testing.assert_array_equal(res.pareto_x[res.chosen], choice)  # the choice is kept
    np.testing.assert_allclose(res.chosen_x, choice - bias)
    assert res.bias_kept() == []
    # the Pareto set's range moves with the estimate and still holds it
    iv = res.intervals()
    moved = res.pareto_x - bias
    for j, p in enumerate(PARAMS):
        assert iv[p].low_si == pytest.approx(min(moved[:, j].min(), res.chosen_x[j]))
        assert iv[p].low_si <= res.chosen_x[j] <= iv[p].high_si
    assert "less the track geometry error's bias" in res.route
    table = res.table().set_index("parameter")
    assert table.loc["X13", "nsga_choice"] == pytest.approx(choice[0] / 1e6)
    assert table.loc["X13", "geometry_bias_pct_range"] == pytest.approx(
        100 * bias[0] / (HI - LO)[0]
    )
    scatter = simex_spread(res.geometry_shifts_si, 2)
    assert table.loc["X14", "geometry_scatter_pct_range"] == pytest.approx(
        100 * scatter[1] / (HI - LO)[1]
    )
    saved = json.loads((res.save(tmp_path / "est") / "estimate.json").read_text())
    assert saved["estimate_display"] == res.estimate
    assert saved["nsga_estimate_display"] == res.estimate  # NSGA-II's estimate, less the bias
    assert saved["nsga_choice_display"]["X13"] == pytest.approx(choice[0] / 1e6)
    geometry = saved["nsga_geometry"]
    assert geometry["draws"] == 8 and geometry["bias_removed"]
    assert geometry["bias_pct_range"]["X13"] == pytest.approx(100 * bias[0] / (HI - LO)[0])


def test_intervals_computed_before_the_draws_are_not_reused_after(long_record):
    rec = long_record["measured"]
    res = nsga(rec)
    before = res.intervals()
    remove_nsga_geometry_bias(res, [rec], TrackForces(), draws=2, seed=3)
    after = res.intervals()
    assert after is not before
    assert after["X13"].value_si == pytest.approx(res.chosen_x[0])
    assert before["X13"].value_si == pytest.approx(res.pareto_x[res.chosen][0])


def test_kept_bias_is_reported_but_not_taken_off(long_record):
    res = nsga(long_record["measured"])
    choice = res.pareto_x[res.chosen].copy()
    remove_nsga_geometry_bias(res, [long_record["measured"]], TrackForces(), 4, 3, remove=False)
    assert res.geometry_shifts_si.shape == (4, 2) and not res.geometry_bias_removed
    np.testing.assert_array_equal(res.chosen_x, choice)
    assert "SIMEX" not in res.route
    assert "geometry_bias_pct_range" in res.table().columns


@pytest.mark.parametrize("draws", [0, 4])
def test_nothing_is_drawn_without_a_stated_accuracy_or_draws(long_record, draws):
    """On exact geometry (no accuracy stated) nothing is known of an error to draw; with no
    draws nothing is drawn: the choice stays the estimate, bit for bit."""
    rec = long_record["exact"] if draws else long_record["measured"]
    res = nsga(rec)
    choice = res.pareto_x[res.chosen].copy()
    remove_nsga_geometry_bias(res, [rec], TrackForces(), draws=draws)
    assert res.geometry_shifts_si.size == 0 and not res.geometry_bias_removed
    np.testing.assert_array_equal(res.chosen_x, choice)
    assert res.nsga_geometry_pct_range() == {}
    assert "geometry_bias_pct_range" not in res.table().columns


def test_record_statistics_are_refused(long_record):
    """The shifts are those of the time-aligned least squares: an estimate from record
    statistics is another problem, refused in one line."""
    res = estimate(
        TrackForces(),
        [long_record["measured"]],
        PARAMS,
        NSGAConfig(pop_size=8, n_gen=2, statistic="mean"),
    )
    with pytest.raises(ValueError, match="NSGA-II compared 'mean'"):
        remove_nsga_geometry_bias(res, [long_record["measured"]], TrackForces())
    both = estimate(
        TrackForces(),
        [long_record["measured"]],
        PARAMS,
        NSGAConfig(pop_size=8, n_gen=2, statistic="aligned+std"),
    )
    with pytest.raises(ValueError, match="alone"):
        remove_nsga_geometry_bias(both, [long_record["measured"]], TrackForces())


def test_simex_arithmetic():
    shifts = np.array([[1.0, -2.0], [3.0, -4.0]])
    np.testing.assert_allclose(simex_bias(shifts, 2), [2.0, -3.0])
    np.testing.assert_allclose(simex_spread(shifts, 2), [np.sqrt(5.0), np.sqrt(10.0)])
    np.testing.assert_array_equal(simex_bias(np.zeros((0, 0)), 2), [0.0, 0.0])
    np.testing.assert_array_equal(simex_spread(np.zeros((0, 0)), 2), [0.0, 0.0])
    # kept within the ranges: a bias past a bound stops at it
    span = HI - LO
    x = np.array([LO[0] + 1.0, HI[1] - 1.0])
    far = np.array([[0.4, -0.4], [0.4, -0.4]]) * span
    np.testing.assert_array_equal(less_bias(PARAMS, x, far), [LO[0], HI[1]])
    # rows of sets at once, each less the same bias
    rows = np.stack([LO + 0.5 * span, LO + 0.6 * span])
    np.testing.assert_allclose(less_bias(PARAMS, rows, shifts), rows - [2.0, -3.0])
    # a parameter the draws throw by more than MAX_SCATTER of its range keeps its value
    wild = np.array([[0.1, 0.1], [0.1, 1.5]]) * span
    assert simex_spread(wild, 2)[1] > MAX_SCATTER * span[1]
    mid = LO + 0.5 * span
    np.testing.assert_allclose(less_bias(PARAMS, mid, wild), [mid[0] - 0.1 * span[0], mid[1]])


def test_the_refinement_screens_nsga_ii_s_estimate_beside_its_choice(long_record):
    """A polish after the bias is taken off also scores NSGA-II's estimate as a start (one
    candidate more than the choice, the Pareto set and the nominal parameters)."""
    from railsusp.estimate import refine_estimate

    rec = long_record["measured"]
    res = nsga(rec)
    remove_nsga_geometry_bias(res, [rec], TrackForces(), draws=2, seed=3)
    refine_estimate(res, [rec], TrackForces(), gains=False, screen=0, starts=1, geometry_draws=0)
    # each distinct point once: NSGA-II's estimate, the Pareto set (the choice on it), nominal
    assert res.refinement.screened == 1 + len(res.pareto_x) + 1
    assert not res.refined  # time-aligned: the refinement is a polish beside the estimate
    np.testing.assert_array_equal(res.chosen_x, res.nsga_x)


def test_the_draws_do_not_depend_on_how_they_are_chunked(long_record, monkeypatch):
    """All geometries are drawn before any goes to the model, so the chunks of
    :data:`~railsusp.estimate.output_error.DRAW_CHUNK` conditions change no draw."""
    import railsusp.estimate.output_error as oe

    rec = long_record["measured"]
    x = TRUTH[None]
    whole = oe.geometry_error_series(TrackForces(), [rec, rec], x, draws=5, seed=2)
    monkeypatch.setattr(oe, "DRAW_CHUNK", 3)
    chunked = oe.geometry_error_series(TrackForces(), [rec, rec], x, draws=5, seed=2)
    for a, b in zip(whole, chunked, strict=True):
        for s, t in zip(a, b, strict=True):
            np.testing.assert_array_equal(s, t)
    assert np.abs(whole[0][0] - whole[1][0]).max() > 0  # the draws differ
    assert np.abs(whole[0][0] - whole[0][1]).max() > 0  # and so do the two recordings'
