"""The information in the whole record's second-order structure (Whittle): can any
geometry-free reading of the instrumented wheelset's forces give a 90 % interval of <= 10 %
of range at 600 s per condition for X11, X13 and X14 (issue 20's width target)?

    python bench/spectral_information.py                    # the cache of statistics_information.py
    python bench/spectral_information.py --seed 0,1,2       # its three seeds pooled

``statistics_information.py`` bounds what chosen statistics (up to 405 of them) can tell;
this bounds what the forces can tell through their means and their full cross-spectral
matrix, whatever statistic reads them. On unknown track the forces are, at constant speed,
a stationary random process whose law the parameters set; for a Gaussian stationary
process the information of a record of T seconds about the parameters is Whittle's
(Whittle 1953; Brockwell and Davis, "Time Series: Theory and Methods", 1991, sec. 10.8):

    I_ab = T * integral over f > 0 of tr(S^-1 dS/da S^-1 dS/db) df  +  dm/da^T C_m^-1 dm/db

with S(f) the (channels x channels) cross-spectral density matrix and m the channels' means
(C_m their covariance over the record). Every periodogram ordinate of the record (one per
1/T Hz) is a complex Gaussian vector of covariance S, independent of the others; the
integral is their information summed. Here it is read in bands of ``--bandwidths`` Hz
(``B T`` ordinates each, S and its derivatives the band averages, which the Welch segments
of ``--segment`` s already smooth). This is an approximation of the integral, neither a
bound nor monotone in the band width: averaging S and dS over a band can overstate the
information about a resonance's damping and understate that about its frequency. The
table shows how much the figures move with the band. The ``sections`` reading
(:func:`condition_information`) is a statistic, so a coarser band there can only carry
less. What lies beyond a Gaussian
process's second-order structure (the forces' skewness and peaks, which EN 14363's
percentiles read) is not in it: for the linearised wagon it is the whole information, for
the real one (flange contact, friction wedges) it is a measurement of the information in
all spectra, cross-spectra and means, not a proof that nothing more exists.

The simulations are statistics_information.py's (same points, conditions, tracks, noise
draws and cache, ``--work``): for each parameter the common-random-number pairs give
Jacobian samples d = (S+ - S-) / 2 delta of each band's cross-spectral matrix (Hann-
tapered periodograms of the 20 s sections, means removed) and of the means, the sections
at the point give S and C_m. The bilinear form tr(S^-1 A S^-1 B) is a dot product of the
whitened matrices S^-1/2 A S^-1/2 (:func:`whitened_features`), so the U-statistic of
``information_estimate.py`` (products of different pairs only) estimates the information
without the upward bias of the pairs' noise. The instrument's gain error (1 % per channel
and record) is a nuisance per condition: S's derivative with respect to channel c's gain is
E_c S + S E_c, the means' m_c e_c; its information is taken out by the Schur complement
with the gain prior's 1 / 0.01^2 added. Widths as statistics_information.py's (box prior,
all ten unknown; no prior; each alone) for the measured wheel alone (Y, Q) and for both
wheels (4 channels), at ``--seconds`` (and 120 s, 900 s, 1200 s from the same information:
the spectra's part grows with T, the means' covariance is the sections' over T / 20 s).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from _cli import parser, run_main
from information_estimate import (
    information_split,
    information_unbiased,
    ledoit_wolf,
    widths_alone_pct,
    widths_pct,
)
from railsusp.estimate.posterior_data import GAIN_ERROR
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import atomic_write_bytes
from statistics_information import (
    KEYS,
    add_design_arguments,
    instrumented,
    named,
    pair_differences,
    parameter_points,
    parse_design,
    run_design,
    simulate_cached,
)

#: channel subsets: the measured wheel (Y, Q) and both wheels of the wheelset
CHANNEL_SETS = {"measured wheel": (0, 1), "both wheels": (0, 1, 2, 3)}
#: other record lengths printed beside ``--seconds``
LENGTHS_S = (120.0, 600.0, 900.0, 1200.0)


# ----------------------------------------------------------------- spectra
def band_edges(fmin: float, fmax: float, width: float) -> np.ndarray:
    """Edges of the bands of ``width`` Hz from fmin, the last one reaching fmax (up to
    one width wider: no sliver of a band without a Fourier frequency)."""
    n = max(1, int(np.floor((fmax - fmin) / width + 1e-9)))
    edges = fmin + width * np.arange(n + 1)
    edges[-1] = fmax
    return edges


def section_spectra(x: np.ndarray, fs: float, bands: list[np.ndarray], segments: int = 4) -> tuple:
    """(means (C,), [band cross-spectral matrices (nb, C, C) complex per set of band edges
    in ``bands``]) of one section ``x`` (C, T): the channels' means, then Welch's estimate
    of the mean-free channels' cross-spectral matrix (Hann segments of T / ``segments``
    samples overlapping by half: a single tapered periodogram would waste about half of
    the section's information, the taper's weight falling to zero at its ends; half-
    overlapping Hann segments weight the section nearly evenly) averaged over the Fourier
    frequencies in each band [e_i, e_i+1) (scaled to a one-sided density; the information
    does not depend on the scale)."""
    x = np.asarray(x, dtype=float)
    m = x.mean(axis=1)
    seg = x.shape[1] // segments
    w = np.hanning(seg)
    starts = range(0, x.shape[1] - seg + 1, seg // 2)
    per = 0.0
    for i in starts:
        part = x[:, i : i + seg]
        spec = np.fft.rfft((part - part.mean(axis=1, keepdims=True)) * w, axis=1)
        per = per + np.einsum("if,jf->fij", spec, spec.conj())
    per = per * (2.0 / (fs * np.sum(w**2) * len(starts)))
    f = np.fft.rfftfreq(seg, 1.0 / fs)
    out = []
    for edges in bands:
        # a frequency on an edge belongs to the band above it, whichever way it rounded
        band = np.searchsorted(edges, f + 1e-9 * fs, side="right") - 1
        spec_b = np.empty((len(edges) - 1, len(m), len(m)), dtype=complex)
        for b in range(len(edges) - 1):
            sel = band == b
            if not np.any(sel):
                raise ValueError(f"band {edges[b]:g}-{edges[b + 1]:g} Hz: no Fourier frequency")
            spec_b[b] = per[sel].mean(axis=0)
        out.append(spec_b)
    return m, out


def spectra_of(forces, keys, fs: float, noise: float, seed: int, bands, segments: int) -> tuple:
    """(means (n, C), [spectra (n, nb, C, C) per set of band edges]) of the runs ``forces``
    (n, C, T) through the instrument of statistics_information.py (its ``instrumented``:
    the same noise draws as its statistics); NaN for a failed run."""
    c = forces.shape[1]
    means = np.full((len(forces), c), np.nan)
    spectra = [np.full((len(forces), len(e) - 1, c, c), np.nan, dtype=complex) for e in bands]
    for i, x in enumerate(instrumented(forces, keys, fs, noise, seed)):
        if x is not None:
            means[i], per_band = section_spectra(x, fs, bands, segments)
            for out, sb in zip(spectra, per_band, strict=True):
                out[i] = sb
    return means, spectra


# ----------------------------------------------------------------- Whittle information
def inverse_sqrt(s: np.ndarray) -> np.ndarray:
    """S^-1/2 of Hermitian positive definite matrices (..., C, C)."""
    w, v = np.linalg.eigh(s)
    return (v / np.sqrt(w)[..., None, :]) @ np.swapaxes(v.conj(), -1, -2)


def hermitian_features(a: np.ndarray) -> np.ndarray:
    """Real vectors (..., C^2) of Hermitian matrices (..., C, C) whose dot product is
    tr(A B): the diagonal, then sqrt 2 times the real and the imaginary parts of the upper
    triangle."""
    c = a.shape[-1]
    iu = np.triu_indices(c, 1)
    diag = np.real(np.diagonal(a, axis1=-2, axis2=-1))
    up = a[..., iu[0], iu[1]]
    return np.concatenate([diag, np.sqrt(2) * up.real, np.sqrt(2) * up.imag], axis=-1)


def whitened_features(d: np.ndarray, s: np.ndarray, ordinates: np.ndarray) -> np.ndarray:
    """(..., nb C^2) features of spectral derivatives ``d`` (..., nb, C, C) whose dot
    products are sum_b N_b tr(S_b^-1 A_b S_b^-1 B_b): the Whittle information's bilinear
    form, ``s`` (nb, C, C) the spectra, ``ordinates`` (nb,) the N_b = B_b T Fourier
    ordinates of each band in the record."""
    root = inverse_sqrt(s)
    white = root @ d @ root
    feats = hermitian_features(0.5 * (white + np.swapaxes(white.conj(), -1, -2)))
    feats = feats * np.sqrt(ordinates)[:, None]
    return feats.reshape(*feats.shape[:-2], -1)


def gain_marginal(i_tt: np.ndarray, i_tg: np.ndarray, i_gg: np.ndarray) -> np.ndarray:
    """The parameters' information with the channel gains unknown: the Schur complement
    I_tt - I_tg (I_gg + P)^-1 I_gt, P the gain prior's information 1 / GAIN_ERROR^2."""
    prior = np.eye(len(i_gg)) / GAIN_ERROR**2
    return i_tt - i_tg @ np.linalg.solve(i_gg + prior, i_tg.T)


