"""Make a network set to ship with railsusp (issue 19, item 5) from networks trained on a
many-track campaign: copies ``RUN/surrogates/KIND/<condition>/`` into ``--out`` with their
accuracy on the campaign's held-out tracks and parameters (the study's Table 7 layout,
scored as bench/surrogate_tracks.py scores them), the commands that trained them
(``--reproduce``, one per line) and reference predictions (:mod:`railsusp.surrogate.pretrained`).
Also writes the accuracy table to bench/results/ship_networks.json.

    python bench/ship_networks.py --run runs/tracks-2048-v3 --kind cnn-gru-seq-nominal-ship \\
        --name c80_k6 --reproduce bench/networks_c80_k6.txt --out src/railsusp/data/networks/c80_k6
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from railsusp.campaign import load_campaign
from railsusp.errors import RailsuspInputError
from railsusp.store import write_json
from railsusp.surrogate import load
from railsusp.surrogate.data import load_series
from railsusp.surrogate.evaluate import evaluate
from railsusp.surrogate.pretrained import write_network_set
from railsusp.surrogate.split import campaign_split


def held_out_accuracy(run: Path, folder: Path, conditions: list[str]) -> pd.DataFrame:
    """Table-7 rows of each condition's network on the campaign's test runs (tracks and
    parameter sets no network saw), scored from the washout on."""
    camp = load_campaign(run)
    rows = []
    for cond in conditions:
        sur = load(folder / cond)
        data = load_series(camp, cond, sur.spec)
        split = campaign_split(camp, int(sur.meta.get("split", {}).get("seed", 0)))
        test = data.subset(split.positions(data.sample_ids, "test"))
        held = {"held_out": split.held_out, "test_tracks": len(np.unique(test.seeds))}
        for r in evaluate(sur, test):
            rows.append(
                {"condition": cond, "model": sur.kind, **r, **held, "first_step": sur.spec.window}
            )
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", type=Path, required=True, help="the many-track campaign")
    ap.add_argument("--kind", required=True, help="folder under RUN/surrogates")
    ap.add_argument("--name", required=True, help="the set's name")
    ap.add_argument("--out", type=Path, required=True, help="the set's folder")
    ap.add_argument("--reproduce", type=Path, required=True, help="commands, one per line")
    ap.add_argument("--conditions", default="straight,curve,uphill")
    ap.add_argument("--description", default="")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    conds = [c.strip() for c in args.conditions.split(",") if c.strip()]
    folder = args.run / "surrogates" / args.kind
    try:
        commands = [
            ln.strip() for ln in args.reproduce.read_text("utf-8").splitlines() if ln.strip()
        ]
        table = held_out_accuracy(args.run, folder, conds)
        ns = write_network_set(
            folder,
            args.out,
            name=args.name,
            conditions=conds,
            accuracy=table,
            reproduce=commands,
            description=args.description,
        )
    except (OSError, RailsuspInputError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    show = table[["condition", "target", "relative_error_of_mean", "relative_error_of_mean_max"]]
    print(show.assign(**{c: 100 * show[c] for c in show.columns[2:]}).to_string(index=False))
    out = Path("bench/results/ship_networks.json")
    write_json(out, {"set": ns.to_json(), "accuracy": table.to_dict(orient="records")})
    print(f"wrote {args.out} and {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
