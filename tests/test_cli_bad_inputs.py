"""Bad input found by a fuzzing pass over the command line (stop 53), each now a one-line
error naming the option and what is accepted, exit status 2, with nothing written or lost:
before, each of these printed a traceback, exited 0 on nonsense, or replaced a user's file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from railsusp.cli import app

runner = CliRunner()

SHORT = '[[condition]]\nbase = "straight"\nname = "short"\nduration_s = 1.0\nn_steps = 50\n'


def refused(args: list[str], needle: str) -> str:
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    assert needle in result.output, result.output
    assert "Traceback" not in result.output
    return result.output


@pytest.fixture
def short_conditions(tmp_path) -> Path:
    path = tmp_path / "short.toml"
    path.write_text(SHORT + "lead_in_m = 20.0\n")
    return path


def test_synth_field_never_replaces_a_file_and_refuses_empty_or_repeated_conditions(
    tmp_path, short_conditions
):
    """Before: a file given as --out was deleted and replaced by a field folder (exit 0), no
    conditions wrote an index listing none over an existing field, two conditions of one
    name wrote one recording over the other, and a negative seed was a traceback."""
    precious = tmp_path / "precious.txt"
    precious.write_text("field notes")
    refused(
        ["synth-field", "--conditions", str(short_conditions), "--out", str(precious)],
        "is an existing file, not a folder",
    )
    assert precious.read_text() == "field notes"
    refused(["synth-field", "--conditions", "", "--out", str(tmp_path / "e")], "none named")
    twice = tmp_path / "twice.toml"
    twice.write_text(SHORT + SHORT)
    refused(
        ["synth-field", "--conditions", str(twice), "--out", str(tmp_path / "d")],
        "short named more than once",
    )
    refused(
        ["synth-field", "--conditions", "straight", "--out", str(tmp_path / "s"), "--seed", "-1"],
        "--seed -1: accepted 0 or more",
    )
    # a geometry error without the geometry was ignored (exit 0, no geometry written)
    refused(
        ["synth-field", "--conditions", "straight", "--out", str(tmp_path / "n"),
         "--track-noise", "2"],
        "--track-noise 2 needs --with-track",
    )  # fmt: skip
    assert not any((tmp_path / n).exists() for n in ("e", "d", "s", "n"))
    from railsusp.conditions import get_condition
    from railsusp.errors import RailsuspInputError
    from railsusp.measured import synthesise_field
    from railsusp.params import ParameterSet

    with pytest.raises(RailsuspInputError, match="track_noise_mm = 0.5 needs with_track = True"):
        synthesise_field(ParameterSet(), [get_condition("straight")], tmp_path / "p",
                         track_noise_mm=0.5)  # fmt: skip
    assert not (tmp_path / "p").exists()


@pytest.mark.parametrize("name", ["x.txt", "x"])
def test_a_plot_of_an_unknown_format_is_refused_before_the_work(tmp_path, name):
    """Before: matplotlib's ValueError after the track was synthesised (a traceback)."""
    refused(
        ["track", "--class", "5", "--length", "200", "--plot", str(tmp_path / name)],
        "accepted .png, .pdf, .svg, .jpg, .jpeg",
    )


def test_a_plot_into_a_folder_is_refused(tmp_path):
    """Before: `sections --plot /tmp` wrote /tmp.png and said it wrote /tmp."""
    from railsusp.input_checks import check_figure_file

    with pytest.raises(Exception, match="is a folder, not a file"):
        check_figure_file(tmp_path, "--plot")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_a_plot_in_a_folder_no_file_can_be_made_in_is_refused_before_the_work(tmp_path):
    """``os.access`` tells root that /proc may be written: `sections --plot /proc/x.png`
    read and cut the long run and then failed to save the figure (stop 78's hunt). A file
    is now tried in the folder first, and removed: nothing is left beside the figure."""
    from railsusp.input_checks import check_figure_file

    refused(
        ["track", "--class", "5", "--length", "200", "--plot", "/proc/x.png"],
        "--plot /proc/x.png: no file can be written in /proc",
    )
    assert check_figure_file(tmp_path / "x.png") == tmp_path / "x.png"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("option", "value", "needle"),
    [
        ("--threshold", "-1", "--threshold -1: accepted above 0 and below 1"),
        ("--threshold", "nan", "--threshold nan: accepted above 0 and below 1"),
        ("--max-keys", "0", "--max-keys 0: accepted 1 to 10"),
        ("--min-cv", "-1", "--min-cv -1: accepted 0 to below 1"),
        ("--base-samples", "0", "--base-samples 0: accepted 64 to 65536"),
        ("--base-samples", "1000000", "--base-samples 1000000: accepted 64 to 65536"),
        ("--seed", "-5", "--seed -5: accepted 0 or more"),
        ("--statistics", "bogus", "--statistics bogus: accepted one or more of mean, rms"),
    ],
)
def test_sensitivity_settings_are_refused_before_any_file_is_written(
    tmp_path, option, value, needle
):
    """Before: each of these ran and wrote a meaningless key_parameters.json over the good
    one (exit 0), or failed deep in SALib or scikit-learn naming no option."""
    refused(["sensitivity", str(tmp_path / "run"), option, value], needle)


