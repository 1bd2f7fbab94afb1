"""What an interrupted command leaves, found by the interrupt/resume QA of stop 74: a Ctrl-C
that Python swallowed (inside an import) let a command replace its output folder and exit
0; the temporaries a killed write left were carried into every later save of a folder or
kept for good; a long message on stderr broke into two lines in a log."""

import json

import pytest
from typer.testing import CliRunner

from railsusp.atomic_files import atomic_folder
from railsusp.cli import app
from railsusp.interrupts import forget_interrupt, record_interrupt
from railsusp.run_lock import LOCK_NAME

runner = CliRunner()


def test_a_recorded_ctrl_c_stops_a_folder_swap_and_leaves_the_old_folder(tmp_path):
    out = tmp_path / "est"
    out.mkdir()
    (out / "estimate.json").write_text("old")
    record_interrupt()  # the handler's record of a Ctrl-C whose KeyboardInterrupt was lost
    try:
        with pytest.raises(KeyboardInterrupt), atomic_folder(out) as tmp:
            (tmp / "estimate.json").write_text("new")
    finally:
        forget_interrupt()
    assert (out / "estimate.json").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["est"]  # no temporary folder left
    with atomic_folder(out) as tmp:  # none recorded: swapped as always
        (tmp / "estimate.json").write_text("new")
    assert (out / "estimate.json").read_text() == "new"


def test_sections_write_stops_on_a_swallowed_ctrl_c_without_replacing_the_folder(
    tmp_path, monkeypatch
):
    """sections --write went on past a Ctrl-C lost inside asammdf's import, replaced the
    folder and exited 0."""
    import railsusp.measured.sections_out as sections_out

    assert runner.invoke(app, ["example-recording", "--out", str(tmp_path)]).exit_code == 0
    run, cmap = tmp_path / "example_run.mf4", tmp_path / "example_run.map.toml"
    out = tmp_path / "secs"
    args = ["sections", str(run), "--map", str(cmap), "--write", str(out)]
    assert runner.invoke(app, args).exit_code == 0
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != LOCK_NAME}
    real = sections_out.write_sections

    def swallowed(*a, **k):
        record_interrupt()  # as the handler does, its KeyboardInterrupt then lost
        return real(*a, **k)

    monkeypatch.setattr(sections_out, "write_sections", swallowed)
    result = runner.invoke(app, args)
    assert result.exit_code != 0 and "wrote" not in result.output
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != LOCK_NAME} == before


def test_a_killed_writes_temporary_is_not_carried_into_the_next_save(tmp_path):
    out = tmp_path / "est"
    out.mkdir()
    (out / ".estimate.json.abcd1234.tmp").write_text("half")  # a killed atomic write's
    (out / "notes.txt").write_text("mine")
    with atomic_folder(out) as tmp:
        (tmp / "estimate.json").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["estimate.json", "notes.txt"]


def test_posterior_train_sweeps_its_killed_writes_temporaries(tmp_path, monkeypatch):
    """posterior train rewrote calibration.json but kept the temporaries a killed write
    had left beside it and among the cached chunks."""
    import railsusp.estimate.posterior as posterior

    folder = tmp_path / "run" / "posterior"
    (folder / "simulations").mkdir(parents=True)
    (folder / "synthetic").mkdir()
    left = [
        folder / ".calibration.json.abcd1234.tmp",
        folder / "simulations" / ".check_0000_50.npz.abcd1234.tmp",
        folder / "synthetic" / ".check.json.abcd1234.tmp",
    ]
    for p in left:
        p.write_bytes(b"half")
    kept = folder / "simulations" / "notes.tmp"  # no railsusp temporary: left alone
    kept.write_text("mine")

    def trained(settings, out):
        raise SystemExit(0)  # the sweep is before the training: nothing more needed

    monkeypatch.setattr(posterior, "train", trained)
    args = ["posterior", "train", "--conditions", "straight", "--out", str(tmp_path / "run")]
    runner.invoke(app, args)
    assert not any(p.exists() for p in left) and kept.exists()


def test_a_long_message_on_stderr_is_one_line_in_a_log(tmp_path):
    """The interrupt line (190 characters) broke in two at a log's 150 columns, as every
    warning and error printed without soft wrap did."""
    import subprocess
    import sys

    code = (
        "from railsusp.cli.common import err_console\n"
        "err_console.print('interrupted: ' + 'x' * 300)\n"
    )
    err = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stderr
    assert err.count("\n") == 1 and len(err) > 300


def test_the_replaced_network_note_reads_a_folder_left_aside_mid_swap(tmp_path):
    """train's 'replacing the network ... trained with other settings' note read a trained
    folder that a crash had left aside as missing, and said nothing (the review of stop
    74): it is put back first."""
    from railsusp.surrogate import replaced_settings

    folder = tmp_path / "cnn-gru" / ".straight.old-abcd1234"
    folder.mkdir(parents=True)
    doc = {"meta": {"train_config": {"epochs": 5}}, "net": {"window": 20}}
    (folder / "surrogate.json").write_text(json.dumps(doc))
    changed = replaced_settings(tmp_path / "cnn-gru" / "straight", {"epochs": 6}, 20, False)
    assert changed and "epochs" in changed[0]
    assert [p.name for p in (tmp_path / "cnn-gru").iterdir()] == ["straight"]
