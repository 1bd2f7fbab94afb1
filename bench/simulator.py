"""Simulator throughput: simulated wagon-seconds per wall-second for N = 1, 16, 256 sets.

Each set runs the standard straight condition (100 m lead-in plus the 20 s record, 26 s of
simulated running in all) in one batched call; the compiled kernels are warmed up first so
the figures exclude compilation. Prints a table and writes JSON (bench/results/simulator.json).
Peak memory is the process's maximum resident set size.

In the same sitting, for ratios (these machines are noisy, so only ratios from one run are
quoted): ``--reference-src DIR`` runs this script on another checkout's ``src`` (e.g. a git
worktree of an older commit) and ``--kernel FILE`` runs the synthetic wagon-sized RK4 kernel
(shared/bench/throughput_kernel.py) at railsusp's 1 ms step (10 s per set);
the table then gains their rates and this model's ratio to each. ``--rounds R`` measures
the three in turn R times and gives the medians (of the per-round ratios) and each round's
ratios. The comparisons run before this model's benchmark, after their paths are checked
(a missing ``--kernel`` or a ``--reference-src`` without railsusp is refused before any
work), so that a failing one loses no measurement.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np

from _cli import fail, number_list, parser, positive_int, run_main
from railsusp.conditions import get_condition
from railsusp.params import MAIN_SUSPENSION, ParameterSet, bounds
from railsusp.store import write_json
from railsusp.vehicle.setup import SolverSettings
from railsusp.vehicle.simulate import simulate_batch
from railsusp.vehicle.wagon import load_wagon
from reference_run import reference_rows, reference_src


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument(
        "--sizes", type=number_list(positive_int), default="1,16,256", help="batch sizes"
    )
    ap.add_argument("--condition", default="straight")
    ap.add_argument("--contact", default="two-point", help="two-point or single-point")
    ap.add_argument("--flange-substeps", type=positive_int, default=None, help="solver step split")
    ap.add_argument("--out", default="bench/results/simulator.json")
    ap.add_argument("--reference-src", default=None, help="another checkout's src, for A/B")
    ap.add_argument("--kernel", default=None, help="path of throughput_kernel.py")
    ap.add_argument(
        "--rounds",
        type=positive_int,
        default=1,
        help="reference, kernel and this model measured in turn this many times; the "
        "table gives the medians (the kernel's own rate moves by up to 15 %% between runs)",
    )
    ap.add_argument(
        "--physics-before-2026-11-24",
        action="store_true",
        help="this code on the model of before 2026-11-24's fidelity changes (the same model "
        "as commit 328b8dd, for a same-model A/B with --reference-src)",
    )
    args = ap.parse_args()
    if args.kernel is not None and not Path(args.kernel).is_file():
        fail(
            f"--kernel {args.kernel}: no such file; accepted the path of the synthetic kernel "
            "(shared/bench/throughput_kernel.py)"
        )
    if args.reference_src:
        reference_src(args.reference_src)  # checked before any run
    cond = get_condition(args.condition)
    wagon = load_wagon().with_contact_model(args.contact)
    if args.physics_before_2026_11_24:
        wagon = wagon.with_physics_before_2026_11_24()
    settings = SolverSettings()
    if args.flange_substeps is not None:
        settings = SolverSettings(flange_substeps=args.flange_substeps)
    sizes = ",".join(str(n) for n in args.sizes)
    simulated = cond.lead_in_m / cond.speed + cond.duration_s
    rounds = []
    for k in range(args.rounds):
        # the comparisons first: one that fails loses no measurement of this model
        reference = _reference_rates(args) if args.reference_src else None
        kernel = _kernel_rates(args.kernel, sizes) if args.kernel else None
        if k == 0:
            simulate_batch(
                [ParameterSet.nominal()],
                get_condition(args.condition, duration_s=1.0, n_steps=50),
                wagon=wagon,
                settings=settings,
            )  # compile
        rounds.append(_model_rows(args.sizes, cond, wagon, settings, simulated))
        for row in rounds[-1]:
            if reference is not None:
                row["reference_wagon_s_per_wall_s"] = reference[row["sets"]]
                row["ratio_to_reference"] = row["wagon_s_per_wall_s"] / reference[row["sets"]]
            if kernel is not None:
                row["kernel_wagon_s_per_wall_s"] = kernel[row["sets"]]
                row["ratio_to_kernel"] = row["wagon_s_per_wall_s"] / kernel[row["sets"]]
    rows = _medians(rounds)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(
        f"condition {cond.name}: {simulated:.1f} s simulated per set "
        f"({cond.duration_s:g} s recorded), {numba.get_num_threads()} threads, "
        f"{args.contact} contact, flange_substeps {settings.flange_substeps}"
    )
    head = f"{'sets':>6} {'wall s':>8} {'wagon-s/s':>10} {'record-s/s':>11} {'failed':>7}"
    if reference is not None:
        head += f" {'reference':>10} {'ratio':>6}"
    if kernel is not None:
        head += f" {'kernel':>8} {'of kernel':>9}"
    print(head)
    for row in rows:
        line = (
            f"{row['sets']:>6} {row['wall_s']:8.2f} {row['wagon_s_per_wall_s']:10.1f} "
            f"{row['record_s_per_wall_s']:11.1f} {row['failed']:>7}"
        )
        if reference is not None:
            line += f" {row['reference_wagon_s_per_wall_s']:10.1f} {row['ratio_to_reference']:6.2f}"
        if kernel is not None:
            line += f" {row['kernel_wagon_s_per_wall_s']:8.1f} {row['ratio_to_kernel']:9.2f}"
        print(line)
    if args.rounds > 1:
        for name in ("ratio_to_reference", "ratio_to_kernel"):
            for row in rows:
                if name in row:
                    each = ", ".join(f"{r[name]:.2f}" for r in row["rounds"])
                    print(f"{row['sets']:>6} sets, {name} per round: {each}")
    print(f"peak memory {peak_mb:.0f} MB")
    payload = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": platform.platform(),
        "cpus": os.cpu_count(),
        "threads": numba.get_num_threads(),
        "condition": cond.name,
        "contact": args.contact,
        "physics_before_2026_11_24": args.physics_before_2026_11_24,
        "flange_substeps": settings.flange_substeps,
        "rounds": args.rounds,
        "rows": rows,
        "peak_rss_mb": peak_mb,
        "reference_src": args.reference_src,
        "kernel": args.kernel,
    }
    out = write_json(args.out, payload)
    print(f"wrote {out}")


def _model_rows(sizes, cond, wagon, settings, simulated: float) -> list[dict]:
    """This model's rate per batch size: random main-suspension sets (seed 0, the same in
    every round) in one batched call each."""
    rng = np.random.default_rng(0)
    lo, hi = bounds(MAIN_SUSPENSION)
    rows = []
    for n in sizes:
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
    return rows


def _medians(rounds: list[list[dict]]) -> list[dict]:
    """Per batch size, the median over rounds of every figure (each round's ratios are of
    rates measured minutes apart; the median of the ratios, not a ratio of medians), with
    the rounds themselves under ``rounds``."""
    rows = []
    for i, first in enumerate(rounds[0]):
        each = [r[i] for r in rounds]
        row = {key: float(np.median([e[key] for e in each])) for key in first if key != "sets"}
        row["failed"] = max(e["failed"] for e in each)
        rows.append({"sets": first["sets"], **row, "rounds": each})
    return rows


def _reference_rates(args: argparse.Namespace) -> dict[int, float]:
    """Wagon-s per wall-s of this script run on ``args.reference_src``, per batch size."""
    sizes = ",".join(str(n) for n in args.sizes)
    argv = ["--sizes", sizes, "--condition", args.condition, "--contact", args.contact]
    if args.flange_substeps is not None:
        argv += ["--flange-substeps", str(args.flange_substeps)]
    rows = reference_rows(__file__, argv, args.reference_src)
    return {r["sets"]: r["wagon_s_per_wall_s"] for r in rows}


#: simulated seconds per set of the synthetic kernel: its random ODE fails (an exception in
#: its compiled loop) in runs of 26 s at the 1 ms step for 16 sets and more, and its rate
#: per wagon-second does not depend on the length (1841 and 1781 wagon-s/s at 5 and 10 s)
KERNEL_SECONDS = 10.0


def _kernel_rates(kernel: str, sizes: str) -> dict[int, float]:
    """Wagon-s per wall-s of the synthetic kernel at a 1 ms step, per batch size."""
    cmd = [sys.executable, kernel, "1e-3", sizes, f"{KERNEL_SECONDS:g}"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise SystemExit(f"--kernel {kernel}: the kernel failed (exit {done.returncode}): {last}")
    text = done.stdout
    found = re.findall(r"B=(\d+) dt=[^:]*: ([0-9.]+) wagon-s per wall-s", text)
    if not found:
        raise SystemExit(f"--kernel {kernel}: no 'B=... wagon-s per wall-s' line in its output")
    return {int(b): float(r) for b, r in found}


if __name__ == "__main__":
    run_main(main)
