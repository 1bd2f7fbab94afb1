"""Credibility of the nominal model: force statistics of the three conditions vs Table 8.

Nominal parameters, FRA Class 5 track, the standard straight / curve / uphill conditions.
For the measured wheel (leading wheelset; outer wheel in the curve) prints mean, RMS, 99th
percentile and maximum of |Y| and Q beside the study's simulated Table 8 values, with the
relative difference; the same over five track seeds gives the seed-to-seed spread. Writes
JSON (bench/results/credibility.json).
"""

from __future__ import annotations

import argparse
import platform
import time

from railsusp.conditions import STANDARD_CONDITIONS
from railsusp.params import ParameterSet
from railsusp.store import write_json
from railsusp.study import TABLE8_BEFORE
from railsusp.vehicle.simulate import WHEEL_NAMES, simulate_batch

STATS = ("mean", "rms", "p99", "max")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=5, help="track seeds per condition")
    ap.add_argument("--out", default="bench/results/credibility.json")
    args = ap.parse_args()
    rows = []
    for name, cond in STANDARD_CONDITIONS.items():
        seeds = [cond.seed + 1000 * k for k in range(args.seeds)]
        r = simulate_batch([ParameterSet.nominal()] * len(seeds), cond, seeds=seeds)
        s = r.statistics()
        ref = TABLE8_BEFORE[name]
        for force, study in (("Y", ref[0]), ("Q", ref[2])):
            for stat in STATS:
                v = s[f"{force}_{stat}"][r.ok]
                rows.append(
                    {
                        "condition": name,
                        "wheel": WHEEL_NAMES[r.measured_wheel()],
                        "force": force,
                        "statistic": stat,
                        "value_kN": float(v[0]),
                        "seed_mean_kN": float(v.mean()),
                        "seed_std_kN": float(v.std()),
                        "study_kN": study,
                        "relative_difference": float(v.mean() / study - 1),
                    }
                )
    print(
        f"{'condition':<9} {'wheel':<5} {'force':<5} {'stat':<5} {'ours kN':>8} "
        f"{'+- seeds':>9} {'study':>7} {'diff':>7}"
    )
    for row in rows:
        print(
            f"{row['condition']:<9} {row['wheel']:<5} {row['force']:<5} {row['statistic']:<5} "
            f"{row['seed_mean_kN']:8.1f} {row['seed_std_kN']:9.1f} {row['study_kN']:7.1f} "
            f"{row['relative_difference']:7.1%}"
        )
    best = {}
    for row in rows:
        key = (row["condition"], row["force"])
        if key not in best or abs(row["relative_difference"]) < abs(
            best[key]["relative_difference"]
        ):
            best[key] = row
    print("\nclosest statistic per condition and force:")
    for (c, f), row in best.items():
        print(f"  {c:<9} {f}: {row['statistic']:<5} {row['relative_difference']:+.1%}")
    payload = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": platform.platform(),
        "seeds": args.seeds,
        "rows": rows,
    }
    out = write_json(args.out, payload)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
