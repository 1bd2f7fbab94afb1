"""Fisher information of candidate geometry-free statistics about X11-X20, straight from
simulations (no emulator): can richer statistics than today's 17 make a 90 % interval of
<= 10 % of range reachable at 600 s per condition for X13, X11 and X14 (issue 20)?

    python bench/statistics_information.py                 # default: 3 points, 24 tracks
    python bench/statistics_information.py --seed 1        # same points, other tracks
    python bench/statistics_information.py --delta 0.025   # another difference step

At each parameter point u (fractions of the ranges: the nominal wagon, then ``--points``
- 1 draws in the middle 80 % of every range) and each working condition (straight, curve,
uphill at 60 km/h, Class 5 track, as the posterior bench; 20 s sections):

- for each parameter j, ``--tracks`` K pairs u + delta e_j, u - delta e_j, each pair on
  one new track realisation and with one instrument noise draw (common random numbers),
  a track of its own per pair and parameter: Jacobian samples d = (s+ - s-) / 2 delta of
  the section statistics s;
- ``--cov`` sections at u, each on a track of its own: the section covariance Sigma
  (Ledoit-Wolf shrunk, :func:`ledoit_wolf`);
- the instrument as the posterior's (15 Hz bandwidth, ``--noise`` white noise); its gain
  error (1 % per channel and record) shared by all sections of a record enters as
  G = 0.01^2 sum_c g_c g_c^T, g_c the statistics' derivative with respect to channel c's
  gain, and the mean of n = ``--seconds`` / 20 sections has covariance Sigma / n + G.

The information of the mean of n sections is J^T (Sigma / n + G)^-1 J, J the mean
Jacobian. The plug-in J-bar^T W J-bar is biased upwards by J-bar's noise (by about
tr(W Cov d) / K, large with many statistics), so the estimate is the U-statistic
(:func:`information_unbiased`): the products of different pairs only, which is unbiased
for J^T W J whatever the noise; a split-half version and the plug-in are printed as checks,
and a null test (the same pairs with random signs: no consistent effect, so zero
information) shows the estimator invents none. Conditions add their informations; the
Cramer-Rao 90 % width 2 x 1.645 x sqrt((I^-1)_jj), all ten parameters unknown
(:func:`railsusp.estimate.posterior_synthetic_information.cramer_rao_width`), per candidate
statistic set (:data:`SETS`) in % of range: with a Gaussian prior of the uniform prior's variance
(``information_estimate.py``), without any prior, and each parameter alone
(the nine others known, :func:`widths_alone_pct`). Simulations (the four force channels of
the measured wheelset) are cached in ``--work``, and so are their statistics; ``--seed
0,1,2`` pools the pairs and sections of several seeds, ``--seconds`` rescores another record
length from the cache without simulating.
"""

from __future__ import annotations

import argparse
import io
import json
import time
from pathlib import Path

import numpy as np

from _cli import parser, run_main
from information_estimate import (
    information_naive,
    information_split,
    information_unbiased,
    ledoit_wolf,
    widths_alone_pct,
    widths_pct,
)
from railsusp.condition_files import resolve_conditions
from railsusp.estimate.posterior_data import BANDWIDTH_HZ, GAIN_ERROR, to_si
from railsusp.measured.synthetic import bandwidth_filter
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import atomic_write_bytes
from statistics_candidates import FIRST_GROUPS, GROUPS, group_names, section_statistics

KEYS = ("X18", "X13", "X11", "X14", "X19")
#: candidate statistic sets: (label, groups of statistics_candidates, conditions)
SETS: tuple[tuple[str, tuple[str, ...], tuple[str, ...]], ...] = (
    ("a today's 17", ("today",), ("straight", "curve")),
    ("b + third-octave", ("today", "third_octave"), ("straight", "curve")),
    ("c + both wheels", ("today", "both_wheels"), ("straight", "curve")),
    ("d + cross", ("today", "cross"), ("straight", "curve")),
    ("e today's, + uphill", ("today",), ("straight", "curve", "uphill")),
    ("f all groups", FIRST_GROUPS, ("straight", "curve")),
    ("g all groups, + uphill", FIRST_GROUPS, ("straight", "curve", "uphill")),
    ("h today's + cross-spectra", ("today", "spectra"), ("straight", "curve")),
    ("i f + cross-spectra", GROUPS, ("straight", "curve")),
    ("j g + cross-spectra", GROUPS, ("straight", "curve", "uphill")),
)
#: track seeds of this bench start here (the posterior's kinds use 10-60 million)
SEED_BASE = 70_000_000
CHUNK = 64
#: the information estimates of :func:`condition_information`
ESTIMATES = ("unbiased", "split", "naive", "null_unbiased", "null_naive")
#: the statistics' version in the names of their cache files (change it with the statistics)
STATISTICS_VERSION = "v2"
#: relative gain step of the statistics' gain derivative
GAIN_STEP = 0.01


