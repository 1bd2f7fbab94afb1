"""How much of a parameter's effect does a sequence surrogate pass on, frequency by frequency?
(issue 19: a network inverted by NSGA-II needs the simulator's parameter sensitivity.)
Writes bench/results/pair_gains.json.

On the campaign's held-out test runs (tracks and parameter sets no network saw) and their
perturbed twins (:mod:`railsusp.campaign.perturbed`: one key parameter moved by 5 % of its
range on the same track), it compares the surrogate's difference of the two predictions,
Δf = f(θ') − f(θ), with the simulator's, Δy = y' − y, after the network's washout, per
moved parameter and force:

- ``gain``: the least-squares slope Σ Δf·Δy / Σ Δy² (1: the right size; a network that
  passes on half of the effect has 0.5), ``cosine`` and the pair error
  Σ (Δf − Δy)² / Σ Δy² (the pair term of :mod:`railsusp.surrogate.pairs`: 1 for a network
  the parameter does not move);
- the same gain per frequency band (real part of the cross spectrum over the simulator's
  auto spectrum, summed over the band and the runs), with the band's share of Σ Δy², so
  that one sees where the effect lies and where the network loses it.

It needs no new simulation (bench/jacobian_check.py measures the same on simulated 60 s
recordings with noise and geometry error, minutes per set)::

    python bench/pair_gains.py RUN --kinds cnn-gru-seq-nominal-e43,cnn-gru-seq-nominal-pairs
"""

from __future__ import annotations

import platform
import time
from pathlib import Path

import numpy as np
import torch

from _cli import parser, run_main
from railsusp.campaign import load_campaign
from railsusp.store import write_json
from railsusp.surrogate import load
from railsusp.surrogate.data import SeriesData, load_series
from railsusp.surrogate.evaluate import predict_series
from railsusp.surrogate.pairs import load_twins
from railsusp.surrogate.split import campaign_split

#: frequency bands, Hz (the last one open to the Nyquist frequency)
BANDS = ((0.0, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 4.0), (4.0, 8.0), (8.0, np.inf))


def open_band(band: tuple[float, float]) -> tuple[float, float | None]:
    """A band as JSON writes it: an open upper end as None."""
    return band[0], None if np.isinf(band[1]) else band[1]


def band_gains(dy: np.ndarray, df: np.ndarray, dt: float) -> list[dict]:
    """Per band of :data:`BANDS`: the gain Re Σ conj(Y) F / Σ |Y|² of differences ``df`` on
    ``dy`` (runs, steps), and the band's share of Σ |Y|² (one-sided spectra, mean removed
    from neither: a shift of the mean is in the lowest band)."""
    y = np.fft.rfft(dy, axis=1)
    f = np.fft.rfft(df, axis=1)
    freq = np.fft.rfftfreq(dy.shape[1], dt)
    cross = np.real(np.conj(y) * f).sum(axis=0)
    auto = (np.abs(y) ** 2).sum(axis=0)
    total = auto.sum()
    rows = []
    for lo, hi in BANDS:
        sel = (freq >= lo) & (freq < hi)
        a = auto[sel].sum()
        rows.append(
            {
                "band_hz": list(open_band((lo, hi))),
                "share": float(a / total) if total > 0 else float("nan"),
                "gain": float(cross[sel].sum() / a) if a > 0 else float("nan"),
            }
        )
    return rows


def pair_scores(dy: np.ndarray, df: np.ndarray, dt: float) -> dict:
    """Gain, cosine, pair error and band gains of differences ``df`` on ``dy`` (runs, steps)."""
    yy = float(np.sum(dy * dy))
    return {
        "gain": float(np.sum(df * dy) / yy),
        "cosine": float(np.sum(df * dy) / np.sqrt(yy * np.sum(df * df))),
        "pair_error": float(np.sum((df - dy) ** 2) / yy),
        "bands": band_gains(dy, df, dt),
    }


