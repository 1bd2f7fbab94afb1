"""Command line: the catalogue, conditions and track commands, and one-line input errors."""

import subprocess
import sys

import pytest
from typer.testing import CliRunner

from railsusp.cli import app

runner = CliRunner()


def test_params_prints_catalogue_with_override():
    result = runner.invoke(app, ["params", "--set", "X13=16.1"])
    assert result.exit_code == 0, result.output
    assert "X20" in result.output and "16.1" in result.output
    assert "primary longitudinal" in result.output


def test_conditions_prints_the_three():
    result = runner.invoke(app, ["conditions"])
    assert result.exit_code == 0, result.output
    for name in ("straight", "curve", "uphill"):
        assert name in result.output
    assert "300" in result.output and "+12" in result.output


def test_track_writes_plot(tmp_path):
    out = tmp_path / "t.png"
    result = runner.invoke(app, ["track", "--class", "5", "--length", "800", "--plot", str(out)])
    assert result.exit_code == 0, result.output
    assert out.stat().st_size > 10_000
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["params", "--set", "X99=1"], "unknown parameter 'X99'"),
        (["params", "--set", "X13=30"], "outside the accepted range [7, 21] MN/m"),
        (["conditions", "bogus"], "unknown condition 'bogus'"),
        (["track", "--class", "9"], "irregularity_class = 9"),
        (["track", "--length", "-1"], "--length"),
    ],
)
def test_bad_input_is_one_line_with_status_2(args, needle):
    # a real process, so that stderr, exit status and the absence of a traceback are checked
    proc = subprocess.run(
        [sys.executable, "-m", "railsusp.cli", *args], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2, proc.stderr
    assert needle in proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_demo_prints_catalogue_conditions_and_track_summary():
    result = runner.invoke(app, ["demo"])
    assert result.exit_code == 0, result.output
    assert "Parameter catalogue" in result.output
    assert "Working conditions" in result.output
    assert "Synthesised track input" in result.output
