"""Simulation-based posterior: coverage on held-out simulations and posterior width against
record length (issue 20). Prints two tables and writes JSON.

    python bench/posterior.py                 # small scale, bench/results/posterior.json
    python bench/posterior.py --train 10000 --check 200 --section 20 \\
        --conditions straight,curve --lengths 20,60,120,600 --sets 12  # the issue's scale

1. Trains (or resumes, ``--run``) the estimator: ``--train`` cases drawn from the Table 2
   prior, a new track realisation each, ``--section`` seconds per condition; its coverage
   and SBC check run on ``--check`` held-out cases (railsusp.estimate.calibration).
2. Draws ``--sets`` parameter sets in the middle 80 % of the ranges, simulates each on a
   fresh track for the longest of ``--lengths`` seconds, makes synthetic recordings of
   them (instrument noise as ``railsusp synth-field``), and estimates each from its first
   L seconds for every L: the median width of the 90 % intervals (% of range), how many
   truths they hold, and how many medians lie within 5 % of range of the truth.

Throughput of the simulator is measured on the way, and the cost of the issue's targets
is extrapolated from it (printed and in the JSON).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from railsusp.conditions import resolve_conditions
from railsusp.estimate import posterior
from railsusp.estimate.posterior_data import PosteriorSettings, to_si
from railsusp.measured import add_sensor_noise, recording_from_simulation
from railsusp.params import MAIN_SUSPENSION
from railsusp.vehicle.simulate import simulate_batch


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", default="bench/results/posterior_run", help="run directory (cache)")
    ap.add_argument("--out", default="bench/results/posterior.json")
    ap.add_argument("--conditions", default="straight")
    ap.add_argument("--parameters", default=",".join(MAIN_SUSPENSION))
    ap.add_argument("--section", type=float, default=5.0)
    ap.add_argument("--lead-in", type=float, default=30.0)
    ap.add_argument("--train", type=int, default=600)
    ap.add_argument("--check", type=int, default=100)
    ap.add_argument("--lengths", default="5,10,20,40")
    ap.add_argument("--sets", type=int, default=12)
    ap.add_argument("--hidden", type=int, default=50, help="flow: hidden features")
    ap.add_argument("--transforms", type=int, default=5, help="flow: number of transforms")
    a = ap.parse_args()

    conds = [c.with_changes(lead_in_m=a.lead_in) for c in resolve_conditions(a.conditions)]
    settings = PosteriorSettings(
        tuple(conds),
        parameters=tuple(a.parameters.split(",")),
        section_s=a.section,
        n_train=a.train,
        n_check=a.check,
        hidden_features=a.hidden,
        num_transforms=a.transforms,
    )
    t0 = time.perf_counter()
    est = posterior.train(settings, a.run)
    t_train = time.perf_counter() - t0
    print(f"\ntrain + check: {t_train:.0f} s (cached parts are read, not redone)")
    print(f"{'parameter':>9} {'coverage90':>10} {'p(cov)':>8} {'p(SBC)':>8} {'passed':>6}")
    for c in est.calibration:
        print(
            f"{c.parameter:>9} {c.coverage:10.3f} {c.coverage_p:8.3f} {c.sbc_p:8.3f} "
            f"{'yes' if c.passed else 'NO':>6}"
        )

    lengths = [float(v) for v in a.lengths.split(",")]
    rng = np.random.default_rng(2026)
    u = 0.1 + 0.8 * rng.random((a.sets, len(MAIN_SUSPENSION)))
    theta = to_si(u)
    cols = [MAIN_SUSPENSION.index(p) for p in settings.parameters]
    wagon_s, t_sim = 0.0, 0.0
    results = {c.name: [] for c in conds}
    for k, cond in enumerate(settings.conditions):
        long = cond.with_duration(max(lengths))
        t1 = time.perf_counter()
        res = simulate_batch(
            theta,
            long,
            symbols=MAIN_SUSPENSION,
            seeds=[5_000_000 + 100 * i + k for i in range(a.sets)],
        )
        t_sim += time.perf_counter() - t1
        wagon_s += a.sets * (max(lengths) + cond.lead_in_m / cond.speed)
        for i in range(a.sets):
            rec = recording_from_simulation(res, set_index=i) if res.ok[i] else None
            results[cond.name].append(None if rec is None else add_sensor_noise(rec, 0.03, i))
    rows = []
    t_est = []
    for length in lengths:
        widths, inside, close = [], [], []
        for i in range(a.sets):
            recs = [results[c.name][i] for c in conds]
            if any(r is None for r in recs):
                continue
            n = round(length / settings.conditions[0].sample_interval)
            cut = [_first(r, n) for r in recs]
            t1 = time.perf_counter()
            r = posterior.estimate(est, cut, seed=i)
            t_est.append(time.perf_counter() - t1)
            df = r.to_dataframe()
            lo, hi = (to_si(np.zeros((1, 10)))[0, cols], to_si(np.ones((1, 10)))[0, cols])
            q = np.quantile(r.samples, [0.05, 0.5, 0.95], axis=0)
            truth = theta[i, cols]
            widths.append(df["width_pct_range"].to_numpy())
            inside.append((truth >= q[0]) & (truth <= q[2]))
            close.append(np.abs(q[1] - truth) <= 0.05 * (hi - lo))
        rows.append(
            {
                "length_s": length,
                "sections": int(length // settings.section_s),
                "cases": len(widths),
                "median_width_pct": dict(
                    zip(
                        settings.parameters,
                        np.median(widths, axis=0).round(1).tolist(),
                        strict=True,
                    )
                ),
                "truth_inside_90": dict(
                    zip(settings.parameters, np.mean(inside, axis=0).round(3).tolist(), strict=True)
                ),
                "median_within_5pct": float(np.mean(close)),
            }
        )
    print("\nmedian 90 % interval width, % of range, against record length per condition")
    print(
        f"{'length s':>8} {'sec.':>4} "
        + " ".join(f"{p:>5}" for p in settings.parameters)
        + "  inside90  within5%"
    )
    for row in rows:
        ins = np.mean(list(row["truth_inside_90"].values()))
        print(
            f"{row['length_s']:8g} {row['sections']:4d} "
            + " ".join(f"{w:5.0f}" for w in row["median_width_pct"].values())
            + f"  {ins:8.2f}  {row['median_within_5pct']:8.2f}"
        )
    rate = wagon_s / t_sim
    n_cond = len(conds)
    lead = conds[0].lead_in_m / conds[0].speed
    full = {  # the targets, at this machine's measured throughput
        "training_10000_cases_20s": 10000 * n_cond * (20 + lead) / rate,
        "heldout_200_cases_120s": 200 * n_cond * (120 + lead) / rate,
        "sets_12_of_600s": 12 * n_cond * (600 + lead) / rate,
    }
    print(
        f"\nsimulator: {rate:.0f} wagon-s per wall-s here; the issue's scale would take "
        + ", ".join(f"{k} {v / 60:.0f} min" for k, v in full.items())
    )
    print(f"estimate of one recording: median {np.median(t_est):.1f} s, max {max(t_est):.1f} s")
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "settings": settings.to_dict(),
        "train_and_check_s": t_train,
        "calibration": [c.to_dict() for c in est.calibration],
        "width_against_length": rows,
        "wagon_s_per_wall_s": rate,
        "issue_scale_estimated_s": full,
        "estimate_s_median": float(np.median(t_est)),
    }
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {a.out}")


def _first(rec, n):
    """The recording's first ``n`` samples (a shorter recording of the same run)."""
    from railsusp.measured import Recording

    return Recording(
        rec.time[:n],
        {w: v[:n] for w, v in rec.Y.items()},
        {w: v[:n] for w, v in rec.Q.items()},
        rec.condition,
        rec.meta,
    )


if __name__ == "__main__":
    main()
