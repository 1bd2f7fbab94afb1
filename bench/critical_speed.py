"""Nonlinear critical speed of the wagon, loaded and tare, on ideal straight track.

At each speed the wagon (nominal parameters) meets one lateral kink, a one-wave alignment
bump of ``--kink-mm`` (10 mm by default, about the flangeway clearance) over 10 m, and runs
on for ``--duration`` s on ideal track (railsusp.vehicle.stability). The leading wheelset's
ΣY oscillation is measured over the last two 5 s windows: it decays when the last window's
RMS is below 0.95 of the one before (or below 20 N). The critical speed is the lowest speed
at which it no longer decays: a sweep from ``--from`` to 200 km/h (the highest speed a
working condition accepts) in ``--step`` finds the first such speed, and bisection below it
narrows it to 1 km/h. Prints a table per wagon and writes JSON
(bench/results/critical_speed.json). About 1 s of compute per speed and wagon.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from _cli import number_list, positive_float, run_main
from railsusp.errors import RailsuspInputError
from railsusp.store import write_json
from railsusp.vehicle.stability import KinkResponse, kink_response
from railsusp.vehicle.wagon import load_wagon

TOP_SPEED_KMH = 200.0  # the highest speed a working condition accepts


def critical_speed(
    wagon_name: str, speeds: np.ndarray, duration: float, kink_m: float
) -> tuple[float | None, list[KinkResponse]]:
    """Lowest speed (km/h, to 1 km/h) at which the kink response does not decay; None if it
    decays at every speed of the sweep. Returns it with every response computed. An empty
    sweep is refused: it would read as "not found" with nothing simulated."""
    if len(speeds) == 0:
        raise RailsuspInputError("the speed sweep is empty: accepted one speed or more")
    wagon = load_wagon(wagon_name)
    runs = []
    first_bad = None
    for v in speeds:
        r = kink_response(wagon, float(v), duration, kink_m)
        runs.append(r)
        if not r.decays:
            first_bad = float(v)
            break
    if first_bad is None:
        return None, runs
    lo = max([r.speed_kmh for r in runs if r.decays and r.speed_kmh < first_bad], default=None)
    if lo is None:
        return first_bad, runs
    hi = first_bad
    while hi - lo > 1.0:
        mid = round(0.5 * (lo + hi), 1)
        r = kink_response(wagon, mid, duration, kink_m)
        runs.append(r)
        lo, hi = (mid, hi) if r.decays else (lo, mid)
    return hi, sorted(runs, key=lambda r: r.speed_kmh)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--wagons", default="loaded,tare", help="packaged names or wagon files")
    ap.add_argument(
        "--kink-mm",
        type=number_list(positive_float),
        default="10,3",
        help="kink amplitudes, mm (comma-separated)",
    )
    ap.add_argument(
        "--from", dest="start", type=positive_float, default=40.0, help="first speed, km/h"
    )
    ap.add_argument("--step", type=positive_float, default=10.0, help="sweep step, km/h")
    ap.add_argument("--duration", type=positive_float, default=30.0, help="record per speed, s")
    ap.add_argument("--out", default="bench/results/critical_speed.json")
    args = ap.parse_args()
    if args.start > TOP_SPEED_KMH:
        ap.error(
            f"--from {args.start:g}: accepted up to {TOP_SPEED_KMH:g} km/h (the sweep's end, "
            "the highest speed a working condition accepts)"
        )
    speeds = np.arange(args.start, TOP_SPEED_KMH + 1e-9, args.step)
    results = []
    t0 = time.perf_counter()
    for name in args.wagons.split(","):
        for kink_mm in args.kink_mm:
            vc, runs = critical_speed(name, speeds, args.duration, kink_mm * 1e-3)
            shown = "not found up to 200" if vc is None else f"{vc:.0f}"
            print(f"\n{name}, kink {kink_mm:g} mm: critical speed {shown} km/h")
            print(f"{'km/h':>6} {'decays':>6} {'RMS ΣY before':>14} {'last':>8} {'ratio':>6} "
                  f"{'amplitude kN':>12} {'f Hz':>5}")  # fmt: skip
            for r in runs:
                print(
                    f"{r.speed_kmh:6.1f} {'yes' if r.decays else 'NO':>6} "
                    f"{r.rms_before / 1e3:14.3f} {r.rms_last / 1e3:8.3f} {r.ratio:6.3f} "
                    f"{r.amplitude_last / 1e3:12.3f} {r.frequency_hz:5.2f}"
                )
            results.append(
                {
                    "wagon": load_wagon(name).name,
                    "kink_mm": kink_mm,
                    "critical_speed_kmh": vc,
                    "runs": [r.to_dict() for r in runs],
                }
            )
    wall = time.perf_counter() - t0
    print(f"\n{wall:.0f} s")
    payload = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": platform.platform(),
        "duration_s": args.duration,
        "criterion": "leading-wheelset ΣY RMS, last 5 s < 0.95 x the 5 s before, or < 20 N",
        "wall_s": wall,
        "results": results,
    }
    print(f"wrote {write_json(args.out, payload)}")


if __name__ == "__main__":
    run_main(main)
