"""Commands for measured recordings: check a recording or a long run, cut a long run into
sections of one working condition, copy the shipped example run."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer
from rich.table import Table

from railsusp.cli.common import (
    WagonOption,
    app,
    console,
    exit_code,
    fail,
    frame_table,
    hold_folders,
)
from railsusp.conditions import RECORDING_MIN_RATE_HZ
from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_figure_file

if TYPE_CHECKING:
    from railsusp.measured.run import MeasuredRun
    from railsusp.vehicle.wagon import WagonData


def wagon_option(wagon: str | Path | None) -> WagonData:
    """The wagon ``--wagon`` names (a packaged name or a file); its one-line error names
    the option ("wagon file nosuch does not exist" did not), in every command taking it."""
    from railsusp.vehicle.wagon import load_wagon

    try:
        return load_wagon(wagon)
    except RailsuspInputError as exc:
        raise RailsuspInputError(f"--wagon: {exc}") from None


def print_problems(exc) -> None:
    """Every problem of a refused recording, one line each, then the one-line error."""
    for p in exc.problems:
        console.print(f"  - {exc.path}: {p}", highlight=False, soft_wrap=True, markup=False)
    fail(f"{exc.path}: {len(exc.problems)} problem(s), listed above")


@app.command("check-recording")
def check_recording(
    path: Annotated[
        Path,
        typer.Argument(
            help="recording: a field-format table (.csv/.parquet) or stem, or a "
            "long run (.mf4, or a table with --map)"
        ),
    ],
    min_rate: Annotated[float, typer.Option(help="lowest usable sampling rate, Hz")] = 50.0,
    channel_map: Annotated[
        Path | None,
        typer.Option("--map", help="channel map TOML: read PATH as a long run through it"),
    ] = None,
    wagon: WagonOption = None,
) -> None:
    """Validate a recording and summarise it (every problem is listed at once, one line
    each naming file, channel and rows; exit status 2)."""
    from railsusp.measured import RecordingError, read_recording
    from railsusp.measured.raw import MDF_SUFFIXES
    from railsusp.measured.recording_reader import MIN_RATE_RANGE_HZ
    from railsusp.vehicle.setup import static_wheel_load

    lo, hi = MIN_RATE_RANGE_HZ
    if not lo <= min_rate <= hi:  # NaN fails too (checked here too: a run file is not read)
        fail(f"--min-rate {min_rate:g} Hz: accepted {lo:g} to {hi:g} Hz")
    try:  # the recordings are read as its: its static wheel load, its axles
        wagon_data = wagon_option(wagon)
    except RailsuspInputError as exc:
        fail(str(exc))
    if channel_map is not None or path.suffix.lower() in MDF_SUFFIXES:
        _check_run(path, channel_map, min_rate, static_wheel_load(wagon_data))
        return
    try:
        rec = read_recording(path, min_rate_hz=min_rate, wagon=wagon_data)
    except RecordingError as exc:
        print_problems(exc)
    except RailsuspInputError as exc:
        fail(str(exc))
    table = force_table(
        f"{path}: {rec.condition.name}, {rec.sampling_rate:.1f} Hz, "
        f"{rec.time[-1] - rec.time[0]:.1f} s",
        [(w, rec.Y[w], rec.Q[w]) for w in rec.wheels],
    )
    console.print(table)
    if rec.condition.track_geometry is not None:
        from railsusp.vehicle.track_geometry import read_track_geometry

        geo = read_track_geometry(rec.condition.track_geometry)
        console.print(
            f"measured track geometry: {rec.condition.track_geometry} "
            f"(distance {geo.s[0]:g} to {geo.s[-1]:g} m, {geo.s.size} points)",
            highlight=False,
        )


def _check_run(path: Path, channel_map: Path | None, min_rate: float, load: float) -> None:
    """check-recording of a long run read through a channel map: its channels as used, the
    forces at ``min_rate`` Hz or more, the wheel loads against ``load`` (N)."""
    from railsusp.measured import RecordingError
    from railsusp.measured.channels import read_channel_map
    from railsusp.measured.run import read_run

    try:
        run = read_run(
            path,
            read_channel_map(channel_map) if channel_map else None,
            min_rate_hz=min_rate,
            wheel_load_N=load,
        )
    except RecordingError as exc:
        print_problems(exc)
    except RailsuspInputError as exc:
        fail(str(exc))
    for note in run.notes:
        console.print(f"note: {note}", highlight=False, markup=False)
    forces, left_out = [], []
    for w in run.wheels:
        kept = {}
        for f, x in (("Y", run.Y[w]), ("Q", run.Q[w])):
            gap = run.interpolated_at(w, f)
            kept[f] = x[~gap] / 1e3
            if gap.any():
                left_out.append(f"{int(gap.sum())} of {f} {w}")
        forces.append((w, kept["Y"], kept["Q"]))
    table = force_table(
        f"{path}: {run.time[-1] - run.time[0]:.1f} s at {run.rate_hz:.4g} Hz, "
        f"{run.position[-1] - run.position[0]:.0f} m, speed {_speed_range(run)}",
        forces,
        f"; measured samples only (left out, interpolated across missing values: "
        f"{', '.join(left_out)})"
        if left_out
        else "",
    )
    console.print(table)


def force_table(
    title: str, forces: list[tuple[str, np.ndarray, np.ndarray]], more: str = ""
) -> Table:
    """The summary of each wheel's forces (kN): Y's signed mean (its sign is the flange
    side in a curve: a channel + towards the track centre reads negative there, and the
    mean and maximum of |Y| alone printed a sign-flipped Y as the right one), the mean and
    maximum of |Y|, and Q's mean and maximum."""
    table = Table(
        title=title,
        title_justify="left",
        caption=f"Y + towards the field side (flange force +){more}",
        caption_justify="left",
    )
    for col in ("wheel", "Y mean kN", "|Y| mean kN", "|Y| max kN", "Q mean kN", "Q max kN"):
        table.add_column(col, justify="right")
    for w, y, q in forces:
        table.add_row(
            w,
            f"{np.mean(y):.2f}",
            f"{np.mean(np.abs(y)):.2f}",
            f"{np.max(np.abs(y)):.2f}",
            f"{np.mean(q):.2f}",
            f"{np.max(q):.2f}",
        )
    return table