# ----------------------------------------------------------------- simulations
def parameter_points(count: int, seed: int) -> np.ndarray:
    """(count, 10) points in fractions of the ranges: the nominal wagon (0.5), then draws
    uniform in the middle 80 % of every range."""
    rng = np.random.default_rng([seed, 20])
    draws = 0.1 + 0.8 * rng.random((max(count - 1, 0), len(MAIN_SUSPENSION)))
    return np.vstack([np.full((1, len(MAIN_SUSPENSION)), 0.5), draws])[:count]


def simulate_cached(cond, u: np.ndarray, seeds: np.ndarray, folder: Path, name: str):
    """(n, 4, T) forces in kN of the measured wheelset (:data:`statistics_candidates.
    CHANNELS`) for the parameter sets ``u`` (fractions) on tracks ``seeds``; NaN for a
    failed run. Chunks of :data:`CHUNK` cached as ``NAME_NNNN.npz`` (atomic writes), read
    back when their sets and seeds are the same."""
    from railsusp.vehicle.simulate import simulate_batch

    out = []
    for c, lo in enumerate(range(0, len(u), CHUNK)):
        uu, ss = u[lo : lo + CHUNK], seeds[lo : lo + CHUNK]
        path = folder / f"{name}_{c:04d}.npz"
        if path.exists():
            with np.load(path) as z:
                if np.array_equal(z["u"], uu) and np.array_equal(z["seeds"], ss):
                    out.append(z["forces"])
                    continue
        res = simulate_batch(to_si(uu), cond, symbols=MAIN_SUSPENSION, seeds=[int(s) for s in ss])
        j = res.measured_wheel()
        f = np.stack([res.Y[:, j], res.Q[:, j], res.Y[:, j ^ 1], res.Q[:, j ^ 1]], axis=1)
        f = (f[..., : cond.n_steps] / 1e3).astype(np.float32)
        f[~res.ok] = np.nan
        buf = io.BytesIO()
        np.savez(buf, u=uu, seeds=ss, forces=f)
        atomic_write_bytes(path, buf.getvalue())
        out.append(f)
    return np.concatenate(out)


def instrument(forces: np.ndarray, fs: float, rng: np.random.Generator, noise: float):
    """The posterior's instrument model without its gain error (which enters as G): a
    15 Hz bandwidth and white noise of ``noise`` times each channel's RMS; (4, T)."""
    x = np.asarray(forces, dtype=float)
    rms = np.sqrt(np.mean(x**2, axis=1, keepdims=True))
    return bandwidth_filter(x, fs, BANDWIDTH_HZ) + noise * rms * rng.standard_normal(x.shape)


def instrumented(forces, keys, fs: float, noise: float, seed: int):
    """Each run of ``forces`` (n, 4, T) through :func:`instrument`, or None for a failed
    run; ``keys`` (n, ...) seed each run's noise draw (equal keys, equal draw: the pairs'
    common numbers; the spectral bench reads the same draws)."""
    for f, key in zip(forces, keys, strict=True):
        if not np.all(np.isfinite(f)):
            yield None
            continue
        yield instrument(f, fs, np.random.default_rng([seed, *[int(k) for k in key]]), noise)


def statistics_of(forces, keys, fs: float, speed: float, noise: float, seed: int):
    """{group: (n, D_g)} statistics of the runs ``forces`` (n, 4, T) through the instrument
    (:func:`instrumented`); NaN for a failed run."""
    rows = [
        section_statistics(x, fs, speed) if x is not None else None
        for x in instrumented(forces, keys, fs, noise, seed)
    ]
    sizes = {g: len(group_names(g)) for g in GROUPS}
    return {
        g: np.array([r[g] if r is not None else np.full(sizes[g], np.nan) for r in rows])
        for g in GROUPS
    }


def gain_derivatives(forces, fs: float, speed: float, noise: float, seed: int):
    """{group: (4, D_g)}: the statistics' derivative with respect to each channel's relative
    gain, central differences of :data:`GAIN_STEP`, averaged over the sections given."""
    out = {g: np.zeros((4, len(group_names(g)))) for g in GROUPS}
    good = [f for f in forces if np.all(np.isfinite(f))]
    for i, f in enumerate(good):
        x = instrument(f, fs, np.random.default_rng([seed, 9, i]), noise)
        for c in range(4):
            up, down = x.copy(), x.copy()
            up[c] *= 1.0 + GAIN_STEP
            down[c] *= 1.0 - GAIN_STEP
            su, sd = section_statistics(up, fs, speed), section_statistics(down, fs, speed)
            for g in GROUPS:
                out[g][c] += (su[g] - sd[g]) / (2 * GAIN_STEP) / len(good)
    return out


