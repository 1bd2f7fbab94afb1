"""Atomic files: how railsusp replaces a file or a folder so that an interrupted write leaves
the old one or the new one, never half of one.

A file is written to a temporary file in the same folder (:func:`replacing_file`), flushed
to disk (fsync), given the mode a plainly written file gets and renamed over its target, and
the folder is fsynced after the rename. Artefacts made of several files are written into a
temporary folder and renamed as one (:func:`atomic_folder`). An OSError is shown naming the
file the user asked for, not a hidden temporary (the disk audit); temporaries a killed
process left are removed by :func:`remove_stale_temporaries`.

It is apart from :mod:`railsusp.store`, which reads and writes the run directory's formats
(JSON, Parquet, CSV, TOML) and hashes them through these writes: this module knows bytes,
files, folders and the disk, and no format. It imports nothing of railsusp but
:mod:`railsusp.interrupts` (the standard library's only): a Ctrl-C recorded while a folder
was written stops the command before the folder is swapped in.
"""

from __future__ import annotations

import errno
import fnmatch
import glob
import os
import re
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from railsusp.interrupts import stop_if_interrupted

#: what ``os.fsync`` of a folder (or ``os.open`` of one) raises where the file system or the
#: platform does not support it: ignored; anything else (EIO: the rename may not be on disk)
#: is an error, not a success reported (the disk audit)
_FSYNC_DIR_UNSUPPORTED = frozenset(
    {errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EBADF, errno.EISDIR}
)


def fsync_dir(path: str | Path) -> None:
    """Flush a folder's entries (a rename into it) to disk; a no-op where unsupported (a
    folder that cannot be opened for it, a file system whose folders take no fsync). Any
    other error (EIO, ENOSPC) is raised: it was swallowed, and a rename perhaps never on
    disk was reported as written (the disk audit)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError as exc:
        if exc.errno in _FSYNC_DIR_UNSUPPORTED | {errno.EACCES, errno.EPERM}:
            return
        raise
    try:
        os.fsync(fd)
    except OSError as exc:
        if exc.errno not in _FSYNC_DIR_UNSUPPORTED:
            raise
    finally:
        os.close(fd)


def fsync_file(path: str | Path) -> None:
    """Flush a written file's content to disk (before a rename makes it the file)."""
    with open(path, "rb+") as fh:
        os.fsync(fh.fileno())