def _speed_range(run: MeasuredRun) -> str:
    """The run's speed range, km/h, signed in its sense of travel: a stretch run backwards
    shows as negative speeds (the run's ``speed`` is their magnitude, so a reversal read as
    0-65 km/h looked like a stop)."""
    v = run.speed * 3.6
    if run.backwards is not None and run.backwards.any():
        v = np.where(run.backwards, -v, v)
        return f"{v.min():.0f} to {v.max():.0f} km/h (negative: backwards)"
    return f"{v.min():.0f}-{v.max():.0f} km/h"


@app.command("sections")
def sections_command(
    recording: Annotated[Path, typer.Argument(help="long run: .mf4, .csv or .parquet")],
    channel_map: Annotated[
        Path | None,
        typer.Option("--map", help="channel map TOML (default: documented column names)"),
    ] = None,
    line: Annotated[
        Path | None,
        typer.Option(
            help="line description CSV: km_start,km_end,radius_m,direction,cant_mm,"
            "grade_permille (direction left/right on each curve row)"
        ),
    ] = None,
    table: Annotated[
        Path | None,
        typer.Option(
            help="section table CSV: start_m,end_m[,name] and optionally the track of each "
            "row: radius_m, direction (left/right on each curve row), cant_mm, grade_permille"
        ),
    ] = None,
    speed_tolerance: Annotated[
        float, typer.Option(help="largest (max - min) / mean speed within a section")
    ] = 0.10,
    min_length: Annotated[float, typer.Option(help="shortest section kept, m")] = 150.0,
    max_duration: Annotated[float, typer.Option(help="longest section, s (longer split)")] = 120.0,
    rate: Annotated[float, typer.Option(help="sampling rate of the written sections, Hz")] = 50.0,
    plot: Annotated[
        Path | None, typer.Option(help="PNG of speed and curvature along the line, sections shaded")
    ] = None,
    write: Annotated[
        Path | None,
        typer.Option(help="write the kept sections as a field folder (index.json) here"),
    ] = None,
    wagon: WagonOption = None,
) -> None:
    """Cut a long run into sections of one working condition each and show the cut."""
    from railsusp.measured import RecordingError
    from railsusp.measured.channels import read_channel_map
    from railsusp.measured.run import read_run
    from railsusp.measured.sections import (
        SectionRules,
        cut_sections,
        read_line,
        read_section_table,
        sections_table,
    )
    from railsusp.measured.sections_out import en14363_table, plot_sections, write_sections
    from railsusp.vehicle.setup import static_wheel_load

    try:
        if line is not None and table is not None:
            raise RailsuspInputError("give --line or --table, not both")
        # the rate every estimation command reads at least (RECORDING_MIN_RATE_HZ): 10-49 Hz
        # wrote a field folder each of them refused (the docs audit of stop 65)
        if not RECORDING_MIN_RATE_HZ <= rate <= 5000.0:
            raise RailsuspInputError(
                f"--rate {rate:g}: accepted {RECORDING_MIN_RATE_HZ:g} to 5000 Hz (the estimation "
                f"commands read recordings of {RECORDING_MIN_RATE_HZ:g} Hz or more)"
            )
        if plot is not None:
            check_figure_file(plot, "--plot")
        for option, given in (("--line", line), ("--table", table), ("--map", channel_map)):
            if given is not None and not Path(given).is_file():
                raise RailsuspInputError(f"{option} {given}: no such file")
        rules = SectionRules(
            speed_tolerance=speed_tolerance, min_length_m=min_length, max_duration_s=max_duration
        )
        cmap = read_channel_map(channel_map) if channel_map else None
        load = static_wheel_load(wagon_option(wagon))
        if write is not None and Path(recording).is_file():  # (a missing run: read_run says)
            from railsusp.measured.field_folder import check_field_output

            # never other data, nor another run's sections (by the file's contents), and
            # before the run is read and cut: a long run takes a while
            check_field_output(write, "sections", "--write", recording)
            # the folder for the command's duration (a second cut into it, or an estimate
            # reading it, is refused), then what it holds checked again under the lock
            hold_folders(creates=[("--write", write)])
            check_field_output(write, "sections", "--write", recording)
        run = read_run(recording, cmap, min_rate_hz=rate, wheel_load_N=load)  # rate: the least
        secs = cut_sections(
            run,
            rules,
            line=read_line(line) if line else None,
            table=read_section_table(table) if table else None,
        )
        for note in run.notes:
            console.print(f"note: {note}", highlight=False, markup=False)
        console.print(frame_table(sections_table(secs), f"Sections of {recording}"))
        if any(s.kept for s in secs):
            console.print(
                frame_table(
                    en14363_table(run, secs),
                    "Forces per section, EN 14363 processing (20 Hz low-pass, 2 m sliding "
                    "mean), percentiles",
                    fmt="{:.2f}",
                )
            )
        if plot is not None:
            console.print(f"wrote {plot_sections(run, secs, plot)}")
        if write is not None:
            from railsusp.measured.field_folder import earlier_sections
            from railsusp.store import atomic_folder

            # the whole folder at once: a kill mid-write left new recordings beside an old
            # index and sidecars. Other files of the folder are carried over, not the
            # earlier cut's recordings: a cut with fewer sections left them beside the index
            # (a linked --write: written where the link points, as its checks read it)
            with atomic_folder(write, drop=earlier_sections(write)) as tmp:
                write_sections(run, secs, tmp, rate, final=write, wheel_load_N=load)
            console.print(f"wrote {sum(s.kept for s in secs)} section recording(s) to {write}")
    except RecordingError as exc:
        print_problems(exc)
    except RailsuspInputError as exc:
        fail(str(exc), options=_SECTION_OPTIONS)


