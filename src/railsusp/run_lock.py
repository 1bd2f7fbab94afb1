"""One railsusp process at a time writing in a folder: an advisory lock on
``FOLDER/.railsusp.lock`` (:func:`run_lock`), held by ``railsusp run`` on its run directory,
by a campaign on its folder (standalone or the pipeline's ``campaign/``) and by every
command that writes into a campaign, run, estimate or field folder (exclusive), or reads
what another command writes there (shared: readers run together, never beside a writer).

The lock is ``flock``'s: the kernel lets it go when its process ends, however it ends (a
kill, a crash), so a lock left by a dead process is taken over by the next one without a
word (the file stays; the lock on it does not). Locks of one folder taken twice in one
process conflict as between processes (each :func:`run_lock` opens the file anew), except
where the outer one is *lent* to the code it runs (``lend=True``: a command that holds its
folder and calls library code that locks the same folder itself)."""

from __future__ import annotations

import errno
import os
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from contextvars import ContextVar
from pathlib import Path

from railsusp.errors import RailsuspInputError

#: the lock file in the folder it guards
LOCK_NAME = ".railsusp.lock"

#: a shared lock's holders append their process ids; past this size the list is started
#: anew (it names the holders in a refusal only; the lock itself is the kernel's)
_MAX_HOLDERS_BYTES = 4096

#: folders (resolved) whose lock this context holds and lends to the code it runs
_lent: ContextVar[frozenset[str]] = ContextVar("railsusp_lent_locks", default=frozenset())


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    except OSError:
        return False
    return True


def _listed(text: str) -> list[int]:
    """The live processes the lock file lists (the exclusive holder's id, or those of the
    shared holders since), each once: where the kernel's table cannot be read."""
    seen: list[int] = []
    for word in text.split():
        if word.isdigit() and int(word) not in seen and _alive(int(word)):
            seen.append(int(word))
    return seen


def _holders(fh) -> list[int]:
    """The processes holding a lock of ``fh``'s file, from the kernel's table of locks
    (``/proc/locks``, Linux: the holders now, readers that have ended left out); else those
    the file lists (:func:`_listed`)."""
    try:
        st = os.fstat(fh.fileno())
        with open("/proc/locks", encoding="ascii", errors="replace") as table:
            lines = table.read().splitlines()
    except OSError:
        lines = []
    else:
        where = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    pids: list[int] = []
    for line in lines:  # "1: FLOCK  ADVISORY  WRITE 1234 fe:00:5678 0 EOF"
        parts = line.split()
        if len(parts) > 5 and parts[1] == "FLOCK" and parts[5] == where:
            pid = int(parts[4]) if parts[4].isdigit() else 0
            if pid > 0 and pid not in pids:  # 0: a process of another pid namespace
                pids.append(pid)
    if pids:
        return pids
    fh.seek(0)
    return _listed(fh.read())


def _refusal(out: Path, option: str, named: Path | None, fh) -> RailsuspInputError:
    pids = _holders(fh)
    held = (
        f" (process {pids[0]})"
        if len(pids) == 1
        else f" (processes {', '.join(map(str, pids))})"
        if pids
        else ""
    )
    where = f"{option} {named if named is not None else out}".strip()
    folder = "this folder" if named is None else f"its run directory {out}"
    return RailsuspInputError(
        f"{where}: another railsusp run is working in {folder}{held}; wait for it to end, "
        "or give another folder"
    )


#: what opening the lock file for writing fails with in a folder that cannot be written
_UNWRITABLE = (errno.EACCES, errno.EPERM, errno.EROFS)


def _unwritable(out: Path, option: str, exc: OSError) -> RailsuspInputError:
    """The one-line refusal of a writer's lock in a folder that cannot be written (read-only,
    on a read-only file system, not ours), as an output folder that cannot be written is
    refused (:func:`railsusp.input_checks.check_output_folder`): the folder named, not the
    lock file the system refused ("rot/.railsusp.lock: Read-only file system")."""
    why = exc.strerror or type(exc).__name__
    where = f"{option} {out}: " if option else ""
    return RailsuspInputError(
        f"{where}the folder {out} is not writable ({why}); this command writes its results there"
    )


