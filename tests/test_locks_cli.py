"""Every command that writes into a campaign, run, estimate or field folder holds that
folder's lock for its duration (the concurrency audit: only ``campaign`` and ``run`` did;
``sensitivity`` went on while ``campaign --force`` replaced the campaign under it, and wrote
the old campaign's indices beside the new one), readers hold it shared, and a stage folder
of a ``railsusp run`` directory is refused while the run works in it. Each test failed on
the code before: the second writer worked (or failed on something else) instead of being
refused in one line, exit status 2, naming the process that holds the folder."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from contextlib import contextmanager
from pathlib import Path

import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.run_lock import LOCK_NAME, run_lock

runner = CliRunner()

#: a process holding the locks of the folders it is given until its stdin closes: flock on
#: FOLDER/.railsusp.lock (railsusp.run_lock's), its process id written into the file
HOLDER = """
import fcntl, os, sys
held = []
for folder in sys.argv[2:]:
    fh = open(os.path.join(folder, ".railsusp.lock"), "a+")
    fcntl.flock(fh, fcntl.LOCK_SH if sys.argv[1] == "shared" else fcntl.LOCK_EX)
    fh.write(f"{os.getpid()}\\n")
    fh.flush()
    held.append(fh)
print("ready", flush=True)
sys.stdin.read()
"""


@contextmanager
def held(mode: str, *folders: Path):
    """Another process holding ``folders``' locks (``exclusive`` as a writer, ``shared`` as a
    reader) while the block runs; yields its process id."""
    for f in folders:
        f.mkdir(parents=True, exist_ok=True)
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLDER, mode, *map(str, folders)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline()
        assert line.strip() == "ready", proc.stderr.read()
        yield proc.pid
    finally:
        proc.stdin.close()
        proc.wait(timeout=30)


def refused_line(args: list[str]) -> str:
    """The one-line refusal of a command, exit status 2."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    return lines[0]


@pytest.fixture(autouse=True)
def no_work(monkeypatch):
    """The commands' work, which none of these tests may reach (the code before ran it):
    each raises at once instead of simulating or training."""
    import railsusp.campaign
    import railsusp.estimate.posterior
    import railsusp.estimate.posterior_joint
    import railsusp.measured
    import railsusp.sensitivity
    import railsusp.surrogate
    import railsusp.surrogate.compare
    import railsusp.validate

    def worked(*args, **kwargs):
        raise AssertionError("worked in a folder another process holds")

    for module, name in (
        (railsusp.campaign, "run_campaign"),
        (railsusp.estimate.posterior, "train"),
        (railsusp.estimate.posterior_joint, "train"),
        (railsusp.measured, "synthesise_field"),
        (railsusp.sensitivity, "analyse"),
        (railsusp.surrogate, "train_surrogate"),
        (railsusp.surrogate.compare, "compare"),
        (railsusp.validate, "validate"),
    ):
        monkeypatch.setattr(module, name, worked)


def _writers(tmp: Path, folder: Path) -> dict[str, list]:
    """Each writing command on ``folder``, with arguments otherwise accepted."""
    estimate = tmp / "estimate"
    return {
        "sensitivity": ["sensitivity", folder],
        "train": ["train", folder, "--epochs", "1", "--batches-per-epoch", "1"],
        "compare": ["compare", folder, "--models", "bp"],
        "estimate": ["estimate", "--measured", tmp / "field", "--out", folder, "--simulator"],
        "validate": ["validate", folder],
        "validate --out": ["validate", estimate, "--out", folder],
        "posterior train": ["posterior", "train", "--out", folder, "--conditions", "straight"],
        "posterior join": [
            "posterior",
            "join",
            "--estimators",
            f"{tmp / 'a'},{tmp / 'b'}",
            "--out",
            folder,
        ],
        "synth-field": ["synth-field", "--out", folder, "--conditions", "straight"],
        "align-track --write": ["align-track", folder, "--write"],
    }


WRITERS = list(_writers(Path("x"), Path("y")))


@pytest.mark.parametrize("command", WRITERS)
def test_a_writer_is_refused_in_a_folder_another_process_works_in(tmp_path, command):
    folder = tmp_path / "run"
    args = _writers(tmp_path, folder)[command]
    (tmp_path / "estimate").mkdir()
    with held("exclusive", folder) as pid:
        line = refused_line(args)
    assert "another railsusp run is working in this folder" in line, line
    assert f"(process {pid})" in line and str(folder) in line, line


