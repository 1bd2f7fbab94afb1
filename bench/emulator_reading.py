"""How much faster the synthetic likelihood's emulator reads its networks in single precision
(stop 67: :meth:`railsusp.estimate.posterior_emulator.StatisticsEmulator.member_means`, all
members stacked in float32) than the float64 reading of before, member by member. Writes
bench/results/emulator_reading.json.

The emulator has the stored layout of the product's (``--members`` networks of two tanh
layers of ``--hidden``, 10 parameters in, ``--outputs`` statistics out, each member with its
linear trend) but **random weights** (twice the spread of their initialisation, as the
product-sized test in tests/estimate/test_posterior_emulator.py): a reading's time hardly
depends on what was learnt (only the tanh's arguments do), and fitting costs time. At each
point count of ``--points`` it times, ``--repeats`` times alternating, on ``--threads`` BLAS
threads (threadpoolctl; the SMC sampler reads on one):

- ``double``: the reading of before, the module's own float64 ``_forward`` on each member,
  plus its trend on ``linear_features``, in the statistics' units;
- ``single``: ``member_means`` as it is now (its stack made before the timing, as it is
  made once per emulator; the one-off cost of making it is reported apart);

the median time per call of each, their ratio, and the largest difference between the two
readings over a statistic's spread over the prior (``x_scale``).

::

    python bench/emulator_reading.py
    python bench/emulator_reading.py --points 200 --members 10 --hidden 64 --threads 2
"""

from __future__ import annotations

import os
import platform
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from _cli import number_list, parser, positive_int, run_main
from railsusp.estimate.posterior_emulator import StatisticsEmulator, _forward, linear_features
from railsusp.store import write_json

#: parameters the emulator reads (the ten of the posterior)
INPUTS = 10
#: each timed repeat calls a reading until it has taken at least this long, s
MIN_REPEAT_S = 0.05


def random_emulator(members: int, hidden: int, outputs: int, seed: int = 0) -> StatisticsEmulator:
    """An emulator of the stored layout with random weights and trends (module docstring)."""
    rng = np.random.default_rng(seed)

    def layer(n_in: int, n_out: int) -> tuple[np.ndarray, np.ndarray]:
        return 2.0 * rng.standard_normal((n_in, n_out)) / np.sqrt(n_in), rng.standard_normal(n_out)

    weights = [
        [layer(INPUTS, hidden), layer(hidden, hidden), layer(hidden, outputs)]
        for _ in range(members)
    ]
    features = 1 + INPUTS + INPUTS * (INPUTS + 1) // 2
    return StatisticsEmulator(
        weights, rng.standard_normal(outputs), np.exp(rng.standard_normal(outputs)),
        np.zeros((features, outputs)), np.eye(outputs),
        trends=rng.standard_normal((members, 1 + INPUTS, outputs)),
    )  # fmt: skip


def double_reading(emu: StatisticsEmulator, u: np.ndarray) -> np.ndarray:
    """(members, N, D) the reading of before stop 67: each member's network in float64."""
    h = np.stack([_forward(layers, 2.0 * u - 1.0) for layers in emu.weights])
    h += np.matmul(linear_features(u)[None], emu.trends)
    return h * emu.x_scale + emu.x_mean


def calls_for(fn) -> int:
    """How many calls of ``fn`` take MIN_REPEAT_S (from one call, which also warms it)."""
    t = time.perf_counter()
    fn()
    return max(1, int(np.ceil(MIN_REPEAT_S / max(time.perf_counter() - t, 1e-9))))


def per_call(fn, calls: int) -> float:
    """Seconds per call of ``fn`` over ``calls`` calls."""
    t = time.perf_counter()
    for _ in range(calls):
        fn()
    return (time.perf_counter() - t) / calls


def main(argv=None) -> dict:
    ap = parser(__doc__)
    ap.add_argument(
        "--points",
        type=number_list(positive_int),
        default="50,200,1000",
        help="point counts per reading, comma-separated",
    )
    ap.add_argument("--members", type=positive_int, default=10)
    ap.add_argument("--hidden", type=positive_int, default=64)
    ap.add_argument("--outputs", type=positive_int, default=8, help="statistics (D)")
    ap.add_argument("--repeats", type=positive_int, default=7)
    ap.add_argument("--threads", type=positive_int, default=1, help="BLAS threads")
    ap.add_argument("--out", type=Path, default=Path("bench/results/emulator_reading.json"))
    args = ap.parse_args(argv)
    emu = random_emulator(args.members, args.hidden, args.outputs)
    rng = np.random.default_rng(1)
    rows = []
    with threadpool_limits(args.threads):
        t = time.perf_counter()
        emu._stacked()  # made once per emulator
        stack_s = time.perf_counter() - t
        load0 = os.getloadavg()[0]
        for n in args.points:
            u = rng.random((n, INPUTS))
            want, got = double_reading(emu, u), emu.member_means(u)
            paths = [lambda u=u: double_reading(emu, u), lambda u=u: emu.member_means(u)]
            calls = [calls_for(fn) for fn in paths]
            double_s, single_s = [], []
            for _ in range(args.repeats):  # alternating, so that a load shift hits both
                double_s.append(per_call(paths[0], calls[0]))
                single_s.append(per_call(paths[1], calls[1]))
            d, s = float(np.median(double_s)), float(np.median(single_s))
            diff = float((np.abs(got - want) / emu.x_scale).max())
            rows.append(
                {
                    "points": n,
                    "double_s": d,
                    "single_s": s,
                    "ratio": d / s,
                    "max_diff_over_scale": diff,
                }
            )
        load = (load0 + os.getloadavg()[0]) / 2.0
    print(
        f"{args.members} members, hidden {args.hidden}, {INPUTS} -> {args.outputs}, "
        f"{args.threads} thread(s), load {load:.1f}; stack made in {stack_s * 1e3:.2f} ms"
    )
    print(
        f"{'points':>6} {'float64 ms':>10} {'float32 ms':>10} {'ratio':>6} {'max |diff|/scale':>16}"
    )
    for r in rows:
        print(
            f"{r['points']:>6} {r['double_s'] * 1e3:10.3f} {r['single_s'] * 1e3:10.3f} "
            f"{r['ratio']:6.2f} {r['max_diff_over_scale']:16.1e}"
        )
    doc = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": platform.platform(),
        "cpus": os.cpu_count(),
        "members": args.members,
        "hidden": args.hidden,
        "inputs": INPUTS,
        "outputs": args.outputs,
        "threads": args.threads,
        "repeats": args.repeats,
        "weights": "random (timing only)",
        "stack_s": stack_s,
        "load_average": load,
        "rows": rows,
    }
    write_json(args.out, doc)
    print(f"wrote {args.out}")
    return doc


if __name__ == "__main__":
    run_main(main)
