"""The time-aligned comparison with each channel's gain profiled out: the least-squares gain
within the instrument's tolerance, an error of zero for a recording that differs from the
model by a gain alone, and the geometry's shifts unchanged by a gain error."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.errors import RailsuspInputError
from railsusp.estimate import NSGAConfig, aligned_error
from railsusp.estimate.comparison import GAIN_LIMIT, channel_gains
from railsusp.estimate.geometry_bias import geometry_shifts_at
from railsusp.estimate.problem import CalibrationProblem
from railsusp.measured import Recording
from test_estimate import ON_TRACK, PARAMS, TrackForces, WaveForces, wave_recording

TRUTH = np.array([16.1e6, 8.3e6])


def test_the_gain_is_the_least_squares_one_clipped_to_the_tolerance():
    rng = np.random.default_rng(0)
    m = 120.0 + rng.standard_normal(400)
    pred = np.stack([m / 1.04, m / 1.3, np.zeros_like(m), m / 0.97 + 0.5])
    g = channel_gains(pred, m)
    assert g[0] == pytest.approx(1.04, rel=1e-12)
    assert g[1] == 1.0 + GAIN_LIMIT  # 1.3 lies outside the tolerance: its bound
    assert g[2] == 1.0  # no signal, no gain
    p = pred[3]
    assert g[3] == pytest.approx(p @ m / (p @ p), rel=1e-12)
    # the gain minimises the squared misfit: any other within the tolerance does worse
    for other in np.linspace(1.0 - GAIN_LIMIT, 1.0 + GAIN_LIMIT, 41):
        assert np.sum((g[3] * p - m) ** 2) <= np.sum((other * p - m) ** 2) + 1e-9
    # undefined leading samples (a washout) are left out, not turned into NaN
    led = pred[:1].copy()
    led[0, :50] = np.nan
    assert channel_gains(led, m)[0] == pytest.approx(
        m[50:] @ led[0, 50:] / (led[0, 50:] ** 2).sum()
    )


def test_a_recording_off_by_a_gain_alone_compares_as_exact_with_gains():
    """Q recorded with a 4 % gain error: without gains the truth misfits by the 4.8 kN it
    shifts the 120 kN wheel load; with them its error is nil, and only the Q channel's."""
    rec = wave_recording(TRUTH)
    rec.Q["w1L"] = rec.Q["w1L"] * 1.04
    pred = WaveForces().series(TRUTH[None], ON_TRACK)
    plain = aligned_error(pred, rec)
    assert plain[0, 1] > 0.5 and plain[0, 0] < 1e-12
    assert np.all(aligned_error(pred, rec, gains=True) < 1e-9)
    # outside the tolerance the gain stops at its bound: the error is that of 1.1
    rec.Q["w1L"] = rec.Q["w1L"] / 1.04 * 1.3
    bounded = pred * [1.0, 1.0 + GAIN_LIMIT]
    np.testing.assert_allclose(
        aligned_error(pred, rec, gains=True)[:, 1], aligned_error(bounded, rec)[:, 1], rtol=1e-9
    )


def test_the_problem_profiles_gains_only_for_the_time_aligned_comparison():
    rec = wave_recording(TRUTH)
    rec.Q["w1L"] = rec.Q["w1L"] * 0.97
    x = np.array([TRUTH, TRUTH * [1.0, 1.05]])
    with_gains = CalibrationProblem(WaveForces(), [rec], PARAMS, "aligned", gains=True)
    without = CalibrationProblem(WaveForces(), [rec], PARAMS, "aligned")
    e, e0 = with_gains.errors(x)[:, 0], without.errors(x)[:, 0]
    assert e[0, 1] < 1e-9 < e0[0, 1]  # the truth fits with the gain
    assert e[1, 1] > 1e-3  # X14 off by 5 % still misfits (a gain cannot make its shape)
    with pytest.raises(RailsuspInputError, match="channel gains with the statistic 'mean'"):
        CalibrationProblem(WaveForces(), [rec], PARAMS, "mean", gains=True)
    with pytest.raises(RailsuspInputError, match="channel_gains with statistic 'p99'"):
        NSGAConfig(statistic="p99", channel_gains=True)
    assert NSGAConfig(statistic="aligned", channel_gains=True).to_dict()["channel_gains"]


class CurvingTrackForces(TrackForces):
    """:class:`TrackForces` with a steady 25 kN lateral force, as in a curve: without it the
    lateral force is X13 times the alignment, and a gain of Y is X13 itself."""

    def series(self, x_si, condition):
        return super().series(x_si, condition) + np.array([25.0, 0.0])


