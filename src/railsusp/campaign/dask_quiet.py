"""The local Dask cluster's workers kept quiet: SIGINT ignored and their Dask log held to
nothing, in every worker process the cluster runs, one that a nanny restarts too.

A Ctrl-C at the terminal reaches the whole process group; the command's process alone
stops on it and closes the cluster, and each worker's shutdown (its tasks cancelled, its
scheduler gone) logged warnings and errors with tracebacks, some 60 lines before the one
"interrupted" line (the QA and CI of stop 74). A task's own error still reaches the command
through its result, and the nannies (in the command's process) still log a worker lost.
Imported only where a local cluster is started (it imports ``distributed``).
"""

from __future__ import annotations

import logging
import signal
import threading

from distributed.diagnostics.plugin import WorkerPlugin


def quiet_worker() -> None:
    """In a worker process: SIGINT ignored (where called in the process's main thread,
    the only one that may set a handler) and the ``distributed`` log held to nothing."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)


class QuietWorkers(WorkerPlugin):
    """:func:`quiet_worker` in each worker as it starts: registered with the client, the
    plugin is set up in the workers running and in every one that joins later (a worker
    the nanny restarted after a crash was left loud by ``client.run``, which reaches the
    workers of the moment only). Its setup runs in the worker's event loop, which is the
    worker process's main thread."""

    idempotent = True
    name = "railsusp-quiet-workers"

    def setup(self, worker) -> None:
        quiet_worker()
