"""Audit findings in the estimate's NSGA-II, settings, refinement and route, each pinned by
the behaviour it broke: the least-squares choice on objectives averaged over recordings,
the start label of NSGA-II's geometry-corrected estimate, a washout's residuals against
their blocks, seeds past pymoo's range, fractional counts, a constant recorded channel,
the route's model and the held prior's 80 % example."""

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from railsusp.errors import RailsuspInputError
from railsusp.estimate import CalibrationProblem, CalibrationResult, NSGAConfig, refine_estimate
from railsusp.estimate import nsga as nsga_module
from railsusp.estimate.config import LEAST_SQUARES, HeldPrior
from railsusp.estimate.nsga import choose, estimate, estimate_with_seeds
from railsusp.estimate.output_error import OutputError
from railsusp.estimate.refine import refine
from railsusp.estimate.refine_intervals import (
    held_error_variance,
    held_moments,
    refinement_intervals,
)
from railsusp.estimate.residual_noise import autocorrelation_time, effective_sample_size
from railsusp.measured import Recording
from railsusp.params import ParameterSet, bounds
from test_estimate import PARAMS, WaveForces, wave_recording
from test_estimate_aligned import Waves
from test_estimate_aligned import wave_recording as waves_recording
from test_intervals import hetero_recording

DOCS = Path(__file__).resolve().parents[1] / "docs"
LO, HI = bounds(PARAMS)


# 1. the least-squares choice ranks the front by the time-aligned cost


def test_least_squares_choice_sums_the_squared_errors_of_every_recording():
    """Two recordings: A's errors (Y, Q) are (0, 0.3) and (0.6, 0.3), C's (0.25, 0.36) in
    both. The objectives, each force's mean over the recordings, are (0.3, 0.3) and
    (0.25, 0.36), neither dominating; their squares sum to 0.18 and 0.19, so the sum of
    squared objectives took A, but the time-aligned cost (half the sum over recordings and
    forces of the squared errors) is 0.27 for A and 0.19 for C."""
    a = np.array([[0.00, 0.30], [0.60, 0.30]])
    c = np.array([[0.25, 0.36], [0.25, 0.36]])
    errors = np.stack([a, c])  # (points, recordings, forces)
    front = errors.mean(axis=1)
    cost = 0.5 * (errors**2).sum(axis=(1, 2))
    assert cost[1] < cost[0] and (front[0] ** 2).sum() < (front[1] ** 2).sum()
    assert choose(front, LEAST_SQUARES, errors) == 1
    assert choose(front, LEAST_SQUARES, errors.reshape(2, -1)) == 1  # as pymoo keeps them
    # per recording (per_condition) the objectives are the errors: the same choice
    assert choose(errors.reshape(2, -1), LEAST_SQUARES) == 1


def test_aligned_estimate_on_two_recordings_chooses_the_least_cost_on_its_front():
    """NSGA-II on two recordings of conflicting truths, objectives averaged over them (the
    default): the choice is the front's point of least time-aligned cost as the problem
    computes it, where the least summed squared objectives is another point (this seed's
    front has both), and each generation's history takes the same rule."""
    recs = [
        waves_recording(LO + 0.2 * (HI - LO), noise=0.02, seed=1),
        waves_recording(LO + 0.8 * (HI - LO), noise=0.02, seed=2),
    ]
    cfg = NSGAConfig(pop_size=16, n_gen=8, statistic="aligned", seed=0)
    res = estimate(Waves(), recs, PARAMS, cfg)
    e = CalibrationProblem(Waves(), recs, PARAMS, "aligned").errors(res.pareto_x)
    cost = 0.5 * (e**2).sum(axis=(1, 2))
    least = int(np.argmin(cost))
    assert int(np.argmin((res.pareto_f**2).sum(axis=1))) != least  # the old rule's pick
    assert res.chosen == least
    assert res.history[-1] == pytest.approx(res.pareto_x[least])


# 2. the start that is NSGA-II's estimate after its geometry correction


