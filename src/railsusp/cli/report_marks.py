"""The stale banner a standalone command puts on the report of a ``railsusp run``
directory whose stages' recorded outputs it is about to write (``railsusp estimate --out
RUN/estimate``), and takes off again where it ends having changed none of them (the
concurrency audit and the review of stop 66). :func:`railsusp.cli.common.hold_folders`
calls it once the command's locks are held; this module knows the commands' outputs and the
run directory's records, not the command line.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

#: the pipeline stage whose outputs each standalone command makes, where it names a
#: folder above them (``validate RUN/estimate`` writes ``RUN/estimate/validation``,
#: ``sensitivity RUN/campaign`` ``RUN/campaign/sensitivity``): the stage its stale banner
#: names (:func:`mark_run_reports`)
_COMMAND_STAGES = {
    "campaign": "campaign",
    "sensitivity": "sensitivity",
    "train": "surrogate",
    "compare": "surrogate",
    "synth-field": "field",
    "sections": "field",
    "align-track": "field",
    "estimate": "estimate",
    "validate": "validate",
}


#: what a standalone command writes in an existing folder it names, where not all of it:
#: ``train RUN/campaign`` writes ``campaign/surrogates`` and ``campaign/splits`` and none of
#: the campaign's own files, ``validate RUN/estimate`` ``estimate/validation``. The stale
#: banner goes by these (:func:`mark_run_reports`): with the default ``[surrogate]
#: samples`` the pipeline's surrogates are ``RUN/surrogate-campaign``'s, and ``train
#: RUN/campaign`` marked the report as if it rewrote the campaign (the review of stop 66). A
#: folder a command makes or names with ``--out`` (``estimate --out``, ``synth-field``,
#: ``campaign``, ``sections --write``) and one it rewrites in place (``align-track
#: --write``: the recordings' sidecars) it writes whole.
_COMMAND_WRITES: dict[str, tuple[str, ...]] = {
    "sensitivity": ("sensitivity",),
    "train": ("surrogates", "splits"),
    "compare": ("surrogates", "splits"),
    "validate": ("validation",),
}


def _relative(folder: Path, run: Path) -> Path | None:
    """``folder`` as a path in the run directory ``run``, as named or where both resolve to
    (a link to ``RUN/campaign``); None where it lies outside."""
    for inner, outer in ((folder.absolute(), run.absolute()), (folder.resolve(), run.resolve())):
        try:
            return Path(os.path.normpath(inner)).relative_to(os.path.normpath(outer))
        except ValueError:
            continue
    return None


def _written_stages(run: Path, folders: Sequence[Path]) -> dict[str, list[str]]:
    """The stages of the run directory ``run`` with files recorded in its ``pipeline.json``
    (what the stage wrote when it finished) at or under one of ``folders``, in the
    pipeline's order, each with those files (paths in ``run``): the stages a command
    writing ``folders`` may change. Empty where the folders hold none of them
    (``RUN/posterior``, a new ``RUN/field/extra``: the report reads nothing there) or
    ``pipeline.json`` does not read (:func:`railsusp.open_run` refuses the run directory
    then)."""
    from railsusp.errors import RailsuspInputError
    from railsusp.pipeline_state import STAGES
    from railsusp.store import read_json

    rels = [r for r in (_relative(f, run) for f in folders) if r is not None]
    if not rels:
        return {}
    try:
        stages = read_json(run / "pipeline.json").get("stages")
    except (RailsuspInputError, AttributeError):
        return {}
    if not isinstance(stages, dict):
        return {}
    order = [s for s in STAGES if s in stages] + [s for s in stages if s not in STAGES]
    found: dict[str, list[str]] = {}
    for stage in order:
        entry = stages[stage]
        files = entry.get("files") if isinstance(entry, dict) else None
        if not isinstance(files, dict):
            continue
        under = [f for f in files if any(Path(f).is_relative_to(rel) for rel in rels)]
        if under:
            found[stage] = under
    return found


#: the files of a run directory that its stale banner is put on
_REPORT_FILES = ("report.html", "report.md")


def _stats(paths: Sequence[Path]) -> list[tuple[int, int, int] | None]:
    """Each file's inode, size and modification time (None: gone): a file replaced (an
    atomic write makes a new one), edited or removed differs."""
    seen: list[tuple[int, int, int] | None] = []
    for path in paths:
        try:
            st = path.stat()
        except OSError:
            seen.append(None)
            continue
        seen.append((st.st_ino, st.st_size, st.st_mtime_ns))
    return seen


def _report_bytes(run: Path) -> dict[str, bytes | None]:
    """The report files of ``run`` as they are (None: not there, or not read)."""
    found: dict[str, bytes | None] = {}
    for name in _REPORT_FILES:
        try:
            found[name] = (run / name).read_bytes()
        except OSError:
            found[name] = None
    return found


@dataclass(frozen=True)
class _Marked:
    """A run directory's report that a command marked stale, with what it takes to put it
    back (:func:`unmark_unwritten`): the report files before and after the banner, and the
    stages' recorded files the command may write with their stat (:func:`_stats`) then."""

    run: Path
    before: dict[str, bytes | None]
    after: dict[str, bytes | None]
    watched: list[Path]
    stats: list[tuple[int, int, int] | None]