def condition_information(
    means_d, spectra_d, means_c, spectra_c, edges, channels, seconds: float, section_s: float,
    rng=None, covariance: str = "whittle",
) -> dict:  # fmt: skip
    """Information (P, P) of a record of ``seconds`` about the parameters from the
    ``channels``' means and band cross-spectra, gains marginalised: ``means_d`` (P, K, C)
    and ``spectra_d`` (P, K, nb, C, C) the pairs' Jacobian samples, ``means_c`` (N, C) and
    ``spectra_c`` (N, nb, C, C) the sections at the point.

    ``covariance="whittle"``: the spectra's covariance a Gaussian process's (each of the
    record's Fourier ordinates an independent complex Gaussian vector of covariance S),
    the means' the sections'. ``"sections"``: the band spectra and means read as statistics
    whose covariance is the sections' own (Ledoit-Wolf, over ``seconds / section_s``
    sections), as statistics_information.py reads its families: no Gaussian assumption,
    but no finer reading than the bands. With ``rng``, the null test: the pairs with random
    signs."""
    if covariance not in ("whittle", "sections"):
        raise ValueError(f"covariance {covariance!r}: accepted whittle, sections")
    ch = np.asarray(channels)
    md, sd = means_d[..., ch], spectra_d[..., ch[:, None], ch[None, :]]
    mc, sc = means_c[:, ch], spectra_c[:, :, ch[:, None], ch[None, :]]
    ok = np.all(np.isfinite(md), axis=(0, 2)) & np.all(np.isfinite(sd), axis=(0, 2, 3, 4))
    md, sd = md[:, ok], sd[:, ok]
    good = np.all(np.isfinite(mc), axis=1) & np.all(np.isfinite(sc), axis=(1, 2, 3))
    mc, sc = mc[good], sc[good]
    if rng is not None:
        signs = rng.choice([-1.0, 1.0], size=md.shape[:2])
        md, sd = md * signs[..., None], sd * signs[..., None, None, None]
    s = sc.mean(axis=0)
    # the gains' derivatives: S_ij (delta_ic + delta_jc), m_c e_c
    e = np.eye(len(ch))
    ds_g = np.stack([e[c][:, None] * s + s * e[c][None, :] for c in range(len(ch))])
    dm_g = np.diag(mc.mean(axis=0))
    out = {"pairs": int(md.shape[1]), "sections": len(mc)}
    if covariance == "whittle":
        ordinates = np.diff(edges) * seconds
        root_m = inverse_sqrt(np.atleast_2d(np.cov(mc.T)) * section_s / seconds).real
        feats = np.concatenate([md @ root_m, whitened_features(sd, s, ordinates)], axis=-1)
        g_feats = np.concatenate([dm_g @ root_m, whitened_features(ds_g, s, ordinates)], axis=-1)
        i_tt = information_unbiased(feats, None)
        i_tg, i_gg = feats.mean(axis=1) @ g_feats.T, g_feats @ g_feats.T
        out["unbiased"] = gain_marginal(i_tt, i_tg, i_gg)
        out["gains_known"] = i_tt
        if rng is None:
            out["split"] = gain_marginal(information_split(feats, None), i_tg, i_gg)
    else:
        ones = np.ones(len(edges) - 1)
        feats = np.concatenate([md, whitened_features(sd, s, ones)], axis=-1)
        x = np.concatenate([mc, whitened_features(sc, s, ones)], axis=-1)
        g_feats = np.concatenate([dm_g, whitened_features(ds_g, s, ones)], axis=-1)
        cov = ledoit_wolf(x) * section_s / seconds
        weight = np.linalg.inv(cov + GAIN_ERROR**2 * g_feats.T @ g_feats)
        out["unbiased"] = information_unbiased(feats, weight)
        out["gains_known"] = information_unbiased(feats, np.linalg.inv(cov))
        if rng is None:
            out["split"] = information_split(feats, weight)
    out["features"] = int(feats.shape[-1])
    return out