def test_sensitivity_accepts_the_campaigns_own_statistics_and_no_other():
    """The statistics are the campaign features' (mean, rms, p99, max): max is accepted,
    std (a record statistic that campaigns do not store) is not."""
    from railsusp.campaign import STATISTICS
    from railsusp.errors import RailsuspInputError
    from railsusp.sensitivity import check_settings

    assert "max" in STATISTICS and "std" not in STATISTICS
    check_settings(STATISTICS, 0.05, ("max",), 6, 0.005, 64, 0)
    with pytest.raises(RailsuspInputError, match="statistics std: accepted one or more of"):
        check_settings(("std",), 0.05, ("mean",), 6, 0.005, 64, 0)


def test_validate_checks_its_paths_before_simulating(tmp_path):
    """Before: an existing file as --out raised FileExistsError after the re-simulations; a
    missing --truth was a bare [Errno 2]; a missing --sensitivity was silently ignored."""
    existing = tmp_path / "out.txt"
    existing.write_text("keep")
    est = str(tmp_path / "est")
    refused(["validate", est, "--out", str(existing)], "--out")
    assert existing.read_text() == "keep"
    refused(["validate", est, "--truth", str(tmp_path / "no.json")], "--truth")
    refused(["validate", est, "--truth", str(existing)], "--truth")  # not JSON
    # JSON, but not a truth file (a recording's sidecar, an empty object): was "est:
    # 'parameters_display'", a KeyError's text
    for name, text in (("sidecar.json", '{"format": "railsusp-recording-1"}'), ("e.json", "{}")):
        (tmp_path / name).write_text(text)
        needle = f"--truth {tmp_path / name}: no 'parameters_display' table; accepted a truth"
        refused(["validate", est, "--truth", str(tmp_path / name)], needle)
    (tmp_path / "t.json").write_text('{"parameters_display": {"X13": 1e9}}')
    refused(["validate", est, "--truth", str(tmp_path / "t.json")], "X13")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "estimate.json").write_text('{"parameters": ["X13"]}')
    needle = "estimate.json: no 'estimate_display', 'config'; accepted the estimate.json of a"
    refused(["validate", str(tmp_path / "other")], needle)
    refused(["validate", est, "--sensitivity", str(tmp_path)], "--sensitivity")


def test_campaign_refuses_a_scheduler_address_before_writing(tmp_path):
    """Before: ValueError 'missing port number' (a traceback) with the run directory
    already written."""
    out = tmp_path / "camp"
    refused(
        ["campaign", "--conditions", "straight", "--samples", "4", "--out", str(out),
         "--scheduler", "bogus"],
        "--scheduler 'bogus': accepted tcp://host:port",
    )  # fmt: skip
    assert not out.exists()


def test_compare_refuses_no_models(tmp_path):
    """Before: KeyError 'condition' from pandas after training nothing."""
    refused(["compare", str(tmp_path), "--models", ""], "--models (none): accepted one or more")