def test_start_from_the_geometry_corrected_estimate_is_named_after_the_correction():
    """NSGA-II's choice biased by 0.2 of each range, the bias removed: the refinement starts
    from the corrected estimate (the truth), which was labelled "NSGA-II's choice before its
    geometry correction" in the start origin and the route."""
    truth = np.array([16.1e6, 8.3e6])
    rec = wave_recording(truth, noise=0.01)
    choice = truth + 0.2 * (HI - LO)
    shifts = np.tile(0.2 * (HI - LO), (8, 1))
    res = CalibrationResult(
        PARAMS,
        choice[None],
        np.zeros((1, 2)),
        0,
        pd.DataFrame(),
        choice[None],
        NSGAConfig(statistic="aligned"),
        geometry_shifts_si=shifts,
        geometry_bias_removed=True,
    )
    assert res.nsga_x == pytest.approx(truth)  # after the correction
    refine_estimate(
        res,
        [rec],
        model=WaveForces(),
        screen=0,
        starts=1,
        max_evaluations=5,
        gains=False,
        polish=False,  # the refined estimate's route names its start
    )
    ref = res.refinement
    named = "NSGA-II's estimate (its choice after its geometry correction)"
    assert ref.start_si == pytest.approx(truth)
    assert ref.start_origin == named and ref.starts[0]["origin"] == named
    assert res.route.endswith(f" from {named}")


# 3. a washout's left-out rows are no residuals


class Washout(WaveForces):
    """WaveForces whose first 50 steps are undefined in every set (a network's washout)."""

    def series(self, x_si, condition):
        s = super().series(x_si, condition).copy()
        s[:, :50] = np.nan
        return s


def test_refinement_residuals_are_the_compared_rows_its_blocks_divide():
    """With undefined leading steps the refinement kept every row's residual but the blocks
    of the compared rows only: they did not add up, and the intervals' effective sample size
    pooled both channels into one block. The residuals are now the compared rows, each
    block a channel, and the interval's n_eff is the sum of each channel's n / τ."""
    rec = hetero_recording(3, 0.02, 0.6)
    ref = refine(Washout(), [rec], PARAMS, LO + 0.4 * (HI - LO), gains=False)
    assert len(ref.residual_blocks) == 2 and min(ref.residual_blocks) > 0
    assert ref.residuals.size == sum(ref.residual_blocks)
    parts = np.split(ref.residuals, np.cumsum(ref.residual_blocks)[:-1])
    n_eff = sum(p.size / autocorrelation_time(p) for p in parts)
    details = refinement_intervals(ref).details
    assert details["effective_sample_size"] == pytest.approx(n_eff, rel=1e-12)
    assert ref.cost == pytest.approx(0.5 * ref.residuals @ ref.residuals, rel=1e-9)


def test_residual_blocks_that_do_not_add_up_are_refused():
    """Blocks that do not add up to the residuals were taken, silently, as one block."""
    r = np.random.default_rng(0).standard_normal(100)
    with pytest.raises(ValueError, match=r"blocks \(40, 50\) add up to 90, not to the 100"):
        effective_sample_size(r, (40, 50))
    assert effective_sample_size(r, ())[0] == pytest.approx(100 / autocorrelation_time(r))


# 4. seeds past pymoo's range


def test_seed_spread_past_the_32_bit_range_is_refused_before_the_first_run(monkeypatch):
    """Run k of the seed spread has seed + k: seed 2**32 - 2 with 3 seeds reached 2**32,
    refused only after the first full NSGA-II run."""
    runs: list[int] = []

    def counted(*args, **kwargs):
        runs.append(args[3].seed)
        raise RuntimeError("a run started")

    monkeypatch.setattr(nsga_module, "estimate", counted)
    cfg = NSGAConfig(pop_size=8, n_gen=2, seed=2**32 - 2)
    rec = wave_recording(np.array([16.1e6, 8.3e6]))
    with pytest.raises(
        RailsuspInputError,
        match=r"^seed 4294967294 with seeds 3: accepted seed \+ seeds - 1 at most 4294967295",
    ):
        estimate_with_seeds(WaveForces(), [rec], PARAMS, cfg, n_seeds=3)
    assert runs == []
    with pytest.raises(RuntimeError, match="a run started"):  # the last seed in range
        estimate_with_seeds(WaveForces(), [rec], PARAMS, cfg, n_seeds=2)
    assert runs == [2**32 - 2]


# 5. counts are integers


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("pop_size", 10.5),
        ("pop_size", 10.0),
        ("n_gen", 3.5),
        ("seed", 1.5),
        ("expected_draws", 2.0),
        ("preview_generations", 1.5),
    ],
)
def test_nsga_config_refuses_a_fractional_count(name, value):
    """pop_size 10.5 failed deep in pymoo, n_gen 3.5 ran 4 generations, seed 1.5 failed in
    numpy: each is refused in one line naming the field and the accepted range."""
    with pytest.raises(RailsuspInputError, match=rf"^{name} {value}: accepted an integer \d+ to"):
        NSGAConfig(**{name: value, "statistic": "aligned"})


