"""Simulation-based posterior: coverage before and after the spread correction, on the
calibration cases and on untouched test cases, one section and products of sections; and
the identification of parameter sets in the middle of the ranges against record length
(issue 20). Prints the tables and writes JSON.

    python bench/posterior.py                 # small scale, bench/results/posterior.json
    python bench/posterior.py --train 3000 --calibration 200 --check 200 --section 20 \\
        --conditions straight,curve --lengths 20,40,60,120,300,600 \\
        --long 200,200,200,100,100 --sets 12 --set-length 600   # near the issue's scale

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
   (posterior/calibration.json), printed and copied into the JSON. ``--long`` is one count
   for every length, or one per length above one section (the longest records, costliest
   to simulate, checked on fewer cases).
3. With ``--sets N``: N parameter sets in the middle 80 % of every range, each simulated
   for ``--set-length`` seconds per condition on a track of its own, their posterior at
   every length of ``--lengths`` up to that; per length and parameter the median 90 %
   interval width and the median error of the posterior median (% of range), and the
   issue's verdict on the key parameters (``--keys``): identifiable (median width at most
   45 % of range, half the prior's), >= 80 % of them within 5 % of range, median width
   <= 10 % of range. A length above the longest checked one, or whose check failed or
   needed a widening flagged excessive (above 2), is marked not calibrated.
4. The time of one recording's posterior (the longest length available).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from _cli import (
    non_negative_float,
    non_negative_int,
    parser,
    positive_float,
    positive_int,
    run_main,
)
from railsusp.condition_files import resolve_conditions
from railsusp.errors import RailsuspInputError
from railsusp.estimate import posterior
from railsusp.estimate.calibration import LEVEL
from railsusp.estimate.posterior_data import cached_cases, prior_draws
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import read_json, write_json

#: the key parameters of the current model (Sobol re-run of the sensitivity, 2026-11-24)
KEYS = "X18,X13,X11,X14,X19"


def main() -> None:
    ap = parser(__doc__)
    add_common_arguments(ap, "bench/results/posterior.json")
    ap.add_argument(
        "--calibration", type=positive_int, default=200, help="cases fitting the correction"
    )
    ap.add_argument("--ensemble", type=positive_int, default=1, help="flows in the ensemble")
    ap.add_argument(
        "--long", default="200", help="cases per set of several sections: one, or one per length"
    )
    ap.add_argument("--hidden", type=positive_int, default=50, help="flow: hidden features")
    ap.add_argument("--transforms", type=positive_int, default=5, help="flow: number of transforms")
    a = ap.parse_args()

    sections = sorted({max(1, round(v / a.section)) for v in lengths_s(a.lengths)})
    many = [k for k in sections if k > 1]
    counts = long_counts(a.long, len(many))
    settings = PosteriorSettings(
        bench_conditions(a),
        parameters=tuple(a.parameters.split(",")),
        section_s=a.section,
        n_train=a.train,
        n_check=a.check,
        n_calibration=a.calibration,
        ensemble=a.ensemble,
        product_sections=tuple(many),
        n_product=counts[0] if counts else 200,
        product_cases=counts if len(set(counts)) > 1 else (),
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
    _width_table(rows, names)
    ident, verdicts = None, []
    if a.sets:
        x, ident, verdicts = identify_sets(est, a, names)
    else:
        n, longest, _ = settings.product_sets()[-1] if many else (a.check, 1, ())
        folder = Path(a.run) / "posterior" / "simulations"
        _, x = cached_cases(settings, folder, "long" if many else "check", n, longest)
        x = x[:, None, :] if x.ndim == 2 else x
    k = x.shape[1]
    t_est = []
    for i, xi in enumerate(x[np.all(np.isfinite(x), axis=(1, 2))][:5]):
        t1 = time.perf_counter()
        est.sample(xi[:k], settings.samples, seed=i)
        t_est.append(time.perf_counter() - t1)
    print(f"posterior of {k} sections: median {np.median(t_est):.2f} s over {len(t_est)} cases")
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "settings": settings.to_dict(),
        "train_correct_and_check_s": t_train,
        "calibration_record": record,
        "coverage_against_length": rows,
        "estimate_s_median": float(np.median(t_est)),
        "estimate_sections": k,
        "identification": ident,
        "identification_verdicts": verdicts,
    }
    write_json(a.out, out)
    print(f"wrote {a.out}")


def add_common_arguments(ap: argparse.ArgumentParser, out: str) -> None:
    """The options every posterior bench shares: the run (its cache), the output, the
    estimator's conditions, parameters, sections and training cases, the lengths checked
    and the middle-80 % sets identified."""
    ap.add_argument("--run", default="bench/results/posterior_run", help="run directory (cache)")
    ap.add_argument("--out", default=out)
    ap.add_argument("--conditions", default="straight")
    ap.add_argument("--parameters", default=",".join(MAIN_SUSPENSION))
    ap.add_argument("--section", type=positive_float, default=5.0, help="section length, s")
    ap.add_argument(
        "--lead-in",
        type=non_negative_float,
        default=30.0,
        help="m; a curve keeps at least its own",
    )
    ap.add_argument("--train", type=positive_int, default=600)
    ap.add_argument(
        "--check", type=positive_int, default=200, help="untouched one-section test cases"
    )
    ap.add_argument("--lengths", default="5,10,20,40", help="record lengths checked, s")
    ap.add_argument(
        "--sets", type=non_negative_int, default=0, help="middle-80 %% sets identified (0: none)"
    )
    ap.add_argument(
        "--set-length", type=positive_float, default=600.0, help="their record length, s"
    )
    ap.add_argument(
        "--set-lengths", default=None, help="lengths they are scored at, s (default --lengths)"
    )
    ap.add_argument("--keys", default=KEYS, help="key parameters of the verdict")


def bench_conditions(a: argparse.Namespace) -> tuple:
    """``--conditions`` with ``--lead-in``: a curve keeps its own lead-in, which holds its
    entry (a longer one stays)."""
    return tuple(
        c.with_changes(lead_in_m=max(a.lead_in, c.lead_in_m if c.curve_radius_m else 0.0))
        for c in resolve_conditions(a.conditions)
    )


def identify_sets(est, a: argparse.Namespace, names: list[str], cases=None):
    """``--sets`` middle-80 % sets identified at every length (:func:`identification`;
    ``cases`` as there, else the sets in ``--run``), their tables printed: (statistics x,
    rows, the issue's verdict per length)."""
    t1 = time.perf_counter()
    _, x, ident = identification(
        est, None if cases else a.run, a.sets, a.set_length,
        lengths_s(a.set_lengths or a.lengths, "--set-lengths" if a.set_lengths else "--lengths"),
        cases,
    )  # fmt: skip
    print(f"\nidentification of {a.sets} sets: {time.perf_counter() - t1:.0f} s")
    keys = a.keys.split(",")
    print_tables(ident, names, keys)
    return x, ident, [verdict(r, keys) for r in ident]


def lengths_s(text: str, option: str = "--lengths") -> list[float]:
    """Record lengths, s, of a comma-separated ``option`` (each a finite number above 0)."""
    try:
        lengths = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        lengths = []
    if not lengths or not all(0.0 < v < math.inf for v in lengths):
        raise RailsuspInputError(
            f"{option} {text}: accepted record lengths in s above 0, comma-separated"
        )
    return lengths


def long_counts(text: str, lengths: int) -> tuple[int, ...]:
    """``--long``: one count for every length above one section, or one per length."""
    try:
        counts = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        counts = ()
    if not counts or min(counts) < 1 or (len(counts) != 1 and len(counts) != lengths):
        raise RailsuspInputError(
            f"--long {text}: accepted one whole number 1 or more, or one per length above one "
            f"section ({lengths})"
        )
    return counts * lengths if len(counts) == 1 else counts


def _width_table(rows: list[dict], names: list[str]) -> None:
    """Median 90 % interval width (% of range) per parameter against record length, on
    the untouched test cases (prior draws) after that length's correction."""
    print("\nmedian 90 % interval width, % of range, untouched test cases (prior draws)")
    print(f"{'length s':>8} {'cases':>5} " + " ".join(f"{p:>5}" for p in names))
    for r in rows:
        cells = " ".join(f"{r['median_width_pct'][p]:5.1f}" for p in names)
        print(f"{r['length_s']:8g} {r['cases']:5d} {cells}")


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


#: a median within this share of the range counts as identified (the issue's target)
WITHIN = 5.0
#: a key parameter counts as identifiable when its median 90 % interval at the longest
#: length is at most this wide (% of range): half the prior's own 90 % interval
IDENTIFIABLE_WIDTH = 45.0


def middle_draws(settings: PosteriorSettings, n: int) -> np.ndarray:
    """(n, 10) parameter sets, fractions of the ranges of X11-X20, in the middle 80 % of
    every range: a Latin hypercube (each parameter's n values one in each of n equal strata
    of [0.1, 0.9]), reproducible from the settings' seed."""
    return 0.1 + 0.8 * prior_draws(settings, "identification", n)


def interval_scores(draws: np.ndarray, truth: np.ndarray) -> dict[str, np.ndarray]:
    """Per parameter of draws (S, d) on the unit box and the truth (d,): the median's
    error and the central 90 % interval's width (% of range), and whether it holds the
    truth."""
    lo, med, hi = np.quantile(draws, [(1 - LEVEL) / 2, 0.5, (1 + LEVEL) / 2], axis=0)
    return {
        "error_pct": 100.0 * np.abs(med - truth),
        "width_pct": 100.0 * (hi - lo),
        "covered": (truth >= lo) & (truth <= hi),
    }


def score_sets(est, x: np.ndarray, u: np.ndarray, lengths: list[int]) -> list[dict]:
    """One row per number of sections k in ``lengths``: per parameter the median over the
    sets of the error and the width (% of range), the coverage, and the per-set values;
    ``x`` (sets, sections, D) summaries, ``u`` (sets, 10) truths (fractions of range).
    Sets whose simulation failed (NaN) are left out."""
    s = est.settings
    cols = [MAIN_SUSPENSION.index(p) for p in s.parameters]
    ok = np.all(np.isfinite(x), axis=(1, 2))
    rows = []
    for k in lengths:
        per = [interval_scores(est.sample(xi[:k], s.samples, seed=i), ui[cols])
               for i, (xi, ui) in enumerate(zip(x[ok], u[ok], strict=True))]  # fmt: skip
        err, width, cov = (np.array([p[key] for p in per]) for key in per[0])
        rows.append(
            {
                "sections": k,
                "length_s": k * s.section_s,
                "calibrated": _calibrated(est, k),
                "sets": int(ok.sum()),
                "median_error_pct": dict(
                    zip(s.parameters, np.median(err, 0).round(1).tolist(), strict=True)
                ),
                "median_width_pct": dict(
                    zip(s.parameters, np.median(width, 0).round(1).tolist(), strict=True)
                ),
                "coverage": dict(zip(s.parameters, cov.mean(0).round(3).tolist(), strict=True)),
                "error_pct": {p: err[:, j].round(2).tolist() for j, p in enumerate(s.parameters)},
                "width_pct": {p: width[:, j].round(2).tolist() for j, p in enumerate(s.parameters)},
            }
        )
    return rows


def _calibrated(est, k: int) -> bool:
    """Whether the estimator's check covers k sections and passed without an excessive
    widening (one section: its own check; several: that of the smallest checked number
    >= k)."""
    if k == 1:
        return bool(est.calibrated)
    product = est.product_for(k)
    return product is not None and bool(product.passed)


def verdict(row: dict, keys: list[str]) -> dict:
    """The issue's target on one length's row: the key parameters identifiable (median
    width at most :data:`IDENTIFIABLE_WIDTH`), the share of their (set, parameter) medians
    within :data:`WITHIN` % of range, and the median width over the identifiable ones;
    the same share over all keys."""
    keys = [k for k in keys if k in row["error_pct"]]
    ident = [k for k in keys if row["median_width_pct"][k] <= IDENTIFIABLE_WIDTH]

    def share(names: list[str]) -> float | None:
        errs = [e for k in names for e in row["error_pct"][k]]
        return float(np.mean(np.array(errs) <= WITHIN)) if errs else None

    widths = [w for k in ident for w in row["width_pct"][k]]
    return {
        "length_s": row["length_s"],
        "calibrated": row["calibrated"],
        "keys": keys,
        "identifiable": ident,
        "within_5pct_identifiable": share(ident),
        "within_5pct_all_keys": share(keys),
        "median_width_pct_identifiable": float(np.median(widths)) if widths else None,
        "targets_met": bool(
            ident and share(ident) >= 0.8 and float(np.median(widths)) <= 10.0 and row["calibrated"]
        ),
    }


def identification(
    est, run: str | Path | None, n: int, length_s: float, lengths_s: list[float], cases=None
):
    """Simulate (or read) ``n`` middle-80 % sets of ``length_s`` per condition and score
    their posterior at every record length of ``lengths_s`` up to it (and at ``length_s``):
    (truths u (n, 10), summaries x, rows of :func:`score_sets`). ``cases(kind, n, sections,
    draws)`` -> (u, x) reads them instead of ``run``'s cache (a joint posterior's parts)."""
    s = est.settings
    longest = max(1, round(length_s / s.section_s))
    ks = sorted({max(1, round(v / s.section_s)) for v in lengths_s} | {longest})
    u = middle_draws(s, n)
    if cases is None:
        folder = Path(run) / "posterior" / "simulations"
        _, x = cached_cases(s, folder, "identification", n, longest, draws=u)
    else:
        _, x = cases("identification", n, longest, u)
    x = x[:, None, :] if x.ndim == 2 else x
    return u, x, score_sets(est, x, u, [k for k in ks if k <= longest])


def print_tables(rows: list[dict], names: list[str], keys: list[str]) -> None:
    """Median width and error against record length, and the verdict at each length."""
    print(f"\n{rows[0]['sets']} sets in the middle 80 % of the ranges: median 90 % interval "
          "width (% of range) against record length per condition")  # fmt: skip
    head = " ".join(f"{p:>5}" for p in names)
    print(f"{'length s':>8} {'calib.':>6} {head}")
    for r in rows:
        cells = " ".join(f"{r['median_width_pct'][p]:5.1f}" for p in names)
        print(f"{r['length_s']:8g} {'yes' if r['calibrated'] else 'NO':>6} {cells}")
    print("median error of the posterior median (% of range); coverage of the sets' intervals")
    for r in rows:
        cells = " ".join(f"{r['median_error_pct'][p]:5.1f}" for p in names)
        cov = " ".join(f"{r['coverage'][p]:5.2f}" for p in names)
        print(f"{r['length_s']:8g} {'':>6} {cells}\n{'':>8} {'cov.':>6} {cov}")
    for r in rows:
        v = verdict(r, keys)
        share = v["within_5pct_identifiable"]
        print(
            f"{r['length_s']:6g} s: identifiable keys {','.join(v['identifiable']) or 'none'}; "
            f"within 5 %: {'-' if share is None else f'{share:.0%}'} of them, "
            f"{v['within_5pct_all_keys']:.0%} of all keys; median width "
            f"{v['median_width_pct_identifiable'] or float('nan'):.1f} %; "
            f"targets met: {v['targets_met']}"
        )


if __name__ == "__main__":
    run_main(main)