def test_modes_of_a_wagon_without_an_operating_point_is_an_input_error(tmp_path, monkeypatch):
    """Before: RuntimeError 'model.rhs failed' (a traceback) for a car body of 1e30 kg; such a
    mass is now refused when the wagon file is read (stop 57), and a wagon that passes its
    checks but still has no operating point is one line too."""
    from importlib.resources import files

    import railsusp.vehicle.modes as modes
    from railsusp.vehicle.operating_point import OperatingPointError

    text = (files("railsusp") / "data" / "c80_k6.toml").read_text()
    huge = tmp_path / "huge.toml"
    huge.write_text(text.replace("mass = 91600.0", "mass = 1e30", 1))
    refused(["modes", "--wagon", str(huge)], "car_body.mass = 1e+30: accepted (1000, 250000] kg")

    def no_operating_point(*args, **kwargs):
        raise OperatingPointError("model.rhs failed")

    monkeypatch.setattr(modes, "modal_analysis", no_operating_point)
    refused(["modes"], "has no operating point to analyse (model.rhs failed)")


def test_a_posterior_settings_file_without_settings_is_refused(tmp_path):
    """Before: KeyError 'settings' from an estimator folder whose settings.json is {}."""
    from railsusp.errors import RailsuspInputError
    from railsusp.estimate.posterior import load

    folder = tmp_path / "posterior"
    folder.mkdir()
    (folder / "settings.json").write_text(json.dumps({}))
    (folder / "estimator.pt").write_bytes(b"")
    (folder / "calibration.json").write_text("{}")
    with pytest.raises(RailsuspInputError, match="holds no estimator settings: train again"):
        load(tmp_path)


@pytest.mark.parametrize(
    ("section", "needle"),
    [
        ("[campaign]\nsamples = 10\nparameters = []\n", "campaign.parameters: none given"),
        ("[sensitivity]\nstatistics = []\n", "sensitivity.statistics: none given"),
    ],
)
def test_empty_lists_in_a_configuration_are_refused_before_any_stage(tmp_path, section, needle):
    """Before: the campaign stage, or the sensitivity stage after the campaign had run,
    failed on them ('Tuple should have at least 1 item', 'No objects to concatenate')."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'name = "t"\n{section}')
    refused(["run", str(cfg), "--out", str(tmp_path / "run")], needle)
    assert not (tmp_path / "run" / "campaign").exists()


@pytest.mark.parametrize("command", ["conditions", "simulate"])
def test_a_condition_list_naming_none_is_refused(command):
    """Before: `conditions ""` and `simulate ""` printed empty tables with exit 0."""
    refused([command, ""], "none named; accepted straight, curve, uphill")


def test_a_configurations_missing_track_geometry_is_refused_before_any_stage(tmp_path):
    """Before: the configuration passed its check and the campaign stage failed on it."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(
        'name = "t"\nconditions = [{base = "straight", name = "short", duration_s = 1.0, '
        f'n_steps = 50, track_geometry = "{tmp_path / "none.csv"}"}}]\n'
    )
    refused(["run", str(cfg), "--out", str(tmp_path / "run")], "track_geometry")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("rate", ["-1", "0", "nan"])
def test_check_recording_refuses_a_minimum_rate_out_of_range(tmp_path, rate):
    """Before: any --min-rate passed, even a negative one."""
    refused(["check-recording", str(tmp_path / "r.csv"), "--min-rate", rate], "--min-rate")


def test_synthesise_field_refuses_no_conditions_from_python_too(tmp_path):
    """The Python API refuses what the command line does (the CLI's condition list is
    refused earlier, by resolve_conditions)."""
    from railsusp.errors import RailsuspInputError
    from railsusp.measured import synthesise_field
    from railsusp.params import ParameterSet

    with pytest.raises(RailsuspInputError, match="conditions: none given"):
        synthesise_field(ParameterSet.nominal(), [], tmp_path / "f")
    assert not (tmp_path / "f").exists()


def test_simulate_writes_parquet_only_to_a_parquet_file(tmp_path):
    """Before: `simulate --out sim.csv` wrote Parquet bytes into a .csv file."""
    refused(["simulate", "straight", "--out", str(tmp_path / "sim.csv")], "accepted a .parquet")
    assert not (tmp_path / "sim.csv").exists()


def test_a_conditions_file_with_a_stray_table_is_refused(tmp_path):
    """Before: a misspelt table ([conditon]) or a stray key was ignored without a word."""
    path = tmp_path / "c.toml"
    path.write_text(SHORT + '[conditon.extra]\nbase = "curve"\n')
    refused(["conditions", str(path)], "conditon unknown")


