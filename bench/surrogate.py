"""Surrogate benchmark: accuracy on held-out runs (Table 7 layout), training time,
prediction throughput (windows per second, batched). Writes bench/results/surrogate.json.

Needs a campaign run directory (``--run``, e.g. ``railsusp campaign --samples 256 --out RUN``);
all models are trained on the campaign's stored 70/15/15 split (by track and parameter set,
``RUN/splits/seed-0.json``; on a many-track campaign the test runs hold tracks no network saw:
bench/surrogate_tracks.py makes such a campaign and prints its table).
``--throughput-only`` needs no campaign: it times randomly initialised default-size networks
on 64 series x 980 windows (bench/results/surrogate_throughput.json), and the prediction of
one NSGA-II generation (50 parameter sets x 3000 steps, a 60 s record at 50 Hz). For the
sequence CNN-GRU (``cnn-gru-seq``) a "window" is a predicted step (after its washout).
Throughput is the fast whole-series path (``Surrogate.predict``), plus the per-window reference path
(``fast=False``) for the CNN-GRU, with ``--threads`` torch threads (2), best of
``--repeats`` calls (3).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
import torch

from _cli import parser, positive_int, run_main
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.params import bounds
from railsusp.store import write_json
from railsusp.surrogate import TrainConfig, load
from railsusp.surrogate.bundle import Surrogate
from railsusp.surrogate.compare import ALL_MODELS, compare, table7
from railsusp.surrogate.data import Normaliser
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.models import NetConfig, build_network, default_window
from railsusp.surrogate.recurrence import torch_threads
from railsusp.vehicle.wagon import load_wagon

NETWORKS = ("cnn-gru", "cnn-lstm", "cnn-bilstm", "bp", "cnn-gru-seq")
KEYS = ("X11", "X12", "X13", "X14", "X17", "X18")


def _random_sets(sur: Surrogate, n_sets: int) -> np.ndarray:
    """``n_sets`` parameter sets drawn (seeded) uniformly over the surrogate's key ranges."""
    lo, hi = bounds(sur.spec.parameters)
    return lo + (hi - lo) * np.random.default_rng(0).random((n_sets, len(lo)))


def _best_predict(
    sur: Surrogate, x: np.ndarray, track: np.ndarray | None, repeats: int, fast: bool = True
) -> tuple[float, np.ndarray]:
    """(best seconds, last output) of ``sur.predict(x, track=track)`` over ``repeats`` calls
    after a warm-up on two sets (at most 400 steps of ``track``)."""
    sur.predict(x[:2], track=None if track is None else track[:400], fast=fast)  # warm-up
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = sur.predict(x, track=track, fast=fast)
        best = min(best, time.perf_counter() - t0)
    return float(best), out


def _rate(
    sur: Surrogate, n_sets: int, repeats: int, fast: bool, track: np.ndarray | None = None
) -> float:
    """Windows per second of ``sur.predict`` on ``n_sets`` parameter sets, best of
    ``repeats`` calls after a warm-up."""
    best, out = _best_predict(sur, _random_sets(sur, n_sets), track, repeats, fast)
    return float(np.isfinite(out[:, :, 0]).sum() / best)


def generation_seconds(
    sur: Surrogate, n_sets: int = 50, n_steps: int = 3000, repeats: int = 3
) -> float:
    """Seconds of ``sur.predict`` for one NSGA-II generation: ``n_sets`` parameter sets on
    one ``n_steps``-step track (random features), best of ``repeats`` after a warm-up."""
    n_track = sur.spec.n_features - len(sur.spec.parameters)
    track = np.random.default_rng(2).normal(size=(n_steps, n_track))
    return _best_predict(sur, _random_sets(sur, n_sets), track, repeats)[0]


def throughput(path, n_sets: int = 64, repeats: int = 3, fast: bool = True) -> float:
    """Windows predicted per second by a saved surrogate, batched over parameter sets."""
    return _rate(load(path), n_sets, repeats, fast)


def random_surrogate(kind: str, n_steps: int = 1000, seed: int = 0) -> Surrogate:
    """A surrogate bundle with randomly initialised default-size weights (timing only)."""
    torch.manual_seed(seed)
    cfg = NetConfig(kind=kind, window=default_window(kind))
    spec = FeatureSpec(parameters=KEYS, window=cfg.window)
    n_track = spec.n_features - len(KEYS)
    return Surrogate(
        build_network(cfg).eval(),
        cfg,
        spec,
        Normaliser([0.0] * n_track, [1.0] * n_track, [0.0, 120.0], [5.0, 20.0]),
        get_condition("straight", n_steps=n_steps),
        load_wagon(),
        seed,
    )


def rates_of(make, kinds: list[str], repeats: int, track=None) -> dict[str, float]:
    """Fast-path rates of every network kind, and the per-window rate of the CNN-GRU."""
    rates = {}
    for kind in kinds:
        sur = make(kind)
        rates[kind] = _rate(sur, 64, repeats, True, track)
        if kind == "cnn-gru":
            rates["cnn-gru per-window"] = _rate(sur, 64, repeats, False, track)
    return rates


