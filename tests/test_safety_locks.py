"""``sections --write`` and ``example-recording --out`` hold their folder's lock as the other
writing commands do, and railsusp's own lock file does not make a folder "another kind"
of folder (it did: a folder holding only ``.railsusp.lock``, the one a writer makes for its
lock or a crashed one leaves, was refused as other data). Each test failed on the code
before: the command worked beside the process holding its folder, or refused the folder
as holding files of another kind."""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import pytest
from typer.testing import CliRunner

from railsusp.errors import RailsuspInputError
from railsusp.measured.field_folder import check_field_output, folder_kind
from railsusp.run_lock import LOCK_NAME, run_lock
from test_locks_cli import held, refused_line

runner = CliRunner()


@pytest.fixture
def long_run(tmp_path) -> Path:
    """A long run's file: never read (read_run is replaced where a test gets that far)."""
    path = tmp_path / "run.csv"
    path.write_text("time,speed\n0,10\n")
    return path


class Reader:
    """``read_run`` replaced: records whether ``folder`` is free to another writer (asked
    from another thread: its own context, as another process), then stops the command."""

    def __init__(self) -> None:
        self.folder: Path | None = None
        self.seen: list[str] = []

    def __call__(self, *args, **kwargs):
        def take() -> None:
            if not self.folder.is_dir():
                self.seen.append("no folder")
                return
            try:
                with run_lock(self.folder, "--write"):
                    self.seen.append("free")
            except RailsuspInputError as exc:
                self.seen.append(str(exc))

        other = threading.Thread(target=take)
        other.start()
        other.join()
        raise RailsuspInputError("stopped here")


@pytest.fixture
def reader(monkeypatch) -> Reader:
    import railsusp.measured.run

    reader = Reader()
    monkeypatch.setattr(railsusp.measured.run, "read_run", reader)
    return reader


def _refusal(folder: Path, pid: int, option: str = "--write") -> str:
    return (
        f"{option} {folder}: another railsusp run is working in this folder (process "
        f"{pid}); wait for it to end, or give another folder"
    )


def _sections_folder(folder: Path, source: str) -> None:
    """What an earlier ``sections --write`` of ``source`` left (an index written before the
    fingerprint: compared by name)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "index.json").write_text(json.dumps({"source": source, "recordings": []}))
    (folder / "sections.csv").write_text("start_m,end_m\n")


def test_sections_write_holds_its_folder_while_it_works(tmp_path, long_run, reader):
    """While the run is read and cut, the folder is locked (made for the lock where new);
    a refused cut leaves no folder of its own."""
    out = reader.folder = tmp_path / "new" / "field"
    assert refused_line(["sections", long_run, "--write", out]) == "error: stopped here"
    assert reader.seen == [_refusal(out, os.getpid())]
    assert not (tmp_path / "new").exists()


def test_sections_write_is_refused_in_a_folder_another_process_works_in(tmp_path, long_run, reader):
    """The folder holds an earlier cut of the same run (accepted to be written again):
    another process writing there refuses it in one line, before the run is read."""
    out = reader.folder = tmp_path / "field"
    _sections_folder(out, long_run.name)
    with held("exclusive", out) as pid:
        line = refused_line(["sections", long_run, "--write", out])
    assert line == f"error: {_refusal(out, pid)}"
    assert not reader.seen  # never read


def test_example_recording_is_refused_in_a_folder_another_process_works_in(tmp_path):
    out = tmp_path / "example"
    with held("exclusive", out) as pid:
        line = refused_line(["example-recording", "--out", out])
    assert line == f"error: {_refusal(out, pid, '--out')}"
    assert [p.name for p in out.iterdir()] == [LOCK_NAME]  # nothing copied


def test_a_folder_holding_only_the_lock_file_is_empty(tmp_path):
    folder = tmp_path / "field"
    folder.mkdir()
    (folder / LOCK_NAME).write_text("12345\n")  # as a crashed or refused writer left it
    assert folder_kind(folder) == "empty"
    for writer in ("synthetic", "sections"):
        assert check_field_output(folder, writer, "--out") == folder
    (folder / "notes.txt").write_text("mine")  # anything else: still another kind
    assert folder_kind(folder) == "other"
    with pytest.raises(RailsuspInputError, match="holds files of another kind"):
        check_field_output(folder, "sections", "--write")


def test_sections_write_accepts_a_folder_left_holding_only_the_lock_file(
    tmp_path, long_run, reader
):
    """It was refused as "files of another kind" (synth-field alone special-cased it)."""
    out = reader.folder = tmp_path / "field"
    out.mkdir()
    (out / LOCK_NAME).write_text("12345\n")
    assert refused_line(["sections", long_run, "--write", out]) == "error: stopped here"
    assert reader.seen == [_refusal(out, os.getpid())]
