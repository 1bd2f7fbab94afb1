"""Does a trained synthetic-likelihood posterior's projection keep what its statistics
carry? The Fisher information of the section statistics about X11-X20 at the information
bench's points, from its common-random-number pairs (no emulator), read in full and through
the run's projection; and the run's emulator Jacobian against the pairs' (issue 20).

    python bench/projection_information.py --run runs/post_r40 --seed 0,1,2

Reads the statistics that bench/statistics_information.py cached in ``--work`` (its design
options, the same defaults; a point not cached there is simulated as that bench would).
The posterior's conditions and statistics must be among that bench's: the run's summary
names pick the columns. Per point, the median of the key parameters' Cramer-Rao 90 %
widths (% of range, all ten unknown, with the uniform prior's information) at
``--seconds`` per condition:

- **full, Ledoit-Wolf**: the information bench's own reading (C the shrunk covariance of
  the point's sections, with the 1 % gain prior);
- **full, sample S^-1 / unbiased**: gains known, C = S / k, S the sample covariance of the
  point's sections per condition, read raw and through :func:`information_estimate.
  unbiased_precision` (the raw inverse overstates the information by (N - 1) / (N - D - 2));
- **through the projection P**: gains known, C = P (S / k) P^T, or with the gain prior,
  P (S / k + G) P^T (r combinations from N sections, after the same correction with r,
  which errs on the wide side: :func:`projected_weight`);
- **the emulator's own bound** at the point (its Jacobian and covariance, statistics
  alone: what bench/posterior_synthetic.py's ``--sets`` table prints);
- **a projection chosen at the point** from the Jacobian there of the run's emulator of
  all the statistics (the one its global combinations were chosen with), whitened with
  the Ledoit-Wolf covariance of half the sections and read through the other half
  (cross-validated; gains known): whether a covariance estimated from sections can choose
  better combinations than the run's global ones.

It also prints, per key, the emulator's Jacobian through P against the pairs' mean
Jacobian (norms in whitened units and their cosine). Writes JSON.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from scipy.linalg import block_diag

from _cli import parser, run_main
from information_estimate import (
    information_unbiased,
    inverse_wishart_factor,
    ledoit_wolf,
    unbiased_precision,
    widths_pct,
)
from railsusp.estimate.posterior_data import GAIN_ERROR
from railsusp.estimate.posterior_synthetic import SyntheticLikelihood
from railsusp.estimate.posterior_synthetic_information import (
    fisher_information,
    mean_jacobian,
    top_directions,
    whitening,
)
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import atomic_write_bytes
from statistics_candidates import GROUPS, group_names
from statistics_information import (
    KEYS,
    add_design_arguments,
    condition_data,
    parameter_points,
    parse_design,
    pooled,
)

#: combinations a projection chosen at a point keeps (the cross-validated reading)
LOCAL_RANK = 40


def columns_of(summary_names: list[str], conditions: list[str]) -> list[int]:
    """Indices of the posterior's ``summary_names`` (``condition:statistic``) in the
    information bench's statistics of ``conditions`` (every group of
    :data:`statistics_candidates.GROUPS`, conditions one after the other); a one-line
    error for a name that bench does not compute."""
    bench = {f"{c}:{n}": i for i, (c, n) in enumerate(
        (c, n) for c in conditions for g in GROUPS for n in group_names(g))}  # fmt: skip
    missing = [n for n in summary_names if n not in bench]
    if missing:
        raise ValueError(f"statistic {missing[0]!r} of the run: not among the information "
                         f"bench's ({len(missing)} missing)")  # fmt: skip
    return [bench[n] for n in summary_names]


def projected_weight(p: np.ndarray, cov: np.ndarray, n: int | None = None) -> np.ndarray:
    """W = P^T (P C P^T)^-1 P (D, D): the weight by which J^T W J is the information of
    the combinations P s (r, D) of statistics of covariance C. ``n``: C is a sample
    covariance of n sections, and (P C P^T)^-1 is scaled by (n - r - 2) / (n - 1) (the
    inverse Wishart's bias, :func:`information_estimate.unbiased_precision`), exact for
    one sample covariance. For the conditions' independent blocks, or with a known gain
    covariance added, the factor over-corrects (by up to about 5 % of the information at
    r = 80 from 900 sections): the reading errs on the wide side."""
    w = p.T @ np.linalg.solve(p @ cov @ p.T, p)
    return w if n is None else w * inverse_wishart_factor(n, p.shape[0])


def point_readings(data: dict, cols, post, u0: np.ndarray, k: int, rng) -> dict:
    """The widths (% of range, per parameter) of one point's readings (module docstring)
    and the Jacobians' comparison; ``data``: per condition the pooled pairs, sections and
    gain derivatives of :func:`statistics_information.condition_data`."""
    conds = list(data)
    d = np.concatenate([data[c]["d_all"] for c in conds], axis=2)[:, :, cols]
    d = d[:, np.all(np.isfinite(d), axis=(0, 2))]
    x = [data[c]["cov_all"] for c in conds]
    good = np.all([np.all(np.isfinite(xc), axis=1) for xc in x], axis=0)
    x = np.concatenate([xc[good] for xc in x], axis=1)[:, cols]
    n = len(x)
    g = block_diag(*[GAIN_ERROR**2 * data[c]["gains_all"].T @ data[c]["gains_all"]
                     for c in conds])[np.ix_(cols, cols)]  # fmt: skip
    # conditions are independent runs: their sections' cross-covariance is zero
    cond_of = np.repeat(np.arange(len(conds)), [data[c]["d_all"].shape[2] for c in conds])[cols]
    blocks = [np.flatnonzero(cond_of == i) for i in range(len(conds))]
    sample = np.zeros((len(cols), len(cols)))
    lw = np.zeros_like(sample)
    precision = np.zeros_like(sample)
    for b in blocks:
        sample[np.ix_(b, b)] = np.cov(x[:, b].T) / k
        lw[np.ix_(b, b)] = ledoit_wolf(x[:, b]) / k
        precision[np.ix_(b, b)] = unbiased_precision(x[:, b]) * k
    sl = post.likelihood
    p = sl.projection

    def width(weight: np.ndarray) -> np.ndarray:
        return widths_pct(information_unbiased(d, weight))

    out = {
        "full_ledoit_wolf_gain_prior": width(np.linalg.inv(lw + g)),
        "full_sample_raw_gains_known": width(np.linalg.inv(sample)),
        "full_unbiased_gains_known": width(precision),
        "projection_gains_known": width(projected_weight(p, sample, n)),
        "projection_gain_prior": width(projected_weight(p, sample + g, n)),
        "emulator_bound": widths_pct(fisher_information(sl, u0[None], k, emulator_error=False)[0]),
    }
    # a projection chosen at the point, whitened by one half's covariance, read by the other
    base = SyntheticLikelihood(sl.emulator, sl.shared)
    jac = mean_jacobian(base, u0[None])[0]
    order = rng.permutation(n)
    halves = (order[: n // 2], order[n // 2 :])
    local = []
    for a, b in (halves, halves[::-1]):
        choose, read = np.zeros_like(sample), np.zeros_like(sample)
        for blk in blocks:
            choose[np.ix_(blk, blk)] = ledoit_wolf(x[np.ix_(a, blk)]) / k
            read[np.ix_(blk, blk)] = np.cov(x[np.ix_(b, blk)].T) / k
        q, _ = top_directions(whitening(choose), jac, LOCAL_RANK)
        local.append(width(projected_weight(q, read, len(b))))
    out["chosen_at_point_cross_validated"] = np.mean(local, axis=0)
    # the emulator's Jacobian through P against the pairs'
    # (the pairs' mean's norm is overstated by their noise: its square is read unbiased, by
    # the products of different pairs; its product with the emulator's is unbiased as it is)
    whiten = whitening(p @ sample @ p.T)
    samples = np.einsum("ij,akj->aki", whiten @ p, d)
    squares = np.diag(information_unbiased(samples, None))
    emulated = whiten @ mean_jacobian(sl, u0[None])[0]
    jacobians = {}
    for j, name in enumerate(MAIN_SUSPENSION):
        na, nb = np.sqrt(max(squares[j], 0.0)), np.linalg.norm(emulated[:, j])
        # None where a parameter moves nothing (X12 at the nominal wagon: its pairs are equal)
        product = samples[j].mean(axis=0) @ emulated[:, j]
        cosine = float(product / (na * nb)) if na * nb > 0 else None
        jacobians[name] = {"pairs": float(na), "emulator": float(nb), "cosine": cosine}
    return {"widths_pct": {key: dict(zip(MAIN_SUSPENSION, np.asarray(v).tolist(), strict=True))
                           for key, v in out.items()},
            "jacobians": jacobians, "pairs": d.shape[1], "sections": n}  # fmt: skip


def main() -> None:
    from railsusp.estimate.posterior_synthetic_run import load

    ap = parser(__doc__)
    add_design_arguments(ap, "bench/results/projection_information.json")
    ap.add_argument("--run", required=True, help="run folder of a trained synthetic likelihood")
    ap.add_argument("--gain-sections", type=int, default=40, help="sections for G (as cached)")
    a = ap.parse_args()
    seeds, conds = parse_design(ap, a, [("--gain-sections", a.gain_sections, 1, 50_000)])
    post = load(a.run)
    if post.likelihood.projection is None:
        ap.error(f"--run {a.run}: its likelihood reads no projection (statistics en14363)")
    names = [c.name for c in post.settings.conditions]
    by_name = {c.name: (ci, c) for ci, c in enumerate(conds)}
    missing = [c for c in names if c not in by_name]
    if missing:
        ap.error(f"--conditions {a.conditions}: the run's condition {missing[0]} is missing")
    try:
        cols = columns_of(post.settings.summary_names, names)
    except ValueError as e:
        ap.error(f"--run {a.run}: {e}")
    # the bench's sections are its conditions' whole runs; the run's must be as long
    for name in names:
        run_s = by_name[name][1].duration_s
        if abs(run_s - post.settings.section_s) > 1e-9:
            ap.error(f"--run {a.run}: its sections of {post.settings.section_s:g} s, the "
                     f"bench's {name} runs {run_s:g} s: accepted equal")  # fmt: skip
    k = round(a.seconds / post.settings.section_s)
    t0 = time.perf_counter()
    rows = []
    for p, u0 in enumerate(parameter_points(a.points, a.point_seed)):
        data = {}  # in the run's order of conditions, as its columns are
        for name in names:
            ci, cond = by_name[name]
            q = pooled([condition_data(a, cond, ci, p, u0, s) for s in seeds])
            data[name] = {
                f"{part}_all": np.concatenate([q[part][g] for g in GROUPS], axis=-1)
                for part in ("d", "cov", "gains")
            }
        rows.append({"point": p, **point_readings(data, cols, post, u0, k,
                                                  np.random.default_rng([p, 41]))})  # fmt: skip
        print(f"point {p}: {time.perf_counter() - t0:.0f} s", flush=True)
    readings = list(rows[0]["widths_pct"])
    print(f"\nCramer-Rao 90 % width at {k * post.settings.section_s:g} s, % of range: the median "
          f"of {', '.join(KEYS)} per point (all ten unknown)")  # fmt: skip
    print(f"{'reading':36s} " + " ".join(f"{'p' + str(r['point']):>6}" for r in rows))
    for key in readings:
        meds = [np.median([r["widths_pct"][key][n] for n in KEYS]) for r in rows]
        print(f"{key:36s} " + " ".join(f"{m:6.1f}" for m in meds))
    print("\nthe emulator's Jacobian through P against the pairs' (whitened norms, cosine)")
    for r in rows:
        jac = r["jacobians"]
        cells = "  ".join(
            f"{n} {jac[n]['pairs']:.0f}/{jac[n]['emulator']:.0f} "
            + ("-" if jac[n]["cosine"] is None else f"{jac[n]['cosine']:.3f}")
            for n in KEYS
        )
        print(f"  p{r['point']}: {cells}")
    out = {"date": time.strftime("%Y-%m-%d"), "options": vars(a), "run": a.run,
           "projection_rank": int(post.likelihood.projection.shape[0]),
           "sections": k, "rows": rows, "seconds": time.perf_counter() - t0}  # fmt: skip
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(Path(a.out), (json.dumps(out, indent=2) + "\n").encode())
    print(f"wrote {a.out}")


if __name__ == "__main__":
    run_main(main)
