"""Commands for field data: synthesise recordings of a hidden truth and align their track
geometry with the forces."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from railsusp.cli.common import WagonOption, app, console, fail, hold_folders
from railsusp.cli.recordings import wagon_option
from railsusp.condition_files import resolve_conditions
from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet, parse_overrides

#: synthesise_field's settings -> the options of ``synth-field``, for its error messages
_SYNTH_OPTIONS = {
    "seed": "--seed",
    "noise": "--noise",
    "track_noise_mm": "--track-noise",
    "duration_s": "--duration",
    "fmt": "--format",
}


@app.command("synth-field")
def synth_field(
    out: Annotated[Path, typer.Option(help="field folder to write")],
    truth: Annotated[str, typer.Option(help="hidden true parameters, e.g. X13=16.1,X14=8.3")] = "",
    conditions: Annotated[str, typer.Option(help="names or a TOML file")] = (
        "straight,curve,uphill"
    ),
    seed: Annotated[int, typer.Option(help="noise seed")] = 7,
    noise: Annotated[float, typer.Option(help="white noise, fraction of the channel RMS")] = 0.03,
    fmt: Annotated[str, typer.Option("--format", help="csv or parquet")] = "csv",
    duration: Annotated[
        float | None,
        typer.Option(help="recorded seconds per condition (default: the condition's)"),
    ] = None,
    with_track: Annotated[
        bool,
        typer.Option(help="also write the track the truth ran on as measured track geometry"),
    ] = False,
    track_noise: Annotated[
        float,
        typer.Option(
            help="RMS measurement error on the written track geometry (within the "
            "measured wavelengths), mm; the recordings state it as track_accuracy_mm, which "
            "limits the time-aligned comparison to the wavelengths the geometry resolves"
        ),
    ] = 0.0,
    wheelset: Annotated[
        bool,
        typer.Option(
            help="record both wheels of the instrumented wheelset (the measured wheel, then "
            "its partner), for the posterior's wheelset, coherence and cross-spectra statistics"
        ),
    ] = False,
    wagon: WagonOption = None,
) -> None:
    """Synthetic instrumented-wheelset recordings of hidden true parameters (truth.json)."""
    from railsusp.measured import synthesise_field
    from railsusp.measured.field_folder import check_field_output

    try:
        if not 0.0 <= noise <= 0.5:
            raise RailsuspInputError(f"--noise {noise:g} outside the accepted range [0, 0.5]")
        if fmt not in ("csv", "parquet"):
            raise RailsuspInputError(f"--format {fmt!r}: accepted csv or parquet")
        if duration is not None and not 1.0 <= duration <= 600.0:
            raise RailsuspInputError(f"--duration {duration:g} s outside the accepted 1-600 s")
        if track_noise and not with_track:  # it was ignored: no geometry is written without
            raise RailsuspInputError(
                f"--track-noise {track_noise:g} needs --with-track (the error is that of the "
                "track geometry written beside the recordings)"
            )
        check_field_output(out, "synthetic", "--out")  # never replaces measured recordings
        pset = ParameterSet(parse_overrides(truth) if truth else {}, units="display")
        conds = resolve_conditions(conditions)
        wagon_data = wagon_option(wagon)
        # the folder for the command's duration (a second synth-field, or an estimate reading
        # it as RUN/field, is refused), then what it holds checked again under the lock
        hold_folders(creates=[("--out", out)])
        check_field_output(out, "synthetic", "--out")
        with console.status("simulating the hidden truth"):
            synthesise_field(
                pset,
                conds,
                out,  # a linked --out: written where the link points, as checked
                seed=seed,
                noise=noise,
                fmt=fmt,
                duration_s=duration,
                with_track=with_track,
                track_noise_mm=track_noise,
                wheelset=wheelset,
                wagon=wagon_data,
            )
    except RailsuspInputError as exc:
        fail(str(exc), options=_SYNTH_OPTIONS)
    console.print(
        f"wrote {len(conds)} recording(s) to {out} (index.json); the truth is in "
        f"{out / 'truth.json'}, which the estimator never reads"
    )


@app.command("align-track")
def align_track_command(
    measured: Annotated[Path, typer.Argument(help="field folder (index.json) of recordings")],
    max_shift: Annotated[float, typer.Option(help="largest offset searched, m")] = 10.0,
    write: Annotated[
        bool, typer.Option(help="write the offsets into the recordings' sidecars")
    ] = False,
    min_correlation: Annotated[
        float,
        typer.Option(
            help="least correlation after alignment taken as a match: one below it is "
            "warned of, and --write refused (default 0.5)"
        ),
    ] = 0.5,  # estimate.alignment.MIN_ALIGNED_CORRELATION (the CLI imports it lazily)
    wagon: WagonOption = None,
) -> None:
    """Align each recording's measured track geometry with its forces (cross-correlation
    with a nominal simulation) and report, or with --write store, the distance offset."""
    from railsusp.estimate import align_track
    from railsusp.estimate.comparison import check_time_base
    from railsusp.measured import read_field
    from railsusp.store import read_json, write_json

    try:
        if not 0.0 < max_shift <= 200.0:  # before the recordings are read
            raise RailsuspInputError(f"--max-shift {max_shift:g}: accepted (0, 200] m")
        if not 0.0 <= min_correlation < 1.0:
            raise RailsuspInputError(f"--min-correlation {min_correlation:g}: accepted [0, 1)")
        wagon_data = wagon_option(wagon)
        if write:  # the sidecars it rewrites: one writer at a time in the folder
            hold_folders(writes=[("", measured)])
        else:  # read only: not beside a writer of the folder (a mixed read, the audit)
            hold_folders(reads=[("", measured)])
        recs = [
            r
            for r in read_field(measured, wagon=wagon_data)
            if r.condition.track_geometry is not None
        ]
        if not recs:
            raise RailsuspInputError(f"{measured}: no recording carries measured track geometry")
        check_time_base(recs, "align-track")  # every recording, before the first simulation
        with console.status("simulating on the measured tracks"):
            found = [align_track(r, max_shift_m=max_shift, wagon=wagon_data) for r in recs]
        for a in found:
            if a.limited_by:  # a third of the record, or whole samples: said, not hidden
                warnings.warn(
                    f"--max-shift {max_shift:g} m: recording {a.recording!r} is searched to "
                    f"{a.limited_by}",
                    stacklevel=1,
                )
        edge = [a for a in found if a.on_edge]
        if edge and write:  # an edge is no peak: a stored offset would move every estimate
            a = edge[0]
            raise RailsuspInputError(
                f"--write: recording {a.recording!r}: its best shift {a.shift_m:+.2f} m lies on "
                f"the edge of the ±{a.searched_m:.3g} m searched, so the correlation may peak "
                "beyond it; nothing written: accepted a larger --max-shift (at most a third "
                "of the record is searched), or no --write"
            )
        weak = [a for a in found if not a.correlation >= min_correlation]
        if weak and write:  # a chance correlation: a stored offset would misalign the track
            a = weak[0]
            raise RailsuspInputError(
                f"--write: recording {a.recording!r}: the correlation after alignment, "
                f"{a.correlation:.3f} at {a.shift_m:+.2f} m, is below --min-correlation "
                f"{min_correlation:g}, so no match was found within ±{a.searched_m:.3g} m; "
                "nothing written: accepted a larger --max-shift, the recording's own track "
                "geometry, or a lower --min-correlation where its forces are known to match "
                "the model this poorly"
            )
    except (RailsuspInputError, ValueError) as exc:
        fail(str(exc), options={"max_shift_m": "--max-shift"})
    for a in weak:
        warnings.warn(
            f"recording {a.recording!r}: the correlation after alignment, {a.correlation:.3f}, "
            f"is below --min-correlation {min_correlation:g}: no match was found within "
            f"±{a.searched_m:.3g} m (the offset shown is a chance peak)",
            stacklevel=1,
        )
    for a in edge:
        warnings.warn(
            f"recording {a.recording!r}: the best shift {a.shift_m:+.2f} m lies on the edge of "
            f"the ±{a.searched_m:.3g} m searched (--max-shift {max_shift:g}), so the "
            "correlation may peak beyond it",
            stacklevel=1,
        )
    table = Table(title="Track geometry alignment", title_justify="left")
    for col in ("recording", "offset m", "shift m", "correlation before", "after"):
        table.add_column(col, justify="left" if col == "recording" else "right")
    for a in found:
        table.add_row(
            a.recording,
            f"{a.offset_m:+.2f}",
            f"{a.shift_m:+.2f}",
            f"{a.correlation_before:.3f}",
            f"{a.correlation:.3f}",
        )
    console.print(table)
    if write:
        from railsusp.measured import read_index

        for table in read_index(measured):  # every listed path inside the folder
            side = table.with_suffix(".json")
            doc = read_json(side)
            for a in found:
                if doc.get("condition", {}).get("name") == a.recording:
                    doc["condition"]["track_offset_m"] = round(a.offset_m, 4)
                    write_json(side, doc)
        console.print(f"wrote the offsets into the sidecars in {measured}")