def run_design(a, cond, ci: int, p: int, u0: np.ndarray, seed: int) -> dict:
    """The runs of one point and condition with the tracks and noise of ``seed``: for the
    pairs and for the covariance sections, the parameter sets ``u`` (fractions), the track
    seeds, the noise keys of :func:`statistics_of` and the cache name of
    :func:`simulate_cached` (``tag`` names the point, condition and seed)."""
    npar, k = len(MAIN_SUSPENSION), a.tracks
    base = SEED_BASE + ((seed * 16 + p) * 4 + ci) * 100_000
    # run order: track k, parameter j, sign (+, -): more tracks append chunks
    kk, jj, ss = np.meshgrid(np.arange(k), np.arange(npar), [1, -1], indexing="ij")
    kk, jj, ss = kk.ravel(), jj.ravel(), ss.ravel()
    u = np.repeat(u0[None], kk.size, axis=0)
    u[np.arange(kk.size), jj] += ss * a.delta
    tag = f"s{seed}_p{p}_{cond.name}"
    cseeds = base + 50_000 + np.arange(a.cov)
    return {
        "tag": tag,
        "pairs": (u, base + kk * npar + jj,
                  np.stack([np.full(kk.size, p), np.full(kk.size, ci), kk, jj], axis=1),
                  f"{tag}_d{a.delta:g}_pairs"),
        "cov": (np.repeat(u0[None], a.cov, axis=0), cseeds,
                np.stack([np.full(a.cov, p), np.full(a.cov, ci), np.full(a.cov, 999), cseeds],
                         axis=1),
                f"{tag}_cov"),
    }  # fmt: skip


def pair_differences(s: np.ndarray, tracks: int, delta: float) -> np.ndarray:
    """(P, K, ...) Jacobian samples (s+ - s-) / 2 delta of per-run values ``s`` (runs in
    :func:`run_design`'s order: track, parameter, sign)."""
    s = s.reshape(tracks, len(MAIN_SUSPENSION), 2, *s.shape[1:])
    return np.moveaxis((s[:, :, 0] - s[:, :, 1]) / (2 * delta), 0, 1)


def condition_data(a, cond, ci: int, p: int, u0: np.ndarray, seed: int) -> dict:
    """Pairs, covariance sections and gain derivatives of one point and condition, the
    tracks and noise of ``seed``."""
    folder = Path(a.work) / "simulations"
    design = run_design(a, cond, ci, p, u0, seed)
    cache_design = f"d{a.delta:g}_k{a.tracks}_c{a.cov}_n{a.noise:g}_g{a.gain_sections}"
    cache = Path(a.work) / "statistics" / f"{design['tag']}_{cache_design}_{STATISTICS_VERSION}.npz"
    if cache.exists():
        with np.load(cache) as z:
            return {part: {g: z[f"{part}_{g}"] for g in GROUPS} for part in ("d", "cov", "gains")}
    fs, speed = 1.0 / cond.sample_interval, cond.speed
    u, seeds, keys, name = design["pairs"]
    forces = simulate_cached(cond, u, seeds, folder, name)
    st = statistics_of(forces, keys, fs, speed, a.noise, seed)
    d = {g: pair_differences(s, a.tracks, a.delta) for g, s in st.items()}
    cu, cseeds, ckeys, cname = design["cov"]
    cforces = simulate_cached(cond, cu, cseeds, folder, cname)
    cov = statistics_of(cforces, ckeys, fs, speed, a.noise, seed)
    gains = gain_derivatives(cforces[: a.gain_sections], fs, speed, a.noise, seed)
    out = {"d": d, "cov": cov, "gains": gains}
    buf = io.BytesIO()
    np.savez(buf, **{f"{part}_{g}": out[part][g] for part in out for g in GROUPS})
    atomic_write_bytes(cache, buf.getvalue())
    return out


def pooled(parts: list[dict]) -> dict:
    """The pairs and covariance sections of several seeds as one sample (the gain
    derivatives averaged)."""
    return {
        "d": {g: np.concatenate([q["d"][g] for q in parts], axis=1) for g in GROUPS},
        "cov": {g: np.concatenate([q["cov"][g] for q in parts]) for g in GROUPS},
        "gains": {g: np.mean([q["gains"][g] for q in parts], axis=0) for g in GROUPS},
    }


