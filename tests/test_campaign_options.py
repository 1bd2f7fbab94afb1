"""``railsusp campaign`` options that did nothing, refused (the surrogate options audit;
each test failed on the code before)."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from railsusp.campaign import CampaignError, make_config
from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.params import MAIN_SUSPENSION

runner = CliRunner()
SHORT = [get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0, name="short")]


def _error(args: list) -> str:
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1, result.output
    return lines[0]


@pytest.mark.parametrize("design", ["lhs", "lhs-optimised"])
def test_second_order_is_refused_without_a_saltelli_design(tmp_path, design):
    """It was stored and unused, yet changed the configuration's hash."""
    # (a campaign that nothing stops runs no batch: the code before accepted it)
    line = _error(["campaign", "--out", tmp_path / "c", "--design", design, "--second-order",
                   "--samples", "8", "--max-batches", "0"])  # fmt: skip
    assert line == (
        f"error: --second-order: accepted only with --design sobol (a Saltelli design), not "
        f"{design}"
    )
    assert not (tmp_path / "c").exists()
    with pytest.raises(
        CampaignError, match=f"second_order: accepted only with design sobol.*{design}"
    ):
        make_config(SHORT, 8, design=design, second_order=True, parameters=("X13", "X14"))
    make_config(SHORT, 64, design="sobol", second_order=True, parameters=("X13", "X14"))


def test_keys_from_refuses_parameters_typed_as_their_default(tmp_path):
    """--parameters X11,...,X20 (the default, typed) with --keys-from was taken as not
    given, and the keys replaced it silently."""
    line = _error(["campaign", "--out", tmp_path / "c", "--keys-from", tmp_path,
                   "--parameters", ",".join(MAIN_SUSPENSION)])  # fmt: skip
    assert line == "error: --keys-from and --parameters: give one of them, not both"
    line = _error(["campaign", "--out", tmp_path / "c", "--keys-from", tmp_path])
    assert "no sensitivity analysis there" in line  # --parameters not given: none refused
