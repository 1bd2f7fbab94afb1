"""Bad input as a careless or hostile user gives it: one-line errors with exit status 2 (or
the safe behaviour), failed simulations counted, files written atomically (issue 22)."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.condition_files import load_conditions
from railsusp.conditions import make_condition
from railsusp.errors import ConditionError, ParameterError, RailsuspInputError
from railsusp.params import ParameterSet, parse_overrides

runner = CliRunner()
GARBAGE = bytes(range(256)) * 3  # not UTF-8, not TOML
SHORT = '[[condition]]\nname = "short"\nduration_s = 1.0\nn_steps = 50\nlead_in_m = 20.0\n'


def one_line_error(args: list[str], needle: str, status: int = 2) -> str:
    """Run the CLI in-process; exit ``status``, one ``error:`` line containing ``needle``, no
    exception but the exit."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == status, result.output
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.output
    assert needle in errors[0], errors[0]
    assert "Traceback" not in result.output
    return errors[0]


@pytest.fixture
def garbage(tmp_path):
    p = tmp_path / "garbage.toml"
    p.write_bytes(GARBAGE)
    return p


@pytest.fixture
def short(tmp_path):
    p = tmp_path / "short.toml"
    p.write_text(SHORT)
    return p


# ---------------------------------------------------------------- files that are not TOML
def test_binary_garbage_as_toml_is_one_line(garbage, tmp_path):
    one_line_error(["params", "--file", garbage], "parameter file")
    one_line_error(["simulate", "straight", "--wagon", garbage], "wagon file")
    one_line_error(["run", garbage, "--out", tmp_path / "o"], "is not UTF-8 text")
    one_line_error(["conditions", garbage], "condition file")
    assert not (tmp_path / "o").exists()


def test_a_folder_as_file_is_one_line(tmp_path):
    one_line_error(["params", "--file", tmp_path], "is a folder, not a TOML file")
    one_line_error(["simulate", "straight", "--file", tmp_path], "is a folder")
    one_line_error(["run", tmp_path], "is a folder, not a TOML file")


def test_nan_options_are_one_line(short, tmp_path):
    one_line_error(["track", "--length", "nan"], "--length = nan m: accepted range (0, 1e6] m")
    one_line_error(
        ["campaign", "--out", tmp_path / "r", "--conditions", short, "--duration", "nan"],
        "--duration nan: accepted range [1, 600] s",  # the option typed
    )
    assert not (tmp_path / "r").exists()


