"""The estimate's steps in order (railsusp.estimate.route), shared by ``railsusp estimate``
and the pipeline's estimate stage."""

from __future__ import annotations

import numpy as np
import pytest
from test_level_correction import PARAMS, TRUTH, Linear, recording  # noqa: F401 (fixture)

from railsusp.errors import RailsuspInputError
from railsusp.estimate import NSGAConfig, estimate_with_seeds
from railsusp.estimate.level_correction import correct_by_simulator
from railsusp.estimate.route import EstimateRoute
from railsusp.measured import Recording
from test_estimate import COND


def _route(**changes) -> EstimateRoute:
    settings = {
        "nsga": NSGAConfig(pop_size=12, n_gen=10, seed=3, statistic="aligned"),
        "seeds": 1,
        "geometry_draws": 0,
        "remove_geometry_bias": True,
        "simulator_corrections": 1,
        "refine": False,
        "refine_evaluations": 10,
        "refine_screen": 4,
        "refine_starts": 1,
    }
    return EstimateRoute(**(settings | changes))


class Counted(Linear):
    """The linear model, counting its predictions."""

    calls = 0

    def series(self, x_si, condition):
        Counted.calls += 1
        return super().series(x_si, condition)


def test_the_route_runs_its_steps_in_order_and_shows_each(recording):  # noqa: F811
    """NSGA-II, then (exact track: no geometry step) one simulator correction: the same
    estimate as the two calls made by hand, each step shown while it runs, in order."""
    surrogate, reference = Linear(offset=-0.2), Linear()
    shown: list[str] = []

    class Shown:
        def __init__(self, text: str):
            shown.append(text)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    res = _route().run(surrogate, [recording], PARAMS, progress=Shown, simulator=reference)
    assert shown == [
        "NSGA-II 12 x 10 on 1 recording(s)",
        "1 simulator correction(s) of the estimate",
    ]
    by_hand = estimate_with_seeds(surrogate, [recording], PARAMS, _route().nsga, n_seeds=1)
    correct_by_simulator(by_hand, [recording], surrogate, 1, simulator=reference)
    np.testing.assert_array_equal(res.chosen_x, by_hand.chosen_x)
    assert res.chosen_x[1] == pytest.approx(TRUTH[1], rel=0.005)  # the level error gone


def test_its_refusals_name_the_setting_as_the_caller_spells_it_before_nsga_ii(recording):  # noqa: F811
    """A refinement of recordings without measured track and simulator corrections of a
    comparison other than 'aligned' are refused in one line naming the caller's setting
    (the command line's option or the configuration's key), before any prediction."""
    Counted.calls = 0
    blind = Recording(recording.time, recording.Y, recording.Q, COND.with_changes(
        duration_s=20.0, n_steps=1000))  # fmt: skip
    with pytest.raises(RailsuspInputError, match="--refine compares time-aligned series"):
        _route(refine=True, refine_setting="--refine").run(Counted(), [blind], PARAMS)
    mean = NSGAConfig(pop_size=12, n_gen=10, seed=3, statistic="mean")
    needle = (
        "estimate.simulator_corrections corrects the time-aligned least squares; statistic 'mean'"
    )
    with pytest.raises(RailsuspInputError, match=needle):
        _route(nsga=mean, corrections_setting="estimate.simulator_corrections").run(
            Counted(), [recording], PARAMS
        )
    assert Counted.calls == 0


def test_the_route_passes_first_order_settings_to_the_corrections(recording):  # noqa: F811
    """correction_slopes and slope_update reach the corrections: the route's estimate is
    the one made by hand with them, and the result records the update."""
    surrogate, reference = Linear(slope=0.8, offset=-0.3), Linear()
    route = _route(simulator_corrections=2, correction_slopes=True, slope_update="broyden")
    res = route.run(surrogate, [recording], PARAMS, simulator=reference)
    by_hand = estimate_with_seeds(surrogate, [recording], PARAMS, route.nsga, n_seeds=1)
    correct_by_simulator(
        by_hand, [recording], surrogate, 2, simulator=reference, slopes=True,
        slope_update="broyden",
    )  # fmt: skip
    np.testing.assert_array_equal(res.chosen_x, by_hand.chosen_x)
    assert res.correction_slopes and res.correction_slope_update == "broyden"
    assert len(res.correction_checks) == 2


def test_broyden_without_first_order_corrections_is_refused_before_nsga_ii(recording):  # noqa: F811
    """The route refuses slope_update = 'broyden' without correction_slopes before NSGA-II
    runs (the model is never called)."""
    Counted.calls = 0
    with pytest.raises(RailsuspInputError, match="slope_update 'broyden' updates the slopes"):
        _route(slope_update="broyden").run(Counted(), [recording], PARAMS, simulator=Linear())
    assert Counted.calls == 0


def test_a_recording_sampled_otherwise_than_its_table_is_refused_before_any_prediction(
    recording,  # noqa: F811
):
    """A sidecar's n_steps at another rate than its table's rows: the time-aligned
    comparison failed in NSGA-II's first generation, a refinement after the whole of
    NSGA-II ("has 1000 samples, the model predicts 2000"); refused first, naming
    condition.n_steps and the table's rate."""
    Counted.calls = 0
    other = Recording(recording.time, recording.Y, recording.Q,
                      recording.condition.with_changes(n_steps=2000))  # fmt: skip
    needle = r"condition.n_steps 2000 samples its 20 s at 100 Hz, its table has 1000 rows at 50 Hz"
    with pytest.raises(RailsuspInputError, match=needle):
        _route(simulator_corrections=0).run(Counted(), [other], PARAMS)
    mean = NSGAConfig(pop_size=4, n_gen=1, seed=3, statistic="mean")
    with pytest.raises(RailsuspInputError, match="--refine \\(the output-error refinement\\)"):
        _route(nsga=mean, simulator_corrections=0, refine=True, refine_setting="--refine").run(
            Counted(), [other], PARAMS
        )
    assert Counted.calls == 0


def test_a_held_prior_on_an_estimated_parameter_is_said(recording):  # noqa: F811
    """A pipeline's key parameters are found after its configuration is read: a held prior
    on one of them is said in a warning (it was only ``held_prior_unused`` in the JSON)."""
    from railsusp.estimate.config import HeldPrior

    prior = HeldPrior.from_display({"X15": [150, 190], "X13": [12, 16]})
    route = _route(nsga=NSGAConfig(pop_size=4, n_gen=1, statistic="aligned"),
                   simulator_corrections=0, held_prior=prior)  # fmt: skip
    with pytest.warns(UserWarning, match="held_prior: X13 estimated, so its range is not used"):
        route.run(Linear(), [recording], PARAMS)
