"""A network set scored again on the simulator of today: Table 7 on a fresh many-track campaign.

A network set (``src/railsusp/data/networks/NAME``) is scored on the campaign it was trained
on. When the force laws change (a new ``railsusp.vehicle.MODEL_REVISION``), its networks no
longer describe the simulator they serve; before they are stamped with the new revision, they
are scored here on a campaign of the new model: the set's own track family and parameters
(the keys by Latin hypercube, every other main-suspension parameter varied over its range),
each run on its own track, a design seed no training campaign used, so that every run is
held out (all of them are scored, not a test split). The rows say how the networks do, and
``nominal wagon`` how much the nominal wagon's response alone explains.

``--wagon-fields before-2026-12-03.2`` makes the campaign with the wagon fields that restore
the force laws of revision 2026-12-03.1 (``FORCE_LAWS_BEFORE_2026_12_03_2``),
``before-2026-12-03.1`` those of revision 2026-12-02.1 (``FORCE_LAWS_BEFORE_2026_12_03_1``),
``before-2026-12-02.1`` those of revision 2026-11-30.2 (``FORCE_LAWS_BEFORE_2026_12_02_1``),
``before-2026-11-30.2`` those of revision 2026-11-30.1 (``FORCE_LAWS_BEFORE_2026_11_30_2``,
which includes the later switches): the same tracks and parameter sets on an earlier model,
the A/B of a change.

    python bench/rescore_networks.py --set src/railsusp/data/networks/c80_k6 \\
        --run runs/rescore-c80_k6 --samples 384 --seed 7

``--restamp NOTE`` then carries the set over to today's revision
(:func:`railsusp.surrogate.restamp.restamp_network_set`): its networks' rows join the set's
``compare.csv``, NOTE (why they serve today's simulator: the figures of this table beside
those of the model they were trained on) goes into the manifest, and the bundles take
today's wagon, whose fields may differ from the one they were trained on in the switches
of the revisions since the set's only (a set of 2026-12-03.1: ``FORCE_LAWS_BEFORE_2026_12_03_2``;
of 2026-12-02.1: ``FORCE_LAWS_BEFORE_2026_12_03_1``;
of 2026-11-30.2: ``FORCE_LAWS_BEFORE_2026_12_02_1``;
an older one: ``FORCE_LAWS_BEFORE_2026_11_30_2``, which holds every later switch too).
"""

from __future__ import annotations

import argparse
import importlib.util
import platform
import time
from pathlib import Path

import pandas as pd

from _cli import parser, run_main
from railsusp.campaign import load_campaign, run_campaign
from railsusp.campaign.twins import run_nominal_twins
from railsusp.store import write_json
from railsusp.surrogate import load
from railsusp.surrogate.network_set import read_network_set
from railsusp.vehicle import MODEL_REVISION
from railsusp.vehicle.wagon import (
    FORCE_LAWS_BEFORE_2026_11_30_2,
    FORCE_LAWS_BEFORE_2026_12_02_1,
    FORCE_LAWS_BEFORE_2026_12_03_1,
    FORCE_LAWS_BEFORE_2026_12_03_2,
    load_wagon,
)

#: the wagon fields a set of each revision may differ in from today's wagon when carried
#: over: those switched since (an older set's: every switch, FORCE_LAWS_BEFORE_2026_11_30_2)
SWITCHED_SINCE = {
    "2026-12-03.1": FORCE_LAWS_BEFORE_2026_12_03_2,
    "2026-12-02.1": FORCE_LAWS_BEFORE_2026_12_03_1,
    "2026-11-30.2": FORCE_LAWS_BEFORE_2026_12_02_1,
}

WAGON_FIELDS = {
    "today": {},
    "before-2026-12-03.2": FORCE_LAWS_BEFORE_2026_12_03_2,
    "before-2026-12-03.1": FORCE_LAWS_BEFORE_2026_12_03_1,
    "before-2026-12-02.1": FORCE_LAWS_BEFORE_2026_12_02_1,
    "before-2026-11-30.2": FORCE_LAWS_BEFORE_2026_11_30_2,
}


