"""Where one NSGA-II generation's time goes with the sequence CNN-GRU, and what the fast path
(:meth:`railsusp.surrogate.sequence.CNNSequence.predict_sets`) saves (issue 19: < 60 s per
estimate of 50 x 100 on 2 cores). Writes bench/results/sequence_predict.json.

On the recordings of bench/estimate_tracks.py's set ``--set`` (``--duration`` 60 s per
condition on measured track, synthesised into ``--work`` as that bench does unless already
there) and the surrogates of ``RUN/surrogates/KIND``, for ``--pop`` parameter sets drawn at
random (seeded) it times, per torch thread count of ``--threads``, ``--repeats`` times
alternating:

- ``reference``: the path before the fast one, :meth:`CNNSequence.predict_series` on the
  per-step inputs built by :func:`railsusp.surrogate.bundle.series_features` (all segments
  of all sets one batch through each whole layer, torch's nn.GRU);
- ``fast``: :meth:`CNNSequence.predict_sets` on the same sets and tracks;
- ``objective``: the whole NSGA-II objective of a generation
  (:meth:`railsusp.estimate.problem.CalibrationProblem.errors` with the statistic
  ``aligned``: prediction through ``Surrogate.predict``, then the time-aligned comparison);
- ``in step``: the three conditions' networks run in step on the same sets and tracks
  (:func:`railsusp.surrogate.sequence_sets.predict_sets_in_step`);
- ``series 1by1`` and ``series step``: the force series in kN of every condition, as the
  objective gets them, condition by condition (``SurrogateForces.series``) and in step
  (``SurrogateForces.series_conditions``, which the objective now uses);
- ``recurrence``: the GRUs' recurrences alone (per layer and step the hidden-side matmul
  and the compiled gate pass, :func:`railsusp.surrogate.sequence_sets.gru_steps`, on the same
  batch of segments in the same blocks of steps, no input side, convolutions or head): the
  floor of the fast path while the method runs every segment from its start.

and the largest difference between the fast and the reference outputs (standardised units,
and over the output's RMS), and between the in-step and the one-by-one outputs. Each row is
the sum over the conditions (one generation).

::

    nice -n 10 python bench/sequence_predict.py RUN --kind cnn-gru-seq-nominal-e30
    python bench/sequence_predict.py --networks src/railsusp/data/networks/c80_k6 --duration 20
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

from _cli import non_negative_int, number_list, parser, positive_float, positive_int, run_main
from estimate_tracks import draw_sets, family_conditions, set_recordings
from railsusp.estimate import SurrogateForces
from railsusp.estimate.problem import CalibrationProblem
from railsusp.store import write_json
from railsusp.surrogate.bundle import series_features
from railsusp.surrogate.recurrence import cell_params
from railsusp.surrogate.sequence import BLOCK_STEPS, CNNSequence, segment_plan
from railsusp.surrogate.sequence_sets import gru_steps, predict_sets_in_step


@torch.inference_mode()
def recurrence_only(net: CNNSequence, rows: int, length: int) -> None:
    """The GRUs' hidden-side work over ``length`` steps of ``rows`` segments, in the fast
    path's blocks of steps, as the fast path does it (per step the hidden side's product, then
    the compiled gate pass; each block's input gates a copy of one fixed block): the floor."""
    g = torch.Generator().manual_seed(0)
    for w_ih, _, w_hh, b_h in (cell_params(layer, "gru")[0] for layer in net.rnn):
        source = torch.randn(1, BLOCK_STEPS, rows, w_ih.shape[0], generator=g)
        state = None
        for lo in range(0, length, BLOCK_STEPS):
            gates = source[:, : min(BLOCK_STEPS, length - lo)].clone()
            _, state = gru_steps(gates, state, w_hh[None], b_h[None])


def timed(fn) -> tuple[float, float]:
    t, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t, time.process_time() - c


