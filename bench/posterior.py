"""Simulation-based posterior: coverage before and after the spread correction, on the
calibration cases and on untouched test cases, one section and products of sections
(issue 20). Prints the tables and writes JSON.

    python bench/posterior.py                 # small scale, bench/results/posterior.json
    python bench/posterior.py --train 10000 --calibration 200 --check 200 --section 20 \\
        --conditions straight,curve --lengths 20,60,120,600 --long 200  # the issue's scale

1. Trains (or resumes, ``--run``) the estimator: ``--train`` cases drawn from the Table 2
   prior, a new track realisation each, ``--section`` seconds per condition, an ensemble of
   ``--ensemble`` flows. Its spread correction is fitted on ``--calibration`` held-out
   cases and checked on ``--check`` other, untouched ones
   (railsusp.estimate.posterior_check): coverage per parameter before and after.
2. The same for the sections fused at every length of ``--lengths`` above one section:
   ``--long`` calibration cases and ``--long`` untouched test cases, each simulated for
   the longest length on one track and cut into consecutive sections; per length the
   coverage before and after that length's correction, the widening factors and the
   median 90 % interval width (% of range). All of it is the estimator's stored record
   (posterior/calibration.json), printed and copied into the JSON.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from railsusp.conditions import resolve_conditions
from railsusp.estimate import posterior
from railsusp.estimate.posterior_data import PosteriorSettings, cached_cases
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import read_json


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", default="bench/results/posterior_run", help="run directory (cache)")
    ap.add_argument("--out", default="bench/results/posterior.json")
    ap.add_argument("--conditions", default="straight")
    ap.add_argument("--parameters", default=",".join(MAIN_SUSPENSION))
    ap.add_argument("--section", type=float, default=5.0)
    ap.add_argument("--lead-in", type=float, default=30.0)
    ap.add_argument("--train", type=int, default=600)
    ap.add_argument("--calibration", type=int, default=200, help="cases fitting the correction")
    ap.add_argument("--check", type=int, default=200, help="untouched test cases")
    ap.add_argument("--ensemble", type=int, default=1, help="flows in the ensemble")
    ap.add_argument("--long", type=int, default=200, help="cases per set of several sections")
    ap.add_argument("--lengths", default="5,10,20,40", help="record lengths checked, s")
    ap.add_argument("--hidden", type=int, default=50, help="flow: hidden features")
    ap.add_argument("--transforms", type=int, default=5, help="flow: number of transforms")
    a = ap.parse_args()

    sections = sorted({max(1, round(float(v) / a.section)) for v in a.lengths.split(",")})
    conds = [c.with_changes(lead_in_m=a.lead_in) for c in resolve_conditions(a.conditions)]
    settings = PosteriorSettings(
        tuple(conds),
        parameters=tuple(a.parameters.split(",")),
        section_s=a.section,
        n_train=a.train,
        n_check=a.check,
        n_calibration=a.calibration,
        ensemble=a.ensemble,
        product_sections=tuple(k for k in sections if k > 1),
        n_product=a.long,
        hidden_features=a.hidden,
        num_transforms=a.transforms,
    )
    names = list(settings.parameters)
    t0 = time.perf_counter()
    est = posterior.train(settings, a.run)
    t_train = time.perf_counter() - t0
    record = read_json(Path(a.run) / "posterior" / "calibration.json")
    print(f"\ntrain + correction + check: {t_train:.0f} s (cached parts are read, not redone)")
    _coverage_table(record, names)

    rows = [_row(1, a.section, record)] + [
        _row(p["sections"], a.section, p) for p in record["products"]
    ]
    _length_table(rows, names)
    k = max(sections)
    _, x = cached_cases(settings, Path(a.run) / "posterior" / "simulations", "long", a.long, k)
    t_est = []
    for i, xi in enumerate(x[np.all(np.isfinite(x), axis=(1, 2))][:5]):
        t1 = time.perf_counter()
        est.sample(xi[:k], settings.samples, seed=i)
        t_est.append(time.perf_counter() - t1)
    print(f"posterior of {k} sections: median {np.median(t_est):.2f} s over 5 cases")
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "settings": settings.to_dict(),
        "train_correct_and_check_s": t_train,
        "calibration_record": record,
        "coverage_against_length": rows,
        "estimate_s_median": float(np.median(t_est)),
    }
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {a.out}")


def _coverage_table(record: dict, names: list[str]) -> None:
    """Coverage per parameter: calibration set and untouched test set, before and after."""
    corr = record.get("correction") or {}
    factors = corr.get("factors", {})
    lines = []
    cal = record.get("calibration_set")
    if cal:
        lines += [("calibration, before", cal["before"]), ("calibration, after", cal["after"])]
    lines += [("test, before", record["before"]), ("test, after", record["parameters"])]
    print(f"coverage of the 90 % intervals; calibration {cal['cases'] if cal else 0} cases, "
          f"test {record['cases']} cases")  # fmt: skip
    print(f"{'':>20} " + " ".join(f"{p:>5}" for p in names) + "  passed")
    for label, checks in lines:
        cells = " ".join(f"{c['coverage']:5.2f}" for c in checks)
        print(f"{label:>20} {cells}  {sum(c['passed'] for c in checks)}/{len(checks)}")
    if factors:
        print(f"{'widening factor':>20} " + " ".join(f"{factors[p]:5.2f}" for p in names))
    print(
        f"calibrated: {record['passed']}; excessive widening: {record.get('excessive_correction')}"
    )


def _row(k: int, section_s: float, rec: dict) -> dict:
    """One row of the length table from a stored check (one section, or a product)."""
    return {
        "length_s": k * section_s,
        "sections": k,
        "cases": rec["cases"],
        "coverage_before": {c["parameter"]: c["coverage"] for c in rec["before"]},
        "coverage_after": {c["parameter"]: c["coverage"] for c in rec["parameters"]},
        "factors": rec["correction"]["factors"] if rec.get("correction") else {},
        "passed_after": sum(c["passed"] for c in rec["parameters"]),
        "median_width_pct": rec["width_pct_range"],
    }


def _length_table(rows: list[dict], names: list[str]) -> None:
    print("\ncoverage of the 90 % intervals on untouched test cases against record length,")
    print("before / after the correction of that length; widening factors; median width")
    head = " ".join(f"{p:>9}" for p in names)
    print(f"{'length s':>8} {'sec.':>4} {'cases':>5} {head}  passed  width %")
    for r in rows:
        cells = " ".join(
            f"{r['coverage_before'][p]:4.2f}/{r['coverage_after'][p]:4.2f}" for p in names
        )
        widths = list(r["median_width_pct"].values())
        print(
            f"{r['length_s']:8g} {r['sections']:4d} {r['cases']:5d} {cells}  "
            f"{r['passed_after']:2d}/{len(names)}  {min(widths):.0f}-{max(widths):.0f}"
        )
        if r["factors"]:
            cells = " ".join(f"{r['factors'][p]:9.2f}" for p in names)
            print(f"{'':>8} {'':>4} {'':>5} {cells}  (widening)")


if __name__ == "__main__":
    main()