@pytest.mark.parametrize(
    ("index", "needle"),
    [
        ({"format": "bogus/9", "recordings": ["a.csv"]}, "format 'bogus/9'; accepted"),
        ({"recordings": ["a.csv", "a.csv"]}, "a.csv listed more than once"),
    ],
)
def test_a_field_index_of_another_format_or_listing_a_recording_twice_is_refused(
    tmp_path, index, needle
):
    """Before: both were read (a recording listed twice weighs double in the estimate)."""
    from railsusp.errors import RailsuspInputError
    from railsusp.measured.reader import read_index

    (tmp_path / "index.json").write_text(json.dumps(index))
    with pytest.raises(RailsuspInputError, match=needle):
        read_index(tmp_path)
    index.pop("format", None)  # without a format, once each: read
    index["recordings"] = ["a.csv"]
    (tmp_path / "index.json").write_text(json.dumps(index))
    assert read_index(tmp_path) == [tmp_path / "a.csv"]


def test_sections_names_the_wagon_option(tmp_path):
    """QA: "wagon file nosuch does not exist", naming no option (check-recording names it)."""
    refused(["sections", str(tmp_path / "run.csv"), "--wagon", "nosuch"], "--wagon: ")


@pytest.mark.parametrize("option", ["--line", "--table", "--map"])
def test_sections_names_a_missing_side_file(tmp_path, option):
    """Before: a bare [Errno 2] naming no option."""
    refused(["sections", str(tmp_path / "run.csv"), option, str(tmp_path / "x")], option)


@pytest.mark.parametrize(
    ("given", "needle"),
    [
        ("X99", "--parameters X99: unknown parameter 'X99'; accepted a comma-separated list of"),
        ("X13,X1", "--parameters X13,X1: X1 is fixed (no range)"),
        ("X13,X13", "--parameters X13,X13: X13 is given twice"),
        ("", "unknown parameter ''"),
    ],
)
def test_estimate_names_an_unknown_parameter(tmp_path, given, needle):
    """Before: X99 read as a mismatch with the surrogate's parameters, naming no option."""
    args = ["estimate", "--measured", str(tmp_path), "--simulator", "--parameters", given]
    refused([*args, "--out", str(tmp_path / "est")], needle)


def test_a_folder_named_like_a_table_is_called_a_folder(tmp_path):
    """Before: 'no .csv or .parquet table found' and 'no such file' for an existing folder."""
    folder = tmp_path / "run.csv"
    folder.mkdir()
    refused(["check-recording", str(folder)], "a folder, not a recording table")
    refused(["sections", str(folder)], "a folder, not a recording file")


def test_the_current_folder_as_a_recording_is_called_a_folder(tmp_path, monkeypatch):
    """Before: ``check-recording .`` (an engineer in the field folder) was a ValueError's
    traceback, exit 1: the folder "." has no name to find its table by."""
    monkeypatch.chdir(tmp_path)
    refused(["check-recording", "."], "a folder, not a recording table")


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["train", "{tmp}/none", "--epochs", "0"], "--epochs 0: accepted an integer from 1"),
        (["posterior", "train", "--seed", "-1", "--out", "{tmp}/p"], "--seed -1: accepted 0 to"),
        (["sections", "{tmp}/none.csv", "--speed-tolerance", "1.5"], "--speed-tolerance 1.5"),
    ],
)
def test_errors_name_the_option_typed_not_the_setting_behind_it(tmp_path, args, needle):
    """Stop 61's documentation audit: "speed_tolerance = 1.5", "training epochs = 0",
    "seed = -1" named the library's settings, not the options the user typed."""
    from railsusp.cli.common import option_names

    if args[0] == "sections":  # the rules are checked before the run is read
        (tmp_path / "none.csv").write_text("time_s\n0\n")
    refused([a.replace("{tmp}", str(tmp_path)) for a in args], needle)
    assert option_names("max_shift_m = 0: accepted", {"max_shift_m": "--max-shift"}) == (
        "--max-shift 0: accepted"
    )
    # a setting's name in prose further on is left alone
    assert option_names("seed 3 of the seeds", {"seed": "--seed"}) == "--seed 3 of the seeds"
    assert option_names("the seed of it", {"seed": "--seed"}) == "the seed of it"