# ----------------------------------------------------------------- the bench
def condition_spectra(a, cond, ci: int, p: int, u0: np.ndarray, seed: int, bands) -> dict:
    """Means and band spectra (a list, one per set of band edges in ``bands``) of the pairs
    (as Jacobian samples) and of the covariance sections of one point, condition and seed,
    from statistics_information.py's cache."""
    folder = Path(a.work) / "simulations"
    design = run_design(a, cond, ci, p, u0, seed)
    fs = 1.0 / cond.sample_interval
    segments = max(1, round(cond.duration_s / a.segment))
    u, seeds, keys, name = design["pairs"]
    forces = simulate_cached(cond, u, seeds, folder, name)
    m, s = spectra_of(forces, keys, fs, a.noise, seed, bands, segments)
    cu, cseeds, ckeys, cname = design["cov"]
    forces = simulate_cached(cond, cu, cseeds, folder, cname)
    mc, sc = spectra_of(forces, ckeys, fs, a.noise, seed, bands, segments)
    return {
        "means_d": pair_differences(m, a.tracks, a.delta),
        "spectra_d": [pair_differences(x, a.tracks, a.delta) for x in s],
        "means_c": mc,
        "spectra_c": sc,
    }


def _named(values) -> dict[str, float]:
    return named(list(MAIN_SUSPENSION), values)