def print_rates(rates: dict[str, float], threads: int) -> None:
    print(f"\nprediction throughput (windows / s, 64 parameter sets per call, {threads} threads):")
    for k, v in rates.items():
        print(f"  {k:<19} {v:12.0f}")
    if "cnn-gru per-window" in rates:
        print(f"  cnn-gru fast / per-window: {rates['cnn-gru'] / rates['cnn-gru per-window']:.1f}")


def parse_models(text: str, throughput_only: bool = False) -> list[str]:
    """The model kinds of ``--models`` (comma-separated). A name that is no model is
    refused, listing the accepted ones (it was dropped, and its table came out empty);
    ``throughput_only`` times the networks among them (rbf and gp-stats predict no
    windows), so at least one must be a network."""
    models = [m.strip() for m in text.split(",") if m.strip()]
    unknown = [m for m in models if m not in ALL_MODELS]
    if unknown or not models:
        raise RailsuspInputError(
            f"--models {text!r}: {', '.join(unknown) or 'none'} unknown; accepted a "
            f"comma-separated list of {', '.join(ALL_MODELS)}"
        )
    if throughput_only and not any(m in NETWORKS for m in models):
        raise RailsuspInputError(
            f"--models {text!r} with --throughput-only: accepted one or more of "
            f"{', '.join(NETWORKS)} (the others predict no windows)"
        )
    return models


def throughput_only(args: argparse.Namespace, models: list[str]) -> None:
    """Throughput of randomly initialised networks, 64 series x 980 windows, no campaign."""
    torch.set_num_threads(args.threads)
    kinds = [k for k in models if k in NETWORKS]
    track = np.random.default_rng(1).normal(size=(1000, 15))
    rates = rates_of(random_surrogate, kinds, args.repeats, track)
    print_rates(rates, args.threads)
    gen = {k: generation_seconds(random_surrogate(k), repeats=args.repeats) for k in kinds}
    print("one NSGA-II generation (50 parameter sets x 3000 steps), s:")
    for k, v in gen.items():
        print(f"  {k:<19} {v:8.3f}")
    out = write_json(
        args.out or "bench/results/surrogate_throughput.json",
        {
            "date": time.strftime("%Y-%m-%d"),
            "machine": platform.platform(),
            "threads": args.threads,
            "repeats": args.repeats,
            "windows_per_second": rates,
            "generation_seconds_50x3000": gen,
        },
    )
    print(f"wrote {out}")


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--run")
    ap.add_argument("--models", default=",".join(ALL_MODELS))
    ap.add_argument("--epochs", type=positive_int, default=10)
    ap.add_argument("--batches-per-epoch", type=positive_int, default=100)
    ap.add_argument("--batch-size", type=positive_int, default=512)
    ap.add_argument("--threads", type=positive_int, default=2, help="torch threads for throughput")
    ap.add_argument(
        "--repeats", type=positive_int, default=3, help="timed predict calls, best kept"
    )
    ap.add_argument("--throughput-only", action="store_true")
    ap.add_argument("--out", help="JSON written (bench/results/surrogate[_throughput].json)")
    args = ap.parse_args()
    models = parse_models(args.models, args.throughput_only)
    if args.throughput_only:
        throughput_only(args, models)
        return
    if args.run is None:
        ap.error("--run is required unless --throughput-only")
    cfg = TrainConfig(
        epochs=args.epochs, batches_per_epoch=args.batches_per_epoch, batch_size=args.batch_size
    )
    times: dict[str, float] = {}
    t_all = time.perf_counter()

    def tick(msg: str, state={"t": None, "m": None}):  # noqa: B006 - a timer between calls
        now = time.perf_counter()
        if state["m"] is not None:
            times[state["m"]] = now - state["t"]
        state["t"], state["m"] = now, msg
        print(f"  training {msg}", flush=True)

    tab = compare(args.run, models=models, train=cfg, progress=tick)
    tick("done")
    total = time.perf_counter() - t_all
    t7 = table7(tab)
    cond = tab.condition.iloc[0]
    with torch_threads(args.threads):
        rates = rates_of(
            lambda kind: load(f"{args.run}/surrogates/{kind}/{cond}"),
            [k for k in models if k in NETWORKS],
            args.repeats,
        )
    print(
        f"\n{'condition':<9} {'model':<10} {'Q sim':>7} {'Q pred':>7} {'Q err%':>7} "
        f"{'Y sim':>6} {'Y pred':>6} {'Y err%':>7} {'Y NRMSE':>8} {'Y R2':>6} {'train s':>8}"
    )
    for r in t7.itertuples(index=False):
        t = times.get(f"{r.condition}: {r.model}", float("nan"))
        print(
            f"{r.condition:<9} {r.model:<10} {r[2]:7.2f} {r[3]:7.2f} {r[4]:7.2f} {r[5]:6.2f} "
            f"{r[6]:6.2f} {r[7]:7.2f} {r[9]:8.3f} {r[11]:6.3f} {t:8.1f}"
        )
    print_rates(rates, args.threads)
    out = write_json(
        args.out or "bench/results/surrogate.json",
        {
            "date": time.strftime("%Y-%m-%d"),
            "machine": platform.platform(),
            "run": args.run,
            "train_config": cfg.to_dict(),
            "table": tab.to_dict(orient="records"),
            "train_seconds": times,
            "total_seconds": total,
            "windows_per_second": rates,
        },
    )
    print(f"wrote {out}")


if __name__ == "__main__":
    run_main(main)
