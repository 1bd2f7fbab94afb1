"""Pipeline stage timings: the quick configuration (and optionally another one), from a clean
run directory. Prints a table and writes JSON (bench/results/pipeline.json)."""

from __future__ import annotations

import platform
import shutil
import tempfile
import time
from pathlib import Path

from _cli import parser, run_main
from railsusp.pipeline import STAGES, demo_config, load_config, run_pipeline
from railsusp.store import write_json


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument(
        "--config",
        action="append",
        default=[],
        help="extra pipeline TOML to time (e.g. examples/study.toml)",
    )
    ap.add_argument("--out", default="bench/results/pipeline.json")
    args = ap.parse_args()
    configs = [("quick (embedded demo)", demo_config())]
    configs += [(c, load_config(c)) for c in args.config]
    results = []
    for label, cfg in configs:
        work = Path(tempfile.mkdtemp(prefix="railsusp-pipeline-"))
        t0 = time.perf_counter()
        state = run_pipeline(cfg, work / "run")
        total = time.perf_counter() - t0
        results.append(
            {
                "config": label,
                "total_s": total,
                "stages": {s: state["stages"][s].get("seconds") for s in STAGES},
            }
        )
        shutil.rmtree(work, ignore_errors=True)
    print(f"{'stage':<12}" + "".join(f"{r['config'][:24]:>26}" for r in results))
    for s in STAGES:
        print(f"{s:<12}" + "".join(f"{r['stages'][s]:26.1f}" for r in results))
    print(f"{'total':<12}" + "".join(f"{r['total_s']:26.1f}" for r in results))
    out = write_json(
        args.out,
        {"date": time.strftime("%Y-%m-%d"), "machine": platform.platform(), "results": results},
    )
    print(f"wrote {out}")


if __name__ == "__main__":
    run_main(main)
