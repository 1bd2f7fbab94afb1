"""The command line's own streams and signals (railsusp.cli.common, railsusp.cli.main,
railsusp.interrupts): a closed stdout, a stdout that refuses writes, and a Ctrl-C that
Python swallowed.

The QA pass found: ``railsusp run ... >&-`` an AttributeError at import (``sys.stdout`` is
None); ``> /dev/full`` "No space left on device; free space and run the same command again",
about the disk, when only stdout was full; a Ctrl-C landing in a weakref callback printed
"Exception ignored ... KeyboardInterrupt" and the run went on to its end.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.cli.common import OutputStreamError, _StreamConsole
from railsusp.interrupts import record_interrupt, stop_if_interrupted

CLI = [sys.executable, "-m", "railsusp.cli"]


def test_a_closed_stdout_is_not_a_crash():
    """Started with its stdout closed, a command runs, its printout dropped (as print's)."""
    done = subprocess.run(
        [*CLI, "version"], preexec_fn=lambda: os.close(1), stderr=subprocess.PIPE, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "isatty" not in done.stderr


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full on this system")
def test_a_full_stdout_says_the_printout_was_lost_not_the_disk():
    with open("/dev/full", "w") as full:
        done = subprocess.run([*CLI, "version"], stdout=full, stderr=subprocess.PIPE, text=True)
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert lines == [
        "error: stdout: No space left on device: the printed output could not be written "
        "(the files the command wrote are whole and kept)"
    ], done.stderr
    assert "free space" not in done.stderr


def test_a_refused_write_names_its_stream():
    class Full:
        def write(self, text: str) -> int:
            raise OSError(errno.ENOSPC, "No space left on device")

        def flush(self) -> None:
            pass

    with pytest.raises(OutputStreamError) as info:
        _StreamConsole(file=Full()).print("x")
    assert info.value.stream == "stdout" and info.value.errno == errno.ENOSPC
    with pytest.raises(OutputStreamError) as info:
        _StreamConsole(file=Full(), stderr=True).print("x")
    assert info.value.stream == "stderr"


def test_main_exits_1_on_a_refused_stdout(monkeypatch, capsys):
    import railsusp.cli as cli

    def refused(**kwargs) -> int:
        raise OutputStreamError("stdout", OSError(errno.ENOSPC, "No space left on device"))

    monkeypatch.setattr(cli, "app", refused)
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == 1
    err = capsys.readouterr().err
    assert "error: stdout: No space left on device: the printed output could not be" in err


def test_a_command_records_ctrl_c_and_restores_the_handler_after():
    """The handler is the command's while it runs (it records, then raises as Python's
    does) and the previous one is back after it: tests run the CLI in-process."""
    seen = []

    @app.command("probe-signal", hidden=True)
    def probe_signal() -> None:
        handler = signal.getsignal(signal.SIGINT)
        seen.append(handler)
        with pytest.raises(KeyboardInterrupt):
            handler(signal.SIGINT, None)
        with pytest.raises(KeyboardInterrupt):  # recorded: a swallowed one still stops
            stop_if_interrupted()

    before = signal.getsignal(signal.SIGINT)
    try:
        result = CliRunner().invoke(app, ["probe-signal"])
        assert result.exit_code == 0, result.output
    finally:
        app.registered_commands[:] = [
            c for c in app.registered_commands if c.name != "probe-signal"
        ]
    assert seen and seen[0] is not before and before is signal.default_int_handler
    assert signal.getsignal(signal.SIGINT) is before
    stop_if_interrupted()  # forgotten when the command ended


def test_stop_if_interrupted_raises_only_after_a_recorded_ctrl_c():
    from railsusp.interrupts import catch_interrupts

    restore = catch_interrupts()
    try:
        stop_if_interrupted()
        record_interrupt()
        with pytest.raises(KeyboardInterrupt):
            stop_if_interrupted()
    finally:
        restore()
    stop_if_interrupted()