@contextmanager
def run_lock(
    out: Path,
    option: str,
    *,
    shared: bool = False,
    named: Path | None = None,
    lend: bool = False,
) -> Iterator[None]:
    """Hold ``out/.railsusp.lock`` while a process works in ``out``: a second writer on the
    same folder is refused in one line at once (two at a time wrote over each other's
    stages, and one failed on a file the other had just replaced; an analysis went on from
    a campaign another process was replacing). An advisory POSIX lock (``flock``),
    released when the process ends however it ends; the file holds the process id(s) for
    the message. Where ``fcntl`` is missing, no lock.

    ``shared``: a reader's lock, held by any number of readers at once and refused beside
    a writer (an exclusive lock), as a writer is refused beside readers. ``option`` and
    ``named`` word the refusal: ``option out`` by default; ``option named`` where ``out``
    is the run directory of the folder the user named. ``lend``: while held, a
    :func:`run_lock` of ``out`` in the same context (the code this one runs) passes
    through instead of being refused. ``out`` must exist; a writer's lock in a folder that
    cannot be written is refused in one line (a reader's is an OSError, which
    :func:`hold_shared` takes as a folder to read unlocked)."""
    try:
        import fcntl
    except ImportError:  # not POSIX
        yield
        return
    key = str(Path(out).resolve())
    if key in _lent.get():  # the caller holds it for us
        yield
        return
    path = Path(out) / LOCK_NAME
    fh = None
    for _ in range(20):  # the file replaced under us (a folder made and removed): again
        try:
            fh = open(path, "a+", encoding="utf-8")
        except PermissionError as denied:  # another user's lock file: flock needs no write
            try:  # access; none there and the folder not ours to write: the refusal itself
                fh = open(path, encoding="utf-8")
            except FileNotFoundError:
                raise (denied if shared else _unwritable(Path(out), option, denied)) from None
            if not shared and not os.access(out, os.W_OK | os.X_OK):  # a writer with nowhere
                fh.close()  # to write (the lock file another's, in a folder not ours)
                raise _unwritable(Path(out), option, denied) from None
        except OSError as exc:  # a read-only file system: no lock file can be made or opened
            if shared or exc.errno not in _UNWRITABLE:  # (a reader reads it unlocked)
                raise
            raise _unwritable(Path(out), option, exc) from None
        try:
            fcntl.flock(fh, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except BlockingIOError:
            refusal = _refusal(Path(out), option, named, fh)
            fh.close()
            raise refusal from None
        try:
            same = os.path.samestat(os.fstat(fh.fileno()), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            break
        fh.close()  # unlinked between our open and our lock: a lock no one else sees
        fh = None
    if fh is None:
        raise RailsuspInputError(f"{option} {out}: its lock file {path} keeps being replaced")
    try:
        if fh.writable() and shared:
            fh.seek(0, os.SEEK_END)
            if fh.tell() > _MAX_HOLDERS_BYTES:
                fh.truncate(0)
            fh.write(f"{os.getpid()}\n")  # appended: other readers' ids stay
        elif fh.writable():
            fh.seek(0)
            fh.truncate()
            fh.write(f"{os.getpid()}\n")
        fh.flush()
        token = _lent.set(_lent.get() | {key}) if lend else None
        try:
            yield
        finally:
            if token is not None:
                try:
                    _lent.reset(token)
                except ValueError:  # let go in another context than taken: by name
                    _lent.set(_lent.get() - {key})
    finally:
        fcntl.flock(fh, fcntl.LOCK_UN)
        fh.close()


def enclosing_runs(folder: Path) -> list[Path]:
    """The ``railsusp run`` directories ``folder`` lies in (their ``pipeline.json`` one to
    three levels up: ``RUN/campaign``, ``RUN/estimate/validation``,
    ``RUN/campaign/surrogates/cnn-gru``), above the folder as named and above where it
    resolves to: a symbolic link to ``RUN/campaign`` lies in ``RUN`` too (looked for as named
    only, a command on the link ran beside ``railsusp run``: the Dask and locks audit). The
    command line's readers and writers and the pipeline's field stage take their locks."""
    found: dict[Path, Path] = {}
    for base in (folder.absolute(), folder.resolve()):
        for up in list(base.parents)[:3]:
            if (up / "pipeline.json").is_file():
                found.setdefault(up.resolve(), up)
                break
    return list(found.values())


def hold_shared(stack: ExitStack, folder: Path, option: str, named: Path | None = None) -> None:
    """``folder``'s shared lock (:func:`run_lock`, ``option`` and ``named`` for the
    refusal) entered on ``stack``; a folder where no lock file can be made (read-only, not
    ours to write) is read without it: nothing writes there either."""
    try:
        stack.enter_context(run_lock(folder, option, shared=True, named=named))
    except OSError as exc:
        if exc.errno not in _UNWRITABLE:
            raise
