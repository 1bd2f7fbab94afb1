"""What an exploratory QA pass found in the commands about inputs, campaigns, their analysis
and an interrupted estimate, each asserted as the command now behaves: a track section
shorter than a grid step crashed the plot (and printed RMS 0.00 without it); errors named a
condition's internal field instead of the option typed; a campaign refused for another
configuration did not say what differed; ``sensitivity`` printed only the key statistics'
tables; an interrupted ``estimate`` promised a resume that does not exist."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from railsusp.cli import app

runner = CliRunner()


def refused(args: list[str], needle: str) -> str:
    """The one error line a refused command ends with (exit 2, no traceback), checked to
    hold needle (a campaign says what it is about to run before its directory refuses)."""
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert lines[-1].startswith("error: ") and "Traceback" not in result.output, result.output
    assert sum(line.startswith("error: ") for line in lines) == 1, result.output
    assert needle in lines[-1], result.output
    return lines[-1]


# ---------------------------------------------------------------- track


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (
            ["--length", "0.1"],
            "--length 0.1 m: accepted at least the shortest wavelength, 1 m (--wavelength-min: "
            "8 grid steps of 0.125 m), up to 1e6 m",
        ),
        (
            ["--wavelength-min", "50", "--wavelength-max", "1000", "--length", "5"],
            "--length 5 m: accepted at least the shortest wavelength, 50 m",
        ),
    ],
)
def test_a_track_section_shorter_than_its_shortest_wave_is_refused(tmp_path, args, needle):
    """Before: an IndexError traceback in the plot (one sample, no grid step), and without
    --plot every RMS 0.00 against an expected 28 mm; now one line, exit 2, no file."""
    png = tmp_path / "t.png"
    refused(["track", *args, "--plot", str(png)], needle)
    refused(["track", *args], needle)
    assert not png.exists()


def test_a_short_track_section_is_plotted_and_said_to_hold_part_of_the_band(tmp_path):
    """A section of one shortest wavelength (9 samples) is plotted; a section shorter than
    the longest wavelength compared with the whole band's RMS says so (--length 5: vertical
    1.34 mm against 9.51 mm, without a word before)."""
    png = tmp_path / "t.png"
    result = runner.invoke(app, ["track", "--length", "1", "--plot", str(png)])
    assert result.exit_code == 0, result.output
    assert png.stat().st_size > 0
    result = runner.invoke(app, ["track", "--length", "5"], terminal_width=240)
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "note: the 5 m section is shorter than the longest wavelength (120 m)" in text
    assert "'expected' is the RMS of the whole 1-120 m band" in text
    whole = runner.invoke(app, ["track", "--length", "800"])
    assert whole.exit_code == 0 and "note:" not in whole.output


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["track", "--class", "0"], "error: --class 0: accepted range [1, 6] ("),
        (["track", "--class", "7"], "error: --class 7: accepted range [1, 6] ("),
        (["track", "--seed", "-1"], "error: --seed -1: accepted 0 or more"),
        (["track", "--wavelength-min", "0.01"], "error: --wavelength-min 0.01: accepted range"),
        (["track", "--wavelength-max", "5000"], "error: --wavelength-max 5000.0: accepted range"),
        (["simulate", "straight", "--seed", "-3"], "error: --seed -3: accepted 0 or more"),
        (["campaign", "--samples", "4", "--seed", "-1"], "error: --seed -1: accepted 0 or more"),
        (
            ["campaign", "--samples", "4", "--duration", "0"],
            "error: --duration 0.0: accepted range [1, 600] s",
        ),
        (["campaign", "--samples", "0"], "error: --samples 0: accepted [2, 1000000]"),
        (
            ["campaign", "--samples", "4", "--batch-size", "0"],
            "error: --batch-size 0: accepted [1, 10000]",
        ),
    ],
)
def test_errors_name_the_option_typed_not_the_conditions_field(tmp_path, args, needle):
    """Before: "condition 'track': irregularity_class = 0: accepted range [1, 6] or "none"
    (perfect track)", "condition 'straight': duration_s = 0.0", "campaign configuration:
    seed: ..." ("none" cannot be given to --class); now the option as typed."""
    if args[0] == "campaign":
        args = [*args, "--out", str(tmp_path / "run")]
    line = refused(args, needle)
    for field in ("irregularity_class", "wavelength_min_m", "duration_s", "condition '", "none"):
        assert field not in line, line
    assert not (tmp_path / "run").exists()


