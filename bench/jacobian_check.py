"""Does the surrogate make the forces depend on the parameters as the simulator does?
(issue 19: a network that is to be inverted needs the simulator's parameter sensitivity, not
only a small held-out error). Writes bench/results/jacobian_check.json.

For ``--sets`` parameter sets drawn as in bench/estimate_tracks.py (all ten parameters over
the middle 80 % of their ranges, the same seeds, so the same recordings: 60 s per condition
on a track no network saw, 3 % instrument noise, the geometry written with 0.5 mm error),
it computes at the truth the forward-difference Jacobian of the time-aligned comparison's
scaled residuals (:func:`railsusp.estimate.aligned_identifiability.aligned_jacobian`, the
refinement's 5 %-of-range step) twice: with the surrogate of ``RUN/surrogates/KIND`` and
with the simulator on the same measured geometry, the parameters that are not network
inputs held at the truth, both on the samples where the surrogate is defined (after its
window or washout). ``--segment`` sets a sequence network's prediction segment
(:meth:`railsusp.surrogate.bundle.Surrogate.segment_steps`). Per key parameter and
condition it reports:

- ``effect``: the simulator's column norm, i.e. the RMS change of the compared force over
  the parameter's whole range in units of the measured force's standard deviation
  (linearised): how much there is to see;
- ``gain``: the least-squares slope of the surrogate's column on the simulator's (1: the
  right size) and ``cosine`` (1: the right shape in time);
- the residual RMS at the truth (units of the force's standard deviation), with the
  surrogate and with the simulator (noise and geometry error only);
- the time-aligned Cramér-Rao bounds (% of range) with each model.

``--steps 0.05,0.02,0.005,0.001`` adds a check of the simulator itself: its forward
differences at each step (fraction of the range) against the first step's, cosine and gain,
on the same compared samples. A response that is not smooth in the compared band (chaos,
stick-slip switching) would make the simulator's own columns disagree, and cap what any
surrogate's gain and cosine could reach (stop 36: they agree, bench/README.md).

::

    python bench/jacobian_check.py RUN --kind cnn-gru --sets 4
"""

from __future__ import annotations

import platform
import time
from pathlib import Path

import numpy as np
import torch

from _cli import parser, positive_int, run_main
from estimate_tracks import draw_sets, family_conditions, set_recordings
from railsusp.estimate import SurrogateForces
from railsusp.estimate.aligned_identifiability import (
    agreement_of,
    aligned_jacobian,
    block_slices,
    bounds_pct_range,
    channel_names,
    defined_from,
)
from railsusp.estimate.forces import SimulatorForces
from railsusp.store import write_json


def block_rms(r: np.ndarray, blocks: list[int], names: list[str]) -> dict[str, float]:
    """RMS of the scaled residuals per channel block, in units of the measured force's
    standard deviation (the scale is std x sqrt(samples))."""
    return {
        n: float(np.linalg.norm(r[rows]))
        for n, rows in zip(names, block_slices(blocks), strict=True)
    }


def column_norms(jac: np.ndarray, blocks: list[int], names: list[str], params) -> dict:
    """Per parameter and channel block the Jacobian column's norm (the linearised RMS
    change over the whole range, in force standard deviations)."""
    return {
        p: {
            n: float(np.linalg.norm(jac[rows, j]))
            for n, rows in zip(names, block_slices(blocks), strict=True)
        }
        for j, p in enumerate(params)
    }


def set_segment(model: SurrogateForces, segment: str) -> None:
    """Give every sequence network of ``model`` the prediction segment ``segment`` ('auto':
    leave each its own, 'none': one run per series, or a number of steps)."""
    if segment == "auto":
        return
    steps = None if segment == "none" else int(segment)
    for name in model.conditions:
        model.surrogate(name).meta["segment_steps"] = steps


def simulator_steps(sim, recs, params, x, steps, lead) -> dict:
    """Per parameter and step h (fraction of the range), the cosine and gain of the
    simulator's Jacobian column at step h (:func:`aligned_jacobian`: the comparison's
    samples and scaling, inwards at the upper bound) against its column at ``steps[0]``."""
    cols = [aligned_jacobian(sim, recs, params, x, defined_from=lead, step=h)[1] for h in steps]
    ref = cols[0]
    return {
        p: {
            f"{h:g}": {
                "cosine": float(
                    c[:, j] @ ref[:, j] / np.linalg.norm(c[:, j]) / np.linalg.norm(ref[:, j])
                ),
                "gain": float(c[:, j] @ ref[:, j] / (ref[:, j] @ ref[:, j])),
            }
            for h, c in zip(steps, cols, strict=True)
        }
        for j, p in enumerate(params)
    }