@pytest.mark.parametrize(
    "command",
    ["campaign --keys-from", "posterior estimate --estimator", "sensitivity --compare"],
)
def test_a_reader_is_refused_while_a_writer_works_in_what_it_reads(tmp_path, command):
    """A campaign sampled the key parameters of an analysis being rewritten, an estimate
    read an estimator being trained again, a comparison a campaign being replaced."""
    folder = tmp_path / "other"
    args = {
        "campaign --keys-from": [
            "campaign",
            "--out",
            tmp_path / "new",
            "--keys-from",
            folder,
            "--conditions",
            "straight",
            "--samples",
            "4",
        ],
        "posterior estimate --estimator": [
            "posterior",
            "estimate",
            "--measured",
            tmp_path / "field",
            "--estimator",
            folder,
        ],
        "sensitivity --compare": ["sensitivity", tmp_path, "--compare", folder],
    }[command]
    option = command.split()[-1]
    with held("exclusive", folder) as pid:
        line = refused_line(args)
    assert line.startswith(f"error: {option} {folder}: another railsusp run is working"), line
    assert f"(process {pid})" in line
    assert not (tmp_path / "new").exists()  # the refused campaign left no folder


def test_readers_run_together_and_a_writer_waits_for_them(tmp_path):
    """Shared locks: a second reader of an estimator goes on (and fails on its missing
    recordings, not on the lock); a writer is refused, naming the reading process."""
    folder = tmp_path / "post"
    with held("shared", folder) as pid:
        result = runner.invoke(
            app,
            ["posterior", "estimate", "--measured", str(tmp_path / "field"),
             "--estimator", str(folder)],
        )  # fmt: skip
        assert result.exit_code == 2 and "another railsusp run" not in result.output
        line = refused_line(["posterior", "train", "--out", folder, "--conditions", "straight"])
        assert f"another railsusp run is working in this folder (process {pid})" in line
        with pytest.raises(RailsuspInputError, match=f"process {pid}"):
            with run_lock(folder, "--out"):  # as `railsusp run` or a campaign takes it
                pass
        with run_lock(folder, "--out", shared=True):  # another reader: together
            pass


@pytest.mark.parametrize(
    "args",
    [
        ["sensitivity", "{run}/campaign"],
        ["train", "{run}/campaign", "--epochs", "1"],
        ["campaign", "--out", "{run}/campaign", "--conditions", "straight", "--samples", "4",
         "--force"],
        ["estimate", "--measured", "{run}/field", "--out", "{run}/estimate", "--simulator"],
        ["validate", "{run}/estimate"],
    ],
    ids=["sensitivity", "train", "campaign", "estimate", "validate"],
)  # fmt: skip
def test_a_stage_folder_of_a_run_is_refused_while_the_run_works(tmp_path, args):
    """``railsusp run RUN`` holds RUN while its stages write RUN/campaign, RUN/estimate:
    a standalone command there went on beside it (a campaign --force of RUN/campaign
    deleted the analysis the run was writing)."""
    run = tmp_path / "run"
    for sub in ("campaign", "estimate", "field"):
        (run / sub).mkdir(parents=True)
    (run / "pipeline.json").write_text('{"stages": {}}')
    args = [a.format(run=run) for a in args]
    with held("exclusive", run) as pid:
        line = refused_line(args)
    assert f"another railsusp run is working in its run directory {run} (process {pid})" in line


@pytest.mark.parametrize(
    "args",
    [
        ["sensitivity", "{link}"],
        ["campaign", "--out", "{link}", "--conditions", "straight", "--samples", "4", "--force"],
    ],
    ids=["sensitivity", "campaign --force"],
)  # fmt: skip
def test_a_stage_folder_named_through_a_link_is_refused_while_the_run_works(tmp_path, args):
    """A symbolic link to RUN/campaign was not seen to lie in RUN (pipeline.json was looked
    for above the link's own name): sensitivity rewrote the run's analysis and campaign
    --force replaced its campaign beside ``railsusp run`` (the Dask and locks audit)."""
    run = tmp_path / "run"
    (run / "campaign").mkdir(parents=True)
    (run / "pipeline.json").write_text('{"stages": {}}')
    link = tmp_path / "elsewhere" / "camp_link"
    link.parent.mkdir()
    link.symlink_to(run / "campaign", target_is_directory=True)
    args = [a.format(link=link) for a in args]
    with held("exclusive", run) as pid:
        line = refused_line(args)
    assert f"another railsusp run is working in its run directory {run} (process {pid})" in line


def test_a_folder_and_a_link_to_it_named_together_are_one_folder(tmp_path):
    """Named once as itself and once through a link, a folder is one folder: the command is
    not refused by its own lock (a guard for the plan keyed by where folders resolve to,
    which the link test above needed; it passed before too)."""
    folder = tmp_path / "camp"
    folder.mkdir()
    link = tmp_path / "link"
    link.symlink_to(folder, target_is_directory=True)
    import typer

    from railsusp.cli.common import hold_folders

    tiny = typer.Typer()

    @tiny.command()
    def work() -> None:
        hold_folders(writes=[("--out", link)], reads=[("--keys-from", folder)])
        print("held")

    result = runner.invoke(tiny, [])
    assert result.exit_code == 0 and "held" in result.output, result.output


