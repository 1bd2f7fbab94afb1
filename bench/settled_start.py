"""Settled start against the lead-in: simulated seconds, time per set and record agreement.

Runs N parameter sets (the ten main suspension parameters drawn uniformly in their
catalogue bounds, one track seed each) in the tangent and curve conditions twice: from the
settled state a ``run_in_m`` ahead of the record, and after the whole lead-in. Prints per
condition the wall and CPU time per set (the batch's CPU time over all threads, steadier on
a shared machine; the fastest of ``--repeat`` alternating runs, the settled one with
its steady-state solve), and the largest relative difference over the sets of the measured
wheel's record statistics (mean, RMS, p99, max of |Y| and Q, and p99.85, EN 14363's
percentile); also over the record after its first 5 s. Writes JSON
(bench/results/settled_start.json).
"""

from __future__ import annotations

import time

import numpy as np

from _cli import parser, positive_int, run_main
from railsusp.conditions import get_condition
from railsusp.params import MAIN_SUSPENSION, spec
from railsusp.store import write_json
from railsusp.vehicle.settle import clear_cache
from railsusp.vehicle.simulate import SolverSettings, simulate_batch
from railsusp.vehicle.wagon import load_wagon

STATISTICS = {
    "mean": lambda v: v.mean(axis=-1),
    "rms": lambda v: np.sqrt((v * v).mean(axis=-1)),
    "p99": lambda v: np.percentile(v, 99, axis=-1),
    "p99.85": lambda v: np.percentile(v, 99.85, axis=-1),
    "max": lambda v: v.max(axis=-1),
}


def record_stats(r, after_s: float) -> dict[str, np.ndarray]:
    """Statistics of |Y| and Q of the measured wheel of every set, from ``after_s`` on."""
    j = r.measured_wheel()
    keep = r.time >= after_s
    out = {}
    for name, arr in (("Y", np.abs(r.Y[:, j, keep])), ("Q", r.Q[:, j, keep])):
        for st, fn in STATISTICS.items():
            out[f"{name}_{st}"] = fn(arr)
    return out


def timed(sets, cond, seeds, settings, wagon):
    """The batch's result, wall time and process CPU time."""
    w0, c0 = time.perf_counter(), time.process_time()
    r = simulate_batch(
        sets, cond, symbols=MAIN_SUSPENSION, seeds=seeds, settings=settings, wagon=wagon
    )
    return r, time.perf_counter() - w0, time.process_time() - c0


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--sets", type=positive_int, default=8)
    ap.add_argument("--run-in", type=float, default=SolverSettings().run_in_m)
    ap.add_argument("--wagon", default="loaded", help="packaged wagon: loaded or tare")
    ap.add_argument(
        "--repeat", type=positive_int, default=3, help="timed runs of each start (min kept)"
    )
    ap.add_argument("--out", default="bench/results/settled_start.json")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    lo = np.array([spec(s).bounds[0] for s in MAIN_SUSPENSION])
    hi = np.array([spec(s).bounds[1] for s in MAIN_SUSPENSION])
    sets = lo + (hi - lo) * rng.uniform(size=(args.sets, len(MAIN_SUSPENSION)))
    seeds = list(range(100, 100 + args.sets))
    lead_in = SolverSettings(start="lead-in")
    settled = SolverSettings(start="settled", run_in_m=args.run_in)
    wagon = load_wagon(args.wagon)
    results = {}
    print(f"{args.sets} sets, wagon {args.wagon}, run-in {args.run_in:g} m")
    for name in ("straight", "curve"):
        cond = get_condition(name)
        timed(sets[:2], cond, seeds[:2], settled, wagon)  # compile / load the kernels
        wall_a = cpu_a = wall_b = cpu_b = np.inf
        for _ in range(args.repeat):  # alternating, the fastest of each kept
            a, w, c = timed(sets, cond, seeds, lead_in, wagon)
            wall_a, cpu_a = min(wall_a, w), min(cpu_a, c)
            clear_cache()  # time the settled states' solve too
            b, w, c = timed(sets, cond, seeds, settled, wagon)
            wall_b, cpu_b = min(wall_b, w), min(cpu_b, c)
        sim_a = cond.lead_in_m / cond.speed + cond.duration_s
        sim_b = (args.run_in / cond.speed + cond.duration_s) if b.settled_start.all() else sim_a
        row = {
            "settled_sets": int(b.settled_start.sum()),
            "simulated_s_per_set": {"lead-in": sim_a, "settled": sim_b},
            "wall_s_per_set": {"lead-in": wall_a / args.sets, "settled": wall_b / args.sets},
            "cpu_s_per_set": {"lead-in": cpu_a / args.sets, "settled": cpu_b / args.sets},
        }
        for after in (0.0, 5.0):
            sa, sb = record_stats(a, after), record_stats(b, after)
            row[f"max_rel_diff_from_{after:g}s"] = {
                k: float(np.max(np.abs(sb[k] / sa[k] - 1.0))) for k in sa
            }
        results[name] = row
        print(
            f"\n{name}: {row['settled_sets']}/{args.sets} settled; simulated s/set "
            f"{sim_a:.1f} -> {sim_b:.1f}; wall s/set {wall_a / args.sets:.3f} -> "
            f"{wall_b / args.sets:.3f}; CPU s/set {cpu_a / args.sets:.3f} -> "
            f"{cpu_b / args.sets:.3f}"
        )
        print(f"{'statistic':>10} {'whole record':>13} {'after 5 s':>10}")
        for k in row["max_rel_diff_from_0s"]:
            whole, late = row["max_rel_diff_from_0s"][k], row["max_rel_diff_from_5s"][k]
            print(f"{k:>10} {whole:>12.2%} {late:>10.2%}")
    summary = {"sets": args.sets, "wagon": args.wagon, "run_in_m": args.run_in}
    print(f"wrote {write_json(args.out, {**summary, 'conditions': results})}")


if __name__ == "__main__":
    run_main(main)