def main(argv=None) -> dict:
    ap = parser(__doc__)
    ap.add_argument(
        "run", type=Path, nargs="?", help="run directory with surrogates/KIND/<condition>/"
    )
    ap.add_argument("--kind", default="cnn-gru-seq-nominal-e30")
    ap.add_argument(
        "--networks", type=Path, help="a folder of <condition>/ bundles instead of RUN and KIND"
    )
    ap.add_argument(
        "--set", type=non_negative_int, default=0, help="estimate_tracks.py's set (recordings)"
    )
    ap.add_argument(
        "--duration", type=positive_float, default=60.0, help="recorded s per condition"
    )
    ap.add_argument("--pop", type=positive_int, default=50, help="parameter sets per generation")
    ap.add_argument("--repeats", type=positive_int, default=5)
    ap.add_argument(
        "--threads",
        type=number_list(positive_int),
        default="1,2",
        help="torch thread counts, comma-separated",
    )
    ap.add_argument("--work", type=Path, default=Path("runs/estimate_tracks"))
    ap.add_argument("--out", type=Path, default=Path("bench/results/sequence_predict.json"))
    args = ap.parse_args(argv)
    if (args.run is None) == (args.networks is None):
        ap.error("give RUN (with --kind) or --networks FOLDER, one of them")
    folder = args.networks or args.run / "surrogates" / args.kind
    model = SurrogateForces(folder)
    # the recordings of estimate_tracks.py's set (its defaults: seed 0, 3 % noise, 0.5 mm)
    rec_args = argparse.Namespace(seed=0, noise=0.03, duration=args.duration, track_noise=0.5)
    conditions, _ = family_conditions(model, rec_args.duration)
    truth = draw_sets(args.set + 1, rec_args.seed)[args.set]
    work = args.work / (args.run.name if args.run else folder.name)
    _, recs = set_recordings(args.set, truth, conditions, work, rec_args)
    problem = CalibrationProblem(model, recs, model.parameters, "aligned")
    x_si = problem.to_si(np.random.default_rng(1).random((args.pop, len(model.parameters))))
    cases = []
    for rec in recs:
        sur = model.surrogate(rec.condition.name)
        if not isinstance(sur.net, CNNSequence):
            raise SystemExit(f"error: {folder} is not a sequence CNN-GRU ({sur.kind})")
        unit = sur._unit(x_si)
        track = sur.normaliser.track(model.track_input(rec.condition)[None]).astype(np.float32)
        cases.append((sur, unit, track))

    def reference():
        for sur, unit, track in cases:
            feats = torch.from_numpy(series_features(unit, track).astype(np.float32))
            sur.net.predict_series(feats, segment=sur.segment_steps)

    def fast():
        for sur, unit, track in cases:
            sur.net.predict_sets(
                torch.from_numpy(unit), torch.from_numpy(track), segment=sur.segment_steps
            )

    def in_step():
        predict_sets_in_step(
            [sur.net for sur, _, _ in cases],
            torch.from_numpy(cases[0][1]),
            [torch.from_numpy(track) for _, _, track in cases],
            segment=cases[0][0].segment_steps,
        )

    conditions_of = [rec.condition for rec in recs]

    def one_by_one():
        return [model.series(x_si, c) for c in conditions_of]

    def stepped():
        return model.series_conditions(x_si, conditions_of)

    def floor():
        for sur, unit, track in cases:
            seg = sur.segment_steps or track.shape[1]
            n_seg = len(segment_plan(track.shape[1], seg, sur.net.washout))
            recurrence_only(sur.net, n_seg * len(unit), min(seg, track.shape[1]))

    diffs = []
    for sur, unit, track in cases:
        feats = torch.from_numpy(series_features(unit, track).astype(np.float32))
        ref = sur.net.predict_series(feats, segment=sur.segment_steps)
        new = sur.net.predict_sets(
            torch.from_numpy(unit), torch.from_numpy(track), segment=sur.segment_steps
        )
        rms = ref.pow(2).mean(dim=(0, 1)).sqrt()
        diffs.append(
            {
                "condition": sur.condition.name,
                "max_abs_difference": float((new - ref).abs().max()),
                "max_difference_over_rms": float(((new - ref).abs() / rms).max()),
            }
        )
    alone, together = one_by_one(), stepped()
    in_step_difference = max(
        float(np.nanmax(np.abs(a - b))) for a, b in zip(alone, together, strict=True)
    )
    runs = {"reference": reference, "fast": fast, "in step": in_step}
    runs |= {"series 1by1": one_by_one, "series step": stepped}
    runs |= {"objective": lambda: problem.errors(x_si), "recurrence": floor}
    rows = []
    for n_threads in args.threads:
        torch.set_num_threads(n_threads)
        times: dict[str, list[tuple[float, float]]] = {k: [] for k in runs}
        for fn in runs.values():  # first calls: filter design, allocations
            fn()
        load0 = os.getloadavg()[0]
        for _ in range(args.repeats):
            for name, fn in runs.items():
                times[name].append(timed(fn))
        load = (load0 + os.getloadavg()[0]) / 2.0
        for name, t in times.items():
            wall = np.array([w for w, _ in t])
            rows.append(
                {
                    "threads": n_threads,
                    "path": name,
                    "min_s": float(wall.min()),
                    "median_s": float(np.median(wall)),
                    "cpu_s_median": float(np.median([c for _, c in t])),
                    "load_average": load,
                }
            )
    print(
        f"one generation: {args.pop} sets x {len(cases)} conditions x "
        f"{cases[0][2].shape[1]} steps, segments of {cases[0][0].segment_steps}"
    )
    print(f"{'threads':>7} {'path':>11} {'min s':>7} {'median s':>9} {'CPU s':>7} {'load':>5}")
    for r in rows:
        print(
            f"{r['threads']:>7} {r['path']:>11} {r['min_s']:7.3f} {r['median_s']:9.3f} "
            f"{r['cpu_s_median']:7.3f} {r['load_average']:5.1f}"
        )
    for d in diffs:
        print(
            f"{d['condition']}: fast - reference max {d['max_abs_difference']:.2e} "
            f"(standardised), {d['max_difference_over_rms']:.2e} of the output's RMS"
        )
    print(f"series in step - one by one: max {in_step_difference:.2e} kN")
    doc = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": platform.platform(),
        "cpus": os.cpu_count(),
        "networks": str(folder),
        "set": args.set,
        "pop": args.pop,
        "repeats": args.repeats,
        "rows": rows,
        "differences": diffs,
        "in_step_max_abs_difference_kN": in_step_difference,
    }
    write_json(args.out, doc)
    print(f"wrote {args.out}")
    return doc


if __name__ == "__main__":
    run_main(main)
