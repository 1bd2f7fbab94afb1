"""Command ``modes``: natural frequencies, damping ratios and mode names of the wagon."""

from __future__ import annotations

from typing import Annotated

import typer

from railsusp.cli.common import WagonOption, app, console, err_console, fail, frame_table
from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet, parse_overrides


@app.command()
def modes(
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="parameter overrides, e.g. --set X13=16.1 (display units)"),
    ] = None,
    wagon: WagonOption = None,
    speed: Annotated[float, typer.Option(help="running speed, km/h (1-200)")] = 60.0,
    friction: Annotated[
        str,
        typer.Option(help="friction sliders in the linearisation: stuck or sliding"),
    ] = "stuck",
    fmax: Annotated[float, typer.Option(help="list modes up to this frequency, Hz")] = 30.0,
    decay: Annotated[
        bool, typer.Option("--decay", help="also run free-decay tests of the car-body modes")
    ] = False,
    amplitude: Annotated[
        float,
        typer.Option(
            help="--decay: depth of the dips and offset of the kink, mm (0.5-50); inputs "
            "of 15 mm and more make the loaded wagon's wedges slide, and a large kink can "
            "make a wheelset climb its flange (the loaded wagon's at 50 mm, 60 km/h)"
        ),
    ] = 5.0,
) -> None:
    """Linearise the wagon about its static equilibrium on ideal straight track and list its
    modes (frequency, damping ratio, name); with --decay, the car-body modes' equivalent
    damping from free-decay runs of the nonlinear model, friction on (docs/model.md).

    The free decay always runs the friction as modelled, and its table compares each decay
    with the **stuck** linearisation, whatever --friction lists above it: at the inputs'
    amplitudes the sliders stick (their pre-sliding loss is the damping measured), so the
    stuck modes are the ones the decays are of, their left eigenvectors read the modal
    coordinates, and the fit check (``fit ok``) is against their frequencies; the sliding
    linearisation's modes are not those of a friction-on decay (no one-to-one match of the
    two sets: docs/model.md). The columns and title say "stuck linearisation" so that a
    --friction sliding table above is not read as its reference.

    Roots in which no body moves (the sliding variant's friction states relaxing) are
    left out of the modes table and counted under it."""
    from railsusp.vehicle.decay import free_decay
    from railsusp.vehicle.decay_runs import AMPLITUDE_RANGE_M, DecayRunError
    from railsusp.vehicle.modes import (
        F_MAX_LIMIT_HZ,
        FRICTION_MODES,
        NO_MOTION_GROUP,
        NO_MOTION_NAME,
        modal_analysis,
    )
    from railsusp.vehicle.operating_point import SPEED_RANGE_KMH, OperatingPointError
    from railsusp.vehicle.wagon import load_wagon

    lo_a, hi_a = (1e3 * a for a in AMPLITUDE_RANGE_M)
    try:
        if friction not in FRICTION_MODES:
            raise RailsuspInputError(
                f"--friction {friction!r}: accepted {', '.join(FRICTION_MODES)}"
            )
        if not SPEED_RANGE_KMH[0] <= speed <= SPEED_RANGE_KMH[1]:
            raise RailsuspInputError(
                f"--speed = {speed:g} km/h: accepted {SPEED_RANGE_KMH[0]:g} to "
                f"{SPEED_RANGE_KMH[1]:g} km/h"
            )
        if not 0.0 < fmax <= F_MAX_LIMIT_HZ:
            raise RailsuspInputError(f"--fmax = {fmax:g} Hz: accepted (0, {F_MAX_LIMIT_HZ:g}] Hz")
        if not lo_a <= amplitude <= hi_a:
            raise RailsuspInputError(
                f"--amplitude = {amplitude:g} mm: accepted {lo_a:g} to {hi_a:g} mm"
            )
        pset = ParameterSet.nominal()
        if set_:
            pset = pset.replace(parse_overrides(set_), units="display")
        wagon_data = load_wagon(wagon)
        result = modal_analysis(pset, wagon_data, speed, friction)  # type: ignore[arg-type]
        decayed = None
        if decay:
            stuck = result if friction == "stuck" else None
            with err_console.status("free-decay runs"):
                decayed = free_decay(
                    pset, wagon_data, speed, amplitude_m=amplitude * 1e-3, modal=stuck
                )
    except RailsuspInputError as exc:
        fail(str(exc))
    except OperatingPointError as exc:
        fail(
            f"--wagon {wagon}: the wagon has no operating point to analyse ({exc}); check its data"
        )
    except DecayRunError as exc:  # the input was too large for the wagon (a flange climb)
        fail(
            f"--amplitude = {amplitude:g} mm: the free-decay run over the {exc.excitation} "
            f"stopped ({exc.reason}) on this wagon at {speed:g} km/h; accepted a smaller "
            f"--amplitude, from {lo_a:g} mm (how large a run stands depends on the wagon, "
            "the speed and the input)"
        )
    except RuntimeError as exc:  # a free-decay run that stopped otherwise
        fail(f"--decay: {exc}; the modes without --decay are those of the linearised wagon")
    df = result.to_dataframe(f_max=fmax)
    still = df["group"] == NO_MOTION_GROUP
    df = df[~still].reset_index(drop=True)
    df["car_body_energy"] *= 100.0
    df["time_constant_s"] *= 1000.0
    df = df.rename(
        columns={
            "frequency_Hz": "f Hz",
            "damping_ratio": "damping ratio",
            "time_constant_s": "overdamped: τ ms",
            "car_body_energy": "car body KE %",
        }
    )
    title = (
        f"Modes of {wagon_data.name}, {speed:g} km/h, ideal straight track, "
        f"friction {friction} (equilibrium residual {result.equilibrium_residual:.2g} m/s²)"
    )
    if df.empty:  # an empty table alone said nothing of why
        console.print(title, highlight=False)
        console.print(lowest_mode_line(result, fmax, NO_MOTION_GROUP), highlight=False)
    else:
        console.print(frame_table(df, title, fmt="{:.3g}"))
    if still.any():
        console.print(
            f"{int(still.sum())} roots below {fmax:g} Hz left out: {NO_MOTION_NAME}, the "
            "friction sliders' auxiliary states relaxing with no body moving (no kinetic "
            "energy: not a mode of the wagon).",
            highlight=False,
        )
    if decayed is not None:
        dd = decayed.to_dataframe().drop(columns=["amplitude", "frequency_ratio"])
        dd = dd.rename(
            columns={
                "linear_frequency_Hz": "stuck linear f Hz",
                "linear_damping_ratio": "stuck linear damping",
                "frequency_Hz": "decay f Hz",
                "damping_ratio": "equivalent damping",
                "fit_R2": "fit R²",
                "car_body_energy": "car body KE",
                "fit_ok": "fit ok",
            }
        )
        console.print(
            frame_table(
                dd,
                f"Free decay of the car-body modes, friction on, {amplitude:g} mm inputs "
                f"({decayed.window_s:g} s windows, damped-sinusoid fit), against the stuck "
                "linearisation",
                fmt="{:.3g}",
            )
        )
        if friction != "stuck":
            console.print(
                "The free decay runs the friction as modelled, whose sliders stick at small "
                "amplitudes: its modes, modal filters and fit check are the stuck "
                f"linearisation's, not the {friction} table's above (a decay whose friction "
                "slides fails the fit check).",
                highlight=False,
            )
        console.print(decay_reading(decayed, amplitude), highlight=False)