def test_integer_counts_of_numpy_are_accepted_and_booleans_refused():
    cfg = NSGAConfig(pop_size=np.int64(8), n_gen=np.int32(3), seed=np.uint32(7))
    assert (cfg.pop_size, cfg.n_gen, cfg.seed) == (8, 3, 7)
    assert all(type(v) is int for v in (cfg.pop_size, cfg.n_gen, cfg.seed))
    with pytest.raises(RailsuspInputError, match=r"^n_gen True: accepted an integer 1 to"):
        NSGAConfig(n_gen=True)


def test_seed_spread_and_refinement_refuse_fractional_counts():
    rec = wave_recording(np.array([16.1e6, 8.3e6]))
    with pytest.raises(RailsuspInputError, match=r"^n_seeds 2.5: accepted an integer 1 to 10"):
        estimate_with_seeds(WaveForces(), [rec], PARAMS, NSGAConfig(), n_seeds=2.5)
    res = estimate(WaveForces(), [rec], PARAMS, NSGAConfig(pop_size=8, n_gen=2))
    with pytest.raises(RailsuspInputError, match=r"^screen 2.5: accepted an integer 0 to"):
        refine_estimate(res, [rec], WaveForces(), screen=2.5)


# 6. a constant recorded channel


def test_output_error_refuses_a_constant_channel_in_one_line():
    """A recording whose vertical force is constant has no spread to scale by: refine()
    ended in scipy's "Residuals are not finite in the initial point"."""
    r0 = wave_recording(np.array([16.1e6, 8.3e6]), noise=0.01)
    f = r0.forces()
    rec = Recording(r0.time, {"w1L": f[:, 0]}, {"w1L": np.full(len(f), 120.0)}, r0.condition)
    msg = r"^recording 'straight': force Q of wheel w1L is constant"
    with pytest.raises(RailsuspInputError, match=msg):
        OutputError(WaveForces(), [rec], PARAMS)
    with pytest.raises(RailsuspInputError, match=msg):
        refine(WaveForces(), [rec], PARAMS, LO + 0.4 * (HI - LO), gains=False)


# 7. the route's model, and the docs


def test_route_names_the_model_the_refinement_compared():
    """refine_estimate(model=...) with a series model other than the simulator: the route
    said "with the simulator" all the same, refined or as a polish."""
    nominal = np.array([ParameterSet.nominal()[p] for p in PARAMS])
    rec = wave_recording(nominal, noise=0.01)
    res = estimate(WaveForces(), [rec], PARAMS, NSGAConfig(pop_size=8, n_gen=2))
    refine_estimate(res, [rec], WaveForces(), screen=0, starts=1, max_evaluations=3)
    assert res.refined
    assert "refined by output-error least squares with the force model WaveForces" in res.route
    assert "simulator" not in res.route
    res.refinement_is_polish = True
    assert "; the output-error refinement with the force model WaveForces is a polish" in (
        res.route
    )
    assert "simulator" not in res.route


def test_intervals_doc_states_how_a_narrower_held_range_scales_the_term():
    """docs/intervals.md's example, the middle 80 % of every held range, said "the term
    times 0.8"; the term is a second moment, which scales by 0.64 (its square root, the
    standard error's part, by 0.8)."""
    held = ("X18", "X19")
    lo, hi = bounds(held)
    nominal = np.array([ParameterSet.nominal()[p] for p in held])
    mid80 = HeldPrior(
        {p: (a + 0.1 * (b - a), b - 0.1 * (b - a)) for p, a, b in zip(held, lo, hi, strict=True)}
    )
    response = np.array([[0.7, -0.4]])
    full = held_error_variance(response, *held_moments(held, nominal))
    narrow = held_error_variance(response, *held_moments(held, nominal, mid80))
    assert narrow / full == pytest.approx(0.64)
    text = " ".join((DOCS / "intervals.md").read_text().split())
    example = re.search(r"the middle 80 % of every range: ([^)]*)\)", text)
    assert example is not None
    assert "0.64" in example.group(1) and "the term times 0.8" not in text