# ---------------------------------------------------------------- output folders
def test_out_that_is_an_existing_file_is_refused_before_any_work(short, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("keep me")
    one_line_error(
        ["campaign", "--out", afile, "--conditions", short, "--samples", "2"],
        "is an existing file, not a folder",
    )
    one_line_error(["run", "examples/quick.toml", "--out", afile], "is an existing file")
    one_line_error(["simulate", short, "--out", tmp_path], "is a folder, not a file")
    one_line_error(["simulate", short, "--out", afile / "f.parquet"], "is a file, not a folder")
    one_line_error(["track", "--plot", afile / "t.png"], "is a file, not a folder")
    assert afile.read_text() == "keep me"


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes anywhere")
def test_out_in_a_read_only_folder_is_refused(short, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        one_line_error(
            ["campaign", "--out", ro / "r", "--conditions", short, "--samples", "2"],
            "is not writable",
        )
        one_line_error(["run", "examples/quick.toml", "--out", ro / "r"], "is not writable")
        one_line_error(["simulate", short, "--out", ro / "f.parquet"], "is not writable")
    finally:
        ro.chmod(0o755)


def test_read_only_check_asks_the_nearest_existing_folder(tmp_path, monkeypatch):
    """The check above where it cannot run (as root, who may write anywhere): what the
    check does around os.access, which answers as a read-only folder would. The folder to
    be made does not exist yet, so the question goes to its nearest existing ancestor, for
    writing and entering; the refusal names that folder and creates nothing; a folder that
    is not the one asked about is not refused (the answer, not the call, decides)."""
    from railsusp.input_checks import check_output_folder

    asked = []
    read_only = tmp_path / "ro"
    read_only.mkdir()

    def access(path, mode, **kw):
        asked.append((Path(path), mode))
        return Path(path) != read_only  # only "ro" is read-only

    monkeypatch.setattr(os, "access", access)
    with pytest.raises(RailsuspInputError) as info:
        check_output_folder(read_only / "new" / "run")
    assert asked == [(read_only, os.W_OK | os.X_OK)]
    assert str(info.value) == (
        f"--out {read_only / 'new' / 'run'}: the folder {read_only} is not writable"
    )
    assert list(read_only.iterdir()) == []  # nothing made
    assert check_output_folder(tmp_path / "new" / "run") == tmp_path / "new" / "run"
    assert asked[-1] == (tmp_path, os.W_OK | os.X_OK)


# ---------------------------------------------------------------- campaign
def test_campaign_workers_0_and_corrupt_campaign_json(short, tmp_path):
    run = tmp_path / "r"
    one_line_error(
        ["campaign", "--out", run, "--conditions", short, "--samples", "2", "--workers", "0"],
        "--workers = 0: accepted an integer >= 1",
    )
    run.mkdir()
    (run / "campaign.json").write_bytes(b'{"config": ')
    one_line_error(["train", run], "is corrupt: not valid JSON")
    # a batch of unknown origin beside it (an unstamped one: written by an older railsusp)
    (run / "batches" / "short").mkdir(parents=True)
    pd.DataFrame({"sample_id": [0]}).to_parquet(run / "batches/short/batch-00000.parquet")
    one_line_error(
        ["campaign", "--out", run, "--conditions", short, "--samples", "2"],
        "1 of its batches is not stamped as this configuration's",
    )
    (run / "campaign.json").write_text("[1, 2]")
    one_line_error(["train", run], "a JSON object was expected")
    (run / "campaign.json").write_text('{"config": {"samples": "many"}}')
    one_line_error(["train", run], "its configuration does not validate")


def test_a_campaign_of_an_older_wagon_model_says_so(tmp_path):
    """A campaign stored before a wagon-data field existed (the centre bowl's rocking
    stiffness, 2026-11-24) is of another model: the error says that and what to do, instead
    of calling the file corrupt."""
    from railsusp.campaign import make_config
    from railsusp.conditions import get_condition

    cfg = make_config([get_condition("straight", duration_s=1.0)], 2)
    stored = json.loads(cfg.model_dump_json())
    del stored["wagon"]["centre_plate"]["rocking_stiffness"]
    run = tmp_path / "old"
    run.mkdir()
    (run / "campaign.json").write_text(json.dumps({"config": stored}))
    msg = one_line_error(["train", run], "was simulated with an older wagon model")
    assert "centre_plate.rocking_stiffness" in msg and "re-run the campaign" in msg


def _fail_first(real):
    """A simulate_requests that reports the first run of its first request as derailed
    (flange climb): a campaign batch's first sample."""

    def wrapped(*args, **kwargs):
        results = real(*args, **kwargs)
        status = results[0].status.copy()
        status[0] = 4
        return [dataclasses.replace(results[0], status=status), *results[1:]]

    return wrapped


def test_campaign_counts_failed_simulations_and_exits_1(short, tmp_path, monkeypatch):
    import railsusp.campaign as campaign
    import railsusp.campaign.batch_simulation as batch_simulation

    monkeypatch.setattr(
        batch_simulation, "simulate_requests", _fail_first(batch_simulation.simulate_requests)
    )
    run = tmp_path / "r"
    args = ["campaign", "--out", run, "--conditions", short, "--samples", "3"]
    args += ["--parameters", "X13", "--batch-size", "2"]
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 1, result.output
    assert "2 of 3 simulations failed" in result.output and "short 2" in result.output
    failed = campaign.failed_runs(run)
    assert list(failed.sample_id) == [0, 2] and set(failed.status) == {4}
    monkeypatch.undo()
    ok = runner.invoke(app, [str(a) for a in [*args[:2], tmp_path / "ok", *args[3:]]])
    assert ok.exit_code == 0 and "0 of 3 simulations failed" in ok.output


def test_simulate_exits_1_when_its_run_derails(short, monkeypatch):
    import railsusp.vehicle.simulate as sim

    real = sim.simulate

    def derailing(*args, **kwargs):
        r = real(*args, **kwargs)
        return dataclasses.replace(r, status=np.array([3]))

    monkeypatch.setattr(sim, "simulate", derailing)
    result = runner.invoke(app, ["simulate", str(short)])
    assert result.exit_code == 1, result.output
    assert "1 of 1 runs failed: short (wheel lift beyond the flange height" in result.output


def test_simulate_writes_no_file_for_a_run_that_stopped(short, monkeypatch, tmp_path):
    """It wrote the stopped run's series as a parquet file of NaN (stop 57's audit)."""
    import railsusp.vehicle.simulate as sim

    real = sim.simulate

    def derailing(*args, **kwargs):
        return dataclasses.replace(real(*args, **kwargs), status=np.array([3]))

    monkeypatch.setattr(sim, "simulate", derailing)
    out = tmp_path / "f.parquet"
    result = runner.invoke(app, ["simulate", str(short), "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert "no file written for them" in result.output and not out.exists()


# ---------------------------------------------------------------- training options
def test_train_refuses_settings_that_train_nothing(tmp_path):
    for args, needle in (
        (["--device", "tpu"], "device 'tpu': accepted cpu, cuda, auto"),
        (["--epochs", "0"], "--epochs 0: accepted an integer from 1 to 10000"),
        (["--batch-size", "0"], "--batch-size 0"),
        (["--window", "0"], "--window = 0: accepted 2 .. 10000 steps"),
    ):
        one_line_error(["train", tmp_path, *args], needle)
    one_line_error(["compare", tmp_path, "--epochs", "0"], "--epochs 0")


def test_a_window_longer_than_the_series_and_an_early_stop_are_said(short, tmp_path):
    """The second audit of stop 56: --window at least the series' length trained into
    numpy's "high <= 0" (and the progress bar's line after it); --max-batches stopped a
    campaign with "campaign stored" and "0 of 4 simulations failed" of the 2 that ran."""
    res = runner.invoke(app, ["campaign", "--conditions", str(short), "--samples", "4",
                              "--batch-size", "2", "--parameters", "X13", "--out",
                              str(tmp_path / "r"), "--max-batches", "1"])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "stopped by --max-batches 1: " in res.output and "(1 of 2 batches)" in res.output
    assert "run the same command without --max-batches" in res.output
    assert "campaign stored" not in res.output and "0 of 2 simulations failed" in res.output
    res = runner.invoke(app, ["campaign", "--conditions", str(short), "--samples", "4",
                              "--batch-size", "2", "--parameters", "X13", "--out",
                              str(tmp_path / "r")])  # fmt: skip
    assert res.exit_code == 0 and "campaign stored in" in res.output, res.output
    n_steps = load_conditions(short)[0].n_steps
    needle = f"--window {n_steps} steps: accepted 2 to {n_steps - 1}, fewer"
    error = one_line_error(["train", tmp_path / "r", "--model", "bp", "--window", n_steps], needle)
    res = runner.invoke(app, ["train", str(tmp_path / "r"), "--model", "bp", "--window",
                              str(n_steps)])  # fmt: skip
    assert res.output.strip().splitlines()[-1] == error  # no progress bar after it


def test_training_on_an_incomplete_campaign_is_refused(short, tmp_path):
    from railsusp.campaign import make_config, run_campaign

    cfg = make_config(load_conditions(short), 4, parameters=("X13",), batch_size=2)
    run_campaign(cfg, tmp_path / "r", max_batches=1)
    one_line_error(["train", tmp_path / "r"], "the campaign is incomplete (1 of 2 batches)")
    one_line_error(["compare", tmp_path / "r"], "incomplete")
    # and from Python: the library refuses it as well, not only the command line
    from railsusp.campaign import CampaignError
    from railsusp.surrogate import train_surrogate
    from railsusp.surrogate.statistics import train_statistics_surrogate

    with pytest.raises(CampaignError, match="incomplete"):
        train_surrogate(tmp_path / "r", "short", kind="bp")
    with pytest.raises(CampaignError, match="incomplete"):
        train_statistics_surrogate(tmp_path / "r", "short")


# ---------------------------------------------------------------- parameters and conditions
def test_repeated_override_is_refused():
    with pytest.raises(ParameterError, match="X13 is given twice"):
        parse_overrides(["X13=16.1,X13=7"])
    with pytest.raises(ParameterError, match="given twice"):
        parse_overrides(["X13=16.1", "primary_longitudinal_stiffness=7"])
    one_line_error(["params", "--set", "X13=16.1,X13=7"], "X13 is given twice")


def test_fixed_parameters_refuse_absurd_values():
    one_line_error(["params", "--set", "X1=1e15"], "outside the accepted range [120, 12000] kg")
    with pytest.raises(ParameterError, match="must be positive"):
        ParameterSet({"X1": -5.0})
    assert ParameterSet({"X1": 1500.0})["X1"] == 1500.0  # a plausible value still goes


def test_booleans_are_not_numbers(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('[[condition]]\nname = "b"\nspeed_kmh = true\n')
    with pytest.raises(ConditionError, match="speed_kmh = true: a boolean is not accepted"):
        load_conditions(p)
    one_line_error(["conditions", p], "a boolean is not accepted")
    q = tmp_path / "p.toml"
    q.write_text("[parameters]\nX13 = true\n")
    with pytest.raises(ParameterError, match="not a number"):
        ParameterSet.from_toml(q)


@pytest.mark.parametrize("name", ["../../x", "/etc/x", "a/b", "..", ".hidden", "", "a\\b", "é"])
def test_condition_names_that_could_leave_the_run_directory_are_refused(name, tmp_path):
    with pytest.raises(ConditionError, match="name"):
        make_condition({"name": name})
    p = tmp_path / "c.toml"
    p.write_text(f"[[condition]]\nname = {json.dumps(name)}\n")
    with pytest.raises(ConditionError):
        load_conditions(p)


def test_safe_condition_names_still_load():
    for name in ("straight", "curve-300", "run_2.1", "A1"):
        assert make_condition({"name": name}).name == name


# ---------------------------------------------------------------- console output
def test_markup_does_not_eat_brackets_in_messages_and_help(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text("[condition]\nx = 1\n")
    one_line_error(["conditions", p], "expected [[condition]] or [condition.NAME] tables")
    assert "[parameters]" in runner.invoke(app, ["params", "--help"]).output
    assert "[parameters]" in runner.invoke(app, ["simulate", "--help"]).output


def test_huge_forces_print_in_scientific_notation():
    from railsusp.cli.simulation import number

    assert number(1e300, 1) == "1.000e+300"
    assert number(-3.2e7, 2) == "-3.200e+07"
    assert number(31.46, 1) == "31.5"
    assert number(float("nan"), 1) == "nan"


def test_errors_reach_a_real_terminal_as_one_line(garbage):
    """One real process: stderr, exit status and no traceback, outside the test runner."""
    proc = subprocess.run(
        [sys.executable, "-m", "railsusp.cli", "params", "--file", str(garbage)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr


# ---------------------------------------------------------------- atomic files
def test_atomic_folder_leaves_the_old_artefact_when_a_save_fails(tmp_path):
    from railsusp.store import atomic_folder

    art = tmp_path / "bundle"
    art.mkdir()
    (art / "model.pt").write_text("old weights")
    (art / "surrogate.json").write_text("old description")
    (art / "checkpoint.pt").write_text("checkpoint")
    with pytest.raises(RuntimeError), atomic_folder(art) as tmp:
        (tmp / "model.pt").write_text("new weights")
        raise RuntimeError("killed between the two files")
    assert (art / "model.pt").read_text() == "old weights"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle"]  # no temporary left
    with atomic_folder(art) as tmp:
        (tmp / "model.pt").write_text("new weights")
        (tmp / "surrogate.json").write_text("new description")
    assert (art / "model.pt").read_text() == "new weights"
    assert (art / "surrogate.json").read_text() == "new description"
    assert (art / "checkpoint.pt").read_text() == "checkpoint"  # other files are kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle"]


def test_writes_are_fsynced_file_and_folder(tmp_path, monkeypatch):
    from railsusp import store

    synced = []
    real = os.fsync

    def spy(fd):
        synced.append(os.readlink(f"/proc/self/fd/{fd}") if os.path.exists("/proc") else fd)
        return real(fd)

    monkeypatch.setattr(os, "fsync", spy)
    store.write_parquet(tmp_path / "batch.parquet", pd.DataFrame({"a": [1.0]}))
    store.write_json(tmp_path / "x.json", {"a": 1})
    assert any(str(s).endswith(".tmp") for s in synced)  # the file, before its rename
    assert synced.count(str(tmp_path)) >= 2  # the folder, after each rename
    assert not list(tmp_path.glob(".*tmp"))


def test_corrupt_json_is_an_input_error(tmp_path):
    from railsusp.store import read_json

    p = tmp_path / "x.json"
    p.write_bytes(b"\xff\xfe{")
    with pytest.raises(RailsuspInputError, match="not UTF-8"):
        read_json(p)
    p.write_text("{")
    with pytest.raises(RailsuspInputError, match="corrupt"):
        read_json(p)


def test_outputs_get_the_mode_of_plainly_written_files_and_stale_temporaries_go(tmp_path):
    """The kill/resume pass (stop 54): every output was 0600 (folders 0700) from mkstemp and
    mkdtemp, and a kill inside atomic_folder left .NAME.new-* for good."""
    import os
    import stat

    import pandas as pd

    from railsusp.store import atomic_folder, atomic_write_text, write_parquet

    mask = os.umask(0o022)
    os.umask(mask)
    mode = lambda p: stat.S_IMODE(p.stat().st_mode)  # noqa: E731
    assert mode(atomic_write_text(tmp_path / "a.json", "{}")) == 0o666 & ~mask
    assert mode(write_parquet(tmp_path / "b.parquet", pd.DataFrame({"x": [1]}))) == 0o666 & ~mask
    stale = tmp_path / ".net.new-abc123"
    stale.mkdir()
    (stale / "half.pt").write_bytes(b"x")
    with atomic_folder(tmp_path / "net") as tmp:
        (tmp / "model.pt").write_bytes(b"y")
    assert mode(tmp_path / "net") == 0o777 & ~mask
    assert not stale.exists() and (tmp_path / "net" / "model.pt").read_bytes() == b"y"


def test_ctrl_c_ends_a_command_with_a_line_saying_what_is_kept(monkeypatch, capsys):
    """Typer turns a KeyboardInterrupt into a silent exit 130 (the kill/resume pass of stop
    54); the console script now says what is kept and how to resume."""
    import railsusp.cli as cli

    def interrupted(**kwargs) -> int:
        assert kwargs == {"standalone_mode": False}
        return 130  # typer's exit status of a KeyboardInterrupt outside standalone mode

    monkeypatch.setattr(cli, "app", interrupted)
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == 130
    assert "interrupted: what was finished is kept" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (
            ["simulate", "straight", "--speed", "500"],
            "error: No such option: --speed (Possible options: --seed, --set) (see railsusp "
            "simulate --help)",
        ),
        (
            ["track", "--class", "5.5"],
            "error: Invalid value for '--class': Input should be a valid integer, unable to "
            "parse string as an integer (see railsusp track --help)",
        ),
        (["nosuch"], "error: No such command 'nosuch'. (see railsusp --help)"),
    ],
)
def test_the_console_script_gives_a_usage_error_in_one_line(args, line):
    """Click printed a usage error as a five-line box (stop 57's audit)."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(sys.executable).parent / "railsusp"
    done = subprocess.run(
        [str(script), *args], capture_output=True, text=True, timeout=120, env={"COLUMNS": "300"}
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [line] and done.stdout == ""


@pytest.mark.parametrize(
    ("error", "status", "line"),
    [
        (OSError(28, "No space left on device", "out/f.csv"), 1, "error: out/f.csv: No space left"),
        (PermissionError(13, "Permission denied", "ro/f"), 2, "error: ro/f: Permission denied"),
    ],
)
def test_an_operating_system_error_is_one_line_not_a_traceback(
    monkeypatch, capsys, error, status, line
):
    """A full disk or a folder that cannot be written ended every writing command in a
    traceback (stop 57's audit: track --plot, simulate --out, campaign, synth-field, ...)."""
    import railsusp.cli as cli

    def failing(**kwargs):
        raise error

    monkeypatch.setattr(cli, "app", failing)
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == status
    err = capsys.readouterr().err
    assert err.startswith(line) and len(err.strip().splitlines()) == 1
    # a full disk says what to do (a refused folder is the user's to change: no such advice)
    remedy = "free space and run the same command again"
    assert (remedy in err) == (error.errno == 28)


def test_a_command_exiting_itself_exits_as_python_would(monkeypatch):
    """The review of stop 57: a SystemExit with a message left main() as exit status 0."""
    import railsusp.cli as cli

    def exiting(**kwargs):
        raise SystemExit("boom")

    monkeypatch.setattr(cli, "app", exiting)
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == "boom"  # Python prints it and exits 1
