"""Time the estimate stage of a finished run (e.g. ``railsusp demo``'s runs/demo) on a copy.

Copies the run directory to a temporary folder, reruns its estimate stage there (campaign,
sensitivity and surrogate must be up to date; field, validate and report may run too) and
reports where the time went: NSGA-II on the surrogates, the screening of refinement starts, the
refinements, the geometry-error draws, and every simulator call (condition, parameter sets,
wall time). Prints a table and writes JSON (bench/results/estimate_stage.json).

    python bench/estimate_stage.py --run runs/demo [--config examples/quick.toml]
"""

from __future__ import annotations

import platform
import shutil
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from _cli import fail, parser, run_main
from railsusp.pipeline import demo_config, load_config, run_pipeline
from railsusp.store import write_json


def _timed(calls: list[dict], owner, name: str, phase: str):
    """Replace ``owner.name`` by a wrapper appending its wall time under ``phase``."""
    inner = getattr(owner, name)

    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            calls.append({"phase": phase, "seconds": time.perf_counter() - t0})

    setattr(owner, name, wrapper)


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--run", default="runs/demo", help="finished run directory (left untouched)")
    ap.add_argument("--config", help="its pipeline TOML (default: the embedded demo)")
    ap.add_argument("--out", default="bench/results/estimate_stage.json")
    args = ap.parse_args()
    if not (Path(args.run) / "pipeline.json").is_file():
        fail(f"--run {args.run}: no pipeline.json in it; accepted a finished run directory")
    config = load_config(args.config) if args.config else demo_config()

    import railsusp.estimate.polish as polish
    import railsusp.estimate.refine as refine
    import railsusp.estimate.route as route  # the stage's steps call NSGA-II from there
    import railsusp.vehicle.simulate as simulate

    phases: list[dict] = []
    sims: list[dict] = []
    inner = simulate._simulate_full  # simulate_batch, _conditions and _requests all call it

    def simulate_full(prepared, *args, **kwargs):
        t0 = time.perf_counter()
        runs = inner(prepared, *args, **kwargs)
        sims.append(
            {
                "conditions": [c.name for _, c, _ in prepared],
                "sets": int(sum(r.n_sets for r in runs)),
                "simulated_s": float(sum(r.n_sets * r.time[-1] for r in runs)),
                "seconds": time.perf_counter() - t0,
            }
        )
        return runs

    simulate._simulate_full = simulate_full
    _timed(phases, route, "estimate_with_seeds", "NSGA-II on the surrogates")
    _timed(phases, polish, "aligned_cost", "screening of starts")
    for name in ("refine", "refine_starts"):  # one start at a time, or all at once
        if hasattr(polish, name):
            _timed(phases, polish, name, "refinements")
    _timed(phases, refine.OutputError, "geometry_shifts", "geometry-error draws")

    def refuse_upstream(stage: str, message: str) -> None:
        # the field stage (about a second) may rerun after a change of its defaults
        if stage in ("campaign", "sensitivity", "surrogate") and message != "up to date":
            raise SystemExit(f"{args.run}: stage {stage} is not up to date for this config")

    work = Path(tempfile.mkdtemp(prefix="railsusp-estimate-"))
    try:
        shutil.copytree(args.run, work / "run")
        state = run_pipeline(config, work / "run", start_from="estimate", progress=refuse_upstream)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    stage_s = state["stages"]["estimate"]["seconds"]

    by_phase: dict[str, float] = defaultdict(float)
    for p in phases:
        by_phase[p["phase"]] += p["seconds"]
    sizes: dict[int, list[float]] = defaultdict(list)
    for s in sims:
        sizes[s["sets"]].append(s["seconds"])
    print(f"estimate stage: {stage_s:.1f} s")
    for name, seconds in by_phase.items():
        print(f"  {name:<28}{seconds:8.1f} s")
    sim_s = sum(s["seconds"] for s in sims)
    wagon_s = sum(s["simulated_s"] for s in sims)
    print(
        f"simulator: {len(sims)} calls, {sum(s['sets'] for s in sims)} sets, "
        f"{wagon_s:.0f} wagon-s simulated in {sim_s:.1f} s ({wagon_s / max(sim_s, 1e-9):.1f}/s)"
    )
    print(f"{'sets per call':>14}{'calls':>8}{'seconds':>10}{'s per call':>12}")
    for n in sorted(sizes):
        t = sizes[n]
        print(f"{n:>14}{len(t):>8}{sum(t):>10.1f}{sum(t) / len(t):>12.2f}")
    out = write_json(
        args.out,
        {
            "date": time.strftime("%Y-%m-%d %H:%M"),
            "machine": platform.platform(),
            "estimate_stage_s": stage_s,
            "phases_s": dict(by_phase),
            "simulator_calls": sims,
        },
    )
    print(f"wrote {out}")


if __name__ == "__main__":
    run_main(main)
