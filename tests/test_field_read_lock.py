"""The commands that read a field folder hold its lock shared while they work: ``estimate
--measured F``, ``validate --measured F`` (and ``validate`` on the estimate's own
recordings) and ``posterior estimate --measured F``. Before, they locked only a run
directory F lay in, so ``synth-field --out F`` (which holds F exclusively) rewrote F under a
running estimate with exit status 0, and a read in the folder's swap returned recordings of
two truths under one ``index.json`` (the concurrency audit, finding 2). The tests marked so
failed on that code: the reader went on beside the writer, or the writer beside the reader."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.run_lock import LOCK_NAME, run_lock
from test_locks_cli import held, refused_line

runner = CliRunner()


def _readers(tmp: Path, field: Path) -> dict[str, list]:
    """Each command reading ``field``, with arguments otherwise accepted up to the read."""
    estimate = tmp / "estimate"
    return {
        "estimate": ["estimate", "--measured", field, "--out", tmp / "est", "--simulator"],
        "validate --measured": ["validate", estimate, "--measured", field],
        "validate": ["validate", estimate],  # the field its estimate.json records
        "posterior estimate": [
            "posterior", "estimate", "--measured", field, "--estimator", tmp / "post",
        ],
    }  # fmt: skip


READERS = list(_readers(Path("x"), Path("y")))


def _estimate_of(tmp: Path, field: Path) -> None:
    """An estimate folder whose ``estimate.json`` records ``field`` as its recordings."""
    (tmp / "estimate").mkdir(parents=True, exist_ok=True)
    (tmp / "estimate" / "estimate.json").write_text(json.dumps({"measured": str(field)}))


@pytest.fixture
def reading(monkeypatch):
    """Where each command reads the recordings (or, validate, starts its work): calls
    ``then`` there, or raises if no test set one; ``calls`` counts the reads."""
    import railsusp.measured
    import railsusp.validate

    state: dict = {"then": None, "calls": 0}

    def read(*args, **kwargs):
        state["calls"] += 1
        if state["then"] is None:
            raise AssertionError("read the field folder another process writes")
        state["then"]()
        raise RailsuspInputError("stopped here")

    for module, name in (
        (railsusp.measured, "read_field"),  # estimate
        (railsusp.measured, "read_index"),  # posterior estimate
        (railsusp.validate, "validate"),
    ):
        monkeypatch.setattr(module, name, read)
    return state


@pytest.mark.parametrize("command", READERS)
def test_a_reader_of_a_field_folder_is_refused_while_a_writer_works_in_it(
    tmp_path, reading, command
):
    """Failed before: the command read the folder ``synth-field`` was rewriting."""
    field = tmp_path / "field"
    _estimate_of(tmp_path, field)
    args = _readers(tmp_path, field)[command]
    with held("exclusive", field) as pid:
        line = refused_line(args)
    option = "--measured " if "--measured" in args else ""
    assert line.startswith(f"error: {option}{field}: another railsusp run is working in this "
                           f"folder (process {pid})"), line  # fmt: skip
    assert reading["calls"] == 0
    assert not (tmp_path / "est").exists()  # the refused estimate left no folder


def _take(folder: Path, shared: bool = False) -> str:
    """What another process gets taking ``folder``'s lock (exclusive as ``synth-field``,
    ``sections --write`` and ``align-track --write`` take it): from another thread, which
    has its own context (no lock lent), as another process would."""
    seen: list[str] = []

    def take() -> None:
        try:
            with run_lock(folder, "--out", shared=shared):
                seen.append("free")
        except RailsuspInputError as exc:
            seen.append(str(exc))

    other = threading.Thread(target=take)
    other.start()
    other.join()
    return seen[0]


@pytest.mark.parametrize("command", READERS)
def test_a_writer_of_a_field_folder_is_refused_while_a_command_reads_it(tmp_path, reading, command):
    """Failed before: the writer took the folder while the command read it. Another
    reader goes on beside it."""
    field = tmp_path / "field"
    field.mkdir()
    _estimate_of(tmp_path, field)
    seen: list[str] = []
    reading["then"] = lambda: seen.extend([_take(field), _take(field, shared=True)])
    result = runner.invoke(app, [str(a) for a in _readers(tmp_path, field)[command]])
    assert result.exit_code == 2 and "stopped here" in result.output, result.output
    assert seen[0] == (
        f"--out {field}: another railsusp run is working in this folder (process "
        f"{os.getpid()}); wait for it to end, or give another folder"
    ), seen
    assert seen[1] == "free"
    assert _take(field) == "free"  # let go with the command


def test_synth_field_is_refused_while_an_estimate_reads_the_folder(tmp_path, reading):
    """The audit's repro: ``synth-field --out F`` run while ``estimate --measured F`` read F
    wrote its recordings with exit status 0 (failed before); now it is refused in one line
    naming the estimate's process, and F is left as it was (empty: an empty folder is
    one synth-field writes into)."""
    field = tmp_path / "field"
    field.mkdir()
    done: list[subprocess.CompletedProcess] = []
    cli = [sys.executable, "-c", "from railsusp.cli import main; main()", "-q"]
    writer = [
        *cli,
        "synth-field",
        "--out",
        str(field),
        "--conditions",
        "straight",
        "--duration",
        "1",
    ]

    def synth_field() -> None:
        done.append(subprocess.run(writer, capture_output=True, text=True, timeout=120))

    reading["then"] = synth_field
    args = ["estimate", "--measured", field, "--out", tmp_path / "est", "--simulator"]
    assert refused_line(args) == f"error: --measured {field}: stopped here"
    proc = done[0]
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = (proc.stdout + proc.stderr).strip().splitlines()
    assert len(lines) == 1 and f"(process {os.getpid()})" in lines[0], lines
    assert [p.name for p in field.iterdir()] == [LOCK_NAME]


@pytest.mark.parametrize("command", ["estimate", "validate"])
def test_a_field_folder_in_a_run_directory_is_held_with_the_run_directory(
    tmp_path, reading, command
):
    """RUN/field: the command holds RUN shared (``near``, as before) and RUN/field shared,
    without refusing itself (validate takes RUN twice: for its estimate RUN/estimate and for
    the field its estimate.json records). While it reads, ``railsusp run RUN`` and a writer
    of RUN/field are refused (the latter failed before), a reader of either goes on."""
    run = tmp_path / "run"
    field = run / "field"
    field.mkdir(parents=True)
    (run / "pipeline.json").write_text('{"stages": {}}')
    _estimate_of(run, field)
    seen: list[str] = []
    reading["then"] = lambda: seen.extend(
        [_take(run), _take(field), _take(run, shared=True), _take(field, shared=True)]
    )
    args = {
        "estimate": ["estimate", "--measured", field, "--out", tmp_path / "est", "--simulator"],
        "validate": ["validate", run / "estimate"],
    }[command]
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2 and "stopped here" in result.output, result.output
    assert reading["calls"] == 1
    assert seen[0].startswith(f"--out {run}: another railsusp run is working"), seen
    assert seen[1].startswith(f"--out {field}: another railsusp run is working"), seen
    assert seen[2:] == ["free", "free"], seen


def test_readers_of_a_field_folder_run_together(tmp_path, reading):
    """Shared: an estimate reads a field folder another reader holds (a guard: it read
    unlocked before, so it was never refused)."""
    field = tmp_path / "field"
    reading["then"] = lambda: None
    with held("shared", field):
        line = refused_line(
            ["estimate", "--measured", field, "--out", tmp_path / "est", "--simulator"]
        )
    assert line == f"error: --measured {field}: stopped here"


@pytest.mark.parametrize("failure", [errno.EACCES, errno.EROFS], ids=["EACCES", "EROFS"])
@pytest.mark.parametrize("command", READERS)
def test_a_read_only_field_folder_without_a_lock_file_is_still_read(
    tmp_path, reading, monkeypatch, command, failure
):
    """A field folder shared read-only (or on a read-only file system) holding no lock
    file: no lock can be taken there, and nothing can write there either, so the command
    reads it unlocked, as the other readers' shared locks do (a guard: a read-only field
    folder must not become unusable; the tests run as root, so the refusal is simulated)."""
    import builtins

    import railsusp.run_lock as rl

    field = tmp_path / "field"
    field.mkdir()
    _estimate_of(tmp_path, field)

    def no_write(path, mode="r", *args, **kwargs):
        if Path(path).parent == field and ("a" in mode or "w" in mode):
            raise OSError(failure, os.strerror(failure), str(path))
        return builtins.open(path, mode, *args, **kwargs)

    monkeypatch.setattr(rl, "open", no_write, raising=False)
    reading["then"] = lambda: None
    result = runner.invoke(app, [str(a) for a in _readers(tmp_path, field)[command]])
    assert result.exit_code == 2 and "stopped here" in result.output, result.output
    assert "Traceback" not in result.output and reading["calls"] == 1
    assert not (field / LOCK_NAME).exists()


@pytest.mark.parametrize("command", ["align-track", "campaign --conditions"])
def test_the_other_readers_of_a_field_folder_are_refused_beside_a_writer(tmp_path, command):
    """Left by the first fix (stop 66): ``align-track F`` without ``--write`` and ``campaign
    --conditions F`` read a field folder, and its recordings' track files, unlocked."""
    field = tmp_path / "field"
    args = {
        "align-track": ["align-track", field],
        "campaign --conditions": ["campaign", "--conditions", field, "--out", tmp_path / "c"],
    }[command]
    (field).mkdir()
    (field / "index.json").write_text("{}")
    with held("exclusive", field) as pid:
        line = refused_line(args)
    option = "--conditions " if "--conditions" in args else ""
    assert line.startswith(f"error: {option}{field}: another railsusp run is working in this "
                           f"folder (process {pid})"), line  # fmt: skip
