"""A Ctrl-C while the console script loads the command line (railsusp.command): one line and
status 130, not Python's KeyboardInterrupt traceback of the import (interrupt QA of stop
74: the command line's handler is installed only once the command has loaded)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

from railsusp.command import INTERRUPTED_LOADING

#: a child that loads the command line as the console script does, with the import of
#: railsusp.cli held for 10 s (a meta-path finder that sleeps): the Ctrl-C lands in it
_CHILD = textwrap.dedent(
    """
    import sys, time

    class SlowCli:
        def find_spec(self, name, path=None, target=None):
            if name == "railsusp.cli":
                print("loading", flush=True)
                time.sleep(10)
            return None

    sys.meta_path.insert(0, SlowCli())
    sys.argv = ["railsusp", "version"]
    from {module} import main
    main()
    """
)


def _interrupted_while_loading(module: str) -> subprocess.CompletedProcess:
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD.format(module=module)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    assert child.stdout.readline().strip() == "loading"
    time.sleep(0.2)
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=60)
    return subprocess.CompletedProcess(child.args, child.returncode, out, err)


def test_a_ctrl_c_while_the_command_line_loads_is_one_line_and_status_130():
    done = _interrupted_while_loading("railsusp.command")
    assert done.returncode == 130
    assert done.stderr.strip() == INTERRUPTED_LOADING
    assert "Traceback" not in done.stderr


def test_the_console_script_enters_through_the_light_module():
    """pyproject's console script names railsusp.command:main (railsusp.cli:main, the
    entry before, gave the traceback: its own import is the half second)."""
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    assert project["project"]["scripts"]["railsusp"] == "railsusp.command:main"
    old = _interrupted_while_loading("railsusp.cli")
    assert old.returncode != 130 and "KeyboardInterrupt" in old.stderr


def test_the_console_scripts_start_loads_the_standard_library_only():
    """``import railsusp`` comes before the entry's Ctrl-C guard: it loaded NumPy and pydantic
    (the parameter catalogue, the conditions), 0.2 s in which a Ctrl-C printed a traceback.
    Its public names now load on first use, and still resolve."""
    probe = (
        "import sys\n"
        "before = set(sys.modules)\n"  # (site's own start: a .pth hook of setuptools)
        "import railsusp.command\n"
        "top = {m.split('.')[0] for m in set(sys.modules) - before}\n"
        "print(sorted(top - set(sys.stdlib_module_names) - {'railsusp'}))\n"
        "import railsusp\n"
        "print(railsusp.ParameterSet.__name__, railsusp.get_condition('straight').name)"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True
    )
    assert done.stdout.splitlines() == ["[]", "ParameterSet straight"]