def lowest_mode_line(result, fmax: float, no_motion_group: str) -> str:
    """The line in place of an empty modes table: no mode lies at or below ``fmax`` Hz, and
    the lowest there is (its frequency, or an overdamped root's time constant, whose |λ| / 2π
    is what ``--fmax`` compares)."""
    moving = [i for i, g in enumerate(result.groups) if g != no_motion_group]
    if not moving:
        return f"no mode at or below {fmax:g} Hz"
    i = min(moving, key=lambda k: result.frequency_hz[k])
    f = float(result.frequency_hz[i])
    if result.overdamped[i]:
        what = f"an overdamped root, τ {1e3 * result.time_constant_s[i]:.3g} ms (|λ|/2π {f:.3g} Hz)"
    else:
        what = f"{f:.3g} Hz"
    return (
        f"no mode at or below {fmax:g} Hz (--fmax): the lowest is {result.names[i]}, {what}; "
        f"a larger --fmax lists it"
    )


def decay_reading(decayed, amplitude_mm: float) -> str:
    """What the free-decay table says about the friction: if every decay is its stuck
    linear mode's, the suspension friction held (the equivalent damping is the sliders'
    pre-sliding loss at that input, not their Coulomb damping); otherwise the modes whose
    decay is not their linear mode's alone (mixed, or friction slid: docs/model.md)."""
    off = [row["mode"] for row in decayed.unreliable]
    if not off:
        return (
            f"Every decay is its stuck mode's (fit ok): at {amplitude_mm:g} mm inputs "
            "the suspension friction (wedges, centre bowls) held, so the equivalent damping "
            "is its pre-sliding loss; larger inputs (--amplitude) make the wedges slide, and "
            "the frequencies move towards those of --friction sliding."
        )
    return (
        f"{len(off)} of {len(decayed.rows)} decays are not their linear mode's alone "
        f"(fit ok: no): {', '.join(off)}. At {amplitude_mm:g} mm inputs their "
        "friction slides or modes mix; their frequency and equivalent damping describe that "
        "decay, not a constant of the wagon."
    )
