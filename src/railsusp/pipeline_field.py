"""The pipeline's field stage: the recordings the estimation reads, in ``RUN/field``.

Three sources, as ``[field]`` says: a long run cut into sections (``recording``, through
:mod:`railsusp.measured.cut`, the same cut as ``railsusp sections``), a copy of a measured
field folder (``measured``), or synthetic recordings of a hidden truth (``truth``). The
configuration comes in as an argument (a :class:`~railsusp.pipeline_config.PipelineConfig`);
this module imports neither the pipeline nor its configuration, so imports flow one way.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

from railsusp.params import ParameterSet


def run_source(field: Any, wagon: str | None = None) -> Any:
    """The :class:`~railsusp.measured.cut.RunSource` of a ``[field]`` section with a
    ``recording`` (its files, the cut's rules, the rate, the static wheel load of the run's
    ``wagon`` file, None: the packaged C80), or None without one."""
    if field.recording is None:
        return None
    from railsusp.measured.cut import RunSource
    from railsusp.measured.sections import SectionRules
    from railsusp.vehicle.setup import static_wheel_load
    from railsusp.vehicle.wagon import load_wagon

    def path(p: str | None) -> Path | None:
        return Path(p) if p is not None else None

    rules = SectionRules(
        speed_tolerance=field.speed_tolerance,
        min_length_m=field.min_length_m,
        max_duration_s=field.max_duration_s,
    )
    return RunSource(
        Path(field.recording),
        path(field.channel_map),
        path(field.line),
        path(field.sections),
        rules,
        field.rate_hz,
        static_wheel_load(load_wagon(wagon)),
    )


@contextmanager
def measured_held(folder: Path, out: Path) -> Iterator[None]:
    """The ``[field] measured`` folder's shared lock (:func:`railsusp.run_lock.run_lock`)
    while the field stage reads and copies it, and that of a run directory it lies in:
    a ``railsusp synth-field --out F`` (or ``sections --write``, ``align-track --write``,
    ``railsusp run`` on the run whose ``field/`` it is) rewriting it under the copy could
    give recordings of two truths under one ``index.json``, as the standalone readers
    (``estimate``, ``validate``, ``posterior estimate``), which hold it, no longer can
    (the review of stop 66). Refused at once in one line naming the holder; a folder not
    ours to write that holds no lock file is read unlocked (nothing writes there), as they
    read it."""
    from railsusp.run_lock import enclosing_runs, hold_shared

    here = Path(out).resolve()  # this run's own: the pipeline holds it itself
    with ExitStack() as stack:
        for run in enclosing_runs(folder):
            if run.resolve() != here:  # `railsusp run` on it rewrites its field/
                hold_shared(stack, run, "field.measured", named=folder)
        hold_shared(stack, folder, "field.measured")
        yield


def field_stage(config: Any, out: str | Path) -> dict:
    """The field stage alone: the recordings the estimation reads, in ``OUT/field``: a long
    run's kept sections (``[field] recording``), a copy of a measured folder, or synthetic
    recordings of the hidden truth. Returns the stage's record for ``pipeline.json``."""
    from railsusp.measured import read_field, synthesise_field
    from railsusp.vehicle.wagon import load_wagon

    out = Path(out)
    f = config.field
    dest = out / "field"
    _own_folder(dest)
    wagon = load_wagon(config.wagon)  # the run's wagon: its recordings' wheel loads, its model
    source = config.run_source()  # its wheel loads checked against the run's wagon
    if source is not None:
        from railsusp.measured.cut import write_run_field
        from railsusp.store import atomic_folder

        with atomic_folder(dest, keep=False) as tmp:  # the old folder stays until replaced
            write_run_field(source, tmp, dest)
        recs = read_field(dest, wagon=wagon)  # the estimation's inputs, checked
        return {"recordings": len(recs), "synthetic": False, "recording": f.recording}
    if f.measured:
        import shutil

        from railsusp.run_lock import LOCK_NAME
        from railsusp.store import atomic_folder

        with measured_held(Path(f.measured), out):  # the recordings read and copied as one
            recs = read_field(f.measured, wagon=wagon)
            with atomic_folder(dest, keep=False) as tmp:  # the old copy stays until replaced
                shutil.copytree(
                    f.measured, tmp, dirs_exist_ok=True, ignore=shutil.ignore_patterns(LOCK_NAME)
                )
                left_out = _foreign_truth(tmp, f.measured, recs)
        record: dict = {"recordings": len(recs), "synthetic": False}
        if left_out:
            record["truth_left_out"] = left_out
        return record
    truth = ParameterSet(f.truth, units="display")
    synthesise_field(
        truth,
        config.working_conditions(),
        dest,
        seed=f.seed,
        noise=f.noise,
        with_track=f.with_track,
        track_noise_mm=f.track_noise_mm,
        wagon=wagon,  # the run's wagon (was always the packaged C80)
    )
    return {"recordings": len(config.conditions), "synthetic": True}


def _foreign_truth(copy: Path, measured: str, recordings: list) -> str | None:
    """Remove from the field stage's ``copy`` of a measured folder a ``truth.json`` that is
    not the truth of its recordings (:func:`~railsusp.measured.check_truth_of`: a recording
    edited since synth-field wrote it, a truth file put there from another field), and say
    so in a warning; the reason, or None where the truth belongs or there is none. The run
    scores the recovery against ``RUN/field/truth.json`` (the validation, ``open_run``'s
    recovery, the report's hidden-truth column): kept, a foreign truth refused the
    validation stage after the whole estimate."""
    import warnings

    from railsusp.errors import RailsuspInputError
    from railsusp.measured import check_truth_of

    truth = copy / "truth.json"
    if not truth.is_file():
        return None
    try:
        check_truth_of(truth, copy, "truth.json", recordings)
    except RailsuspInputError as exc:
        truth.unlink()
        reason = str(exc).replace(str(copy), str(measured))
        warnings.warn(
            f"field.measured {measured}: its truth.json is left out of the run, the recovery "
            f"not scored: {reason}",
            stacklevel=2,
        )
        return reason
    return None


def _own_folder(dest: Path) -> None:
    """A ``RUN/field`` that is a symbolic link, removed (the folder it names left as it is,
    with a warning): the stage writes its recordings there whole, and through the link it
    replaced the recordings of the folder it named, a user's field folder (the review of
    stop 74)."""
    if not dest.is_symlink():
        return
    import os
    import warnings

    named = os.readlink(dest)
    dest.unlink()
    warnings.warn(
        f"{dest} was a link to {named}: the field stage writes the run's own folder there, "
        "and left the folder the link named as it is",
        stacklevel=3,
    )