def widths_row(total: dict) -> dict:
    """Widths (% of range) of a summed information: box prior, no prior, alone, split-half,
    gains known."""
    return {
        "width_pct": _named(widths_pct(total["unbiased"])),
        "width_no_prior_pct": _named(widths_pct(total["unbiased"], 0.0)),
        "width_alone_pct": _named(widths_alone_pct(total["unbiased"])),
        "width_split_pct": _named(widths_pct(total["split"])),
        "width_gains_known_pct": _named(widths_pct(total["gains_known"])),
    }


def point_rows(data, edges, bw, p, lengths, seconds_main, section_s, seed, covariances):
    """Rows of one point and band width: per covariance (:func:`condition_information`),
    channel set, conditions and record length, the widths of the summed informations; at
    ``seconds_main`` also the null test."""
    rows = []
    names = list(data)
    csets = [cs for cs in (("straight", "curve"), tuple(names)) if all(c in data for c in cs)]
    for covariance in covariances:
        for label, channels in CHANNEL_SETS.items():
            # each condition's information once per length, summed for every set of conditions
            kws = {seconds: dict(edges=edges, channels=channels, seconds=seconds,
                                 section_s=section_s, covariance=covariance)
                   for seconds in lengths}  # fmt: skip
            per_condition = {
                seconds: {c: condition_information(**data[c], **kw) for c in names}
                for seconds, kw in kws.items()
            }
            for cset in csets:
                for seconds in lengths:
                    kw = kws[seconds]
                    infos = [per_condition[seconds][c] for c in cset]
                    total = {
                        k: sum(i[k] for i in infos) for k in ("unbiased", "split", "gains_known")
                    }
                    row = {
                        "covariance": covariance,
                        "bandwidth_hz": bw,
                        "point": p,
                        "channels": label,
                        "conditions": list(cset),
                        "seconds": seconds,
                        "pairs": min(i["pairs"] for i in infos),
                        "sections": min(i["sections"] for i in infos),
                        "features": sum(i["features"] for i in infos),
                        **widths_row(total),
                        "information": total["unbiased"].tolist(),
                    }
                    if seconds == seconds_main:
                        rng = np.random.default_rng([seed, 5, p])
                        null = sum(condition_information(**data[c], **kw, rng=rng)["unbiased"]
                                   for c in cset)  # fmt: skip
                        with np.errstate(divide="ignore", invalid="ignore"):
                            ratio = np.diag(null) / np.diag(total["unbiased"])
                        row["null_over_information"] = _named(ratio)
                    rows.append(row)
    return rows


