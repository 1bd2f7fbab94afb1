"""A Ctrl-C at the terminal reaches the whole process group, the local Dask cluster's
worker processes too: `campaign --workers 2` printed some 60 lines of worker warnings and
KeyboardInterrupt tracebacks before its one "interrupted" line (the QA of stop 74): the
workers' cancelled tasks and the nannies' shutdown are unsaid now, and a Ctrl-C while the
cluster starts waits until it has (the command's process stops and closes it)."""

import os
import signal
import subprocess
import sys
import textwrap
import time

TASK = """
import pathlib, time

def busy(flag, seconds):
    pathlib.Path(flag).touch()  # running: the harness may interrupt now
    end = time.time() + seconds
    while time.time() < end:  # a simulation's busy loop, not a sleep
        sum(range(1000))
    return seconds
"""

DRIVER = """
import sys
import dask.distributed  # loaded before "starting": the interrupt meets the cluster's start
from railsusp.campaign.dask_cluster import run_on_dask
from slowtask import busy

if __name__ == "__main__":
    flag = sys.argv[1]
    print("starting", flush=True)
    try:
        run_on_dask(busy, [(0, b) for b in range(4)], lambda ci, b: (f"{flag}{b}", 60.0),
                    lambda b, r: None, None, 2)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        sys.exit(130)
"""


def _driver(tmp_path):
    """The driver running four minute-long batches on a local cluster of two workers, in a
    process group of its own as a terminal's foreground job."""
    (tmp_path / "slowtask.py").write_text(textwrap.dedent(TASK))
    (tmp_path / "driver.py").write_text(textwrap.dedent(DRIVER))
    flag = tmp_path / "started-"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    return subprocess.Popen(
        [sys.executable, "driver.py", str(flag)],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def test_a_ctrl_c_to_the_process_group_stops_a_local_cluster_in_one_line(tmp_path):
    proc = _driver(tmp_path)
    try:
        deadline = time.time() + 120
        while not list(tmp_path.glob("started-*")) and time.time() < deadline:
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.2)
        time.sleep(1.0)
        os.killpg(proc.pid, signal.SIGINT)  # what the terminal does on Ctrl-C
        _, err = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert proc.returncode == 130
    assert lines == ["interrupted"], err


def test_a_ctrl_c_while_the_cluster_starts_is_not_lost(tmp_path):
    """SIGINT ignored while the cluster started lost a Ctrl-C pressed then, and the campaign
    went on (the review of stop 74): blocked, it waits and stops the command once the
    cluster has started, the cluster closed."""
    proc = _driver(tmp_path)
    try:
        assert proc.stdout.readline().strip() == "starting"
        time.sleep(0.3)  # the cluster starting its processes
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=90)  # lost, it would run its batches: 2 minutes
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130
    # the command's own line last; a worker still importing when the cluster is closed
    # may print its traceback before it (its process is not railsusp's yet)
    assert [ln for ln in err.splitlines() if ln.strip()][-1] == "interrupted", err


CRASHING = """
import logging, os, pathlib, signal

def crash_once(flag):
    # the first attempt kills its worker process, as a crash or the kernel's OOM killer
    # would; the nanny starts a new worker, where Dask runs the task again
    flag = pathlib.Path(flag)
    if not flag.exists():
        flag.touch()
        os._exit(1)
    quiet = logging.getLogger("distributed").level > logging.CRITICAL
    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN, quiet
"""


def test_a_worker_restarted_after_a_crash_is_kept_quiet_too(tmp_path):
    """The workers were quieted once, as the cluster started (client.run): a worker the
    nanny restarted after a crash took Ctrl-C and logged its shutdown again. A worker plugin
    quiets each worker as it starts (railsusp.campaign.dask_quiet); checked in the
    restarted worker itself."""
    (tmp_path / "crashing.py").write_text(textwrap.dedent(CRASHING))
    driver = textwrap.dedent(
        """
        import json, sys
        from railsusp.campaign.dask_cluster import run_on_dask
        from crashing import crash_once

        if __name__ == "__main__":
            got = []
            run_on_dask(crash_once, [(0, 0)], lambda ci, b: (sys.argv[1],),
                        lambda b, r: got.append(r), None, 1)
            print(json.dumps(got))
        """
    )
    (tmp_path / "driver.py").write_text(driver)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    done = subprocess.run(
        [sys.executable, "driver.py", str(tmp_path / "crashed")],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "crashed").exists()  # the first worker did crash
    assert done.stdout.strip().splitlines()[-1] == "[[true, true]]", done.stdout
