"""Run a bench script on another checkout's ``src`` in a subprocess, for an A/B in one sitting.

The scripts that compare with an older commit (simulator.py, rhs_profile.py) call
:func:`reference_rows` with their own path and arguments; the reference run writes its JSON to
a temporary file, whose ``rows`` come back. ``src`` is e.g. a git worktree of the older
commit (``git worktree add /tmp/ref COMMIT``, then ``/tmp/ref/src``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def reference_rows(script: str, args: list[str], src: str) -> list[dict]:
    """``rows`` of the JSON that ``script args --out TMP`` writes with PYTHONPATH=src."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "reference.json"
        env = dict(os.environ, PYTHONPATH=str(Path(src).resolve()))
        cmd = [sys.executable, script, *args, "--out", str(out)]
        subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
        return json.loads(out.read_text())["rows"]
