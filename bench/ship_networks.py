"""Make a network set to ship with railsusp (issue 19, item 5) from networks trained on
many-track campaigns: copies each condition's bundle into ``--out`` with its accuracy on its
campaign's held-out tracks and parameters (the study's Table 7 layout, scored as
bench/surrogate_tracks.py scores them), the commands that trained them (``--reproduce``, one
per line) and reference predictions (:mod:`railsusp.surrogate.pretrained`). Also writes the
accuracy table to bench/results/ship_networks.json (``--results``).

    python bench/ship_networks.py --run runs/tracks-2048-v3 --kind cnn-gru-seq-nominal-ship \\
        --source uphill=runs/tracks-8192-up:cnn-gru-seq-nominal-8k \\
        --name c80_k6 --reproduce bench/networks_c80_k6.txt --out src/railsusp/data/networks/c80_k6

Each condition's network comes from ``--run``/``--kind`` (``RUN/surrogates/KIND/<condition>/``)
unless a ``--source`` names another: ``COND=RUN:KIND`` (a network trained on another
campaign, scored on that campaign's test runs) or ``COND=SET`` (the condition's network of an
existing set of today's force-law revision, with the accuracy rows that set already holds
for it: the bundle is unchanged, so its held-out score is too, and its campaign need not be
on this machine). A network is scored only on the campaign it was trained on.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from _cli import parser, run_main
from railsusp.campaign import load_campaign
from railsusp.errors import RailsuspInputError
from railsusp.store import write_json
from railsusp.surrogate import load
from railsusp.surrogate.data import load_series
from railsusp.surrogate.evaluate import evaluate
from railsusp.surrogate.network_set import ACCURACY, MANIFEST, read_network_set
from railsusp.surrogate.pretrained import write_network_set
from railsusp.surrogate.split import own_split
from railsusp.vehicle import MODEL_REVISION


@dataclass(frozen=True)
class Source:
    """Where one condition's network comes from: a campaign's trained networks (``run`` and
    ``kind``: scored on the campaign's test runs) or an existing set (``set_folder``: its
    rows kept)."""

    bundle: Path
    run: Path | None = None
    set_folder: Path | None = None


def parse_source(text: str, conditions: list[str]) -> tuple[str, Source]:
    """``COND=SET`` (a folder holding a network set: its ``networks.json``) or
    ``COND=RUN:KIND``; refused in one line naming ``--source`` otherwise, or for a set made
    on another force-law revision (its networks and rows belong to that model) or without
    the condition."""
    cond, sep, where = text.partition("=")
    if not sep or cond not in conditions or not where:
        raise RailsuspInputError(
            f"--source {text!r}: expected COND=RUN:KIND or COND=SET with COND one of "
            f"{', '.join(conditions)}"
        )
    folder = Path(where)
    if (folder / MANIFEST).is_file():
        try:
            ns = read_network_set(folder)
        except RailsuspInputError as exc:
            raise RailsuspInputError(f"--source {text!r}: {exc}") from None
        if ns.model_revision != MODEL_REVISION:
            raise RailsuspInputError(
                f"--source {text!r}: the set was made on force-law revision "
                f"{ns.model_revision!r}, today's is {MODEL_REVISION!r}; train its networks again"
            )
        if cond not in ns.conditions:
            raise RailsuspInputError(
                f"--source {text!r}: the set holds {', '.join(ns.conditions)}, not {cond}"
            )
        return cond, Source(folder / cond, set_folder=folder)
    run, colon, kind = where.rpartition(":")
    if not (colon and run and kind and "/" not in kind):
        raise RailsuspInputError(
            f"--source {text!r}: {where} holds no {MANIFEST} (not a network set) and is not "
            "RUN:KIND"
        )
    return cond, Source(Path(run) / "surrogates" / kind / cond, run=Path(run))


def collect_sources(args: argparse.Namespace, conditions: list[str]) -> dict[str, Source]:
    """Each condition's source: its ``--source`` (one each), else ``--run``/``--kind``
    (needed exactly when some condition has no ``--source``)."""
    given: dict[str, Source] = {}
    for text in args.source:
        cond, src = parse_source(text, conditions)
        if cond in given:
            raise RailsuspInputError(f"--source {text!r}: {cond} has a --source already")
        given[cond] = src
    rest = [c for c in conditions if c not in given]
    if rest and (args.run is None or args.kind is None):
        raise RailsuspInputError(
            f"--run and --kind are needed for {', '.join(rest)} (no --source names them)"
        )
    if not rest and (args.run is not None or args.kind is not None):
        raise RailsuspInputError(
            "--run/--kind: every condition has a --source, so they would not be used"
        )
    return {
        c: given.get(c) or Source(args.run / "surrogates" / args.kind / c, run=args.run)
        for c in conditions
    }


def held_out_accuracy(run: Path, bundle: Path, condition: str) -> pd.DataFrame:
    """Table-7 rows of a condition's network on its campaign's test runs (tracks and
    parameter sets no network saw), scored from the washout on."""
    camp = load_campaign(run)
    sur = load(bundle)
    why = f"its test runs are held out of that campaign's training, not of {run}'s"
    split = own_split(sur.meta, camp, str(bundle), why)
    data = load_series(camp, condition, sur.spec)
    test = data.subset(split.positions(data.sample_ids, "test"))
    held = {"held_out": split.held_out, "test_tracks": len(np.unique(test.seeds))}
    rows = [
        {"condition": condition, "model": sur.kind, **r, **held, "first_step": sur.spec.window}
        for r in evaluate(sur, test)
    ]
    return pd.DataFrame(rows)


def kept_accuracy(set_folder: Path, condition: str) -> pd.DataFrame:
    """The rows an existing set holds for ``condition`` (refused if it holds none)."""
    table = pd.read_csv(set_folder / ACCURACY)
    rows = table[table.condition == condition]
    if rows.empty:
        raise RailsuspInputError(f"{set_folder / ACCURACY}: no accuracy rows for {condition!r}")
    return rows


def accuracy_table(sources: dict[str, Source]) -> pd.DataFrame:
    """Every condition's rows, in the set's condition order, with the campaign each was
    scored on (``scored_on``: a kept row's is its network's own campaign)."""
    parts = []
    for cond, src in sources.items():
        if src.run is not None:
            rows = held_out_accuracy(src.run, src.bundle, cond)
            rows["scored_on"] = str(src.run)
        else:
            rows = kept_accuracy(src.set_folder, cond)
            if "scored_on" not in rows or rows["scored_on"].isna().any():
                rows = rows.assign(scored_on=str(load(src.bundle).meta.get("campaign", "")))
        parts.append(rows)
    return pd.concat(parts, ignore_index=True)


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--run", type=Path, help="the many-track campaign of every other condition")
    ap.add_argument("--kind", help="folder under RUN/surrogates")
    ap.add_argument(
        "--source",
        action="append",
        default=[],
        help="COND=RUN:KIND or COND=SET: this condition's network from elsewhere (repeatable)",
    )
    ap.add_argument("--name", required=True, help="the set's name")
    ap.add_argument("--out", type=Path, required=True, help="the set's folder")
    ap.add_argument("--reproduce", type=Path, required=True, help="commands, one per line")
    ap.add_argument("--conditions", default="straight,curve,uphill")
    ap.add_argument("--description", default="")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument(
        "--results", type=Path, default=Path("bench/results/ship_networks.json"), help="JSON"
    )
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    conds = [c.strip() for c in args.conditions.split(",") if c.strip()]
    try:
        sources = collect_sources(args, conds)
        commands = [
            ln.strip() for ln in args.reproduce.read_text("utf-8").splitlines() if ln.strip()
        ]
        table = accuracy_table(sources)
        ns = write_network_set(
            {c: s.bundle for c, s in sources.items()},
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
    show = show.assign(**{c: 100 * show[c] for c in show.columns[2:]}, scored_on=table.scored_on)
    print(show.to_string(index=False))
    write_json(args.results, {"set": ns.to_json(), "accuracy": table.to_dict(orient="records")})
    print(f"wrote {args.out} and {args.results}")
    return 0


if __name__ == "__main__":
    run_main(main)
