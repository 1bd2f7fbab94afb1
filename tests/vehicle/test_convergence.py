"""Step convergence: halving the integration step on the study's 20 s records.

The force statistics an estimate is built on (mean, p99, RMS and max of |Y| and Q of the
measured wheel) must not depend on the integration step: between the default step
(SolverSettings.max_step, 1 ms, RK4) and half of it they change by less than
:data:`TOLERANCE`, loaded and tare, on tangent, curve and up-grade with Class 5 track. On
2026-11-24 the largest change was 0.29 % (tare tangent Y max); loaded, 0.09 %. (Replaces a 6 s
check of RMS and max on tangent and curve.)
"""

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.vehicle.simulate import SolverSettings, simulate
from railsusp.vehicle.wagon import load_wagon

TOLERANCE = 0.01  # relative change of a statistic between dt and dt/2
STATISTICS = ("Y_mean", "Y_rms", "Y_p99", "Y_max", "Q_mean", "Q_rms", "Q_p99", "Q_max")


def step_change(condition, wagon, step: float) -> tuple[dict[str, float], bool]:
    """Relative change of each statistic from ``step`` to ``step / 2``, and whether the
    run with ``step`` completed."""
    coarse = simulate(None, condition, wagon=wagon, settings=SolverSettings(max_step=step))
    fine = simulate(None, condition, wagon=wagon, settings=SolverSettings(max_step=step / 2))
    a, b = coarse.statistics(), fine.statistics()
    return {k: abs(a[k] / b[k] - 1.0) for k in STATISTICS}, bool(coarse.ok[0])


@pytest.mark.parametrize("wagon_name", ["loaded", "tare"])
@pytest.mark.parametrize("name", ["straight", "curve", "uphill"])
def test_halving_the_step_on_20_s_records_changes_force_statistics_under_1_percent(
    name, wagon_name
):
    cond = get_condition(name)
    assert cond.duration_s == 20.0 and cond.irregularity_class == 5  # the study's record
    change, ok = step_change(cond, load_wagon(wagon_name), SolverSettings().max_step)
    assert ok
    worst = max(change, key=change.get)
    assert change[worst] < TOLERANCE, f"{worst} changes {change[worst]:.2%}"


def test_the_convergence_check_catches_a_step_too_large():
    """With a 2 ms step the tangent run either fails or its lateral statistics move far
    more than the tolerance when the step is halved (2026-11-24: Y p99 +76 %): the check
    above can fail. (Since the step is kept within RK4's stability bound,
    :mod:`railsusp.vehicle.step_bound`, a 2 ms ``max_step`` is shortened to 1.04 ms at
    60 km/h; the bound is lifted here to show the check, and then a 2 ms ``max_step`` runs
    the default's step.)"""
    import railsusp.vehicle.batch_runs as batch_runs

    bound = batch_runs.set_steps
    try:
        batch_runs.set_steps = lambda wagon, speed, P, max_step: np.full(len(P), max_step)
        change, ok = step_change(get_condition("straight"), load_wagon(), 2e-3)
    finally:
        batch_runs.set_steps = bound
    assert not ok or max(change["Y_mean"], change["Y_p99"]) > 10 * TOLERANCE
    change, ok = step_change(get_condition("straight", duration_s=4.0), load_wagon(), 2e-3)
    assert ok and max(change.values()) < TOLERANCE
