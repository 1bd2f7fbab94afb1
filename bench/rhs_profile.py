"""Cost of one right-hand-side evaluation of the wagon model, in microseconds.

States are captured from a straight and a curve run (nominal parameters, at 7, 9, ..., 21 s:
running, flanging in the curve), each with the state one step (1 ms) before it; then ``rhs``
alone is evaluated on them many times in one compiled loop, single-threaded, each pair in
order with one work array, so that every evaluation starts its shared-rail solves warm from
a state one step away, as in a run (a state evaluated after itself would start them at
their solution); the figure is the minimum over repeats of CPU time per evaluation.
``--reference-src DIR`` times another checkout's ``src`` in a subprocess in the same sitting
(the right-hand side's signature has not changed), for an A/B ratio.
``--contact`` also times the wheel-rail contact of the eight wheels alone on the same states,
the scalar kernel (``wheel_rail.wheel_rail_forces`` wheel by wheel) against the SIMD one
(``contact_batch.contact_forces_8``), and checks that they give the same forces.
``--states DIR`` keeps the captured states in DIR (written on the first run, read on the
next): an ablated copy of the source (an element's call replaced by constant forces, run
with PYTHONPATH at the copy) is then timed on the whole model's states, not on those of its
own, different motion. Prints a table and writes JSON (bench/results/rhs_profile.json).
"""

from __future__ import annotations

import inspect
import io
import os
import time
from pathlib import Path

import numba as nb
import numpy as np
from scipy.signal import butter

from _cli import parser, positive_int, run_main
from railsusp.conditions import get_condition
from railsusp.params import ParameterSet
from railsusp.store import atomic_write_bytes, write_json
from railsusp.vehicle import layout as L
from railsusp.vehicle.integrate import _run_one
from railsusp.vehicle.model import rhs
from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays

try:
    from railsusp.vehicle.track_grid import track_arrays
except ImportError:  # a --reference-src checkout before stop 63 kept it in setup
    from railsusp.vehicle.setup import track_arrays
from railsusp.vehicle.wagon import load_wagon
from reference_run import reference_rows, reference_src

TIMES_S = (7.0, 9.0, 11.0, 13.0, 15.0, 17.0, 19.0, 21.0)
DT = 1e-3