def test_a_run_is_refused_while_a_command_works_in_one_of_its_stage_folders(tmp_path, monkeypatch):
    """The other way round: ``sensitivity RUN/campaign`` holds RUN shared while it works, so
    ``railsusp run RUN`` (which takes RUN exclusively, railsusp.pipeline) is refused
    instead of rewriting the stage under it; a second reader of RUN goes on."""
    import railsusp.sensitivity

    run = tmp_path / "run"
    (run / "campaign").mkdir(parents=True)
    (run / "pipeline.json").write_text('{"stages": {}}')
    seen = []

    def take(shared: bool) -> None:  # another thread: its own context, as another process
        try:
            with run_lock(run, "--out", shared=shared):
                seen.append("free")
        except RailsuspInputError as exc:
            seen.append(str(exc))

    def analyse(folder, **kwargs):
        for shared in (False, True):
            other = threading.Thread(target=take, args=(shared,))
            other.start()
            other.join()
        raise RailsuspInputError("stopped here")

    monkeypatch.setattr(railsusp.sensitivity, "analyse", analyse)
    assert refused_line(["sensitivity", run / "campaign"]) == "error: stopped here"
    assert seen[1:] == ["free"], seen
    assert seen[0] == (
        f"--out {run}: another railsusp run is working in this folder (process "
        f"{os.getpid()}); wait for it to end, or give another folder"
    )
    with run_lock(run, "--out"):  # let go with the command
        pass


def test_the_lock_is_held_for_the_command_and_let_go_at_its_end(tmp_path, monkeypatch):
    """While ``sensitivity`` works, its campaign is locked (a ``campaign --force`` is
    refused); when it ends, however it ends, the folder is free again; a refused command
    leaves no folder of its own behind."""
    import railsusp.sensitivity

    folder = tmp_path / "camp"
    folder.mkdir()
    seen = []

    def take(run: Path) -> None:  # what a campaign --force takes, elsewhere than here
        try:
            with run_lock(run, "--out"):
                seen.append("free")
        except RailsuspInputError as exc:
            seen.append(str(exc))

    def analyse(run, **kwargs):
        other = threading.Thread(target=take, args=(Path(run),))  # not lent: its own context
        other.start()
        other.join()
        raise RailsuspInputError("stopped here")

    monkeypatch.setattr(railsusp.sensitivity, "analyse", analyse)
    line = refused_line(["sensitivity", folder])
    assert line == "error: stopped here"
    assert seen and f"(process {os.getpid()})" in seen[0], seen
    with run_lock(folder, "--out"):  # let go with the command
        pass
    import railsusp.measured

    def refuse(*args, **kwargs):  # as it refuses a negative seed, after the lock was taken
        raise RailsuspInputError("seed = -1: accepted 0 or more")

    monkeypatch.setattr(railsusp.measured, "synthesise_field", refuse)
    new = tmp_path / "new" / "field"
    refused_line(["synth-field", "--out", new, "--conditions", "straight", "--seed", "-1"])
    assert not (tmp_path / "new").exists()


def test_a_dead_holder_is_taken_over_and_the_lock_file_names_live_holders_only(tmp_path):
    """A killed process's lock goes with it (the file stays, naming it): the next command
    takes the folder; a refusal names the live holders, not the dead one."""
    folder = tmp_path / "camp"
    folder.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLDER, "exclusive", str(folder)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "ready"
    proc.kill()
    proc.wait()
    assert str(proc.pid) in (folder / LOCK_NAME).read_text()
    with run_lock(folder, "--out", shared=True):
        with held("shared", folder) as pid:
            with pytest.raises(RailsuspInputError) as info:
                with run_lock(folder, "--out"):
                    pass
    text = str(info.value)
    named = text[text.index("(processes ") + len("(processes ") : text.index(")")]
    assert sorted(named.split(", ")) == sorted([str(os.getpid()), str(pid)]), text
    assert str(proc.pid) not in text


def test_a_lent_lock_lets_the_code_it_runs_take_the_folder(tmp_path):
    """A command holding its folder calls library code that locks it too (the campaign
    command and run_campaign): lent, the inner lock passes; not lent, it is refused, as
    two processes are."""
    with run_lock(tmp_path, "--out", lend=True):
        with run_lock(tmp_path, "--out"):
            pass
    with run_lock(tmp_path, "--out"):
        with pytest.raises(RailsuspInputError, match="another railsusp run"):
            with run_lock(tmp_path, "--out"):
                pass


def test_a_reader_of_a_folder_it_cannot_write_without_a_lock_file_is_told_so(tmp_path, monkeypatch):
    """A folder shared read-only and holding no lock file (an estimator trained before every
    command locked): opening the lock file to write was refused, the read-only open then
    found none and raised FileNotFoundError, which the readers' skip of unwritable folders
    did not take: the command failed with a traceback (the review of stop 64). The refusal
    to write is what comes out now, and the reader goes on without the lock."""
    import builtins
    import errno

    import railsusp.run_lock as rl

    def no_write(path, mode="r", *args, **kwargs):
        if "a" in mode or "w" in mode:
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return builtins.open(path, mode, *args, **kwargs)

    monkeypatch.setattr(rl, "open", no_write, raising=False)
    with pytest.raises(PermissionError) as info, rl.run_lock(tmp_path, "--estimator", shared=True):
        pass
    assert info.value.errno == errno.EACCES