def _process_umask() -> int:
    """The process's umask (read by setting it and back; done once, at import)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: the umask the outputs' modes follow: a temporary file is created 0600 (a folder 0700),
#: and renamed into place it would stay so; a file written in place would be 0666 & ~umask
_UMASK = _process_umask()


def plain_mode(path: str | Path) -> None:
    """Give a temporary file (created 0600) the mode a plainly written one gets, before it
    is renamed into place."""
    os.chmod(path, 0o666 & ~_UMASK)


def _naming(exc: OSError, target: Path, folder: Path | None = None) -> OSError:
    """``exc`` as it is to be shown, its errno kept (the exit status depends on it): the user
    was told "No space left on device" and not where, or was shown a hidden temporary (the
    disk audit). For a file ``target`` (``folder`` None): an error naming no file
    (pyarrow's "[errno 28] No space left on device", a bare write error) or naming one of
    its temporaries (``.NAME.XXXXXXXX.tmp``) names ``target``. For a folder ``target``
    written in the temporary ``folder`` (:func:`atomic_folder`): an error naming a file
    inside ``folder``, or ``folder``, names the same file inside ``target``. Any other error
    is returned as it is."""
    named = exc.filename
    if isinstance(named, (str, bytes, os.PathLike)):
        named = os.path.abspath(os.fsdecode(named))
    else:  # none, or a file descriptor
        named = None
    where: Path | None = None
    if folder is None:
        found = None if named is None else _TEMPORARY.match(os.path.basename(named))
        if named is None or (
            found is not None
            and found["target"] == target.name
            and os.path.dirname(named) == os.path.abspath(target.parent)
        ):
            where = target
    elif named is not None:
        hidden = os.path.abspath(folder)
        if named == hidden:
            where = target
        elif named.startswith(hidden + os.sep):
            where = target / os.path.relpath(named, hidden)
    if where is None:
        return exc
    reason = exc.strerror or (os.strerror(exc.errno) if exc.errno else str(exc))
    return OSError(exc.errno, reason, str(where))


@contextmanager
def replacing_file(path: Path) -> Iterator[str]:
    """The one way a file is written: yields a temporary file beside ``path`` (``.NAME.*.tmp``)
    to write and close; then its content is flushed to disk, it gets the mode a plainly
    written file gets (0666 less the umask, not the temporary file's 0600), is renamed over
    ``path`` and the rename is flushed too. On an error the temporary file is removed and
    ``path`` is untouched; an OSError naming no file or the temporary names ``path``
    (:func:`_naming`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        os.close(fd)
        try:
            yield tmp
            fsync_file(tmp)
            plain_mode(tmp)
            os.replace(tmp, path)
            fsync_dir(path.parent)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except OSError as exc:
        shown = _naming(exc, path)
        if shown is exc:
            raise
        raise shown from exc


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + rename), with the mode a
    plainly written file gets (0666 less the umask), not the temporary file's 0600."""
    path = Path(path)
    with replacing_file(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
    return path


#: the name of a temporary file :func:`replacing_file` makes: ``.NAME.`` + mkstemp's eight
#: random characters + ``.tmp`` (a user's ``.notes.tmp`` is no railsusp temporary)
_TEMPORARY = re.compile(r"^\.(?P<target>.+)\.[a-z0-9_]{8}\.tmp$")

#: the folders a swap of :func:`atomic_folder` leaves where it is killed (``.NAME.new-*``,
#: ``.NAME.old-*``, mkdtemp's eight characters): never carried into a new version of the
#: folder holding them (a nested folder's old version came back: the review of stop 74)
_SWAP_LEFTOVER = re.compile(r"^\..+\.(old|new)-[a-z0-9_]{8}$")


def remove_stale_temporaries(folder: str | Path, targets: Sequence[str] | None = None) -> int:
    """Remove the temporaries of :func:`replacing_file` (``.NAME.XXXXXXXX.tmp``) that a process
    killed while writing left directly in ``folder``; the number removed. ``targets``: only
    those of files of these names (default: of any name). Subfolders are not entered, and
    other hidden files are left alone: only for a folder whose lock the caller holds
    (:func:`railsusp.run_lock.run_lock`) and whose files no other process writes, since
    another writer's temporary would be live (a training checkpoint being saved under a
    campaign's ``surrogates/``, which the campaign's whole-tree sweep deleted: the
    run-directory store audit). A kill during a write left them for good (the
    interrupt/resume audit of stop 60)."""
    removed = 0
    folder = Path(folder)
    if not folder.is_dir():
        return 0
    for tmp in folder.iterdir():
        found = _TEMPORARY.match(tmp.name)
        if found is None or (targets is not None and found["target"] not in targets):
            continue
        if tmp.is_file() and not tmp.is_symlink():
            tmp.unlink(missing_ok=True)
            removed += 1
    return removed


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


@contextmanager
def atomic_folder(path: str | Path, keep: bool = True, drop: Sequence[str] = ()) -> Iterator[Path]:
    """Write a multi-file artefact as one: yields a temporary sibling folder to write into;
    on success it replaces ``path``, on an error it is removed and ``path`` is untouched.

    ``keep``: other entries of an existing ``path`` (a training checkpoint, figures) are
    carried into the new folder (hard links where possible), except those whose names match
    a glob pattern of ``drop`` (what the old artefact wrote and this one replaces or no
    longer has: an old estimate's validation, a removed condition's recording). The swap is
    two renames (the old folder aside, the new one in); a crash between them leaves the old
    folder beside ``path`` as ``.NAME.old-*`` and no ``path``: the next save puts it back
    first (it held finished work: a trained network and its checkpoint), then carries on. A
    process killed while writing leaves ``.NAME.new-*``: the next save removes it. The
    folder gets the mode a plainly made one gets (0777 less the umask), not the temporary
    folder's 0700. A ``path`` that is a symbolic link (it was renamed aside and left as
    ``.NAME.old-*`` for good: rmtree refuses a link, the QA of stop 73): with ``keep`` the
    folder it names is written, where it points, the link kept (its other files are carried,
    so nothing is lost: a training's checkpoint there stays with its network); without
    ``keep``, which would drop every other file, the link is replaced as an entry, a real
    folder put in its place and the folder it names never touched (a copy of shipped
    networks into a folder linked to the user's: the review of stop 74).
    """
    path = Path(path)
    if keep and path.is_symlink():
        path = followed(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    name = glob.escape(path.name)  # ``est[1]``, ``run*``: a pattern only of this name's
    put_back_aside(path)
    for pattern in (f".{name}.old-*", f".{name}.new-*"):
        for stale in path.parent.glob(pattern):
            if stale.is_symlink():  # a link an older railsusp renamed aside
                stale.unlink(missing_ok=True)
            else:
                shutil.rmtree(stale, ignore_errors=True)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.new-"))
    try:
        yield tmp
        # a Ctrl-C Python swallowed while the folder was written (inside an import of
        # asammdf: sections --write replaced the folder and exited 0, the QA of stop 74)
        stop_if_interrupted()
        os.chmod(tmp, 0o777 & ~_UMASK)
        for f in tmp.rglob("*"):
            if f.is_file():
                fsync_file(f)
        if keep and path.is_dir():  # (a link was followed above)
            for entry in path.iterdir():
                target = tmp / entry.name
                if target.exists() or any(fnmatch.fnmatchcase(entry.name, d) for d in drop):
                    continue
                if _TEMPORARY.match(entry.name) or _SWAP_LEFTOVER.match(entry.name):
                    continue  # a killed write's leftover: not carried into every later save
                if entry.is_dir():  # nor in its subfolders
                    shutil.copytree(entry, target, copy_function=_link_or_copy, ignore=_temporaries)
                else:
                    _link_or_copy(entry, target)
        fsync_dir(tmp)
        if path.exists() or path.is_symlink():
            old = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.old-"))
            os.rmdir(old)
            os.rename(path, old)
            os.rename(tmp, path)
            if old.is_symlink():  # the link alone, never the folder it names
                old.unlink()
            else:
                shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(tmp, path)
        fsync_dir(path.parent)
    except OSError as exc:  # a file of the hidden folder named as the one it was to become
        shown = _naming(exc, path, folder=tmp)
        if shown is exc:
            raise
        raise shown from exc
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def put_back_aside(path: str | Path) -> bool:
    """Put back the folder an :func:`atomic_folder` swap set aside (``.NAME.old-*``, the
    newest) where a crash between its two renames left no ``path``; whether it did. Called
    by every swap before it writes, and by a reader holding the folder's lock before it
    reads what the folder holds (a training's checkpoint: ``train`` started again from epoch
    1 and then deleted the trained network set aside, the QA of stop 74). A link set aside
    (by a railsusp before stop 74) is never put back: it names a folder the swap did not
    write (a dangling one stopped every save, its time unreadable: the review of stop 74)."""
    path = Path(path)
    name = glob.escape(path.name)
    aside = [p for p in path.parent.glob(f".{name}.old-*") if not p.is_symlink()]
    aside.sort(key=lambda p: p.lstat().st_mtime)
    if aside and not path.exists() and not path.is_symlink():
        os.rename(aside.pop(), path)
        return True
    return False


def followed(path: str | Path) -> Path:
    """``path``, or the folder it names where it is a symbolic link: where
    :func:`atomic_folder` with ``keep`` writes, so that the link is kept and the folder it
    names is the output (the QA of stop 73), as a command's checks of its ``--out`` read
    it (:func:`railsusp.input_checks.check_replaced_folder`)."""
    path = Path(path)
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def _temporaries(folder: str, names: list[str]) -> list[str]:
    """Of ``names`` in ``folder``, those of killed writes' temporaries (copytree's ignore)."""
    return [n for n in names if _TEMPORARY.match(n) or _SWAP_LEFTOVER.match(n)]


def _link_or_copy(src: str | Path, dst: str | Path) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)