# ----------------------------------------------------------------- the analysis
def condition_information(data: dict, groups, sections: int, rng, half_cov=False) -> dict:
    """Estimated informations (P, P) of the mean of ``sections`` sections of one point and
    condition for the statistics ``groups``: unbiased, split-half, plug-in, and the null
    test (the pairs with random signs) by the unbiased and the plug-in estimators."""
    d = np.concatenate([data["d"][g] for g in groups], axis=2)
    x = np.concatenate([data["cov"][g] for g in groups], axis=1)
    gains = np.concatenate([data["gains"][g] for g in groups], axis=1)
    d = d[:, np.all(np.isfinite(d), axis=(0, 2))]  # pairs where every run ran
    x = x[np.all(np.isfinite(x), axis=1)]
    x = x[: len(x) // 2] if half_cov else x
    cov = ledoit_wolf(x) / sections + GAIN_ERROR**2 * gains.T @ gains
    weight = np.linalg.inv(cov)
    signs = rng.choice([-1.0, 1.0], size=d.shape[:2])[..., None]
    return {
        "unbiased": information_unbiased(d, weight),
        "split": information_split(d, weight),
        "naive": information_naive(d, weight),
        "null_unbiased": information_unbiased(signs * d, weight),
        "null_naive": information_naive(signs * d, weight),
        "pairs": d.shape[1],
        "cov_sections": len(x),
        "statistics": d.shape[2],
    }


def named(names: list[str], values: np.ndarray) -> dict[str, float]:
    """{name: value} of a vector over ``names``, for the JSON."""
    return dict(zip(names, np.asarray(values, float).tolist(), strict=True))


def set_results(data: dict, names: list[str], sections: int, seed: int) -> list[dict]:
    """Per point and candidate set: the widths of every estimate and the null test."""
    out = []
    for p, per_cond in data.items():
        for label, groups, conds in SETS:
            if any(c not in per_cond for c in conds):
                continue
            rng = np.random.default_rng([seed, 5, p])
            infos = [condition_information(per_cond[c], groups, sections, rng) for c in conds]
            half = [condition_information(per_cond[c], groups, sections, rng, True) for c in conds]
            total = {k: sum(i[k] for i in infos) for k in ESTIMATES}
            diag = np.diag(total["unbiased"])
            row = {
                "point": p,
                "set": label,
                "statistics": sum(i["statistics"] for i in infos),
                "pairs": min(i["pairs"] for i in infos),
                "cov_sections": min(i["cov_sections"] for i in infos),
                "width_pct": named(names, widths_pct(total["unbiased"])),
                "width_no_prior_pct": named(names, widths_pct(total["unbiased"], 0.0)),
                "width_alone_pct": named(names, widths_alone_pct(total["unbiased"])),
                "width_split_pct": named(names, widths_pct(total["split"])),
                "width_naive_pct": named(names, widths_pct(total["naive"])),
                "width_half_cov_pct": named(names, widths_pct(sum(i["unbiased"] for i in half))),
                "null_over_information": named(names, np.diag(total["null_unbiased"]) / diag),
                "null_naive_over_information": named(names, np.diag(total["null_naive"]) / diag),
                "information": total["unbiased"].tolist(),
            }
            out.append(row)
    return out


def print_tables(rows: list[dict], names: list[str], points: int) -> None:
    labels = [s[0] for s in SETS]
    print("\nCramer-Rao 90 % width, % of range, all ten unknown, median over the points")
    print(f"{'set':24s} {'D':>4} " + " ".join(f"{n:>6}" for n in names))
    for lab in labels:
        rs = [r for r in rows if r["set"] == lab]
        if not rs:
            continue
        med = [np.median([r["width_pct"][n] for r in rs]) for n in names]
        print(f"{lab:24s} {rs[0]['statistics']:4d} " + " ".join(f"{w:6.1f}" for w in med))
    print(
        "\nper point, key parameters (unbiased | split-half | plug-in | C from half the sections)"
    )
    for p in range(points):
        print(f"point {p}")
        for r in (r for r in rows if r["point"] == p):
            cells = "  ".join(
                f"{n} {r['width_pct'][n]:5.1f}|{r['width_split_pct'][n]:5.1f}|"
                f"{r['width_naive_pct'][n]:5.1f}|{r['width_half_cov_pct'][n]:5.1f}"
                for n in KEYS
            )
            print(f"  {r['set']:24s} {cells}")
    print("\nnull test (pairs with random signs), information / the real one, keys:")
    for r in rows:
        nu = " ".join(f"{r['null_over_information'][n]:6.3f}" for n in KEYS)
        nn = " ".join(f"{r['null_naive_over_information'][n]:6.3f}" for n in KEYS)
        print(f"  p{r['point']} {r['set']:24s} unbiased {nu}   plug-in {nn}")


def add_design_arguments(ap: argparse.ArgumentParser, out: str) -> None:
    """The options of the simulation design (points, seeds, pairs, sections, instrument,
    record length, conditions) that this bench and spectral_information.py share."""
    ap.add_argument("--work", default="runs/statistics_information", help="simulation cache")
    ap.add_argument("--out", default=out)
    ap.add_argument("--points", type=int, default=3, help="nominal + middle-80 %% draws")
    ap.add_argument("--point-seed", type=int, default=0, help="seed of the points' draws")
    ap.add_argument("--seed", default="0", help="seed of tracks and noise; several (0,1,2): pooled")
    ap.add_argument("--tracks", type=int, default=24, help="pairs per parameter (K)")
    ap.add_argument("--cov", type=int, default=300, help="sections at the point for Sigma")
    ap.add_argument("--delta", type=float, default=0.05, help="half-step, fraction of range")
    ap.add_argument("--noise", type=float, default=0.03, help="instrument noise, of the RMS")
    ap.add_argument("--seconds", type=float, default=600.0, help="record per condition, s")
    ap.add_argument("--conditions", default="straight,curve,uphill")
    ap.add_argument("--lead-in", type=float, default=30.0, help="m; a curve keeps its own")


def parse_design(ap: argparse.ArgumentParser, a, checks=()) -> tuple[list[int], list]:
    """(seeds, conditions) of :func:`add_design_arguments`' options, with their ranges and
    the further ``checks`` (name, value, low, high) checked: a one-line error otherwise."""
    try:
        seeds = [int(v) for v in a.seed.split(",") if v.strip()]
    except ValueError:
        seeds = []
    if not seeds or any(not 0 <= v <= 99 for v in seeds) or len(set(seeds)) != len(seeds):
        ap.error(f"--seed {a.seed}: accepted distinct whole numbers 0 to 99, comma-separated")
    design = [("--points", a.points, 1, 16), ("--tracks", a.tracks, 4, 1000),
              ("--cov", a.cov, 20, 50_000), ("--delta", a.delta, 0.001, 0.1),
              ("--noise", a.noise, 0.0, 0.5), ("--seconds", a.seconds, 20.0, 36_000.0)]  # fmt: skip
    for name, value, lo, hi in [*design, *checks]:
        if not lo <= value <= hi:
            ap.error(f"{name} {value:g}: accepted {lo:g} to {hi:g}")
    conds = [
        c.with_changes(lead_in_m=max(a.lead_in, c.lead_in_m if c.curve_radius_m else 0.0))
        for c in resolve_conditions(a.conditions)
    ]
    return seeds, conds


def main() -> None:
    ap = parser(__doc__)
    add_design_arguments(ap, "bench/results/statistics_information.json")
    ap.add_argument("--gain-sections", type=int, default=40, help="sections for G")
    a = ap.parse_args()
    seeds, conds = parse_design(ap, a, [("--gain-sections", a.gain_sections, 1, 50_000)])
    points = parameter_points(a.points, a.point_seed)
    sections = round(a.seconds / conds[0].duration_s)
    names = list(MAIN_SUSPENSION)
    t0 = time.perf_counter()
    data: dict = {}
    for p, u0 in enumerate(points):
        for ci, cond in enumerate(conds):
            t1 = time.perf_counter()
            parts = [condition_data(a, cond, ci, p, u0, seed) for seed in seeds]
            data.setdefault(p, {})[cond.name] = pooled(parts)
            print(f"point {p} {cond.name}: {time.perf_counter() - t1:.0f} s", flush=True)
    t_sim = time.perf_counter() - t0
    rows = set_results(data, names, sections, seeds[0])
    print_tables(rows, names, len(points))
    print(f"\nsimulations + statistics {t_sim:.0f} s, in all {time.perf_counter() - t0:.0f} s")
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "options": vars(a),
        "points": points.tolist(),
        "sections_per_condition": sections,
        "conditions": [c.model_dump() for c in conds],
        "sets": [{"label": s[0], "groups": s[1], "conditions": s[2]} for s in SETS],
        "rows": rows,
        "seconds": time.perf_counter() - t0,
    }
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(Path(a.out), (json.dumps(out, indent=2) + "\n").encode())
    print(f"wrote {a.out}")


if __name__ == "__main__":
    run_main(main)