#: the section rules' settings -> the options of ``sections``, for its error messages
_SECTION_OPTIONS = {
    "speed_tolerance": "--speed-tolerance",
    "min_length_m": "--min-length",
    "max_duration_s": "--max-duration",
}


EXAMPLE_FILES = (
    "example_run.mf4",
    "example_run.map.toml",
    "example_line.csv",
    "example_run.truth.json",
    "example_run.pipeline.toml",
)

#: the SHA-256 of example files an earlier railsusp shipped, replaced by this one's where
#: found (not taken for the user's edits: the truth gained its run's SHA-256 in stop 74, and
#: a copy of the older one was called edited)
EARLIER_SHIPPED = {
    "example_run.truth.json": {
        "8bcd93ba64cb88257699c93c355988897cc52a04ff2635b26a5e454ff7d1bb6b",
    },
}


def _earlier_shipped(path: Path) -> bool:
    """Whether ``path`` is an example file as an earlier railsusp shipped it."""
    import hashlib

    known = EARLIER_SHIPPED.get(path.name, set())
    return bool(known) and hashlib.sha256(path.read_bytes()).hexdigest() in known


@app.command("example-recording")
def example_recording(
    out: Annotated[Path, typer.Option(help="folder to copy the example run into")],
) -> None:
    """Copy the example run shipped with railsusp into OUT: an MDF4 recording of a C80 run
    over five sections (hidden-truth simulation), its channel map, the line description,
    a ``railsusp run`` configuration on it, and the hidden truth (for comparison only)."""
    from importlib import resources

    from railsusp.store import atomic_write_bytes

    try:
        if out.exists() and not out.is_dir():
            raise RailsuspInputError(
                f"--out {out}: a file, not a folder; accepted a new folder or an existing one"
            )
        # the example's files are not mixed into a field folder (they were, beside the
        # recordings: the QA of stop 73), as no command writes its results among them
        from railsusp.measured.field_folder import check_not_recordings

        check_not_recordings(out)
        # one writer at a time in the folder (two copies at once checked each other's
        # half-written files as edited)
        hold_folders(creates=[("--out", out)])
        data = resources.files("railsusp") / "data"
        # a file there that is not the shipped one (the tutorial has the user edit the
        # configuration) is not written over: it was, silently (command-line audit, stop 60);
        # nor is one there as shipped: rewritten, its new modification time made the next
        # `railsusp run` redo its stages (the docs audit of stop 65). The missing ones are
        # written whatever else is there: beside an edited file the command wrote nothing,
        # a deleted recording was not restored (the docs audit of stop 72)
        there = [n for n in EXAMPLE_FILES if (out / n).exists()]
        older = [n for n in there if _earlier_shipped(out / n)]  # replaced, as missing ones
        there = [n for n in there if n not in older]
        edited = [n for n in there if (out / n).read_bytes() != (data / n).read_bytes()]
        written = [n for n in EXAMPLE_FILES if n not in there]
        for name in written:
            atomic_write_bytes(out / name, (data / name).read_bytes())
    except OSError as exc:  # a full disk, a quota, an I/O error exit 1 (the machine, as
        # every other command): it exited 2, bad input (the disk audit); the file it names
        name = f"{exc.filename}: " if exc.filename else ""
        fail(f"--out {out}: cannot write there ({name}{exc.strerror or exc})", exit_code(exc))
    except RailsuspInputError as exc:
        fail(str(exc))
    if edited:  # a warning: shown under --quiet too
        warnings.warn(
            f"--out {out}: left as they are, not the shipped files (edited?): "
            f"{', '.join(edited)}; move them away, or give a new --out, for fresh copies",
            stacklevel=1,
        )
    same = [n for n in there if n not in edited]
    console.print(
        (f"wrote {', '.join(written)} to {out}" if written else f"nothing written to {out}")
        + (f"; already there as shipped: {', '.join(same)}" if same else "")
    )
