"""Reference wheel-rail forces of the simulator, to prove that a speed change left them alone.

``--write`` stores the forces (Y, Q of all eight wheels) of three parameter sets in the
straight and curve conditions (10 s simulated each: 100 m lead-in, 4 s record) in
tests/data/force_reference.npz; without it, the script simulates again and prints, per
condition, the largest difference from the stored forces relative to the largest force.
tests/vehicle/test_force_reference.py asserts the same at 1e-9. A deliberate change of the
model's physics rewrites the file (``--write``) in the same commit, saying why, with a new
:data:`railsusp.vehicle.MODEL_REVISION` (stored with the forces; ``--write`` refuses changed
forces under the stored revision, since run directories are re-simulated only when it
changes). The file it replaces can stay beside it as the reference of a switch that restores
the old model (tests/data/force_reference_zero_yaw.npz: ``[contact] yaw_geometry = false``;
force_reference_wedge_pair.npz: ``[secondary] wedge_half_spacing = 0``;
force_reference_2026-11-30.1.npz: the wagon fields of
``railsusp.vehicle.wagon.FORCE_LAWS_BEFORE_2026_11_30_2``; force_reference_2026-11-30.2.npz:
those of ``FORCE_LAWS_BEFORE_2026_12_02_1``; force_reference_2026-12-02.1.npz: those of
``FORCE_LAWS_BEFORE_2026_12_03_1``; force_reference_2026-12-03.1.npz: those of
``FORCE_LAWS_BEFORE_2026_12_03_2``).
"""

from __future__ import annotations

import io
import time
from pathlib import Path

import numpy as np

from _cli import parser, run_main
from railsusp.conditions import get_condition
from railsusp.params import MAIN_SUSPENSION, bounds
from railsusp.store import atomic_write_bytes, write_json
from railsusp.vehicle import MODEL_REVISION
from railsusp.vehicle.simulate import simulate_batch
from railsusp.vehicle.wagon import WagonData

REFERENCE = Path(__file__).resolve().parents[1] / "tests" / "data" / "force_reference.npz"
CONDITIONS = ("straight", "curve")


def reference_sets() -> np.ndarray:
    """Nominal-centred and two corner-ish sets of the main suspension parameters (SI)."""
    lo, hi = bounds(MAIN_SUSPENSION)
    return lo + (hi - lo) * np.array([[0.5] * len(lo), [0.2] * len(lo), [0.8] * len(lo)])


def reference_forces(
    condition: str, wagon: WagonData | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(Y, Q) of the reference sets in ``condition``, N, shape (3, 8, 200); ``wagon``: the
    packaged loaded wagon by default."""
    cond = get_condition(condition, duration_s=4.0, n_steps=200, lead_in_m=100.0)
    r = simulate_batch(reference_sets(), cond, symbols=MAIN_SUSPENSION, wagon=wagon)
    return r.Y, r.Q


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| over max |b|."""
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def stored_revision() -> str | None:
    """The model revision the stored forces were made with (None: no file, or one written
    before revisions were stored)."""
    if not REFERENCE.exists():
        return None
    ref = np.load(REFERENCE)
    return str(ref["model_revision"]) if "model_revision" in ref.files else None


def write_reference(forces: dict[str, np.ndarray]) -> Path:
    """Store ``forces`` with :data:`MODEL_REVISION` (atomically: the tests' reference is
    never left half written); refused when they differ from forces stored under that same
    revision."""
    if stored_revision() == MODEL_REVISION:
        ref = np.load(REFERENCE)
        moved = max(relative_difference(forces[k], ref[k]) for k in forces)
        if moved > 1e-9:
            raise SystemExit(
                f"the forces moved by {moved:.2e} of the largest under the stored model revision "
                f"{MODEL_REVISION!r}: give railsusp.vehicle.MODEL_REVISION a new value first"
            )
    buf = io.BytesIO()
    np.savez_compressed(buf, model_revision=np.array(MODEL_REVISION), **forces)
    return atomic_write_bytes(REFERENCE, buf.getvalue())


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--write", action="store_true", help="store the reference forces")
    ap.add_argument("--out", default="bench/results/force_reference.json")
    args = ap.parse_args()
    forces = {}
    for c in CONDITIONS:
        forces[f"{c}_Y"], forces[f"{c}_Q"] = reference_forces(c)
    if args.write:
        print(f"wrote {write_reference(forces)}")
        return
    ref = np.load(REFERENCE)
    rows = [
        {"channel": k, "max_rel_difference": relative_difference(forces[k], ref[k])} for k in forces
    ]
    print(f"{'channel':<12} {'max |diff| / max |F|':>22}")
    for row in rows:
        print(f"{row['channel']:<12} {row['max_rel_difference']:22.2e}")
    out = write_json(args.out, {"date": time.strftime("%Y-%m-%d"), "rows": rows})
    print(f"wrote {out}")


if __name__ == "__main__":
    run_main(main)