def check_set(index, truth_si, model, conditions, work, args) -> dict:
    truth, recs = set_recordings(index, truth_si, conditions, work, args)
    params = model.parameters
    x = np.array([truth[p] for p in params])
    names = channel_names(recs)
    t0 = time.perf_counter()
    lead = defined_from(model, recs, x)  # both models compared on the same samples
    rn, jn, blocks = aligned_jacobian(model, recs, params, x, defined_from=lead)
    t1 = time.perf_counter()
    sim = SimulatorForces(params, base=truth)
    rs, js, _ = aligned_jacobian(sim, recs, params, x, defined_from=lead)
    t2 = time.perf_counter()
    row = {}
    if args.steps:
        row["simulator_steps"] = simulator_steps(sim, recs, params, x, args.steps, lead)
    return row | {
        "set": index,
        "compared_from_step": dict(zip([r.condition.name for r in recs], lead, strict=True)),
        "truth_display": {p: truth.to_display()[p] for p in params},
        "agreement": agreement_of(jn, js, blocks, names, params),
        "effect": column_norms(js, blocks, names, params),
        "residual_rms": {
            "surrogate": block_rms(rn, blocks, names),
            "simulator": block_rms(rs, blocks, names),
        },
        "bounds_pct_range": {
            "surrogate": dict(
                zip(params, map(float, bounds_pct_range(rn, jn, blocks)), strict=True)
            ),
            "simulator": dict(
                zip(params, map(float, bounds_pct_range(rs, js, blocks)), strict=True)
            ),
        },
        "seconds": {"surrogate": t1 - t0, "simulator": t2 - t1},
    }


def print_set(row: dict, params) -> None:
    res = row["residual_rms"]
    names = list(res["surrogate"])
    print(f"\nset {row['set']}: residual RMS / force std, surrogate | simulator:")
    print(
        "  "
        + "  ".join(f"{n} {res['surrogate'][n]:.3f} | {res['simulator'][n]:.3f}" for n in names)
    )
    print(
        f"  {'param':<5} {'bound net %':>11} {'bound sim %':>11} "
        + " ".join(f"{n + ' eff/gain/cos':>26}" for n in names)
    )
    for p in params:
        a = row["agreement"][p]["by_channel"]
        cells = " ".join(
            f"{row['effect'][p][n]:8.3f} {a[n]['gain']:+7.2f} {a[n]['cosine']:+6.2f}   "
            for n in names
        )
        b = row["bounds_pct_range"]
        print(f"  {p:<5} {b['surrogate'][p]:11.1f} {b['simulator'][p]:11.1f} {cells}")
    if "simulator_steps" in row:
        print("  the simulator's forward difference at each step against the first's, cos/gain:")
        for p, by_step in row["simulator_steps"].items():
            cells = "  ".join(
                f"{h}: {v['cosine']:+.2f}/{v['gain']:+.2f}" for h, v in by_step.items()
            )
            print(f"  {p:<5} {cells}")


def main(argv=None) -> dict:
    ap = parser(__doc__)
    ap.add_argument("run", type=Path, help="run directory with surrogates/KIND/<condition>/")
    ap.add_argument("--kind", default="cnn-gru")
    ap.add_argument("--sets", type=positive_int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--track-noise", type=float, default=0.5)
    ap.add_argument("--noise", type=float, default=0.03)
    ap.add_argument("--conditions", default="")
    ap.add_argument("--threads", type=positive_int, default=1)
    ap.add_argument(
        "--segment",
        default="auto",
        help="sequence networks: prediction segment in steps, 'none' (one run, state carried) "
        "or 'auto' (the surrogate's own: its training chunk)",
    )
    ap.add_argument(
        "--steps",
        default="",
        help="e.g. 0.05,0.02,0.005,0.001: the simulator's forward differences at these steps "
        "(fractions of the range) against the first's",
    )
    ap.add_argument("--work", type=Path, default=Path("runs/estimate_tracks"))
    ap.add_argument("--out", type=Path, default=Path("bench/results/jacobian_check.json"))
    args = ap.parse_args(argv)
    try:
        args.steps = [float(h) for h in args.steps.split(",") if h.strip()]
    except ValueError:
        ap.error(f"--steps {args.steps}: accepted fractions of the range like 0.05,0.01")
    if any(not 0.0 < h <= 0.5 for h in args.steps):
        ap.error(f"--steps {args.steps}: accepted fractions in (0, 0.5]")
    torch.set_num_threads(args.threads)
    model = SurrogateForces(args.run / "surrogates" / args.kind)
    set_segment(model, args.segment)
    names = [c.strip() for c in args.conditions.split(",") if c.strip()] or None
    conditions, moved = family_conditions(model, args.duration, names)
    rows = []
    for i, truth in enumerate(draw_sets(args.sets, args.seed)):
        row = check_set(i, truth, model, conditions, args.work / args.run.name, args)
        print_set(row, model.parameters)
        rows.append(row)
    params = model.parameters
    chans = list(rows[0]["effect"][params[0]])
    summary = {
        p: {
            n: {
                "effect": float(np.median([r["effect"][p][n] for r in rows])),
                "gain": float(
                    np.median([r["agreement"][p]["by_channel"][n]["gain"] for r in rows])
                ),
                "cosine": float(
                    np.median([r["agreement"][p]["by_channel"][n]["cosine"] for r in rows])
                ),
            }
            for n in chans
        }
        for p in params
    }
    print("\nmedian over the sets: effect (force std over the range) / gain / cosine")
    for p in params:
        print(
            f"  {p:<5} "
            + "  ".join(
                f"{n} {m['effect']:.3f}/{m['gain']:+.2f}/{m['cosine']:+.2f}"
                for n, m in summary[p].items()
            )
        )
    doc = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "machine": platform.platform(),
        "run": str(args.run),
        "kind": args.kind,
        "segment_steps": {c: model.surrogate(c).segment_steps for c in model.conditions},
        "settings": vars(args)
        | {"run": str(args.run), "work": str(args.work), "out": str(args.out)},
        "moved_into_family": moved,
        "per_set": rows,
        "median": summary,
    }
    write_json(args.out, doc)
    print(f"wrote {args.out}")
    return doc


if __name__ == "__main__":
    run_main(main)
