"""Commands about the inputs: parameter catalogue, working conditions, track input."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table

from railsusp.cli.common import app, console, fail, option_names
from railsusp.condition_files import resolve_conditions
from railsusp.conditions import STANDARD_CONDITIONS, WorkingCondition, make_condition
from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_figure_file
from railsusp.params import CATALOGUE, ParameterSet, parse_overrides
from railsusp.vehicle.track import COMPONENTS, GRID_STEPS_PER_WAVE, band_rms, synthesise
from railsusp.vehicle.track_geometry import irregularities_for


def parameter_table(pset: ParameterSet, title: str = "Parameter catalogue (C80 / K6)") -> Table:
    """Catalogue rows: symbol, description, unit, nominal, range, current value."""
    table = Table(title=title, title_justify="left")
    for col in ("symbol", "description", "unit", "nominal", "range", "value"):
        table.add_column(col, justify="right" if col in ("nominal", "value") else "left")
    for s in CATALOGUE:
        rng = (
            "fixed"
            if s.bounds_display is None
            else (f"{s.bounds_display[0]:g} .. {s.bounds_display[1]:g}")
        )
        value = pset.display(s.symbol)
        shown = f"{value:g}" if value == s.nominal_display else f"[bold yellow]{value:g}[/]"
        unit = s.display_unit + (f" (study: {s.table_unit})" if s.table_unit else "")
        table.add_row(s.symbol, s.description, unit, f"{s.nominal_display:g}", rng, shown)
    return table


def condition_table(conditions: list[WorkingCondition]) -> Table:
    """One row per working condition, in engineering units."""
    table = Table(title="Working conditions", title_justify="left")
    for col in (
        "name",
        "speed km/h",
        "radius m",
        "cant mm",
        "deficiency mm",
        "spirals m",
        "grade ‰",
        "coupler kN",
        "track",
        "record",
    ):
        table.add_column(col)
    for c in conditions:
        curve = c.curve_radius_m is not None
        table.add_row(
            c.name,
            f"{c.speed_kmh:g}",
            f"{c.curve_radius_m:g} {c.curve_direction}" if curve else "tangent",
            f"{c.cant_mm:g}" if curve else "-",
            f"{c.cant_deficiency_mm:.1f}" if curve else "-",
            f"{c.entry_spiral_m:g}/{c.exit_spiral_m:g}" if curve else "-",
            f"{c.grade_permille:+g}",
            f"{c.coupler_force_kN:g}",
            "perfect"
            if c.irregularity_class is None
            else f"class {c.irregularity_class}, seed {c.seed}",
            f"{c.duration_s:g} s / {c.n_steps}",
        )
    return table


def track_summary_table(conditions: list[WorkingCondition]) -> Table:
    """RMS of the synthesised irregularities over each section vs the PSD band integral."""
    table = Table(title="Synthesised track input (RMS over the section, mm)", title_justify="left")
    table.add_column("condition")
    table.add_column("length m", justify="right")
    for comp in COMPONENTS:
        table.add_column(f"{comp} (PSD)", justify="right")
    for c in conditions:
        irr = irregularities_for(c)
        if irr is None:
            table.add_row(c.name, f"{c.section_length_m:.0f}", *["0 (0)"] * len(COMPONENTS))
            continue
        cells = []
        for comp in COMPONENTS:
            rms = float(np.std(irr.component(comp)[0])) * 1e3
            ref = band_rms(comp, irr.track_class, irr.wavelength_min, irr.wavelength_max) * 1e3
            cells.append(f"{rms:.2f} ({ref:.2f})")
        table.add_row(c.name, f"{c.section_length_m:.0f}", *cells)
    return table


@app.command()
def params(
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="override, e.g. --set X13=16.1,X14=8.3 (display units)"),
    ] = None,
    file: Annotated[
        Path | None,
        typer.Option("--file", help="TOML file with a \\[parameters] table (display units)"),
    ] = None,
) -> None:
    """Print the parameter catalogue (Tables 1 and 2 of the study), with any overrides."""
    try:
        pset = ParameterSet.from_toml(file) if file else ParameterSet.nominal()
        if set_:
            pset = pset.replace(parse_overrides(set_), units="display")
    except RailsuspInputError as exc:
        fail(str(exc))
    console.print(parameter_table(pset))


@app.command()
def conditions(
    which: Annotated[
        str, typer.Argument(help="comma-separated standard names or a TOML file")
    ] = ",".join(STANDARD_CONDITIONS),
) -> None:
    """Print the working conditions (Table 6 of the study, with our documented choices)."""
    try:
        conds = resolve_conditions(which)
    except RailsuspInputError as exc:
        fail(str(exc))
    console.print(condition_table(conds))
    for c in conds:
        console.print(f"  [bold]{c.name}[/]: {c.describe()}", highlight=False)


#: the ``track`` command's options for the fields of the condition it checks its input as
_TRACK_OPTIONS = {
    "irregularity_class": "--class",
    "wavelength_min_m": "--wavelength-min",
    "wavelength_max_m": "--wavelength-max",
    "seed": "--seed",
}


def condition_options(message: str, options: Mapping[str, str], name: str | None = None) -> str:
    """A working condition's one-line error as the options typed: each field of ``options``
    that it names given as its option (``duration_s = 0.0: ...`` -> ``--duration 0.0:
    ...``), and, where ``name`` is the condition the command made up for the check (``track``
    has none of its own), its ``condition 'NAME': `` prefix and the "none" that only a
    conditions file can give taken off."""
    text = option_names(message, options)
    if name is not None:
        text = text.removeprefix(f"condition {name!r}: ").replace(' or "none" (perfect track)', "")
    return text


def check_seed(seed: int | None) -> None:
    """Refuse a negative ``--seed`` in the words of the other commands' (synth-field's)."""
    if seed is not None and seed < 0:
        raise RailsuspInputError(f"--seed {seed}: accepted 0 or more")


@app.command()
def track(
    track_class: Annotated[int, typer.Option("--class", help="FRA track class 1..6")] = 5,
    length: Annotated[
        float,
        typer.Option(
            help="section length, m: at least the shortest wavelength (8 grid steps). "
            "'expected' is the RMS of the whole wavelength band; a section shorter than the "
            "longest wavelength holds only part of its longer waves, so its RMS is mostly "
            "below it (a note says so)"
        ),
    ] = 2000.0,
    seed: Annotated[int, typer.Option(help="random seed, 0 or more")] = 0,
    wavelength_min: Annotated[float, typer.Option(help="shortest wavelength, m")] = 1.0,
    wavelength_max: Annotated[float, typer.Option(help="longest wavelength, m")] = 120.0,
    plot: Annotated[Path | None, typer.Option(help="write a PNG of traces and PSDs")] = None,
) -> None:
    """Synthesise FRA-class irregularities and compare their RMS and PSD with the spectrum."""
    try:
        if not 0 < length <= 1e6:  # also refuses nan
            raise RailsuspInputError(f"--length = {length:g} m: accepted range (0, 1e6] m")
        if plot is not None:
            check_figure_file(plot, "--plot")
        for name, v in (("--wavelength-min", wavelength_min), ("--wavelength-max", wavelength_max)):
            if v != v or v in (float("inf"), float("-inf")):
                raise RailsuspInputError(f"{name} = {v:g} m is not finite")
        check_seed(seed)
        try:
            make_condition(
                {
                    "name": "track",
                    "irregularity_class": track_class,
                    "wavelength_min_m": wavelength_min,
                    "wavelength_max_m": wavelength_max,
                    "seed": seed,
                }
            )
        except RailsuspInputError as exc:
            raise RailsuspInputError(condition_options(str(exc), _TRACK_OPTIONS, "track")) from None
        if length < wavelength_min:  # one sample or a few: no RMS, no PSD, no plot
            raise RailsuspInputError(
                f"--length {length:g} m: accepted at least the shortest wavelength, "
                f"{wavelength_min:g} m (--wavelength-min: {GRID_STEPS_PER_WAVE} grid steps "
                f"of {wavelength_min / GRID_STEPS_PER_WAVE:g} m), up to 1e6 m"
            )
        irr = synthesise(
            length, track_class, seed, wavelength_min=wavelength_min, wavelength_max=wavelength_max
        )
    except RailsuspInputError as exc:
        fail(str(exc))
    table = Table(title=f"FRA class {track_class}, {length:g} m, seed {seed}", title_justify="left")
    for col in ("component", "RMS mm", "expected mm", "max |x| mm"):
        table.add_column(col, justify="right")
    for comp in COMPONENTS:
        x = irr.component(comp)[0]
        ref = band_rms(comp, track_class, wavelength_min, wavelength_max)
        table.add_row(
            comp, f"{np.std(x) * 1e3:.2f}", f"{ref * 1e3:.2f}", f"{np.abs(x).max() * 1e3:.2f}"
        )
    console.print(table)
    if length < wavelength_max:
        console.print(short_section_note(length, wavelength_min, wavelength_max), highlight=False)
    if plot is not None:
        from railsusp.report import plot_track_irregularities

        out = plot_track_irregularities(irr, plot)
        console.print(f"wrote {out}")


def short_section_note(length: float, wavelength_min: float, wavelength_max: float) -> str:
    """What the RMS of a section shorter than the longest wavelength is compared with: the
    whole band's expected RMS, of which such a section holds only part."""
    return (
        f"note: the {length:g} m section is shorter than the longest wavelength "
        f"({wavelength_max:g} m): 'expected' is the RMS of the whole {wavelength_min:g}-"
        f"{wavelength_max:g} m band, and a section this short holds only part of its longer "
        "waves, so its RMS is mostly below it and varies with the seed (a section of several "
        "longest wavelengths compares with it)"
    )
