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
2. ``--long`` further cases from the prior (their own seeds: untouched too), each simulated
   for the longest of ``--lengths`` seconds on one track, estimated from their first L
   seconds for every L (one section, or the sections fused, railsusp.estimate.posterior):
   coverage of the 90 % intervals per parameter before and after the correction, the
   median interval width (% of range) and how many medians lie within 5 % of range of the
   truth.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from railsusp.conditions import resolve_conditions
from railsusp.estimate import posterior
from railsusp.estimate.calibration import check
from railsusp.estimate.posterior import _fused_samples
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
    ap.add_argument("--long", type=int, default=100, help="test cases of the longest length")
    ap.add_argument("--lengths", default="5,10,20,40", help="record lengths, s")
    ap.add_argument("--hidden", type=int, default=50, help="flow: hidden features")
    ap.add_argument("--transforms", type=int, default=5, help="flow: number of transforms")
    a = ap.parse_args()

    conds = [c.with_changes(lead_in_m=a.lead_in) for c in resolve_conditions(a.conditions)]
    settings = PosteriorSettings(
        tuple(conds),
        parameters=tuple(a.parameters.split(",")),
        section_s=a.section,
        n_train=a.train,
        n_check=a.check,
        n_calibration=a.calibration,
        ensemble=a.ensemble,
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

    sections = [max(1, round(float(v) / a.section)) for v in a.lengths.split(",")]
    t1 = time.perf_counter()
    u, x = cached_cases(settings, Path(a.run) / "posterior" / "simulations", "long", a.long,
                        max(sections))  # fmt: skip
    t_long = time.perf_counter() - t1
    ok = np.all(np.isfinite(x), axis=(1, 2))
    truth = u[ok][:, [MAIN_SUSPENSION.index(p) for p in names]]
    rows, t_est = [], []
    for k in sections:
        raw = []
        for i, xi in enumerate(x[ok]):
            t2 = time.perf_counter()
            if k == 1:
                raw.append(est.sample_raw(xi[0], settings.samples, seed=i))
            else:
                raw.append(_fused_samples(est, xi[:k], settings.samples, np.random.default_rng(i)))
            t_est.append(time.perf_counter() - t2)
        raw = np.stack(raw)
        corrected = est.correct(raw)
        q = np.quantile(corrected, [0.05, 0.5, 0.95], axis=1)
        rows.append(
            {
                "length_s": k * a.section,
                "sections": k,
                "cases": int(ok.sum()),
                "coverage_before": _coverages(raw, truth, names),
                "coverage_after": _coverages(corrected, truth, names),
                "passed_after": sum(c.passed for c in check(corrected, truth, names)),
                "median_width_pct": dict(
                    zip(
                        names, (100 * np.median(q[2] - q[0], axis=0)).round(1).tolist(), strict=True
                    )
                ),
                "median_within_5pct": float(np.mean(np.abs(q[1] - truth) <= 0.05)),
            }
        )
    _length_table(rows, names)
    print(f"\nlong test cases: {int(ok.sum())} of {a.long} ({t_long:.0f} s to simulate or read)")
    print(f"estimate of one case: median {np.median(t_est):.2f} s, max {max(t_est):.1f} s")
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "settings": settings.to_dict(),
        "train_correct_and_check_s": t_train,
        "calibration_record": record,
        "coverage_against_length": rows,
        "estimate_s_median": float(np.median(t_est)),
        "estimate_s_max": float(max(t_est)),
    }
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {a.out}")


def _coverages(draws, truth, names) -> dict[str, float]:
    return {c.parameter: round(c.coverage, 3) for c in check(draws, truth, names)}


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


def _length_table(rows: list[dict], names: list[str]) -> None:
    print("\ncoverage of the 90 % intervals on the long test cases, before / after the correction")
    head = " ".join(f"{p:>9}" for p in names)
    print(f"{'length s':>8} {'sec.':>4} {head}  passed  width  within5%")
    for r in rows:
        cells = " ".join(
            f"{r['coverage_before'][p]:4.2f}/{r['coverage_after'][p]:4.2f}" for p in names
        )
        widths = list(r["median_width_pct"].values())
        print(
            f"{r['length_s']:8g} {r['sections']:4d} {cells}  {r['passed_after']:2d}/{len(names)}"
            f"  {min(widths):.0f}-{max(widths):.0f}  {r['median_within_5pct']:.2f}"
        )


if __name__ == "__main__":
    main()