def network_pair_gains(run: Path, kind: str, condition: str, split_seed: int = 0) -> dict:
    """Scores of :func:`pair_scores` per moved parameter and force of the surrogate
    ``RUN/surrogates/<kind>/<condition>`` on its campaign's test runs and their twins."""
    sur = load(run / "surrogates" / kind / condition)
    camp = load_campaign(run)
    data = load_series(camp, condition, sur.spec)
    test = data.subset(campaign_split(camp, split_seed).positions(data.sample_ids, "test"))
    twins = load_twins(camp, test, sur.spec)
    table = camp_moves(run, test.sample_ids)
    pred = predict_series(sur, test)
    w = sur.spec.window
    dt = test.condition.sample_interval
    out: dict = {}
    for j in range(twins.params_unit.shape[1]):
        ok = twins.ok[:, j]
        twin = SeriesData(**{**vars(test), "params_unit": twins.params_unit[:, j]})
        pred_twin = predict_series(sur, twin)
        moved = table[j]
        for p in sorted(set(moved[ok])):
            rows = ok & (moved == p)
            for k, target in enumerate(sur.spec.targets):
                dy = (twins.targets[rows, j, w:, k] - test.targets[rows, w:, k]).astype(float)
                df = pred_twin[rows, w:, k] - pred[rows, w:, k]
                out.setdefault(p, {}).setdefault(target, []).append((dy, df))
    scores = {}
    for p, per_target in out.items():
        for target, parts in per_target.items():
            dy = np.concatenate([a for a, _ in parts])
            df = np.concatenate([b for _, b in parts])
            scores.setdefault(p, {})[target] = {"pairs": len(dy), **pair_scores(dy, df, dt)}
    return scores


def camp_moves(run: Path, sample_ids: np.ndarray) -> list[np.ndarray]:
    """Per twin, the parameter each of ``sample_ids``'s twin moved."""
    from railsusp.campaign.perturbed import read_perturbations

    table = read_perturbations(run).set_index(["twin", "sample_id"])["parameter"]
    n_twins = int(table.index.get_level_values(0).max()) + 1
    return [table.loc[j].loc[sample_ids].to_numpy() for j in range(n_twins)]


def print_scores(kind: str, scores: dict) -> None:
    print(f"\n{kind}: gain / cosine / pair error; gain per band (share of the effect)")
    for p in sorted(scores):
        for target, s in scores[p].items():
            bands = "  ".join(f"{b['gain']:+.2f}({100 * b['share']:.0f}%)" for b in s["bands"])
            print(
                f"  {p} {target}  {s['gain']:+.2f} / {s['cosine']:+.2f} / {s['pair_error']:.2f}"
                f"   {bands}"
            )


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("run", type=Path, help="campaign with surrogates and perturbed twins")
    ap.add_argument("--kinds", required=True, help="comma list of folders under surrogates/")
    ap.add_argument("--condition", default="straight")
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--out", type=Path, default=Path("bench/results/pair_gains.json"))
    args = ap.parse_args()
    if args.threads < 1:
        ap.error(f"--threads {args.threads}: accepted an integer >= 1")
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    missing = [k for k in kinds if not (args.run / "surrogates" / k / args.condition).exists()]
    if missing:
        ap.error(
            f"--kinds {','.join(missing)}: no surrogate of {args.condition!r} under "
            f"{args.run / 'surrogates'}"
        )
    torch.set_num_threads(args.threads)
    result = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": platform.platform(),
        "run": str(args.run),
        "condition": args.condition,
        "bands_hz": [list(open_band(b)) for b in BANDS],
        "networks": {},
    }
    for kind in kinds:
        t0 = time.perf_counter()
        scores = network_pair_gains(args.run, kind, args.condition)
        result["networks"][kind] = {"seconds": time.perf_counter() - t0, "scores": scores}
        print_scores(kind, scores)
    print(f"wrote {write_json(args.out, result)}")


if __name__ == "__main__":
    run_main(main)
