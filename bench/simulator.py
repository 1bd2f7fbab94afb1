"""Simulator throughput: simulated wagon-seconds per wall-second for N = 1, 16, 256 sets.

Each set runs the standard straight condition (100 m lead-in plus the 20 s record, 26 s of
simulated running in all) in one batched call; the compiled kernels are warmed up first so
the figures exclude compilation. Prints a table and writes JSON (bench/results/simulator.json).
Peak memory is the process's maximum resident set size.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import time

import numba
import numpy as np

from railsusp.conditions import get_condition
from railsusp.params import MAIN_SUSPENSION, ParameterSet, bounds
from railsusp.store import write_json
from railsusp.vehicle.setup import SolverSettings
from railsusp.vehicle.simulate import simulate_batch
from railsusp.vehicle.wagon import load_wagon


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="1,16,256")
    ap.add_argument("--condition", default="straight")
    ap.add_argument("--contact", default="two-point", help="two-point or single-point")
    ap.add_argument("--flange-substeps", type=int, default=None, help="solver step split")
    ap.add_argument("--out", default="bench/results/simulator.json")
    args = ap.parse_args()
    cond = get_condition(args.condition)
    wagon = load_wagon().with_contact_model(args.contact)
    settings = SolverSettings()
    if args.flange_substeps is not None:
        settings = SolverSettings(flange_substeps=args.flange_substeps)
    simulated = cond.lead_in_m / cond.speed + cond.duration_s
    simulate_batch(
        [ParameterSet.nominal()],
        get_condition(args.condition, duration_s=1.0, n_steps=50),
        wagon=wagon,
        settings=settings,
    )  # compile
    rng = np.random.default_rng(0)
    lo, hi = bounds(MAIN_SUSPENSION)
    rows = []
    for n in (int(s) for s in args.sizes.split(",")):
        x = lo + (hi - lo) * rng.random((n, len(MAIN_SUSPENSION)))
        t0 = time.perf_counter()
        r = simulate_batch(x, cond, symbols=MAIN_SUSPENSION, wagon=wagon, settings=settings)
        wall = time.perf_counter() - t0
        rows.append(
            {
                "sets": n,
                "wall_s": wall,
                "simulated_s_per_set": simulated,
                "wagon_s_per_wall_s": n * simulated / wall,
                "record_s_per_wall_s": n * cond.duration_s / wall,
                "failed": int((~r.ok).sum()),
            }
        )
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(
        f"condition {cond.name}: {simulated:.1f} s simulated per set "
        f"({cond.duration_s:g} s recorded), {numba.get_num_threads()} threads, "
        f"{args.contact} contact, flange_substeps {settings.flange_substeps}"
    )
    print(f"{'sets':>6} {'wall s':>8} {'wagon-s/s':>10} {'record-s/s':>11} {'failed':>7}")
    for row in rows:
        print(
            f"{row['sets']:>6} {row['wall_s']:8.2f} {row['wagon_s_per_wall_s']:10.1f} "
            f"{row['record_s_per_wall_s']:11.1f} {row['failed']:>7}"
        )
    print(f"peak memory {peak_mb:.0f} MB")
    payload = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": platform.platform(),
        "cpus": os.cpu_count(),
        "threads": numba.get_num_threads(),
        "condition": cond.name,
        "contact": args.contact,
        "flange_substeps": settings.flange_substeps,
        "rows": rows,
        "peak_rss_mb": peak_mb,
    }
    out = write_json(args.out, payload)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