def mark_run_reports(
    folders: Sequence[tuple[Path, bool]], command: str, runs_of: Callable[[Path], list[Path]]
) -> list[_Marked]:
    """A stale banner on the report of each ``railsusp run`` directory (``runs_of`` a
    folder: those it lies in) that ``folders``, which ``command`` (as typed) is about to
    write, lie in, where what it writes there holds a stage's
    recorded outputs (:func:`railsusp.report_stale.mark_report_stale`): ``railsusp estimate
    --out RUN/estimate`` left ``RUN/report.html`` presenting the estimate it replaced as
    the answer (the concurrency audit). Each folder comes with whether the command writes
    it whole (one it makes); else it writes the subfolders :data:`_COMMAND_WRITES` names
    for it, or the whole folder where it names none. Marked before the command writes, so
    that one killed halfway leaves the banner (as does one that fails after changing any
    of those files); ``railsusp run`` remakes the report. The stage named: the command's
    own (:data:`_COMMAND_STAGES`) where it records files there, else the first of those
    that do. Returns the reports marked, for :func:`unmark_unwritten`."""
    from railsusp.report_stale import mark_report_stale

    name = command.removeprefix("railsusp ")
    own, within = _COMMAND_STAGES.get(name), _COMMAND_WRITES.get(name)
    runs: dict[Path, tuple[Path, list[Path]]] = {}
    for folder, whole in folders:
        targets = [folder / sub for sub in within] if within and not whole else [folder]
        for run in runs_of(folder):
            runs.setdefault(run.resolve(), (run, []))[1].extend(targets)
    marked = []
    for run, targets in runs.values():
        stages = _written_stages(run, targets)
        if not stages:
            continue
        watched = [run / f for files in stages.values() for f in files]
        before, stats = _report_bytes(run), _stats(watched)
        mark_report_stale(run, own if own in stages else next(iter(stages)), by=command)
        marked.append(_Marked(run, before, _report_bytes(run), watched, stats))
    return marked


def unmark_unwritten(marked: Sequence[_Marked]) -> None:
    """The report of each run directory :func:`mark_run_reports` marked put back as it
    was, where the command ends (its click context closes, the locks still held) without
    having replaced, edited or removed any of the stages' recorded files it watched: a
    command refused by its own checks after the locks (``train RUN/campaign`` on a
    campaign with no ``campaign.json``) left the banner, and ``open_run(RUN).report_path``
    refused a report whose run directory it had not changed (the review of stop 66). A
    report changed since (another command's banner put over this one) is left as it is."""
    from railsusp.store import atomic_write_bytes

    for mark in marked:
        if _stats(mark.watched) != mark.stats:
            continue  # a stage's outputs changed: the banner stands until `railsusp run`
        run = mark.run
        now = _report_bytes(run)
        for name in _REPORT_FILES:
            old, ours = mark.before[name], mark.after[name]
            if old is None or ours is None or ours == old or now[name] != ours:
                continue
            try:
                atomic_write_bytes(run / name, old)
            except OSError:  # the banner stays: a report marked stale needlessly, no harm
                continue
