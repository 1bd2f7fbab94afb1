"""Record correction: a GP of log(simulated / predicted record mean) on the key parameters."""

import numpy as np
import pytest

from railsusp.surrogate.correction import MIN_RUNS, RecordCorrection, record_means

TARGETS = ("Y", "Q")
WINDOW = 5


def _runs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Parameters (unit) and simulated series: |Y| alternating sign, Q about a static load."""
    rng = np.random.default_rng(seed)
    x = rng.random((n, 3))
    t = np.arange(60)
    amp = 20.0 * (1.0 + 0.5 * x[:, :1])
    y = amp * np.sin(0.7 * t)[None] + rng.normal(0, 1.0, (n, 60))
    q = 120.0 + 5.0 * np.cos(0.3 * t)[None] + 10.0 * x[:, 1:2]
    return x, np.stack([y, q], axis=2)


def _shrink(x: np.ndarray) -> np.ndarray:
    """A smooth parameter-dependent amplitude error of a network: (n, 2) factors."""
    return np.column_stack([0.95 - 0.04 * x[:, 0] + 0.02 * x[:, 2], 1.0 + 0.003 * x[:, 1]])


def test_learns_a_smooth_amplitude_error_and_removes_it_on_new_runs():
    x, sim = _runs(60, 1)
    corr = RecordCorrection.fit(x, sim, sim * _shrink(x)[:, None, :], TARGETS, WINDOW)
    x_new, sim_new = _runs(20, 2)
    pred_new = sim_new * _shrink(x_new)[:, None, :]
    np.testing.assert_allclose(corr.factors(x_new), 1.0 / _shrink(x_new), rtol=2e-3)
    before = np.abs(
        record_means(pred_new, TARGETS, WINDOW) / record_means(sim_new, TARGETS, WINDOW) - 1
    )
    fixed = corr.apply(pred_new, x_new)
    after = np.abs(
        record_means(fixed, TARGETS, WINDOW) / record_means(sim_new, TARGETS, WINDOW) - 1
    )
    assert before[:, 0].mean() > 0.04 and after[:, 0].mean() < 2e-3
    assert after[:, 1].mean() < 1e-3


def test_round_trip_through_a_dict_gives_the_same_factors():
    x, sim = _runs(30, 3)
    corr = RecordCorrection.fit(x, sim, sim * _shrink(x)[:, None, :], TARGETS, WINDOW)
    back = RecordCorrection.from_dict(corr.to_dict())
    x_new, _ = _runs(7, 4)
    np.testing.assert_array_equal(back.factors(x_new), corr.factors(x_new))


def test_too_few_runs_with_finite_means_are_refused():
    x, sim = _runs(MIN_RUNS + 1, 5)
    pred = sim.copy()
    pred[:2, :, 0] = 0.0  # two runs predicted flat: no finite ratio
    with pytest.raises(ValueError, match=f"at least {MIN_RUNS} runs"):
        RecordCorrection.fit(x, sim, pred, TARGETS, WINDOW)


def test_more_runs_than_the_cap_are_fitted_on_a_seeded_draw(monkeypatch):
    """The GP's cost grows as the cube of its runs: past ``MAX_RUNS`` it is fitted on a
    draw of them (the same draw for the same seed), and still removes the error."""
    import railsusp.surrogate.correction as correction

    x, sim = _runs(60, 6)
    pred = sim * _shrink(x)[:, None, :]
    monkeypatch.setattr(correction, "MAX_RUNS", 40)
    corr = RecordCorrection.fit(x, sim, pred, TARGETS, WINDOW, seed=1)
    assert corr.x_unit.shape == (40, 3) and corr.log_ratio.shape == (40, 2)
    rows = {tuple(r) for r in x.round(12)}
    assert all(tuple(r) in rows for r in corr.x_unit.round(12))  # runs of the training set
    again = RecordCorrection.fit(x, sim, pred, TARGETS, WINDOW, seed=1)
    np.testing.assert_array_equal(again.x_unit, corr.x_unit)
    other = RecordCorrection.fit(x, sim, pred, TARGETS, WINDOW, seed=2)
    assert not np.array_equal(other.x_unit, corr.x_unit)
    assert RecordCorrection.fit(x, sim, pred, TARGETS, WINDOW, max_runs=60).x_unit.shape[0] == 60
    x_new, _ = _runs(20, 7)
    np.testing.assert_allclose(corr.factors(x_new), 1.0 / _shrink(x_new), rtol=3e-3)


def test_the_cap_draws_from_the_runs_with_finite_means_only():
    x, sim = _runs(30, 8)
    pred = sim * _shrink(x)[:, None, :]
    pred[:5, :, 0] = 0.0  # five runs predicted flat: no finite ratio, never drawn
    corr = RecordCorrection.fit(x, sim, pred, TARGETS, WINDOW, max_runs=20)
    assert corr.x_unit.shape[0] == 20 and np.isfinite(corr.log_ratio).all()
    flat = {tuple(r) for r in x[:5].round(12)}
    assert not flat & {tuple(r) for r in corr.x_unit.round(12)}
    with pytest.raises(ValueError, match=f"max_runs: 3, accepted {MIN_RUNS} or more"):
        RecordCorrection.fit(x, sim, pred, TARGETS, WINDOW, max_runs=3)
