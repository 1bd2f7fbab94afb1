"""Bad estimation settings and recordings: a one-line error naming the setting and what is
accepted, exit status 2, before the recordings are read or NSGA-II runs."""

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import (
    CalibrationProblem,
    NSGAConfig,
    SimulatorForces,
    estimate,
    estimate_with_seeds,
    refine_estimate,
)
from railsusp.measured import Recording

runner = CliRunner()
COND = get_condition("straight", duration_s=2.0, n_steps=100)
PARAMS = ("X13", "X14")


def one_line_error(result) -> str:
    """The single line a refused command prints, after checking exit status 2."""
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0].removeprefix("error: ")


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    """Two seconds of synthetic recordings without track geometry."""
    root = tmp_path_factory.mktemp("field")
    cond = root / "c.toml"
    cond.write_text('[[condition]]\nname = "short"\nduration_s = 2.0\nn_steps = 100\n')
    out = root / "field"
    result = runner.invoke(
        app, ["synth-field", "--truth", "X13=16.1", "--conditions", str(cond), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    return out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--n-gen", "0"], "--n-gen 0: accepted 1 to 100000"),  # was a ZeroDivisionError
        (["--crossover", "5"], "--crossover 5: accepted 0 to 1"),  # was accepted
        (["--crossover", "nan"], "--crossover nan: accepted 0 to 1"),
        (["--mutation", "-1"], "--mutation -1: accepted 0 to 1"),  # was accepted
        (["--seeds", "-3"], "--seeds -3: accepted 1 to 10"),  # was read as 1
        (["--seeds", "11"], "--seeds 11: accepted 1 to 10"),
        (["--pop-size", "3"], "--pop-size 3: accepted 4 to 10000"),
        (["--seed", "-1"], "--seed -1: accepted 0 to 4294967295"),
        # were checked only after NSGA-II had run
        (["--refine", "--refine-starts", "0"], "--refine-starts 0: accepted 1 to 20"),
        (["--refine-screen", "-1"], "--refine-screen -1: accepted 0 to 10000"),
        (["--refine-evaluations", "0"], "--refine-evaluations 0: accepted 1 to 500"),
        (  # accepted on the command line, refused in a configuration (audit of stop 60)
            ["--refine", "--refine-screen", "1", "--refine-starts", "2"],
            "--refine-screen 1 screens fewer points than --refine-starts 2 starts; accepted "
            "--refine-screen 0 (no screening) or at least --refine-starts",
        ),
        (["--geometry-draws", "101"], "--geometry-draws 101: accepted 0 to 100"),
        (
            ["--held-prior", "X15=100:200"],
            "--held-prior: only with --refine and a statistic other than aligned (the refined "
            "intervals take it)",
        ),
        (
            ["--refine", "--statistic", "mean+aligned", "--held-prior", "X15=100:200"],
            "--held-prior: only with --refine and a statistic other than aligned (the refined "
            "intervals take it)",
        ),
        (
            ["--refine", "--held-prior", "X15=100"],
            "--held-prior: 'X15=100': accepted SYMBOL=LOW:HIGH in display units, "
            "comma-separated (e.g. X15=100:200,X19=20000:40000)",
        ),
        (
            ["--refine", "--held-prior", "X15=10:200"],
            "--held-prior.X15 = [10, 200] MN/m reaches outside X15's Table 2 range; accepted "
            "[low, high] with 85 <= low < high <= 255 MN/m",
        ),
        (
            ["--refine", "--held-prior", "X99=1:2"],
            "--held-prior.X99: unknown parameter; accepted the main-suspension parameters "
            "X11..X20 or their names",
        ),
    ],
)
def test_bad_option_is_refused_before_the_recordings_are_read(tmp_path, args, message):
    """The recordings folder does not exist: the option is refused first."""
    out = tmp_path / "est"
    result = runner.invoke(
        app,
        ["estimate", "--measured", str(tmp_path / "no-field"), "--simulator", "--out", str(out),
         *args],
    )  # fmt: skip
    assert one_line_error(result) == message
    assert not out.exists()


def test_out_that_is_a_file_is_refused(tmp_path, field):
    out = tmp_path / "est"
    out.write_text("not a folder")
    result = runner.invoke(
        app, ["estimate", "--measured", str(field), "--simulator", "--out", str(out)]
    )
    assert one_line_error(result) == f"--out {out} is an existing file, not a folder"
    assert out.read_text() == "not a folder"


def test_out_in_an_unwritable_folder_is_refused_before_any_work(tmp_path, field, monkeypatch):
    """A read-only folder (faked: the tests run as root, who writes anywhere)."""
    import railsusp.input_checks as input_checks

    real = input_checks.os.access
    monkeypatch.setattr(
        input_checks.os, "access", lambda p, m: False if str(p) == str(tmp_path) else real(p, m)
    )
    out = tmp_path / "est"
    result = runner.invoke(
        app, ["estimate", "--measured", str(field), "--simulator", "--out", str(out)]
    )
    assert one_line_error(result) == f"--out {out}: the folder {tmp_path} is not writable"
    assert not out.exists()


def test_refine_on_recordings_without_track_is_refused_before_nsga(tmp_path, field):
    """It failed after NSGA-II had run, with a message about statistic 'aligned'."""
    out = tmp_path / "est"
    result = runner.invoke(
        app,
        ["estimate", "--measured", str(field), "--simulator", "--out", str(out), "--refine",
         "--pop-size", "4", "--n-gen", "1"],
    )  # fmt: skip
    line = one_line_error(result)
    assert line.startswith("--refine compares time-aligned series on the recordings' measured")
    assert "short carry no track geometry" in line and "aligned'" not in line
    assert not out.exists()


