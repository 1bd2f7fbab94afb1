"""The EN 14363 estimated maximum as an estimation statistic (``p99.85``): analytic values
of the processed force, the recording and the model giving the same number, its use in the
calibration objectives with a series model and with the simulator."""

from __future__ import annotations

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.estimate import parse_statistics
from railsusp.estimate.forces import SimulatorForces
from railsusp.estimate.problem import CalibrationProblem
from railsusp.estimate.statistics import (
    EN14363_MAX,
    en14363_maximum,
    force_statistic,
    measured_statistics,
    series_statistics,
)
from railsusp.measured import Recording
from railsusp.params import ParameterSet
from test_estimate import WaveForces  # the series model with a known answer

FS = 200.0


def sine(f_hz: float, amplitude: float, offset: float, seconds: float = 20.0) -> np.ndarray:
    t = np.arange(int(seconds * FS)) / FS
    return offset + amplitude * np.sin(2 * np.pi * f_hz * t)


def test_maximum_of_a_sine_is_its_sinc_scaled_crest():
    """A sine of wavelength L = v / f run at speed v: the 2 m mean scales it by
    sin(pi 2/L) / (pi 2/L); the 20 Hz low-pass (4th order, both ways) passes 1 Hz with
    gain 1 - 1e-10; the 99.85 % value of a sine is its crest times sin(pi 0.4985)."""
    crest = np.sin(np.pi * (0.9985 - 0.5))
    for speed, f in ((20.0, 1.0), (5.0, 2.0)):  # L = 20 m: 0.984; L = 2.5 m: 0.234
        x = np.pi * 2.0 / (speed / f)
        expected = 30.0 + 10.0 * np.sin(x) / x * crest
        got = en14363_maximum(sine(f, 10.0, 30.0), FS, speed)
        assert got == pytest.approx(expected, abs=2e-3)


def test_the_window_is_one_of_distance_not_time():
    """The same series at another speed is another track: at 5 m/s a 2 Hz sine has a 2.5 m
    wavelength, which the 2 m mean all but removes; at 40 m/s it passes nearly whole."""
    x = sine(2.0, 10.0, 0.0)
    slow, fast = en14363_maximum(x, FS, 5.0), en14363_maximum(x, FS, 40.0)
    assert slow < 3.0 < 9.5 < fast


def test_undefined_first_window_is_left_out_and_other_gaps_give_nan():
    x = np.stack([sine(1.0, 10.0, 30.0), sine(1.0, 5.0, 30.0), np.full(4000, np.nan)])
    ref = en14363_maximum(x[:, 100:], FS, 20.0)
    lead = x.copy()
    lead[:, :100] = np.nan  # a window surrogate: nothing before its first window
    np.testing.assert_allclose(en14363_maximum(lead, FS, 20.0), ref)
    assert np.isnan(ref[2])  # a failed set
    gap = x.copy()
    gap[0, 2000] = np.nan
    out = en14363_maximum(gap, FS, 20.0)
    assert np.isnan(out[0]) and np.isfinite(out[1])


def test_statistic_needs_rate_and_speed():
    with pytest.raises(ValueError, match="needs the sampling rate"):
        force_statistic(sine(1.0, 1.0, 0.0), EN14363_MAX, True)
    with pytest.raises(ValueError, match="running speed above 0"):
        force_statistic(sine(1.0, 1.0, 0.0), EN14363_MAX, True, rate_hz=FS, speed_ms=0.0)


def test_statistic_names():
    assert parse_statistics("mean+p99.85") == ("mean", "p99.85")
    with pytest.raises(ValueError, match="p99.85"):
        parse_statistics("p99.9")