def test_a_seed_set_in_a_conditions_file_is_still_named_as_its_field(tmp_path):
    """Only what an option set is named as the option: a file's own field keeps its name."""
    conds = tmp_path / "c.toml"
    conds.write_text('[[condition]]\nname = "s"\nseed = -2\n')
    line = refused(["simulate", str(conds)], "seed = -2")
    assert "--seed" not in line


# ---------------------------------------------------------------- campaign refusal


@pytest.fixture
def stored_campaign(tmp_path) -> list[str]:
    """`railsusp campaign` arguments of a campaign stored (configuration and design, no
    batch: --max-batches 0) in two 1 s conditions, into tmp_path/c1."""
    conds = tmp_path / "c.toml"
    conds.write_text(
        '[[condition]]\nname = "straight"\nduration_s = 4.0\nn_steps = 200\n'
        '[[condition]]\nname = "curve"\nbase = "curve"\nduration_s = 4.0\nn_steps = 200\n'
    )
    args = ["campaign", "--samples", "8", "--conditions", str(conds), "--batch-size", "4",
            "--max-batches", "0", "--out", str(tmp_path / "c1")]  # fmt: skip
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    return args


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (["--samples", "9"], "(samples 8, now 9; hash "),
        (["--duration", "5"], "(conditions straight,curve: duration_s 4, now 5; "),
        (["--seed", "3"], "(seed 0, now 3; hash "),
        (["--parameters", "X13,X18"], "(parameters X11,X12,X13,X14,X15,X16,X17,X18,X19,X20, now"),
    ],
)
def test_a_campaign_refused_for_another_configuration_says_what_differs(
    stored_campaign, change, needle
):
    """Before: only "holds a campaign with another configuration (hash 14abf..., now
    c02ce...)"; now the settings that differ, stored value first (as `posterior train`
    names its other --parameters)."""
    line = refused([*stored_campaign, *change], "holds a campaign with another configuration")
    assert needle in line
    assert "use a new --out, or --force to discard the old results" in line


def test_conditions_in_another_order_are_named(stored_campaign, tmp_path):
    conds = tmp_path / "swapped.toml"
    text = (tmp_path / "c.toml").read_text().split("[[condition]]")
    conds.write_text("[[condition]]" + text[2] + "[[condition]]" + text[1])
    args = [a if a != str(tmp_path / "c.toml") else str(conds) for a in stored_campaign]
    line = refused(args, "another configuration")
    assert "(conditions straight,curve, now curve,straight; hash " in line


def test_the_nominal_twins_of_another_configuration_say_what_differs(tmp_path):
    """The twins' stamp now holds their configuration, and its refusal names what differs
    (a stamp without one, written before, names the hashes alone)."""
    from railsusp.campaign import CampaignError, make_config, run_campaign
    from railsusp.campaign.twins import nominal_folder, run_nominal_twins
    from railsusp.conditions import get_condition

    cond = [get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)]
    cfg = make_config(cond, 4, batch_size=4, independent_seeds=True)
    run_campaign(cfg, tmp_path, max_batches=0)
    run_nominal_twins(tmp_path, max_batches=0)
    stamp = nominal_folder(tmp_path) / "twins.json"
    held = json.loads(stamp.read_text())
    assert held["config"] == cfg.model_dump(mode="json")
    other = make_config(cond, 4, batch_size=4, independent_seeds=True, seed=5)
    stamp.write_text(json.dumps({**held, "config_hash": other.hash(), "config": {
        **held["config"], "seed": 5}}))  # fmt: skip
    with pytest.raises(CampaignError, match=r"another configuration \(seed 5, now 0; hash "):
        run_nominal_twins(tmp_path, max_batches=0)
    stamp.write_text(json.dumps({"kind": "railsusp nominal twins", "config_hash": "x"}))
    with pytest.raises(CampaignError, match=r"another configuration \(hash x, the campaign's"):
        run_nominal_twins(tmp_path, max_batches=0)


