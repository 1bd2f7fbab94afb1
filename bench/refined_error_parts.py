"""Where the refined estimate's error comes from, on the sets of bench/refined_coverage.py
(issue 20, target 3: why the 90 % intervals covered more than 90 %).

For every stored set (``--work``: the set-NN folders a refined_coverage.py run kept, exact
track), the hidden truth is known, so the error of each estimated parameter can be split.
One batch of simulations at the stored estimate (the estimated and the held parameters'
forward-difference steps, the estimate with the held parameters at their true values, and
the truth itself, noiseless) gives, in % of the parameter's range:

- ``linear``: the held parameters' part as the intervals model it, R (h_true - h_held),
  R = J_e⁺ J_h the estimate's linear response to the held parameters;
- ``stepped``: the same from the simulated change of the forces at the estimate when the
  held parameters move to their true values (a Gauss-Newton step): the linearisation's
  check over the whole deviation instead of a 5 % step;
- ``noise``: the sensor noise's part, -J_e⁺ r_truth, r_truth the residuals of the noiseless
  truth against the recordings (what the noise and gain errors leave);
- the standard errors of the noise part: the pooled Gauss-Newton one times √τ (the intervals
  before 2026-11-24 stop 23) and each channel with its own variance and τ (the sandwich,
  :func:`~railsusp.estimate.refine_intervals.noise_standard_errors`), and the held part's
  standard deviation with each held parameter uniform over its whole Table 2 range.

Prints per parameter the slope of the actual error on the linear prediction and the noise
part (1 and 1 where the model is right), the RMS of each part and of what they leave, and
the RMS of the noise part, and of the error less the linear held part, over each standard
error (1 where it is right), and the coverage of the 90 % intervals that each noise
standard error and each quantile (normal or the error's distribution) would give under
each prior (:data:`PRIORS`); writes JSON
(bench/results/refined_error_parts.json).

    python bench/refined_error_parts.py --work runs/refined_coverage/noise-0
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd

from _cli import parser, run_main
from railsusp.estimate.comparison import comparison_samples
from railsusp.estimate.forces import SimulatorForces
from railsusp.estimate.interval_distribution import error_quantiles
from railsusp.estimate.output_error import OutputError
from railsusp.estimate.refine import standard_errors
from railsusp.estimate.refine_intervals import (
    autocorrelation_time,
    effective_sample_size,
    held_parameters,
    held_values,
    noise_standard_errors,
)
from railsusp.measured import read_field
from railsusp.params import ParameterSet, bounds
from railsusp.store import read_json, write_json


def error_parts(set_dir: Path) -> list[dict]:
    """The error parts (module docstring) of every estimated parameter the set's validator
    called identifiable, % of range."""
    doc = read_json(set_dir / "estimate" / "estimate.json")
    params = tuple(doc["parameters"])
    recs = read_field(set_dir / "field")
    truth = ParameterSet(
        read_json(set_dir / "field" / "truth.json")["parameters_display"], units="display"
    )
    held = held_parameters(params)
    k, h = len(params), len(held)
    # where the estimate held them: a held prior's centres (held_at_display), else nominal
    held_at = doc.get("held_at_display") or {}
    base = ParameterSet(held_at, units="display") if held_at else None
    ext = OutputError(SimulatorForces((*params, *held)), recs, (*params, *held))
    lo, hi = bounds(params)
    lo_h, hi_h = bounds(held)
    x = ParameterSet(doc["estimate_display"], units="display").to_array(params)
    gains = doc["refinement"]["channel_gains"]
    g = np.array([gains[f"{r.condition.name}:{f}_{r.wheels[0]}"] for r in recs for f in "YQ"])
    u_e = (x - lo) / (hi - lo)
    u_t = (truth.to_array(params) - lo) / (hi - lo)
    u_h0 = (held_values(held, base) - lo_h) / (hi_h - lo_h)
    u_ht = (truth.to_array(held) - lo_h) / (hi_h - lo_h)
    zz = np.concatenate([u_e, u_h0, g])
    batch = np.vstack([ext.steps(zz[: k + h]), np.r_[u_e, u_ht], np.r_[u_t, u_ht]])
    preds = ext.predictions(batch)
    jac = ext.jacobian_of([p[: k + h + 1] for p in preds], zz)
    res = ext.residuals(preds, g)
    r_est, r_held_true, r_truth = res[0], res[k + h + 1], res[k + h + 2]
    j_e, j_h = jac[:, np.r_[0:k, k + h : jac.shape[1]]], jac[:, k : k + h]
    response = np.linalg.lstsq(j_e, j_h, rcond=None)[0][:k]
    linear = response @ (u_ht - u_h0)
    stepped = np.linalg.lstsq(j_e, r_held_true - r_est, rcond=None)[0][:k]
    noise = -np.linalg.lstsq(j_e, r_truth, rcond=None)[0][:k]
    blocks = [u[c].size for u in (comparison_samples(r) for r in recs) for c in range(2)]
    n_fit = j_e.shape[1]
    _, tau = effective_sample_size(r_est, blocks)
    pooled = np.sqrt(tau) * standard_errors(j_e, r_est @ r_est / (r_est.size - n_fit))[:k]
    per_channel = noise_standard_errors(j_e, r_est, blocks, n_fit)[:k]
    held_sd = np.sqrt((response**2).sum(axis=1) / 12.0)
    half = half_widths(response, pooled, per_channel)
    rec = pd.read_csv(set_dir / "estimate" / "validation" / "recovery.csv")
    identifiable = set(rec.loc[rec["identifiable"].astype(bool), "parameter"])
    taus = [autocorrelation_time(b) for b in np.split(r_est, np.cumsum(blocks)[:-1])]
    return [
        {
            "set": set_dir.name,
            "parameter": p,
            "error": 100 * (u_e[i] - u_t[i]),
            "linear": 100 * linear[i],
            "stepped": 100 * stepped[i],
            "noise": 100 * noise[i],
            "pooled_se": 100 * pooled[i],
            "per_channel_se": 100 * per_channel[i],
            "held_sd_table2": 100 * held_sd[i],
            "channel_mean_square": [
                float(b @ b / b.size) for b in np.split(r_est, np.cumsum(blocks)[:-1])
            ],
            "channel_tau": taus,
            **{name: 100 * w[i] for name, w in half.items()},
        }
        for i, p in enumerate(params)
        if p in identifiable
    ]


#: the held parameters' prior as the intervals may assume it, by name: each uniform over its
#: whole Table 2 range, or over the middle 80 % the sets are drawn from (both centred on
#: nominal, the value held, so a fraction of the range's half-width), or over
#: refined_coverage.py's ``lower40`` band, 40 % of the range centred on the value its sets
#: held (its centre, since stop 78): each right only for the sets drawn for it
PRIORS = {"table2": 1.0, "middle80": 0.8, "lower40": 0.4}


def half_widths(
    response: np.ndarray, pooled: np.ndarray, per_channel: np.ndarray
) -> dict[str, np.ndarray]:
    """(k,) half-widths of the 90 % interval, unit coordinates, for each prior, noise
    standard error (``pooled``, ``channel``) and quantile (``normal``: 1.645 times the total
    standard deviation; ``quantiles``: the central 90 % of the error's distribution,
    :func:`~railsusp.estimate.interval_distribution.error_quantiles`); the priors are
    centred on the values held, so the intervals are symmetric."""
    out = {}
    for prior, f in PRIORS.items():
        held_sd = f * np.sqrt((response**2).sum(axis=1) / 12.0)
        for noise_name, se in (("pooled", pooled), ("channel", per_channel)):
            out[f"half_{prior}_{noise_name}_normal"] = 1.645 * np.hypot(se, held_sd)
            _, upper = error_quantiles(response, np.full(response.shape[1], -f / 2),
                                       np.full(response.shape[1], f / 2), se)  # fmt: skip
            out[f"half_{prior}_{noise_name}_quantiles"] = upper
    return out


def coverage(rows: pd.DataFrame) -> pd.DataFrame:
    """Per prior and interval (noise standard error, quantile): the pooled share of the
    errors within the half-width and the 90th percentile of |error| over it (1: calibrated;
    the intervals before 2026-11-24 stop 23 are pooled + normal, those after channel +
    quantiles)."""
    out = []
    for col in [c for c in rows if c.startswith("half_")]:
        _, prior, noise, quantile = col.split("_")
        ratio = rows["error"].abs() / rows[col]
        out.append(
            {
                "prior": prior,
                "noise_standard_error": noise,
                "quantile": quantile,
                "covered": int((ratio <= 1.0).sum()),
                "cases": len(rows),
                "error_over_half_width_p90": float(np.quantile(ratio, 0.9)),
            }
        )
    return pd.DataFrame(out)


def rms(v: pd.Series) -> float:
    return float(np.sqrt(np.mean(np.square(v))))


def summary(rows: pd.DataFrame) -> pd.DataFrame:
    """Per parameter: slopes of the error on the linear held part and the noise part (least
    squares, no intercept), RMS of the parts and of the remainder, and the RMS of the noise
    part, and of the error less the linear held part, over each standard error."""
    out = {}
    for p, g in rows.groupby("parameter"):
        slopes = np.linalg.lstsq(np.c_[g.linear, g.noise], g.error, rcond=None)[0]
        out[p] = {
            "cases": len(g),
            "slope_linear": slopes[0],
            "slope_noise": slopes[1],
            "rms_error": rms(g.error),
            "rms_linear": rms(g.linear),
            "rms_stepped": rms(g.stepped),
            "rms_noise": rms(g.noise),
            "rms_left": rms(g.error - g.linear - g.noise),
            "noise_over_pooled": rms(g.noise / g.pooled_se),
            "noise_over_per_channel": rms(g.noise / g.per_channel_se),
            "not_held_over_pooled": rms((g.error - g.linear) / g.pooled_se),
            "not_held_over_per_channel": rms((g.error - g.linear) / g.per_channel_se),
        }
    return pd.DataFrame(out).T


def main(argv: list[str] | None = None) -> dict:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--work", type=Path, default=Path("runs/refined_coverage/noise-0"))
    ap.add_argument("--out", type=Path, default=Path("bench/results/refined_error_parts.json"))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = pd.DataFrame(
        [r for d in sorted(args.work.glob("set-[0-9][0-9]")) for r in error_parts(d)]
    )
    if rows.empty:
        print(f"no scored set under {args.work}")
        return {}
    table = summary(rows)
    print(f"{rows['set'].nunique()} sets under {args.work}; % of range, identifiable only\n")
    print(table.to_string(float_format=lambda v: f"{v:.3g}"))
    ms = np.array(rows.groupby("set").first()["channel_mean_square"].tolist())
    cover = coverage(rows)
    print("\n" + cover.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    print(f"\nresidual mean square per channel at the estimate (median over sets): "
          f"{np.round(np.median(ms, axis=0), 7).tolist()}")  # fmt: skip
    doc = {
        "date": time.strftime("%Y-%m-%d"),
        "work": str(args.work),
        "seconds": time.perf_counter() - t0,
        "per_case": rows.to_dict(orient="records"),
        "by_parameter": table.reset_index(names="parameter").to_dict(orient="records"),
        "coverage": cover.to_dict(orient="records"),
    }
    write_json(args.out, doc)
    print(f"wrote {args.out}")
    return doc


if __name__ == "__main__":
    run_main(main)