def test_recording_and_model_series_give_the_same_value_over_segments():
    """A 60 s record is three 20 s segments: the statistic is their average, for the
    recording (its rate and condition speed) and for a model's series alike; Y is signed
    (the flange force of the measured wheel), not its magnitude."""
    cond = get_condition("straight", duration_s=60.0, n_steps=3000)  # 50 Hz
    t = np.arange(3000) / 50.0
    y = -2.0 + 8.0 * np.sin(2 * np.pi * 0.5 * t) * (1.0 + (t > 20) + (t > 40))
    q = 120.0 + 5.0 * np.cos(2 * np.pi * 0.3 * t)
    rec = Recording(t, {"w1L": y}, {"w1L": q}, cond)
    meas = measured_statistics(rec, ("p99.85",))
    pred = series_statistics(np.stack([y, q], axis=1)[None], cond, ("p99.85",))
    np.testing.assert_allclose(pred[0], meas, rtol=1e-12)
    parts = [en14363_maximum(p, 50.0, cond.speed) for p in np.array_split(y, 3)]
    assert meas[0, 0] == pytest.approx(np.mean(parts))
    assert meas[0, 0] == pytest.approx(-2.0 + 8.0 * 2.0, abs=0.5)  # crest of the middle part
    assert meas[1, 0] == pytest.approx(125.0, abs=0.1)


def test_objectives_on_the_en14363_maximum_vanish_at_the_truth():
    cond = get_condition("straight", duration_s=20.0, n_steps=1000)
    truth = np.array([[14e6, 10e6]])
    s = WaveForces().series(truth, cond)[0]
    t = np.arange(1000) * cond.sample_interval
    rec = Recording(t, {"w1L": s[:, 0]}, {"w1L": s[:, 1]}, cond)
    prob = CalibrationProblem(WaveForces(), [rec], ("X13", "X14"), statistic="p99.85")
    err = prob.errors(np.array([[14e6, 10e6], [18e6, 10e6], [14e6, 13e6]]))
    assert np.all(err[0] < 1e-6)  # the rates: 1 / median step vs n_steps / duration
    assert err[1, 0, 0] > 0.1 and err[1, 0, 1] < 1e-12  # X13 moves Y only
    assert err[2, 0, 1] > 0.005  # X14 moves Q


def test_simulator_estimation_can_use_the_en14363_maximum():
    """With the simulator as force model (``railsusp estimate --simulator``): a recording
    simulated with some parameters gives zero error there (same design track), and other
    parameters do not."""
    from railsusp.vehicle.simulate import simulate_batch

    cond = get_condition("curve", duration_s=4.0, n_steps=200)
    params = ("X13", "X14")
    truth = ParameterSet({"X13": 16.1, "X14": 8.3}, units="display")
    x = truth.to_array(params)[None]
    r = simulate_batch(x, cond, symbols=params)
    j = r.measured_wheel("auto")
    t = np.arange(cond.n_steps) * cond.sample_interval
    w = "w1R" if j == 1 else "w1L"
    rec = Recording(t, {w: r.Y[0, j] / 1e3}, {w: r.Q[0, j] / 1e3}, cond)
    prob = CalibrationProblem(SimulatorForces(params), [rec], params, statistic="mean+p99.85")
    other = x * np.array([[0.5, 1.5]])
    err = prob.errors(np.vstack([x, other]))
    assert np.all(err[0] < 1e-9)
    assert err[1].max() > 1e-3


def test_a_statistics_surrogate_refuses_the_en14363_maximum_before_optimising():
    """``railsusp estimate --surrogate GP --statistic p99.85``: refused in one line when the
    problem is built (the GPs predict mean, rms, p99 and std only), not in NSGA-II's first
    evaluation."""
    from railsusp.errors import RailsuspInputError
    from railsusp.estimate import StatisticsForces

    cond = get_condition("straight", duration_s=20.0, n_steps=1000)
    s = WaveForces().series(np.array([[14e6, 10e6]]), cond)[0]
    rec = Recording(np.arange(1000) * cond.sample_interval, {"w1L": s[:, 0]}, {"w1L": s[:, 1]},
                    cond)  # fmt: skip
    gp = object.__new__(StatisticsForces)  # no trained GPs needed: refused before any use
    with pytest.raises(RailsuspInputError, match=r"statistic 'p99.85' needs force series") as e:
        CalibrationProblem(gp, [rec], ("X13", "X14"), statistic="mean+p99.85")
    assert "\n" not in str(e.value)
