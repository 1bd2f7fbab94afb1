"""Campaign throughput: simulations (samples x conditions) per minute, local vs Dask.

Runs the same small LHS campaign (three standard conditions, full 20 s records) into fresh
run directories: locally (one process, the simulator's threads on all cores) and on a Dask
LocalCluster with 1 and 2 single-threaded worker processes. Checks that all give identical
features. Prints a table and writes JSON (bench/results/campaign.json).
"""

from __future__ import annotations

import platform
import shutil
import tempfile
import time
from pathlib import Path

from _cli import parser, positive_int, run_main
from railsusp.campaign import load_campaign, make_config, run_campaign
from railsusp.conditions import STANDARD_CONDITIONS
from railsusp.store import write_json


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--samples", type=positive_int, default=64)
    ap.add_argument("--batch-size", type=positive_int, default=16)
    ap.add_argument("--out", default="bench/results/campaign.json")
    args = ap.parse_args()
    cfg = make_config(
        list(STANDARD_CONDITIONS.values()), args.samples, batch_size=args.batch_size, seed=0
    )
    runs = cfg.n_runs * len(cfg.conditions)
    tmp = Path(tempfile.mkdtemp(prefix="railsusp-bench-"))
    warm = make_config(list(STANDARD_CONDITIONS.values())[:1], 2, batch_size=2)
    run_campaign(warm, tmp / "warm")  # compile the kernels (cached for the workers too)
    rows, ref = [], None
    for label, kw in (
        ("local", {}),
        ("dask 1 worker", {"workers": 1}),
        ("dask 2 workers", {"workers": 2}),
    ):
        out = tmp / label.replace(" ", "-")
        t0 = time.perf_counter()
        run_campaign(cfg, out, **kw)
        wall = time.perf_counter() - t0
        feats = (
            load_campaign(out)
            .features()
            .sort_values(["condition", "quantity", "statistic", "sample_id"])
            .reset_index(drop=True)
        )
        same = True if ref is None else feats.equals(ref)
        ref = feats if ref is None else ref
        rows.append(
            {
                "mode": label,
                "runs": runs,
                "wall_s": wall,
                "runs_per_minute": 60.0 * runs / wall,
                "identical_to_local": same,
            }
        )
    shutil.rmtree(tmp, ignore_errors=True)
    print(f"{runs} simulations ({args.samples} samples x 3 conditions, 26 s each)")
    print(f"{'mode':<16} {'wall s':>8} {'runs/min':>9} {'identical':>10}")
    for r in rows:
        print(
            f"{r['mode']:<16} {r['wall_s']:8.1f} {r['runs_per_minute']:9.0f} "
            f"{r['identical_to_local']!s:>10}"
        )
    payload = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": platform.platform(),
        "samples": args.samples,
        "rows": rows,
    }
    out = write_json(args.out, payload)
    print(f"wrote {out}")


if __name__ == "__main__":
    run_main(main)
