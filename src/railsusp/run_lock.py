"""One railsusp process at a time in a run directory: an advisory lock on
``FOLDER/.railsusp.lock`` (:func:`run_lock`), held by ``railsusp run`` on its run directory
and by a campaign on its folder (standalone or the pipeline's ``campaign/``)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from railsusp.errors import RailsuspInputError

#: the lock file in the folder it guards
LOCK_NAME = ".railsusp.lock"


@contextmanager
def run_lock(out: Path, option: str) -> Iterator[None]:
    """Hold ``out/.railsusp.lock`` while a run works in ``out``: a second ``railsusp run``
    on the same folder is refused in one line at once (two at a time wrote over each
    other's stages, and one failed on a file the other had just replaced). An advisory
    POSIX lock (``flock``), released when the process ends however it ends; the file
    holds the process id for the message. Where ``fcntl`` is missing, no lock."""
    try:
        import fcntl
    except ImportError:  # not POSIX
        yield
        return
    with open(out / LOCK_NAME, "a+", encoding="utf-8") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            holder = fh.read().strip()
            raise RailsuspInputError(
                f"{option} {out}: another railsusp run is working in this folder"
                + (f" (process {holder})" if holder.isdigit() else "")
                + "; wait for it to end, or give another folder"
            ) from None
        fh.seek(0)
        fh.truncate()
        fh.write(str(os.getpid()))
        fh.flush()
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)