def main() -> None:
    ap = parser(__doc__)
    add_design_arguments(ap, "bench/results/spectral_information.json")
    ap.add_argument("--bandwidths", default="1,0.5,0.25", help="band widths, Hz")
    ap.add_argument("--segment", type=float, default=5.0, help="Welch segment, s")
    ap.add_argument(
        "--min-section-band",
        type=float,
        default=0.5,
        help="Hz; the sections' covariance only for bands this wide or wider",
    )
    ap.add_argument("--fmin", type=float, default=0.1, help="lowest frequency, Hz")
    ap.add_argument("--fmax", type=float, default=15.0, help="highest: the instrument's band")
    a = ap.parse_args()
    try:
        widths = [float(v) for v in a.bandwidths.split(",") if v.strip()]
    except ValueError:
        widths = []
    if not widths or any(not 0.05 <= w <= 5.0 for w in widths):
        ap.error(f"--bandwidths {a.bandwidths}: accepted 0.05 to 5 Hz, comma-separated")
    seeds, conds = parse_design(
        ap,
        a,
        [("--segment", a.segment, 1.0, 20.0), ("--fmin", a.fmin, 0.05, 10.0),
         ("--fmax", a.fmax, a.fmin + 0.05, 25.0)],
    )  # fmt: skip
    if min(widths) < 1.0 / a.segment - 1e-9:
        ap.error(f"--bandwidths {a.bandwidths}: every band at least 1 / --segment "
                 f"= {1.0 / a.segment:g} Hz wide (the segments' frequency step)")  # fmt: skip
    section_s = conds[0].duration_s
    points = parameter_points(a.points, a.point_seed)
    lengths = sorted({a.seconds, *LENGTHS_S})
    t0 = time.perf_counter()
    bands = [band_edges(a.fmin, a.fmax, bw) for bw in widths]
    rows = []
    for p, u0 in enumerate(points):
        per_cond = {}
        for ci, cond in enumerate(conds):
            parts = [condition_spectra(a, cond, ci, p, u0, s, bands) for s in seeds]
            per_cond[cond.name] = {
                "means_d": np.concatenate([q["means_d"] for q in parts], axis=1),
                "spectra_d": [np.concatenate([q["spectra_d"][b] for q in parts], axis=1)
                              for b in range(len(bands))],
                "means_c": np.concatenate([q["means_c"] for q in parts]),
                "spectra_c": [np.concatenate([q["spectra_c"][b] for q in parts])
                              for b in range(len(bands))],
            }  # fmt: skip
        print(f"point {p}: spectra {time.perf_counter() - t0:.0f} s", flush=True)
        for b, (bw, edges) in enumerate(zip(widths, bands, strict=True)):
            data = {
                c: {k: (v[b] if k.startswith("spectra") else v) for k, v in q.items()}
                for c, q in per_cond.items()
            }
            covs = ("whittle", "sections") if bw >= a.min_section_band else ("whittle",)
            rows += point_rows(data, edges, bw, p, lengths, a.seconds, section_s, seeds[0], covs)
    print(f"in all {time.perf_counter() - t0:.0f} s")
    print_tables(rows, a.seconds)
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "options": vars(a),
        "points": points.tolist(),
        "rows": rows,
        "seconds": time.perf_counter() - t0,
    }
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(Path(a.out), (json.dumps(out, indent=2) + "\n").encode())
    print(f"wrote {a.out}")