def test_with_gains_the_errors_and_geometry_shifts_do_not_see_a_gain_error(tmp_path):
    """Each channel's misfit is scaled by its measured standard deviation, so a gain error f
    scales the profiled misfit's numerator and denominator alike: the comparison, and the
    geometry's shifts of its estimate, are the same for a recording with gain errors of
    -2 % on Y and 3 % on Q as for the recording without them. Compared plainly they are
    not."""
    from railsusp.vehicle.track import synthesise
    from railsusp.vehicle.track_geometry import with_measurement_error, write_track_geometry
    from test_estimate import COND

    true_track = synthesise(1800.0, 5, 1, dx=0.125)
    cond = COND.with_changes(duration_s=100.0, n_steps=5000)
    exact = write_track_geometry(tmp_path / "e.csv", true_track)
    model = CurvingTrackForces()
    s = model.series(TRUTH[None], cond.with_changes(track_geometry=str(exact)))[0]
    s = s + 0.03 * s.std(axis=0) * np.random.default_rng(4).standard_normal(s.shape)
    measured = with_measurement_error(true_track, 2e-3, 1.0, np.random.default_rng(9))
    on_measured = cond.with_changes(
        track_geometry=str(write_track_geometry(tmp_path / "m.csv", measured)),
        track_accuracy_mm=2.0,
    )
    t = np.arange(cond.n_steps) * cond.sample_interval
    clean = Recording(t, {"w1L": s[:, 0]}, {"w1L": s[:, 1]}, on_measured)
    gained = Recording(t, {"w1L": 0.98 * s[:, 0]}, {"w1L": 1.03 * s[:, 1]}, on_measured)
    x = TRUTH * np.array([[1.0, 1.0], [1.1, 0.95], [0.9, 1.05]])
    pred = model.series(x, on_measured)
    np.testing.assert_allclose(
        aligned_error(pred, gained, gains=True), aligned_error(pred, clean, gains=True), rtol=1e-9
    )
    assert not np.allclose(aligned_error(pred, gained), aligned_error(pred, clean), rtol=0.01)

    def shifts(rec: Recording, gains: bool) -> np.ndarray:
        return geometry_shifts_at(model, [rec], PARAMS, TRUTH, draws=3, seed=1, gains=gains)

    profiled = shifts(gained, True)
    assert profiled.shape == (3, 2) and np.all(np.abs(profiled) > 1e3)
    np.testing.assert_allclose(profiled, shifts(clean, True), rtol=1e-6)
    assert not np.allclose(shifts(gained, False), shifts(clean, False), rtol=0.01)


def test_nsga_with_gains_reports_them_and_is_not_led_off_by_a_gain_error(tmp_path):
    """A 4 % gain error on the wheel load: NSGA-II on the plain comparison trades X14 (the
    vertical force's dynamic amplitude) against it; profiling the gain out, its choice is
    at the truth and the result carries the gains it found there (estimate.json too)."""
    import json

    from railsusp.estimate import estimate
    from railsusp.params import bounds

    rec = wave_recording(TRUTH)
    rec.Q["w1L"] = rec.Q["w1L"] * 1.04
    lo, hi = bounds(PARAMS)
    cfg = dict(pop_size=16, n_gen=30, statistic="aligned", seed=3)
    plain = estimate(WaveForces(), [rec], PARAMS, NSGAConfig(**cfg))
    profiled = estimate(WaveForces(), [rec], PARAMS, NSGAConfig(**cfg, channel_gains=True))
    assert plain.channel_gains == {}
    err = lambda r: np.abs(r.pareto_x[r.chosen] - TRUTH) / (hi - lo)  # noqa: E731
    # X14 and the wheel load's gain are fixed by the 120 kN mean; X13 and the lateral gain
    # trade along a flat valley (Y = g 3 a sin + g b), so only their product is asserted
    assert err(profiled)[1] < 0.01 and err(plain)[1] > 0.05
    assert profiled.channel_gains["straight:Q_w1L"] == pytest.approx(1.04, abs=0.002)
    x13 = profiled.pareto_x[profiled.chosen][0]
    assert profiled.channel_gains["straight:Y_w1L"] * x13 == pytest.approx(TRUTH[0], rel=0.01)
    assert "each force channel's gain profiled out" in profiled.route
    saved = json.loads((profiled.save(tmp_path / "est") / "estimate.json").read_text())
    assert saved["channel_gains"] == profiled.channel_gains
    assert saved["config"]["channel_gains"] is True


def test_the_geometry_draws_and_the_run_hash_follow_the_setting(monkeypatch):
    """NSGA-II's geometry shifts are taken with the gains where its comparison profiled
    them; a pipeline run with the setting off hashes its estimate stage as before the
    setting existed (old runs stay up to date), on re-estimates."""
    from railsusp.estimate import estimate, nsga_geometry
    from railsusp.pipeline_config import PipelineConfig
    from railsusp.pipeline_inputs import stage_section

    asked = []

    def shifts(model, recordings, parameters, x_si, draws, seed, gains=False):
        asked.append(gains)
        return np.zeros((draws, len(parameters)))

    monkeypatch.setattr(nsga_geometry, "geometry_shifts_at", shifts)
    monkeypatch.setattr(nsga_geometry, "takes_geometry_bias", lambda *a: True)
    rec = wave_recording(TRUTH)
    for on in (False, True):
        cfg = NSGAConfig(pop_size=8, n_gen=2, statistic="aligned", channel_gains=on)
        res = estimate(WaveForces(), [rec], PARAMS, cfg)
        nsga_geometry.remove_nsga_geometry_bias(res, [rec], WaveForces(), draws=2)
    assert asked == [False, True]
    assert "channel_gains" not in stage_section(PipelineConfig(), "estimate")
    on = PipelineConfig(estimate={"statistic": "aligned", "channel_gains": True})
    assert stage_section(on, "estimate")["channel_gains"] is True


def test_statistics_beside_the_comparison_see_the_same_gains():
    """With ``aligned+mean`` the mean wheel load is compared as the gain-scaled prediction
    gives it: at the truth, on a recording whose wheel load reads 4 % high, both parts
    vanish with gains and the mean's relative error is the gain's 4 % without."""
    rec = wave_recording(TRUTH)
    rec.Q["w1L"] = rec.Q["w1L"] * 1.04
    x = TRUTH[None]
    with_gains = CalibrationProblem(WaveForces(), [rec], PARAMS, "aligned+mean", gains=True)
    plain = CalibrationProblem(WaveForces(), [rec], PARAMS, "aligned+mean")
    assert with_gains.errors(x)[0, 0, 1] < 1e-6
    # the vertical objective averages the aligned error and the mean's relative error
    mean_part = (
        2 * plain.errors(x)[0, 0, 1] - aligned_error(WaveForces().series(x, ON_TRACK), rec)[0, 1]
    )
    assert mean_part == pytest.approx(1 - 1 / 1.04, rel=1e-3)
