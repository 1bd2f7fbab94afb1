"""Running a campaign's batches on a Dask cluster: the scheduler's address checked before
any connection, the connection bounded in time, the batches submitted and stored as they
complete (:func:`run_on_dask`; :func:`railsusp.campaign.run.run_campaign` chooses it with
``--scheduler`` or ``--workers``), the cluster's own failures one line
(:class:`ClusterError`), and how a campaign ran recorded (:func:`executor_record`). Dask is
imported only here, and only when used."""

from __future__ import annotations

import errno
import logging
import re
import signal
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from railsusp.campaign.design import CampaignError

#: how a failed cluster's error ends: what is kept and what to do
RESUME_HINT = "the batches stored are kept; run the same command again"


class ClusterError(OSError):
    """The Dask cluster failed while a campaign ran on it: its scheduler lost, the workers
    of a batch killed, a batch cancelled. Not bad input but the machines' failure, as a full
    disk is: an OSError of ``errno.EIO``, which the command line reports in one line with
    exit status 1 (:func:`railsusp.cli.main`, and ``railsusp run`` through
    :func:`railsusp.cli.common.exit_code`); distributed's own errors were a traceback."""

    def __init__(self, message: str) -> None:
        super().__init__(errno.EIO, message)

    def __str__(self) -> str:  # the message alone, not "[Errno 5] ..."
        return str(self.strerror)


def _cluster_failures() -> tuple[type[BaseException], ...]:
    """The errors by which distributed reports its cluster failing (not a task's own):
    a cancelled future (``FutureCancelledError``, e.g. the scheduler's connection lost),
    a batch whose workers all died (``KilledWorker``), a connection closed. (Not the
    built-in TimeoutError, which a task may raise itself: its own error, not the
    cluster's.)"""
    import asyncio
    import concurrent.futures

    from distributed.comm.core import CommClosedError
    from distributed.scheduler import KilledWorker

    return (
        concurrent.futures.CancelledError,
        asyncio.CancelledError,
        KilledWorker,
        CommClosedError,
    )


def cluster_error(exc: BaseException) -> ClusterError:
    """``exc``, one of :func:`_cluster_failures`, as a one-line :class:`ClusterError` naming
    it and ending with :data:`RESUME_HINT`."""
    try:
        text = " ".join(str(exc).split())  # KilledWorker's message runs over several lines
    except Exception:  # a message that cannot be made: the type says enough
        text = ""
    if len(text) > 300:
        text = text[:297] + "..."
    cause = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return ClusterError(f"the Dask cluster failed during the campaign ({cause}); {RESUME_HINT}")


def executor_record(scheduler: str | None, workers: int | None) -> dict[str, Any]:
    """How a campaign's batches run, for ``campaign.json``: ``serial`` (here, one batch
    after another), ``local processes`` (a LocalCluster of ``workers``) or ``scheduler`` (its
    address), with the dask and distributed versions where Dask runs them."""
    if scheduler is None and workers is None:
        return {"executor": "serial"}
    from importlib import metadata

    where = (
        {"executor": "local processes", "workers": workers or 1}
        if scheduler is None
        else {"executor": "scheduler", "scheduler": scheduler}
    )
    return {
        **where,
        **{name: metadata.version(name) for name in ("dask", "distributed")},
    }


def check_scheduler_address(address: str, setting: str) -> None:
    """Refuse (one line naming ``setting``) a Dask scheduler address other than
    ``tcp://host:port``: host a name, an IPv4 address or ``[IPv6]``, port 1-65535. A
    trailing slash, a port out of range or ``tls://`` (which needs security settings that
    railsusp does not take) failed inside distributed with a traceback, or waited for a
    scheduler that could not answer."""
    m = re.fullmatch(r"tcp://(\[[0-9A-Fa-f:.]+\]|[^\s:/\[\]]+):(\d{1,5})", address)
    if m is None or not 1 <= int(m.group(2)) <= 65535:
        raise CampaignError(
            f"{setting} {address!r}: accepted tcp://host:port (host a name, an IPv4 address "
            "or [IPv6], port 1-65535; tls:// is not taken: it needs security settings)"
        )


#: the longest wait for a Dask scheduler to answer, s: distributed's own timeout does not
#: bound its handshake (a port held by a server that never speaks Dask hung for good)
CONNECT_TIMEOUT_S = 20.0