@nb.njit
def _evaluate(states, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, reps, dxdt, out):
    """``reps`` passes over the states; states 2 i and 2 i + 1 (a state one step before
    another, then it) share work array i."""
    total = 0.0
    for _ in range(reps):
        for j in range(states.shape[0]):
            rhs(states[j], dxdt[j], P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front[j],
                out[j // 2])  # fmt: skip
            total += dxdt[j, 0]
    return total


def _arguments(condition: str):
    wagon = load_wagon()
    settings = SolverSettings()
    cond = get_condition(condition)
    P = ParameterSet.nominal().to_array()
    ca = contact_arrays(wagon)
    K = constants(wagon, cond, P, ca, settings)
    tracks, s0, ds = track_arrays(cond, [cond.seed], wagon, settings)
    return P, K, tracks[0], s0, ds, ca


def _states(condition: str, states_dir: str | None = None):
    """(rhs arguments with the captured states first, s_front): at each of TIMES_S the state
    one step before it, then it. With ``states_dir``, the states and positions are read from
    STATES_DIR/CONDITION-pairs.npz if it exists, else captured and written there: an ablated
    copy of the source is then timed on the states of the whole model (its own motion would
    differ)."""
    P, K, trk, s0, ds, ca = _arguments(condition)
    path = Path(states_dir) / f"{condition}-pairs.npz" if states_dir else None
    if path is not None and path.exists():
        with np.load(path) as f:
            args = (f["states"], P, K, trk, s0, ds, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R)
            return args, f["s_front"]
    sos = np.ascontiguousarray(butter(2, 0.4, output="sos"))
    states, s_front = [], []
    for n in [round(t / DT) + k for t in TIMES_S for k in (-1, 0)]:
        x = np.zeros(L.N_STATE)
        series = np.zeros((L.N_OUT, 1))
        # the integrator gained the start position (settled start) after 328b8dd
        start = (0.0,) if "s_init" in inspect.signature(_run_one.py_func).parameters else ()
        _run_one(x, P, K, trk, s0, ds, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R, DT, *start, n, 1,
                 1, sos, series, 4)  # fmt: skip
        states.append(x)
        s_front.append(K[L.K["V"]] * (n + 1) * DT)
    args = (np.array(states), P, K, trk, s0, ds, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R)
    if path is not None:
        buf = io.BytesIO()
        np.savez(buf, states=args[0], s_front=np.array(s_front))
        atomic_write_bytes(path, buf.getvalue())
    return args, np.array(s_front)


def time_rhs(condition: str, reps: int, repeats: int, states_dir: str | None = None) -> float:
    """Minimum CPU time per evaluation (us) over ``repeats`` loops of ``reps`` passes."""
    args, s_front = _states(condition, states_dir)
    n = args[0].shape[0]
    dxdt = np.zeros_like(args[0])
    out = np.zeros((n // 2, L.N_OUT_WORK))
    _evaluate(*args, s_front, 1, dxdt, out)
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        _evaluate(*args, s_front, reps, dxdt, out)
        best = min(best, time.process_time() - t0)
    return best / (reps * n) * 1e6


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--reps", type=positive_int, default=10000, help="passes per timed loop")
    ap.add_argument("--repeats", type=positive_int, default=7, help="timed loops, fastest kept")
    ap.add_argument("--reference-src", default=None, help="another checkout's src, for A/B")
    ap.add_argument("--contact", action="store_true", help="also time the contact alone")
    ap.add_argument(
        "--states",
        default=None,
        help="folder of captured states: read if there, else captured and written (ablation)",
    )
    ap.add_argument("--out", default="bench/results/rhs_profile.json")
    args = ap.parse_args()
    if args.reference_src:
        reference_src(args.reference_src)  # refused before any timing, as simulator.py does
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    rows = [{"condition": c, "us_per_eval": time_rhs(c, args.reps, args.repeats, args.states)}
            for c in ("straight", "curve")]  # fmt: skip
    if args.reference_src:
        argv = ["--reps", str(args.reps), "--repeats", str(args.repeats)]
        ref_rows = reference_rows(__file__, argv, args.reference_src)
        ref = {r["condition"]: r["us_per_eval"] for r in ref_rows}
        for row in rows:
            row["reference_us_per_eval"] = ref[row["condition"]]
            row["speed_up"] = ref[row["condition"]] / row["us_per_eval"]
    print(
        f"{'condition':<10} {'us/eval':>8}"
        + (f" {'reference':>10} {'speed-up':>9}" if args.reference_src else "")
    )
    for row in rows:
        line = f"{row['condition']:<10} {row['us_per_eval']:8.3f}"
        if args.reference_src:
            line += f" {row['reference_us_per_eval']:10.3f} {row['speed_up']:9.2f}"
        print(line)
    contact = []
    if args.contact:  # (imported here: a reference checkout may have no SIMD contact)
        from contact_timing import time_contact

        print(
            f"{'contact of 8 wheels':<20} {'scalar ns':>10} {'SIMD ns':>8} {'max |dF|/max |F|':>17}"
        )
        for c in ("straight", "curve"):
            row = time_contact(_states(c, args.states), args.reps, args.repeats)
            contact.append({"condition": c, **row})
            print(f"{c:<20} {row['scalar_ns']:10.0f} {row['simd_ns']:8.0f}"
                  f" {row['max_rel_diff']:17.1e}")  # fmt: skip
    result = {"date": time.strftime("%Y-%m-%d"), "rows": rows, "contact": contact}
    out = write_json(args.out, {**result, "reference_src": args.reference_src})
    print(f"wrote {out}")


if __name__ == "__main__":
    run_main(main)
