"""Running a campaign's batches on a Dask cluster: the scheduler's address checked before
any connection, the connection bounded in time, the batches submitted and stored as they
complete (:func:`run_on_dask`; :func:`railsusp.campaign.run.run_campaign` chooses it with
``--scheduler`` or ``--workers``). Dask is imported only here, and only when used."""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from typing import Any

from railsusp.campaign.design import CampaignError


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


def _connect(scheduler: str):
    """A Dask client of ``scheduler``, or a one-line :class:`CampaignError` within
    :data:`CONNECT_TIMEOUT_S`: no answer, a refused port, or a peer that is no Dask
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
            f"--scheduler {scheduler}: no Dask scheduler answered ({why}); accepted the "
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
) -> None:
    """Submit ``task(*args(ci, b))`` for each batch ``(ci, b)`` of ``todo`` to a Dask
    cluster (``scheduler``'s, or a local one of ``workers`` single-threaded processes) and
    hand each result to ``finish(b, result)`` as it completes, so that a batch is stored the
    moment it is done and an interrupted campaign resumes from them."""
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers or 1, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    else:  # the run directory is written and resumes once a scheduler answers
        client = _connect(scheduler)
    try:
        futures = {}
        for ci, b in todo:
            fut = client.submit(task, *args(ci, b), pure=False)
            futures[fut] = b
        for fut in as_completed(futures):
            finish(futures[fut], fut.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
