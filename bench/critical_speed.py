"""Nonlinear critical speed of the wagon, loaded and tare, on ideal straight track.

At each speed the wagon (nominal parameters) meets one lateral kink, a one-wave alignment
bump of ``--kink-mm`` (10 mm by default, about the flangeway clearance) over 10 m, and runs
on for ``--duration`` s on ideal track (railsusp.vehicle.stability). The leading wheelset's
ΣY oscillation is measured over the last two 5 s windows: it decays when the last window's
RMS is below 0.95 of the one before (or below 20 N). The critical speed is the lowest speed
at which it no longer decays: a sweep from ``--from`` to 200 km/h (the highest speed a
working condition accepts) in ``--step`` finds the first such speed, and bisection below it
narrows it to 1 km/h. Where the sweep's first speed is already unstable there is nothing
to bisect: the critical speed is only known to lie at or below it, and the table and the JSON
say so (``critical_speed_kmh`` null, ``at_or_below_kmh`` and the ``reason``), not a value.
Every wagon is loaded and ``--duration`` checked (15 to 600 s: two 5 s windows after the
kink's 5 s, at most a working condition's record) before the first run. Prints a table per
wagon and writes JSON (bench/results/critical_speed.json). About 1 s of compute per speed
and wagon.
"""

from __future__ import annotations

import platform
import time
from dataclasses import dataclass

import numpy as np

from _cli import fail, number_list, parser, positive_float, run_main
from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.store import write_json
from railsusp.vehicle.stability import MIN_DURATION_S, KinkResponse, kink_response
from railsusp.vehicle.wagon import WagonData, load_wagon

TOP_SPEED_KMH = 200.0  # the highest speed a working condition accepts
#: the longest record a working condition accepts, s (its ``duration_s`` bound)
MAX_DURATION_S = next(
    m.le for m in WorkingCondition.model_fields["duration_s"].metadata if hasattr(m, "le")
)


@dataclass(frozen=True)
class Found:
    """What the sweep found for one wagon and kink: the critical speed (km/h, to 1 km/h),
    or None with the ``reason``; ``at_or_below`` is the sweep's first speed where that
    speed was already unstable (the critical speed lies at or below it, unbracketed)."""

    speed_kmh: float | None
    at_or_below: float | None
    reason: str | None
    runs: list[KinkResponse]

    def shown(self) -> str:
        """The finding as the table prints it, after "critical speed "."""
        if self.speed_kmh is not None:
            return f"{self.speed_kmh:.0f} km/h"
        if self.at_or_below is not None:
            return f"at or below {self.at_or_below:.0f} km/h ({self.reason})"
        return f"not found ({self.reason})"


def critical_speed(wagon: WagonData, speeds: np.ndarray, duration: float, kink_m: float) -> Found:
    """Lowest speed (km/h, to 1 km/h) at which the kink response does not decay, with every
    response computed. None if it decays at every speed of the sweep, and a bound only
    (:attr:`Found.at_or_below`) if it does not decay at the sweep's first speed. An empty
    sweep is refused: it would read as "not found" with nothing simulated."""
    if len(speeds) == 0:
        raise RailsuspInputError("the speed sweep is empty: accepted one speed or more")
    runs = []
    first_bad = None
    for v in speeds:
        r = kink_response(wagon, float(v), duration, kink_m)
        runs.append(r)
        if not r.decays:
            first_bad = float(v)
            break
    if first_bad is None:
        top = float(speeds[-1])
        return Found(None, None, f"decays at every speed of the sweep up to {top:g} km/h", runs)
    lo = max([r.speed_kmh for r in runs if r.decays and r.speed_kmh < first_bad], default=None)
    if lo is None:
        reason = "unstable at the sweep's first speed; lower --from"
        return Found(None, first_bad, reason, runs)
    hi = first_bad
    while hi - lo > 1.0:
        mid = round(0.5 * (lo + hi), 1)
        r = kink_response(wagon, mid, duration, kink_m)
        runs.append(r)
        lo, hi = (mid, hi) if r.decays else (lo, mid)
    return Found(hi, None, None, sorted(runs, key=lambda r: r.speed_kmh))


def load_wagons(text: str) -> list[tuple[str, WagonData]]:
    """(name, wagon) of every wagon of ``--wagons`` (comma-separated), loaded before any
    run: a bad name refused (exit 2) before the first wagon's sweep, not after it."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        fail(f"--wagons {text!r}: accepted packaged names or wagon files, comma-separated")
    try:
        return [(name, load_wagon(name)) for name in names]
    except RailsuspInputError as exc:
        fail(f"--wagons {text}: {exc}")


def main() -> None:
    ap = parser(__doc__, whole=True)
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
    ap.add_argument(
        "--duration",
        type=positive_float,
        default=30.0,
        help=f"record per speed, s ({MIN_DURATION_S:g} to {MAX_DURATION_S:g})",
    )
    ap.add_argument("--out", default="bench/results/critical_speed.json")
    args = ap.parse_args()
    if args.start > TOP_SPEED_KMH:
        ap.error(
            f"--from {args.start:g}: accepted up to {TOP_SPEED_KMH:g} km/h (the sweep's end, "
            "the highest speed a working condition accepts)"
        )
    if not MIN_DURATION_S <= args.duration <= MAX_DURATION_S:
        ap.error(
            f"--duration {args.duration:g}: accepted {MIN_DURATION_S:g} to {MAX_DURATION_S:g} s "
            "(the kink's passage and two 5 s windows; at most a working condition's record)"
        )
    wagons = load_wagons(args.wagons)
    speeds = np.arange(args.start, TOP_SPEED_KMH + 1e-9, args.step)
    results = []
    t0 = time.perf_counter()
    for name, wagon in wagons:
        for kink_mm in args.kink_mm:
            found = critical_speed(wagon, speeds, args.duration, kink_mm * 1e-3)
            print(f"\n{name}, kink {kink_mm:g} mm: critical speed {found.shown()}")
            print(f"{'km/h':>6} {'decays':>6} {'RMS ΣY before':>14} {'last':>8} {'ratio':>6} "
                  f"{'amplitude kN':>12} {'f Hz':>5}")  # fmt: skip
            for r in found.runs:
                print(
                    f"{r.speed_kmh:6.1f} {'yes' if r.decays else 'NO':>6} "
                    f"{r.rms_before / 1e3:14.3f} {r.rms_last / 1e3:8.3f} {r.ratio:6.3f} "
                    f"{r.amplitude_last / 1e3:12.3f} {r.frequency_hz:5.2f}"
                )
            results.append(
                {
                    "wagon": wagon.name,
                    "kink_mm": kink_mm,
                    "critical_speed_kmh": found.speed_kmh,
                    "at_or_below_kmh": found.at_or_below,
                    "reason": found.reason,
                    "runs": [r.to_dict() for r in found.runs],
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
