"""Credibility of the nominal model: force statistics of the three conditions vs Table 8.

Nominal parameters, FRA Class 5 track, the standard straight / curve / uphill conditions,
several track seeds per condition (mean and spread over seeds). For the leading wheelset's
wheels (in the curve both the outer wheel, railsusp's default measured wheel, and the inner
one) prints mean, RMS, 99th percentile and maximum of |Y| and Q beside the study's simulated
Table 8 values, with the relative difference, and the share of single 20 s records whose
value lies within 30 % of the study's (the study reports one record). The study names
neither its statistic nor, in the curve, its wheel; its curve vertical force is 6 % below
its tangent one, which for one statistic only the inner wheel can give (cant deficiency
loads the outer wheel): the last table checks that. Writes JSON
(bench/results/credibility.json).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from railsusp.conditions import STANDARD_CONDITIONS
from railsusp.params import ParameterSet
from railsusp.store import write_json
from railsusp.study import TABLE8_BEFORE
from railsusp.vehicle.simulate import WHEEL_NAMES, record_statistic, simulate_batch
from railsusp.vehicle.wagon import load_wagon

STATS = ("mean", "rms", "p99", "max")


def wheel_statistic(force: np.ndarray, statistic: str, lateral: bool) -> np.ndarray:
    """Per-record statistic (kN) of one wheel's series (n_records, T)."""
    if statistic == "max":
        return np.abs(force).max(axis=1) if lateral else force.max(axis=1)
    return record_statistic(force, statistic, lateral)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=32, help="track seeds per condition")
    ap.add_argument("--out", default="bench/results/credibility.json")
    ap.add_argument("--contact", default="two-point", help="two-point or single-point")
    args = ap.parse_args()
    wagon = load_wagon().with_contact_model(args.contact)
    rows = []
    for name, cond in STANDARD_CONDITIONS.items():
        seeds = [cond.seed + 1000 * k for k in range(args.seeds)]
        r = simulate_batch([ParameterSet.nominal()] * len(seeds), cond, seeds=seeds, wagon=wagon)
        ref = TABLE8_BEFORE[name]
        default = r.measured_wheel()
        wheels = (default, default ^ 1) if cond.curve_radius_m else (default,)
        for j in wheels:
            role = "outer" if j == default and cond.curve_radius_m else "inner"
            role = role if cond.curve_radius_m else "leading"
            for force, study in (("Y", ref[0]), ("Q", ref[2])):
                series = (r.Y if force == "Y" else r.Q)[r.ok, j] / 1e3
                for stat in STATS:
                    v = wheel_statistic(series, stat, force == "Y")
                    rows.append(
                        {
                            "condition": name,
                            "wheel": WHEEL_NAMES[j],
                            "role": role,
                            "force": force,
                            "statistic": stat,
                            "value_kN": float(v[0]),
                            "seed_mean_kN": float(v.mean()),
                            "seed_std_kN": float(v.std()),
                            "study_kN": study,
                            "relative_difference": float(v.mean() / study - 1),
                            "records_within_30pct": float(np.mean(np.abs(v / study - 1) <= 0.3)),
                        }
                    )
    print(
        f"{'condition':<9} {'wheel':<13} {'force':<5} {'stat':<5} {'ours kN':>8} "
        f"{'+- seeds':>9} {'study':>7} {'diff':>7} {'in 30%':>7}"
    )
    for row in rows:
        print(
            f"{row['condition']:<9} {row['wheel'] + ' ' + row['role']:<13} {row['force']:<5} "
            f"{row['statistic']:<5} {row['seed_mean_kN']:8.1f} {row['seed_std_kN']:9.1f} "
            f"{row['study_kN']:7.1f} {row['relative_difference']:7.1%} "
            f"{row['records_within_30pct']:7.0%}"
        )
    best = {}
    for row in rows:
        key = (row["condition"], row["role"], row["force"])
        if key not in best or abs(row["relative_difference"]) < abs(
            best[key]["relative_difference"]
        ):
            best[key] = row
    print("\nclosest statistic per condition, wheel and force:")
    for (c, role, f), row in best.items():
        print(f"  {c:<9} {role:<7} {f}: {row['statistic']:<5} {row['relative_difference']:+.1%}")
    # which curve wheel: the study's curve/tangent ratio of the vertical force, per statistic
    study_ratio = TABLE8_BEFORE["curve"][2] / TABLE8_BEFORE["straight"][2]
    value = {(r["condition"], r["role"], r["force"], r["statistic"]): r for r in rows}
    print(f"\ncurve / tangent vertical force: study {study_ratio:.3f}; ours by wheel:")
    ratios = {}
    for role in ("outer", "inner"):
        for stat in STATS:
            ratio = (
                value[("curve", role, "Q", stat)]["seed_mean_kN"]
                / value[("straight", "leading", "Q", stat)]["seed_mean_kN"]
            )
            ratios[f"{role}_{stat}"] = ratio
        print(f"  {role:<5} " + "  ".join(f"{s} {ratios[f'{role}_{s}']:.3f}" for s in STATS))
    payload = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": platform.platform(),
        "seeds": args.seeds,
        "contact": args.contact,
        "rows": rows,
        "curve_to_tangent_Q": {"study": study_ratio, **ratios},
    }
    out = write_json(args.out, payload)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