def test_all_zero_recordings_are_refused_before_pymoo(tmp_path, field):
    """All-zero forces ended in an assertion inside pymoo (infinite relative errors)."""
    zero = tmp_path / "zero"
    zero.mkdir()
    for f in field.iterdir():
        (zero / f.name).write_bytes(f.read_bytes())
    table = pd.read_csv(zero / "short.csv")
    forces = [c for c in table.columns if c != "time_s"]
    assert forces
    table[forces] = 0.0
    table.to_csv(zero / "short.csv", index=False)
    out = tmp_path / "est"
    result = runner.invoke(
        app,
        ["estimate", "--measured", str(zero), "--simulator", "--out", str(out),
         "--pop-size", "4", "--n-gen", "1"],
    )  # fmt: skip
    # the recording reader may refuse the file itself; either way one line naming zeros
    assert "zero" in one_line_error(result).lower()
    assert not out.exists()


def test_refine_without_track_in_a_configuration_is_refused_before_any_stage(tmp_path):
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[field]\nwith_track = false\n\n[estimate]\nrefine = true\n")
    run = tmp_path / "run"
    result = runner.invoke(app, ["run", str(cfg), "--out", str(run)])
    line = one_line_error(result)
    assert "estimate.refine = true with field.with_track = false" in line
    assert not run.exists()
    cfg.write_text("[field]\nwith_track = true\n\n[estimate]\nrefine = true\nn_gen = 0\n")
    assert "estimate.n_gen" in one_line_error(runner.invoke(app, ["run", str(cfg)]))


def recording(y: np.ndarray, q: np.ndarray) -> Recording:
    t = np.arange(100) * 0.02
    return Recording(t, {"w1L": y}, {"w1L": q}, COND)


def test_recordings_the_objectives_cannot_use_are_refused_by_the_problem():
    ones = np.ones(100)
    wave = 10.0 + np.sin(np.arange(100) / 5.0)
    model = SimulatorForces(PARAMS)
    cases = [
        (recording(0 * ones, 0 * ones), "force Y of wheel w1L is zero throughout", "mean"),
        (recording(wave, 0 * ones), "force Q of wheel w1L is zero throughout", "mean"),
        (recording(wave, np.where(ones > 0, np.nan, 0)), "Q of wheel w1L has non-finite", "mean"),
        # a constant Q has a standard deviation of 0 kN: its relative error divides by zero
        (recording(wave, 120 * ones), "statistic 'std' of force Q of wheel w1L is 0 kN", "std"),
    ]
    for rec, message, statistic in cases:
        with pytest.raises(RailsuspInputError, match=f"recording 'straight': .*{message}"):
            CalibrationProblem(model, [rec], PARAMS, statistic)
    with pytest.raises(RailsuspInputError, match="zero throughout"):  # before pymoo runs
        estimate(model, [cases[0][0]], PARAMS, NSGAConfig(pop_size=4, n_gen=1))
    with pytest.raises(RailsuspInputError, match="at least one recording"):
        CalibrationProblem(model, [], PARAMS)
    CalibrationProblem(model, [recording(wave, 120 * ones)], PARAMS, "mean")  # usable


def test_settings_are_checked_in_the_library_too():
    for name, value, accepted in (
        ("n_gen", 0, "1 to 100000"),
        ("pop_size", 2, "4 to 10000"),
        ("crossover_prob", 1.5, "0 to 1"),
        ("mutation_prob", -0.1, "0 to 1"),
        ("seed", -1, "0 to 4294967295"),
    ):
        with pytest.raises(RailsuspInputError, match=f"^{name} {value:g}: accepted {accepted}$"):
            NSGAConfig(**{name: value})
    rec = recording(10.0 + np.sin(np.arange(100) / 5.0), 120.0 + np.cos(np.arange(100) / 7.0))
    with pytest.raises(RailsuspInputError, match="^n_seeds 0: accepted 1 to 10$"):
        estimate_with_seeds(SimulatorForces(PARAMS), [rec], PARAMS, n_seeds=0)


def test_refinement_settings_and_recordings_are_checked_before_it_simulates():
    class NoSimulation:
        def series(self, x_si, condition):
            raise AssertionError("simulated although the settings are bad")

    from railsusp.estimate import CalibrationResult

    res = CalibrationResult(
        PARAMS,
        np.array([[16e6, 8e6]]),
        np.zeros((1, 2)),
        0,
        pd.DataFrame(),
        np.zeros((1, 2)),
        NSGAConfig(),
    )
    rec = recording(10.0 + np.sin(np.arange(100) / 5.0), 120.0 + np.cos(np.arange(100) / 7.0))
    with pytest.raises(RailsuspInputError, match="^starts 0: accepted 1 to 20$"):
        refine_estimate(res, [rec], NoSimulation(), starts=0)
    with pytest.raises(RailsuspInputError, match="^refine compares .* straight carry no track"):
        refine_estimate(res, [rec], NoSimulation())


def test_the_help_example_of_held_prior_is_accepted():
    """The option's help gave X19=20:40 (kN/m), which its own check refuses: X19 is entered
    in kN/m, 15000-45000 (stop 57's audit)."""
    import re

    from railsusp.cli.estimation_options import parse_held_prior

    result = CliRunner().invoke(app, ["estimate", "--help"], env={"COLUMNS": "300"})
    example = re.search(r"e\.g\. (X15=\S+?) \(", result.output).group(1)
    prior = parse_held_prior(example, True, "mean")
    assert sorted(prior.ranges_si) == ["X15", "X19"]