# ---------------------------------------------------------------- sensitivity


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    """A campaign of 10 samples of two parameters in one 1 s condition."""
    root = tmp_path_factory.mktemp("sens")
    conds = root / "c.toml"
    conds.write_text(
        '[[condition]]\nname = "short"\nduration_s = 1.0\nn_steps = 50\nlead_in_m = 20.0\n'
    )
    args = ["campaign", "--samples", "10", "--conditions", str(conds), "--batch-size", "10",
            "--parameters", "X13,X18", "--out", str(root / "run")]  # fmt: skip
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    return root / "run"


def test_sensitivity_prints_every_statistic_asked_and_says_the_key_ones(tiny_run):
    """Before: `--statistics rms,max` printed the tables of mean and p99 (the key
    statistics) alone; rms and max reached only indices.csv and the figures."""
    result = runner.invoke(
        app,
        ["sensitivity", str(tiny_run), "--statistics", "rms,max", "--base-samples", "64"],
        terminal_width=240,
    )
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    for st in ("rms", "max"):
        assert f"statistic '{st}', not in the key rule;" in text
    for st in ("mean", "p99"):
        assert f"statistic '{st}', a key statistic;" in text


@pytest.mark.parametrize("value", ["", ",", " , "])
def test_an_empty_statistics_list_is_refused_as_an_empty_key_list_is(tiny_run, value):
    refused(
        ["sensitivity", str(tiny_run), "--statistics", value],
        "--statistics (none): accepted one or more of mean, rms, p99, max",
    )
    refused(
        ["sensitivity", str(tiny_run), "--key-statistics", value],
        "--key-statistics (none): accepted one or more of mean, rms, p99, max",
    )


# ---------------------------------------------------------------- interrupted estimate


@pytest.fixture(scope="module")
def field(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("field")
    conds = root / "c.toml"
    conds.write_text('[[condition]]\nname = "short"\nduration_s = 2.0\nn_steps = 100\n')
    args = ["synth-field", "--truth", "X13=16.1", "--conditions", str(conds),
            "--out", str(root / "field")]  # fmt: skip
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    return root / "field"


def test_an_interrupted_estimate_says_it_starts_again_not_that_it_resumes(
    field, tmp_path, monkeypatch
):
    """Before: exit 130 with "what was finished is kept ...; run the same command again to
    resume", while no --out folder was left and the same command started from scratch.
    Now the estimate's own line says that; the common line is not added."""
    from railsusp.estimate.route import EstimateRoute

    def ctrl_c(*_a, **_k):
        raise KeyboardInterrupt

    monkeypatch.setattr(EstimateRoute, "run", ctrl_c)
    out = tmp_path / "ex12"
    args = ["estimate", "--measured", str(field), "--simulator", "--parameters", "X13",
            "--pop-size", "8", "--n-gen", "2", "--out", str(out)]  # fmt: skip
    result = runner.invoke(app, args)
    assert result.exit_code == 130, result.output
    text = " ".join(result.output.split())
    assert "interrupted: an estimate is written whole when it finishes" in text
    assert "the same command starts it again from the beginning" in text
    assert "resume" not in text
    assert not out.exists()


def test_the_console_script_adds_no_second_line_to_a_command_that_said_its_own(monkeypatch, capsys):
    import railsusp.cli as cli
    from railsusp.cli.estimation_options import INTERRUPTED, interrupted

    def estimate_interrupted(**_k) -> int:
        raise interrupted()

    monkeypatch.setattr(cli, "app", estimate_interrupted)
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == 130
    err = " ".join(capsys.readouterr().err.split())
    assert err == " ".join(INTERRUPTED.split())


def test_the_track_figure_refuses_a_track_without_a_grid_step(tmp_path):
    """The figure itself, as the report and the API call it: one sample was an IndexError."""
    from railsusp.errors import RailsuspInputError
    from railsusp.report import plot_track_irregularities
    from railsusp.vehicle.track import synthesise

    with pytest.raises(RailsuspInputError, match=r"track of 1 sample\(s\), 0 m: accepted at"):
        plot_track_irregularities(synthesise(0.1), tmp_path / "t.png")
    assert not (tmp_path / "t.png").exists()