def _tracks_bench():
    path = Path(__file__).with_name("surrogate_tracks.py")
    spec = importlib.util.spec_from_file_location("_bench_surrogate_tracks", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--set", required=True, help="network set folder")
    ap.add_argument("--run", required=True, help="campaign run directory (made or resumed)")
    ap.add_argument("--samples", type=int, default=384)
    ap.add_argument("--seed", type=int, default=7, help="design seed (not a training one)")
    ap.add_argument("--duration", type=float, default=20.0, help="record length, s")
    ap.add_argument("--wagon-fields", choices=sorted(WAGON_FIELDS), default="today")
    ap.add_argument("--out", default="bench/results/rescore_networks.json")
    ap.add_argument("--restamp", metavar="NOTE", help="carry the set over (docstring)")
    args = ap.parse_args()
    # before the campaign, the twins and the scoring (minutes to hours): it was checked after
    if args.restamp is not None and args.wagon_fields != "today":
        ap.error(
            f"--restamp with --wagon-fields {args.wagon_fields}: accepted with the campaign "
            "of today's wagon only (--wagon-fields today)"
        )
    if args.restamp is not None and not args.restamp.strip():
        ap.error("--restamp NOTE: accepted a note that is not empty (why the set serves today)")
    ns = read_network_set(args.set)
    if args.restamp is not None:  # a set that cannot be carried over: before the campaign
        from railsusp.errors import RailsuspInputError
        from railsusp.surrogate.restamp import check_restampable

        try:
            check_restampable(ns, wagon=load_wagon(), fields=_switched_since(ns))
        except RailsuspInputError as exc:
            ap.error(f"--restamp: {exc}")
    bench = _tracks_bench()
    # the set's track family: each key from the first bundle that states it (a network
    # trained on a campaign of one condition, the straight one of stop 75, states no curve)
    family = {}
    for cond in ns.conditions:
        for key, value in (load(ns.bundle(cond)).meta.get("track_family") or {}).items():
            family.setdefault(key, value)
    cfg = bench.tracks_config(
        args.samples,
        conditions=ns.conditions,
        duration_s=args.duration,
        keys=ns.parameters,
        classes=tuple(family.get("irregularity_classes", (4, 6))),
        radius_m=tuple(family["curve_radius_m"]) if "curve_radius_m" in family else None,
        cant_mm=tuple(family["cant_mm"]) if "cant_mm" in family else None,
        seed=args.seed,
    )
    wagon = load_wagon().with_values(WAGON_FIELDS[args.wagon_fields])
    cfg = cfg.model_copy(update={"wagon": wagon}) if WAGON_FIELDS[args.wagon_fields] else cfg
    t0 = time.perf_counter()
    print(f"campaign: {cfg.n_runs} samples x {len(cfg.conditions)} conditions into {args.run}")
    run_campaign(cfg, args.run)
    run_nominal_twins(args.run, conditions=list(ns.conditions))
    simulate_s = time.perf_counter() - t0
    print(f"  campaign and nominal twins: {simulate_s:.0f} s", flush=True)
    rows = []
    camp = load_campaign(args.run)
    for cond in ns.conditions:
        sur = load(ns.bundle(cond))
        rows += bench.score_rows(camp, cond, sur, f"set {ns.name}", every_run=True)
    t7 = bench.table7_per_run(pd.DataFrame(rows))
    bench.print_table(t7, {})
    out = write_json(
        args.out,
        {
            "date": time.strftime("%Y-%m-%d"),
            "machine": platform.platform(),
            "set": str(args.set),
            "set_revision": ns.model_revision,
            "model_revision": MODEL_REVISION,
            "wagon_fields": args.wagon_fields,
            "run": str(args.run),
            "samples": args.samples,
            "seed": args.seed,
            "simulate_s": simulate_s,
            "table7": t7.to_dict(orient="records"),
        },
    )
    print(f"wrote {out}")
    if args.restamp is not None:
        restamp(args, ns, pd.DataFrame(rows))


def _switched_since(ns) -> tuple[str, ...]:
    """The wagon fields the set's networks may differ in from today's wagon (SWITCHED_SINCE)."""
    return tuple(SWITCHED_SINCE.get(ns.model_revision, FORCE_LAWS_BEFORE_2026_11_30_2))


def restamp(args: argparse.Namespace, ns, rows: pd.DataFrame) -> None:
    """Carry the set over with its networks' rows on this campaign (docstring)."""
    from railsusp.surrogate.restamp import restamp_network_set

    nets = rows[rows.model != "nominal wagon"].copy()
    nets["model"] = ns.kind
    nets["held_out"] = "tracks and parameters"
    nets["scored_on"] = (
        f"{args.run}: revision {MODEL_REVISION}, every run of design seed {args.seed}"
    )
    nets["first_step"] = [load(ns.bundle(c)).spec.window for c in nets.condition]
    out = restamp_network_set(
        args.set,
        wagon=load_wagon(),
        fields=_switched_since(ns),
        accuracy=nets,
        note=args.restamp,
    )
    print(f"{out.folder}: network set {out.name!r} stamped with revision {out.model_revision}")


if __name__ == "__main__":
    run_main(main)
