"""The posterior's settings refuse counts that are not whole numbers or out of range, in one
line naming the field and its range, when they are made (the configuration audit of stop
64: ``ensemble = 1.5`` failed with a TypeError after 42 s of simulation, ``product_sections``
2.7 was cut to 2); the command line states the same ranges (one source)."""

import inspect
import typing

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate.posterior_settings import PosteriorSettings

runner = CliRunner()
STRAIGHT = (get_condition("straight"),)
SMALL = {"n_train": 20, "n_check": 10, "n_calibration": 0}


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"n_train": 20.5}, "n_train = 20.5: accepted an integer 20 to 1000000"),
        ({"n_check": 10.0}, "n_check = 10.0: accepted an integer 10 to 100000"),
        ({"seed": 1.5}, "seed = 1.5: accepted an integer 0 to 4294967295"),
        ({"ensemble": 1.5}, "ensemble = 1.5: accepted an integer 1 to 20"),
        ({"samples": 150.5}, "samples = 150.5: accepted an integer 100 to 100000"),
        ({"condition_offset": 0.5}, "condition_offset = 0.5: accepted an integer 0 to 9"),
        ({"hidden_features": 0}, "hidden_features = 0: accepted 1 to 1000"),
        ({"hidden_features": 2.5}, "hidden_features = 2.5: accepted an integer 1 to 1000"),
        ({"num_transforms": -1}, "num_transforms = -1: accepted 1 to 50"),
        ({"projection_rank": True}, "projection_rank = True: accepted an integer 1 to 1000"),
        (
            {"n_calibration": 20.5},
            "n_calibration = 20.5: accepted an integer, 0 (no correction) or 20 to 100000",
        ),
        (
            {"product_sections": (2.7,)},
            "product_sections = 2.7: accepted distinct section "
            "counts from 2 to 1000, whole numbers",
        ),
        (
            {"product_sections": (2, 4), "product_cases": (30, 20.5)},
            "product_cases = 30,20.5: "
            "accepted one count from 20 to 100000 per entry of product_sections (2), whole "
            "numbers",
        ),
        (
            {"product_sections": (2,), "n_product": 30.5},
            "n_product = 30.5: accepted an integer 20 to 100000",
        ),
        (
            {"statistics": ("all",), "statistics_emulator_cases": 20.5},
            "statistics_emulator_cases = 20.5: accepted an integer, 0 or 20 to the training "
            "cases, n_train = 20",
        ),
    ],
)
def test_a_count_that_is_not_a_whole_number_in_range_is_one_line(changes, message):
    with pytest.raises(RailsuspInputError) as err:
        PosteriorSettings(STRAIGHT, **{**SMALL, **changes})
    assert str(err.value) == message


def test_the_audits_ensemble_of_one_and_a_half_is_refused_before_any_simulation():
    """It reached ``posterior.train`` and failed after the simulations with "TypeError:
    'float' object cannot be interpreted as an integer"; the settings now refuse it."""
    with pytest.raises(RailsuspInputError, match=r"^ensemble = 1\.5: accepted an integer"):
        PosteriorSettings(STRAIGHT, **SMALL, ensemble=1.5)


def test_numpy_counts_are_taken_as_python_ints_and_product_sets_sorted():
    s = PosteriorSettings(
        STRAIGHT, **{**SMALL, "n_train": np.int64(30)}, product_sections=(np.int64(4), 2),
        product_cases=(20, 30),
    )  # fmt: skip
    assert type(s.n_train) is int and s.n_train == 30
    assert s.product_sections == (2, 4) and s.product_cases == (30, 20)
    assert all(type(k) is int for k in (*s.product_sections, *s.product_cases))


def test_a_projection_rank_beside_the_summary_alone_is_refused():
    """The EN 14363 summary is read as it is: the rank was silently ignored."""
    with pytest.raises(RailsuspInputError, match="projection_rank = 5 conflicts with statistics"):
        PosteriorSettings(STRAIGHT, **SMALL, projection_rank=5)
    assert PosteriorSettings(STRAIGHT, **SMALL, statistics=("all",), projection_rank=5)


def test_the_command_line_states_the_settings_ranges():
    """One source: the defaults and ranges the options state are the settings'."""
    from railsusp.cli import posterior as cli
    from railsusp.estimate.posterior_settings import DEFAULT_PROJECTION_RANK, POSTERIOR_COUNTS

    hints = typing.get_type_hints(cli.train_command, include_extras=True)
    low, high = POSTERIOR_COUNTS["samples"]
    assert f"({low} to {high};" in hints["samples"].__metadata__[0].help
    default = inspect.signature(cli.train_command).parameters["projection_rank"].default
    assert default == DEFAULT_PROJECTION_RANK
    args = ["posterior", "train", "--out", "unused", "--product-sections", "two"]
    low, high = POSTERIOR_COUNTS["product_sections"]
    result = runner.invoke(app, args)
    assert result.exit_code == 2 and f"accepted whole numbers from {low} to {high}" in result.output
