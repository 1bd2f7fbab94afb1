"""Surrogate training data: how accurately the key parameters alone predict a record
statistic, when the other parameters vary unseen and when they are held nominal.

For each run directory (``--runs``: CRN campaigns, e.g. one over all ten parameters and one
made with ``railsusp campaign --keys-from``) and condition, fits Gaussian processes (scikit-
learn, anisotropic RBF + white noise) from the key parameters, and from every sampled
parameter, to the record mean of |Y| of the measured wheel on growing training sets, and
prints the relative error per held-out run. Writes bench/results/surrogate_data.json.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C

from _cli import parser, run_main
from railsusp.campaign import load_campaign
from railsusp.params import bounds
from railsusp.store import write_json

KEYS = ("X11", "X12", "X13", "X14", "X17", "X18")


def record_means(run: str, condition: str, quantity: str) -> tuple[pd.DataFrame, np.ndarray]:
    """Design (sampled parameters, unit scaled) and the record mean of the measured wheel."""
    load_campaign(run)  # validates the run directory
    f = pd.read_parquet(f"{run}/features.parquet")
    f = f[(f.condition == condition) & (f.quantity == quantity) & (f.statistic == "mean")]
    if f.empty:
        raise SystemExit(f"{run}: no condition {condition!r}")
    y = f[f.wheel == f.wheel.iloc[0]].set_index("sample_id").value  # the measured wheel
    design = pd.read_parquet(f"{run}/design.parquet").set_index("sample_id")
    lo, hi = bounds(tuple(design.columns))
    unit = (design - lo) / (hi - lo)
    return unit, y.loc[unit.index].to_numpy()


def gp_error(x: np.ndarray, y: np.ndarray, train: np.ndarray, test: np.ndarray) -> float:
    """Mean relative error (%) on ``test`` of a GP fitted on ``train``."""
    kernel = C(1.0) * RBF(np.ones(x.shape[1])) + WhiteKernel(1e-3)
    gp = GaussianProcessRegressor(kernel, normalize_y=True, n_restarts_optimizer=1, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        gp.fit(x[train], y[train])
    return float(100 * np.mean(np.abs(gp.predict(x[test]) - y[test]) / np.abs(y[test])))


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--runs", nargs="+", required=True, help="campaign run directories")
    ap.add_argument("--conditions", default="straight,uphill")
    ap.add_argument("--sizes", default="200,400,800", help="training runs")
    ap.add_argument("--test", type=int, default=150, help="held-out runs")
    ap.add_argument("--quantity", default="Y", choices=("Y", "Q"))
    ap.add_argument("--out", default="bench/results/surrogate_data.json")
    a = ap.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")]
    rows = []
    print(f"{'run':28s} {'condition':9s} {'inputs':>6s} {'train':>5s} {'err %':>6s}")
    for run in a.runs:
        for cond in a.conditions.split(","):
            unit, y = record_means(run, cond, a.quantity)
            order = np.random.default_rng(0).permutation(len(y))
            test = order[: a.test]
            sets = {"keys": [k for k in KEYS if k in unit.columns], "sampled": list(unit.columns)}
            if sets["keys"] == sets["sampled"]:
                del sets["sampled"]
            for n in sizes:
                train = order[a.test : a.test + n]
                if len(train) < n:
                    continue
                for cols in sets.values():
                    err = gp_error(unit[cols].to_numpy(), y, train, test)
                    rows.append(
                        {
                            "run": run,
                            "condition": cond,
                            "sampled": list(unit.columns),
                            "inputs": cols,
                            "n_train": n,
                            "n_test": len(test),
                            "relative_error_pct": err,
                        }
                    )
                    print(f"{run[-28:]:28s} {cond:9s} {len(cols):6d} {n:5d} {err:6.2f}", flush=True)
    write_json(a.out, {"quantity": a.quantity, "statistic": "mean", "rows": rows})
    print(f"written {a.out}")


if __name__ == "__main__":
    run_main(main)
