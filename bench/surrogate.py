"""Surrogate benchmark: accuracy on held-out runs (Table 7 layout), training time,
prediction throughput (windows per second, batched). Writes bench/results/surrogate.json.

Needs a campaign run directory (``--run``, e.g. ``railsusp campaign --samples 256 --out RUN``);
all models are trained on the same 70/15/15 split by sample.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
import torch

from railsusp.params import bounds
from railsusp.store import write_json
from railsusp.surrogate import TrainConfig, load
from railsusp.surrogate.compare import ALL_MODELS, compare, table7


def throughput(path, n_sets: int = 64) -> float:
    """Windows predicted per second by a saved surrogate, batched over parameter sets."""
    sur = load(path)
    lo, hi = bounds(sur.spec.parameters)
    x = lo + (hi - lo) * np.random.default_rng(0).random((n_sets, len(lo)))
    sur.predict(x[:2])  # warm-up
    t0 = time.perf_counter()
    out = sur.predict(x)
    wall = time.perf_counter() - t0
    return np.isfinite(out[:, :, 0]).sum() / wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--run", required=True)
    ap.add_argument("--models", default=",".join(ALL_MODELS))
    ap.add_argument("--epochs", type=int, default=10)
    ap.add_argument("--batches-per-epoch", type=int, default=100)
    ap.add_argument("--batch-size", type=int, default=512)
    ap.add_argument("--out", default="bench/results/surrogate.json")
    args = ap.parse_args()
    models = args.models.split(",")
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
    rates = {}
    for kind in models:
        if kind in ("cnn-gru", "cnn-lstm", "cnn-bilstm", "bp"):
            cond = tab.condition.iloc[0]
            rates[kind] = float(throughput(f"{args.run}/surrogates/{kind}/{cond}"))
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
    print(
        "\nprediction throughput (windows / s, 64 parameter sets per call, "
        f"{torch.get_num_threads()} threads):"
    )
    for k, v in rates.items():
        print(f"  {k:<10} {v:12.0f}")
    out = write_json(
        args.out,
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
    main()