def connect_scheduler(scheduler: str, setting: str = "--scheduler"):
    """A Dask client of ``scheduler``, or a one-line :class:`CampaignError` naming the
    ``setting`` the user gave it in (``--scheduler``, or a configuration's ``scheduler =``)
    within :data:`CONNECT_TIMEOUT_S`: no answer, a refused port, or a peer that is no Dask
    scheduler (an SSH banner read as a message gave an allocation error of 2.8 EiB)."""
    import threading

    from dask.distributed import Client

    made: dict[str, Any] = {}

    def connect() -> None:
        try:
            made["client"] = Client(scheduler, timeout="10s")
        except BaseException as exc:  # whatever distributed raises on a wrong peer
            made["error"] = exc

    thread = threading.Thread(target=connect, daemon=True)  # a hung one does not block exit
    thread.start()
    thread.join(CONNECT_TIMEOUT_S)
    why = (
        f"no answer within {CONNECT_TIMEOUT_S:g} s"
        if thread.is_alive()
        else f"{type(made['error']).__name__}: {made['error']}"
        if "error" in made
        else ""
    )
    if why:
        raise CampaignError(
            f"{setting} {scheduler}: no Dask scheduler answered ({why}); accepted the "
            "address of a running one (the campaign resumes from what is stored)"
        )
    return made["client"]


def run_on_dask(
    task: Callable[..., Any],
    todo: Iterable[tuple[int, int]],
    args: Callable[[int, int], tuple],
    finish: Callable[[int, Any], None],
    scheduler: str | None,
    workers: int | None,
    setting: str = "--scheduler",
) -> None:
    """Submit ``task(*args(ci, b))`` for each batch ``(ci, b)`` of ``todo`` to a Dask
    cluster (``scheduler``'s, or a local one of ``workers`` single-threaded processes) and
    hand each result to ``finish(b, result)`` as it completes, so that a batch is stored the
    moment it is done and an interrupted campaign resumes from them. ``setting``: where the
    user gave the scheduler (named when none answers). The cluster failing on the way is a
    :class:`ClusterError` (the batches finished so far are stored); a task's own error and
    one of ``finish`` come through as they are."""
    from dask.distributed import Client, LocalCluster, as_completed

    failures = _cluster_failures()

    cluster = client = None
    try:  # the cluster closed whatever stops it, a Ctrl-C while it starts too
        if scheduler is None:
            with _sigint_blocked():  # a Ctrl-C meanwhile: raised once it has started
                cluster = LocalCluster(
                    n_workers=workers or 1,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                )
            client = Client(cluster)
            from railsusp.campaign.dask_quiet import QuietWorkers

            # our own workers, a restarted one too: no Ctrl-C, no shutdown log
            client.register_plugin(QuietWorkers())
        else:  # the run directory is written and resumes once a scheduler answers
            client = connect_scheduler(scheduler, setting)
        try:
            futures = {}
            for ci, b in todo:
                fut = client.submit(task, *args(ci, b), pure=False)
                futures[fut] = b
            done = as_completed(futures)
        except failures as exc:
            raise cluster_error(exc) from exc
        while True:
            try:
                fut = next(done, None)
                if fut is None:
                    break
                result = fut.result()
            except failures as exc:
                raise cluster_error(exc) from exc
            except (TypeError, ImportError) as exc:
                # a worker of a railsusp whose task takes other arguments, or that has no
                # module of that name (the task moved to campaign.batch_simulation in stop 67)
                other = (
                    "positional argument" in str(exc)
                    if isinstance(exc, TypeError)
                    else (exc.name or "").startswith("railsusp")
                )
                if not other:
                    raise
                raise CampaignError(
                    f"a worker of the Dask cluster runs another railsusp ({exc}): install the "
                    "same railsusp on every worker of the cluster (the batches stored so far "
                    "are kept)"
                ) from exc
            finish(futures[fut], result)  # (its own errors as they are: not the cluster's)
    finally:
        # after a Ctrl-C the local cluster's shutdown (tasks cancelled, workers busy in a
        # simulation killed) logged some 60 warning lines before the one "interrupted" line
        # (the QA of stop 74): not said; a cluster's failure is raised above as it was
        with _quiet_shutdown(sys.exc_info()[0] is KeyboardInterrupt):
            try:
                if client is not None:
                    client.close()
            except failures:  # a lost scheduler: nothing left to close, the error is above
                pass
            if cluster is not None:
                cluster.close()


@contextmanager
def _sigint_blocked() -> Iterator[None]:
    """SIGINT blocked in this thread while the local cluster starts: a Ctrl-C pressed then
    waits, pending, and is raised here once the cluster has started, so that the command
    closes a whole cluster, not one half made. Ignored instead (SIG_IGN, which the worker
    processes would inherit) it was lost and the campaign went on (the review of stop 74);
    the worker processes do not inherit the mask (they start from a clean one)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


@contextmanager
def _quiet_shutdown(quiet: bool) -> Iterator[None]:
    """Dask's loggers held to errors above CRITICAL while ``quiet`` (an interrupted run's
    cluster closing)."""
    if not quiet:
        yield
        return
    logger = logging.getLogger("distributed")
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        logger.setLevel(level)
