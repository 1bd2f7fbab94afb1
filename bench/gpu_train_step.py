"""Time one training step of the sequence CNN-GRU (forward, backward, Adam) on a device, for
planning a training on a lent GPU (issue 19; bench/README.md, "Trained on a GPU").

Synthetic inputs of the shipped tangent network's sizes (its ``surrogate.json``: features,
washout, outputs), chunks of 400 steps as the training draws them, for the study's GRU sizes
and two wider variants; the mean of ``--steps`` timed steps after ``--warmup`` untimed ones
(default 3: the first steps allocate and, on a GPU, pick kernels). No campaign and no
simulation: it runs in seconds, so a lease's first minutes can say how far a
budget goes. Prints a table and writes JSON (bench/results/gpu_train_step.json)::

    python bench/gpu_train_step.py --device cuda
"""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Sequence
from pathlib import Path

import torch

from _cli import parser, run_main
from railsusp.store import write_json
from railsusp.surrogate.models import NetConfig, build_network

SHIPPED = Path(__file__).resolve().parents[1] / "src/railsusp/data/networks/c80_k6/straight"
#: GRU and dense sizes of the variants timed beside the study's network
VARIANTS = {
    "study": {},
    "wide": {"rnn_hidden": (128, 64, 32), "dense": (64, 32, 16)},
    "wider": {"rnn_hidden": (256, 128, 64), "dense": (128, 64, 32)},
}
CHUNK_STEPS = 400


def shipped_config() -> NetConfig:
    """The shipped tangent network's architecture (its sizes, features and washout)."""
    doc = json.loads((SHIPPED / "surrogate.json").read_text())["net"]
    return NetConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in doc.items()})


def time_step(cfg: NetConfig, chunks: int, steps: int, device: str, warmup: int = 3) -> float:
    """Mean seconds of one training step on ``chunks`` random chunks, after ``warmup``
    untimed ones."""
    net = build_network(cfg).to(device).train()
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    x = torch.randn(chunks, CHUNK_STEPS, cfg.n_features, device=device)
    y = torch.randn(chunks, CHUNK_STEPS - cfg.window, cfg.n_outputs, device=device)
    t0 = 0.0
    for k in range(steps + warmup):
        if k == warmup:
            if device == "cuda":
                torch.cuda.synchronize()
            t0 = time.perf_counter()
        opt.zero_grad()
        torch.nn.functional.mse_loss(net(x), y).backward()
        opt.step()
    if device == "cuda":
        torch.cuda.synchronize()
    return (time.perf_counter() - t0) / steps


def main(argv: Sequence[str] | None = None) -> list[dict]:
    ap = parser(__doc__)
    ap.add_argument("--device", default="cuda", help="cuda or cpu")
    ap.add_argument("--chunks", default="32,256,1024", help="chunks per step, comma list")
    ap.add_argument("--steps", type=int, default=20, help="timed steps")
    ap.add_argument("--warmup", type=int, default=3, help="untimed steps before them")
    ap.add_argument("--variants", default=",".join(VARIANTS), help="of " + ", ".join(VARIANTS))
    ap.add_argument("--out", default="bench/results/gpu_train_step.json")
    args = ap.parse_args(argv)
    names = [v.strip() for v in args.variants.split(",") if v.strip()]
    bad = [v for v in names if v not in VARIANTS]
    if bad:
        ap.error(f"--variants {bad}: accepted {', '.join(VARIANTS)}")
    if args.device not in ("cuda", "cpu") or (
        args.device == "cuda" and not torch.cuda.is_available()
    ):
        ap.error(f"--device {args.device}: accepted cpu, or cuda where a GPU is present")
    try:
        sizes = [int(c) for c in args.chunks.split(",")]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < 1 or args.steps < 1:
        ap.error(f"--chunks {args.chunks} --steps {args.steps}: accepted integers >= 1")
    if args.warmup < 0:
        ap.error(f"--warmup {args.warmup}: accepted an integer >= 0")
    base = shipped_config()
    rows = []
    print(f"{'network':8s} {'GRU':>12s} {'chunks':>7s} {'ms/step':>9s} {'chunks/s':>10s}")
    for name in names:
        cfg = NetConfig(**{**base.to_dict(), **VARIANTS[name]})
        for chunks in sizes:
            s = time_step(cfg, chunks, args.steps, args.device, args.warmup)
            rows.append(
                {"network": name, "rnn_hidden": list(cfg.rnn_hidden), "dense": list(cfg.dense),
                 "chunks": chunks, "ms_per_step": 1e3 * s, "chunks_per_s": chunks / s}
            )  # fmt: skip
            gru = ",".join(map(str, cfg.rnn_hidden))
            print(f"{name:8s} {gru:>12s} {chunks:7d} {1e3 * s:9.2f} {chunks / s:10.0f}")
    device = torch.cuda.get_device_name() if args.device == "cuda" else platform.processor()
    out = write_json(
        args.out,
        {
            "date": time.strftime("%Y-%m-%d"),
            "device": device,
            "torch": torch.__version__,
            "chunk_steps": CHUNK_STEPS,
            "steps": args.steps,
            "warmup": args.warmup,
            "rows": rows,
        },
    )
    print(f"wrote {out}")
    return rows


if __name__ == "__main__":
    run_main(main)
