"""Synthetic likelihood of a long record's mean statistics (railsusp.estimate.
posterior_synthetic) against the section fusion of bench/posterior.py: coverage of the 90 %
intervals on held-out records of several sections, and the issue's identification of
parameter sets in the middle of the ranges at 600 s per condition (issue 20). Prints the
tables and writes JSON. Reuses bench/posterior.py's run folder (its cached simulations:
training cases, held-out records, the middle-80 % sets) and its scoring.

    python bench/posterior_synthetic.py --run RUN --conditions straight,curve --section 20 \\
        --train 2000 --check 200 --long 100 --long-length 600 --lengths 20,120,600 \\
        --scale-records 150 --sets 12 --set-length 600 --set-lengths 20,60,120,300,600

1. Fits (or reads) the emulator on the ``--train`` training cases (one section each, all
   ten parameters from the prior, a new track each): ``RUN/posterior/synthetic/``.
2. Fits c and the model error per direction A on ``--scale-records`` calibration records
   of ``--long-length`` (the fusion's ``long-calibration`` records; never the test records).
   Checks the posterior, with no widening fitted: one section on ``--check`` held-out
   cases, k sections on the first k of ``--long`` held-out records of ``--long-length``
   seconds per condition (the fusion's ``long`` records, same seeds), for every length of
   ``--lengths``; coverage per parameter and median 90 % width (% of range).
3. With ``--sets N``: the N middle-80 % sets of bench/posterior.py at every length of
   ``--lengths`` up to ``--set-length``, scored and judged exactly as there.
4. The time of one recording's posterior at the longest length.
5. With ``--sets N``: the Cramer-Rao bound of the 90 % width at ``--set-length`` at the N
   sets' truths, from the synthetic likelihood's Fisher information (the emulator's
   Jacobian of mu, C_k with and without the emulator's error).
6. With ``--replicates N``: the first N held-out ``long`` records simulated again at the
   same parameters on other tracks (``replicate`` cases). Per combination the likelihood
   reads: how far the two records' means lie apart (half their mean squared difference, in
   a section's variance; 1/k if a record holds nothing but its k sections' scatter) against
   how far each lies from the emulator's mean: the emulator's error, told apart from a
   record's own randomness.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from _cli import parser, positive_float, positive_int, run_main
from posterior import add_common_arguments, bench_conditions, identify_sets, lengths_s, middle_draws
from railsusp.estimate import posterior_synthetic_fit as synthetic_fit
from railsusp.estimate import posterior_synthetic_run as synthetic
from railsusp.estimate.posterior_data import cached_cases
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.posterior_synthetic_information import cramer_rao_width, fisher_information
from railsusp.store import write_json


def main() -> None:
    ap = parser(__doc__)
    add_common_arguments(ap, "bench/results/posterior_synthetic.json")
    ap.add_argument(
        "--long", type=positive_int, default=200, help="held-out records of several sections"
    )
    ap.add_argument("--long-length", type=positive_float, default=40.0, help="their length, s")
    ap.add_argument(
        "--scale-records",
        type=int,
        default=0,
        help="held-out calibration records of --long-length fitting the covariance's scales "
        "(0: not fitted)",
    )
    ap.add_argument(
        "--statistics",
        default="en14363",
        help="families of statistics (railsusp.estimate.statistic_families), or 'all'",
    )
    ap.add_argument(
        "--projection-rank",
        type=int,
        default=15,
        help="combinations of the statistics read beyond the EN 14363 summary",
    )
    ap.add_argument(
        "--replicates",
        type=int,
        default=0,
        help="held-out long records simulated again at their parameters on other tracks",
    )
    ap.add_argument(
        "--statistics-emulator-cases",
        type=int,
        default=0,
        help="0: one emulator of all statistics on every training case; N: it on the first "
        "N cases, and an emulator of the projected combinations on all of them",
    )
    ap.add_argument(
        "--condition-offset",
        type=int,
        default=0,
        help="index of the first condition in a joint design (another run of the same cases "
        "holds the conditions before it): its own tracks and noise",
    )
    a = ap.parse_args()

    longest = max(1, round(a.long_length / a.section))
    settings = PosteriorSettings(
        bench_conditions(a),
        parameters=tuple(a.parameters.split(",")),
        section_s=a.section,
        n_train=a.train,
        n_check=a.check,
        product_sections=(longest,) if longest > 1 else (),
        n_product=a.long,
        statistics=tuple(a.statistics.split(",")),
        projection_rank=a.projection_rank,
        statistics_emulator_cases=a.statistics_emulator_cases,
        condition_offset=a.condition_offset,
    )
    sets = checked_sets(a, a.section, longest)
    names = list(settings.parameters)
    t0 = time.perf_counter()
    where = ("long-calibration", a.scale_records, longest) if a.scale_records else None
    post = synthetic.train(settings, a.run, sets, scales_on=where)
    scales = {k: getattr(post.likelihood, k) for k in ("within_scale", "model_error")}
    matrix = post.likelihood.model_error_matrix
    if matrix is not None:  # the emulator's error per direction, S A S: A's eigenvalues
        scales["model_error_eigenvalues"] = np.linalg.eigvalsh(matrix)[::-1].round(4).tolist()
    print(f"covariance scales: {scales}")
    t_train = time.perf_counter() - t0
    print(f"\nemulator + checks: {t_train:.0f} s (cached parts are read, not redone)")
    rows = [c.to_dict() for c in post.checks]
    coverage_table(rows, names, a.section)

    ident, verdicts = None, []
    if a.sets:
        x, ident, verdicts = identify_sets(post, a, names)
        t_est = posterior_seconds(post, x)
    bound = _cramer_rao(post, a, names) if a.sets else None
    replicates = _replicates(post, a, longest) if a.replicates and longest > 1 else None
    if a.replicates and longest == 1:
        print("--replicates: not measured, --long-length holds one section (accepted several)")
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "method": "synthetic-likelihood",
        "settings": settings.to_dict(),
        "members": synthetic_fit.MEMBERS,
        "hidden": synthetic_fit.HIDDEN,
        "projected_hidden": synthetic_fit.PROJECTED_HIDDEN,
        "training": synthetic_fit.TRAINING,
        "emulator_and_checks_s": t_train,
        "scale_records": a.scale_records,
        "scales": scales,
        "checks": rows,
        "replicates": replicates,
        "identification": ident,
        "identification_verdicts": verdicts,
        "estimate_s_median": float(np.median(t_est)) if a.sets else None,
        "cramer_rao_width_pct": bound,
    }
    write_json(a.out, out)
    print(f"wrote {a.out}")


def checked_sets(a: argparse.Namespace, section_s: float, longest: int) -> list[tuple]:
    """The held-out sets checked at every length of ``--lengths`` (``held_out_sets``'
    form): one section on ``--check`` cases, k sections on the first k of the ``--long``
    records of ``longest`` sections."""
    ks = sorted({max(1, round(v / section_s)) for v in lengths_s(a.lengths)})
    sets = [("check", a.check, 1, (1,))] if 1 in ks else []
    if any(k > 1 for k in ks):
        sets.append(("long", a.long, longest, tuple(k for k in ks if 1 < k <= longest)))
    return sets


def posterior_seconds(post, x: np.ndarray, records: int = 5) -> list[float]:
    """Seconds of one recording's posterior, for the first ``records`` finite records of
    ``x`` (records, sections, D); their median printed."""
    xs = x[np.all(np.isfinite(x), axis=(1, 2))][:records]
    seconds = []
    for i, xi in enumerate(xs):
        t1 = time.perf_counter()
        post.sample(xi, post.settings.samples, seed=i)
        seconds.append(time.perf_counter() - t1)
    print(f"posterior of {xs.shape[1]} sections: median {np.median(seconds):.2f} s over "
          f"{len(seconds)} records")  # fmt: skip
    return seconds


def _cramer_rao(post, a: argparse.Namespace, names: list[str]) -> dict:
    """Cramer-Rao 90 % widths (% of range) at the ``--sets`` truths for ``--set-length``
    (:func:`cramer_rao_table` of the posterior's likelihood)."""
    s = post.settings
    k = max(1, round(a.set_length / s.section_s))
    u = middle_draws(s, a.sets)
    return cramer_rao_table([post.likelihood], post.columns, u, k, s.section_s, names)


def cramer_rao_table(likelihoods, columns, u, k: int, section_s: float, names) -> dict:
    """Cramer-Rao 90 % widths (% of range) at the truths ``u`` for ``k`` sections per
    condition, the ``likelihoods``' informations added (independent conditions: one
    likelihood, or a joint posterior's parts): per set and parameter, with the emulator's
    error in C_k (what this emulator can tell) and without it (what the statistics hold,
    read by a perfect emulator); printed as the median over the sets."""
    out = {"sections": k, "length_s": k * section_s}
    print(f"\nCramer-Rao bound of the 90 % width at {k * section_s:g} s, % of range, "
          f"median over the {len(u)} sets (all ten parameters unknown)")  # fmt: skip
    print(f"{'C_k':>24} " + " ".join(f"{p:>6}" for p in names))
    for label, err in (("statistics alone", False), ("with emulator error", True)):
        info = sum(fisher_information(sl, u, k, emulator_error=err) for sl in likelihoods)
        w = 100.0 * cramer_rao_width(info)[:, columns]
        out[label.replace(" ", "_")] = {p: w[:, i].tolist() for i, p in enumerate(names)}
        print(f"{label:>24} " + " ".join(f"{np.median(w[:, i]):6.1f}" for i in range(len(names))))
    return out


def replicate_split(sl, u: np.ndarray, first: np.ndarray, second: np.ndarray) -> dict:
    """Per combination the likelihood reads (``sl.project``), for records ``first`` and
    ``second`` (n, k, D) simulated at the same parameters ``u`` (n, d) on different tracks,
    in units of one section's variance as the emulator gives it: ``between``, half the mean
    squared difference of the two records' means (their own scatter; 1/k for k independent
    sections and nothing shared by a record); ``from_emulator``, the mean squared distance of
    each record's mean from the emulator's mean (its own scatter plus the emulator's error
    at u); ``correlation`` of the two records' distances (near 1 when the emulator's error,
    the same for both, dominates)."""
    a, b = (sl.project(np.asarray(x, float)).mean(axis=1) for x in (first, second))
    _, _, section, _ = sl.parts(u)
    sd = np.sqrt(np.diagonal(section, axis1=1, axis2=2))
    mean = sl.mean(u)
    ra, rb = (a - mean) / sd, (b - mean) / sd
    return {
        "records": len(u),
        "sections": int(np.shape(first)[1]),
        "between": (np.mean(((a - b) / sd) ** 2, axis=0) / 2).tolist(),
        "from_emulator": (np.mean(ra**2 + rb**2, axis=0) / 2).tolist(),
        "correlation": [float(np.corrcoef(ra[:, j], rb[:, j])[0, 1]) for j in range(a.shape[1])],
    }


def _replicates(post, a: argparse.Namespace, longest: int) -> dict:
    """:func:`replicate_split` on the first ``--replicates`` ``long`` records and their
    ``replicate`` cases (cached in the run folder like every simulation); printed."""
    s = post.settings
    folder = Path(a.run) / "posterior" / "simulations"
    u, first = cached_cases(s, folder, "long", a.long, longest)
    n = min(a.replicates, a.long)
    _, second = cached_cases(s, folder, "replicate", n, longest, draws=u[:n])
    ok = np.all(np.isfinite(first[:n]), axis=(1, 2)) & np.all(np.isfinite(second), axis=(1, 2))
    out = replicate_split(post.likelihood, u[:n][ok], first[:n][ok], second[ok])
    k = out["sections"]
    print(
        f"\nreplicate records: {out['records']} pairs of {k} sections at the same parameters "
        f"on other tracks; per combination, in a section's variance (1/k = {1 / k:.3f})"
    )
    print(f"{'':>16} " + " ".join(f"{j + 1:>6}" for j in range(len(out["between"]))))
    for key in ("between", "from_emulator", "correlation"):
        print(f"{key:>16} " + " ".join(f"{v:6.3f}" for v in out[key]))
    return out


def coverage_table(rows: list[dict], names: list[str], section_s: float) -> None:
    """Coverage per parameter and median width against record length (no widening)."""
    print("\ncoverage of the 90 % intervals on held-out records (no widening fitted)")
    print(f"{'length s':>8} {'cases':>5} " + " ".join(f"{p:>5}" for p in names) + "  passed")
    for r in rows:
        cov = {c["parameter"]: c["coverage"] for c in r["parameters"]}
        passed = sum(c["passed"] for c in r["parameters"])
        cells = " ".join(f"{cov[p]:5.2f}" for p in names)
        print(f"{r['sections'] * section_s:8g} {r['cases']:5d} {cells}  {passed}/{len(names)}")
    print("median 90 % interval width, % of range")
    for r in rows:
        cells = " ".join(f"{r['width_pct_range'][p]:5.1f}" for p in names)
        print(f"{r['sections'] * section_s:8g} {r['cases']:5d} {cells}")


if __name__ == "__main__":
    run_main(main)
