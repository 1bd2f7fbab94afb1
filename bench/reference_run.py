"""Run a bench script on another checkout's ``src`` in a subprocess, for an A/B in one sitting.

The scripts that compare with an older commit (simulator.py, rhs_profile.py) call
:func:`reference_rows` with their own path and arguments; the reference run writes its JSON to
a temporary file, whose ``rows`` come back. ``src`` is e.g. a git worktree of the older
commit (``git worktree add /tmp/ref COMMIT``, then ``/tmp/ref/src``).

A ``src`` without ``railsusp/__init__.py`` (the worktree's root given instead of its
``src``, a typo) is refused: the child would import the installed railsusp instead, today's
code, and the A/B would compare it with itself. The child also checks that the railsusp it
imports lies under ``src`` before running the script, and says which it is.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from railsusp.errors import RailsuspInputError

#: the child's start: the script's folder first on the path (as ``python SCRIPT`` has it),
#: railsusp imported and checked to come from the reference ``src``, then the script run
_CHILD = """
import os, runpy, sys
from pathlib import Path
script, src = sys.argv[1], Path(sys.argv[2])
sys.argv = [script, *sys.argv[3:]]
sys.path[0] = str(Path(script).resolve().parent)
import railsusp
got = Path(railsusp.__file__).resolve()
if src not in got.parents:
    sys.exit(f"the reference run imported {got}, not the railsusp under {src}")
print(f"reference railsusp: {got}", file=sys.stderr)
runpy.run_path(script, run_name="__main__")
"""


def reference_src(src: str | Path) -> Path:
    """``src`` resolved, when it holds a railsusp package (``railsusp/__init__.py``); else a
    :class:`~railsusp.errors.RailsuspInputError` naming it."""
    path = Path(src).resolve()
    if not (path / "railsusp" / "__init__.py").is_file():
        raise RailsuspInputError(
            f"--reference-src {src}: no railsusp/__init__.py under it; accepted a checkout's "
            "src folder (e.g. WORKTREE/src)"
        )
    return path


def reference_rows(script: str, args: list[str], src: str) -> list[dict]:
    """``rows`` of the JSON that ``script args --out TMP`` writes with PYTHONPATH=src (the
    railsusp it imported is said on stderr; one not under ``src`` fails the run)."""
    path = reference_src(src)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "reference.json"
        env = dict(os.environ, PYTHONPATH=str(path))
        cmd = [sys.executable, "-c", _CHILD, script, str(path), *args, "--out", str(out)]
        # its stderr passed on as it comes (its progress, as before), the last line kept
        # for the refusal where it fails
        last = "no message"
        with subprocess.Popen(
            cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
        ) as child:
            for line in child.stderr:
                print(line, end="", file=sys.stderr)
                last = line.strip() or last
        if child.returncode != 0:
            raise RailsuspInputError(
                f"--reference-src {src}: the reference run failed (exit {child.returncode}): {last}"
            )
        return json.loads(out.read_text())["rows"]