def print_tables(rows: list[dict], seconds: float) -> None:
    """Median over the points of the keys' widths: per covariance, channels, conditions and
    band width at ``seconds``, then per record length at each covariance's finest band."""

    def med(rs, col, n):
        return np.median([r[col][n] for r in rs])

    def group(r):
        return (r["covariance"], r["channels"], tuple(r["conditions"]))

    groups = sorted({group(r) for r in rows})
    print(f"\n90 % width at {seconds:g} s, % of range, box prior, median over the points")
    head = f"{'covariance':10s} {'channels':15s} {'conditions':21s} {'band Hz':>7} "
    print(head + " ".join(f"{k:>6}" for k in KEYS))
    for g in groups:
        for bw in sorted({r["bandwidth_hz"] for r in rows if group(r) == g}, reverse=True):
            rs = [r for r in rows if group(r) == g and r["bandwidth_hz"] == bw
                  and r["seconds"] == seconds]  # fmt: skip
            cells = " ".join(f"{med(rs, 'width_pct', k):6.1f}" for k in KEYS)
            print(f"{g[0]:10s} {g[1]:15s} {'+'.join(g[2]):21s} {bw:7g} {cells}")
    print("\nfinest band: box prior | no prior | alone | split-half | gains known; by length")
    for g in groups:
        finest = min(r["bandwidth_hz"] for r in rows if group(r) == g)
        for sec in sorted({r["seconds"] for r in rows}):
            rs = [r for r in rows if group(r) == g and r["bandwidth_hz"] == finest
                  and r["seconds"] == sec]  # fmt: skip
            cells = "  ".join(
                f"{k} {med(rs, 'width_pct', k):5.1f}|{med(rs, 'width_no_prior_pct', k):5.1f}|"
                f"{med(rs, 'width_alone_pct', k):5.1f}|{med(rs, 'width_split_pct', k):5.1f}|"
                f"{med(rs, 'width_gains_known_pct', k):5.1f}"
                for k in KEYS
            )
            print(f"  {g[0]:8s} {g[1]:14s} {'+'.join(g[2]):21s} {finest:g} Hz {sec:6g} s  {cells}")
    print("\nnull test (pairs with random signs), information / the real one, keys:")
    for r in rows:
        if "null_over_information" in r:
            cells = " ".join(f"{r['null_over_information'][k]:6.3f}" for k in KEYS)
            print(f"  p{r['point']} {r['covariance']:8s} {r['bandwidth_hz']:4g} Hz "
                  f"{r['channels']:14s} {'+'.join(r['conditions']):21s} {cells}")  # fmt: skip


if __name__ == "__main__":
    run_main(main)
