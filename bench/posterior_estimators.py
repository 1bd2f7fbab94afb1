"""Neural posterior (NPE) against neural likelihood (NLE) and ratio (NRE) estimation with
sbi, on the same simulations and the same held-out records (issue 20, item 1: "compare with
its neural likelihood or ratio estimators"). Prints the tables and writes JSON.

    python bench/posterior_estimators.py --run RUN --conditions straight,curve --section 20 \\
        --train 2000 --check 200 --long 200 --long-length 120 [--statistics all] \\
        [--read en14363] [--methods npe,nle,nre]

Reads (or simulates what is missing, like every posterior bench) the cached cases of
``RUN/posterior/simulations``: the first ``--train`` training cases (one section each, all
ten parameters from the prior, a new track each), ``--check`` held-out one-section cases
and ``--long`` held-out records of ``--long-length`` seconds per condition cut into
sections; ``--statistics`` names the families the run's files hold (its cache names
them), ``--read`` the families the estimators read (the EN 14363 summary by default: the
estimators are compared on the statistics every recording has).

Every estimator models the logit coordinates z of the parameters' fractions of range under
the logistic prior (the uniform box's image, as railsusp.estimate.posterior does), with the
same network size (``--hidden``, ``--transforms``), trained by sbi with its defaults on one
thread:

- **npe**: a masked autoregressive flow q(z | x), the production estimator; several sections
  are combined by its information fusion (railsusp.estimate.posterior_fusion), as in
  production, but with no spread correction (that needs the production's calibration
  cases; it is fitted on top of any of the three);
- **nle**: a flow q(x | z) of one section's statistics; a record's likelihood is taken as
  the product of its sections' (no fusion), which *assumes* the sections independent given
  the parameters: they are consecutive stretches of one run and share the record's
  instrument gain error (railsusp.estimate.posterior_data), so the assumption is tested
  here, not granted;
- **nre**: a classifier of (z, x) pairs (sbi's NRE, contrastive), whose log-ratios add over
  the sections likewise.

NLE's and NRE's posteriors are sampled by importance sampling (``--proposal`` draws per
record and round), resampled to ``--samples`` draws: for one section from the prior (sbi's
ImportanceSamplingPosterior); for several sections, whose product is far narrower than the
prior, by two rounds of adaptive importance sampling started from the NPE fusion's Gaussian
(``--guide npe``, the default; ``--guide prior`` keeps the prior, whose effective sample size
collapses there). The effective sample size per record is reported and stored: an interval
read from m effectively distinct draws covers less than 90 % however good the estimator
(about (m - 1) / (m + 1) at the level's edges), so coverage is also scored on the records
whose ESS reaches ``--min-ess``.
Scored per parameter on the held-out cases: coverage of the central 90 % interval with its
binomial check and the SBC rank test (railsusp.estimate.calibration.check), the median 90 %
width (% of range); plus training time and seconds per record.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from _cli import parser, positive_float, positive_int, run_main
from posterior import add_common_arguments, bench_conditions
from railsusp.estimate.calibration import check
from railsusp.estimate.posterior import TrainingLog
from railsusp.estimate.posterior_check import median_width
from railsusp.estimate.posterior_data import cached_cases
from railsusp.estimate.posterior_estimator import PosteriorEstimator, one_thread
from railsusp.estimate.posterior_fusion import (
    from_logit,
    fused_gaussian,
    fused_samples,
    logistic_prior,
    to_logit,
)
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import write_json

METHODS = ("npe", "nle", "nre")


def read_columns(stored: PosteriorSettings, read: PosteriorSettings) -> np.ndarray:
    """Indices into the stored statistics of those the estimators read."""
    names = list(stored.summary_names)
    missing = [n for n in read.summary_names if n not in names]
    if missing:
        raise SystemExit(f"--read: the run's statistics lack {missing[:3]} ...")
    return np.array([names.index(n) for n in read.summary_names])


def train_method(
    method: str,
    z: np.ndarray,
    x: np.ndarray,
    hidden: int,
    transforms: int,
    seed: int,
    max_epochs: int = 2**31 - 1,
):
    """(sbi inference object, trained network, seconds, epochs) of one method on (z, x)."""
    import torch
    from sbi.inference import NLE, NPE, NRE
    from sbi.neural_nets import classifier_nn, likelihood_nn, posterior_nn

    prior = logistic_prior(z.shape[1])
    torch.manual_seed(seed)
    if method == "npe":
        inference = NPE(prior=prior, density_estimator=posterior_nn(
            "maf", hidden_features=hidden, num_transforms=transforms),
            show_progress_bars=False, tracker=TrainingLog())  # fmt: skip
    elif method == "nle":
        inference = NLE(prior=prior, density_estimator=likelihood_nn(
            "maf", hidden_features=hidden, num_transforms=transforms),
            show_progress_bars=False, tracker=TrainingLog())  # fmt: skip
    else:
        inference = NRE(prior=prior, classifier=classifier_nn("resnet", hidden_features=hidden),
                        show_progress_bars=False, tracker=TrainingLog())  # fmt: skip
    t0 = time.perf_counter()
    with one_thread():
        inference.append_simulations(
            torch.as_tensor(z, dtype=torch.float32), torch.as_tensor(x, dtype=torch.float32)
        )
        net = inference.train(show_train_summary=False, max_num_epochs=max_epochs)
    net.eval()
    return inference, net, time.perf_counter() - t0, int(inference.summary["epochs_trained"][-1])


def draws_npe(
    flow: PosteriorEstimator, x: np.ndarray, n: int, seed: int
) -> tuple[np.ndarray, float]:
    """(n, d) uncorrected draws on the unit box of the sections ``x`` (k, D); ESS nan."""
    if x.shape[0] == 1:
        return flow.sample_raw(x[0], n, seed), float("nan")
    return fused_samples(flow, x, n, np.random.default_rng(seed)), float("nan")


def _mixture_draws(posterior, xt, proposal: int, prior_share: float, mean, cov):
    """(z, log weights) of ``proposal`` draws from a defensive mixture: a ``prior_share`` of
    them from the prior, the rest from the Gaussian (mean, cov) in logit coordinates; the
    weights are the potential (log prior + the sections' log likelihoods or ratios) over the
    mixture's density, with the shares actually drawn."""
    import torch

    prior = posterior.proposal  # the prior: sbi's proposal of an importance posterior
    gauss = torch.distributions.MultivariateNormal(
        torch.as_tensor(mean, dtype=torch.float32), torch.as_tensor(cov, dtype=torch.float32)
    )
    n_prior = round(prior_share * proposal)
    z = torch.cat([prior.sample((n_prior,)), gauss.sample((proposal - n_prior,))])
    log_mix = torch.logaddexp(
        prior.log_prob(z) + np.log(max(n_prior, 1e-300) / proposal),
        gauss.log_prob(z) + np.log(max(proposal - n_prior, 1e-300) / proposal),
    )
    return z, posterior.potential(z, x=xt) - log_mix


def _normalised(logw) -> np.ndarray:
    logw = logw.double().numpy()
    logw[~np.isfinite(logw)] = -np.inf
    if not np.any(np.isfinite(logw)):
        raise RuntimeError("importance sampling: no draw has a finite weight")
    w = np.exp(logw - logw.max())
    return w / w.sum()


def draws_importance(posterior, x: np.ndarray, n: int, proposal: int, seed: int, guide=None):
    """(n, d) draws on the unit box of the sections ``x`` (k, D) taken as independent
    trials, resampled (systematic) from ``proposal`` importance draws weighted by the
    estimator's likelihood (or ratio) times the prior over the proposal's density; and the
    effective sample size of the final weights.

    Without ``guide``: the prior is the proposal (sbi's ImportanceSamplingPosterior). With
    ``guide`` = (mean, covariance) in logit coordinates (the NPE fusion's Gaussian): two
    rounds of adaptive importance sampling, since the product of several sections'
    likelihoods is far narrower than the prior and prior draws leave too few effective
    samples: first a mixture of half prior, half the guide with its covariance doubled; then
    a fifth prior, four fifths the Gaussian of the first round's weighted draws, its
    covariance x 1.5 (the prior's share keeps the weights bounded in the tails)."""
    import torch

    torch.manual_seed(seed)
    xt = torch.as_tensor(x, dtype=torch.float32)
    with one_thread(), torch.no_grad():
        if guide is None:
            z, logw = posterior.sample(
                (proposal,), x=xt, method="importance", show_progress_bars=False
            )
        else:
            z, logw = _mixture_draws(posterior, xt, proposal, 0.5, guide[0], 2.0 * guide[1])
            w = _normalised(logw)
            zz = z.double().numpy()
            mean = w @ zz
            cov = (zz - mean).T @ ((zz - mean) * w[:, None]) + 1e-6 * np.eye(zz.shape[1])
            z, logw = _mixture_draws(posterior, xt, proposal, 0.2, mean, 1.5 * cov)
    w = _normalised(logw)
    ess = float(1.0 / np.sum(w**2))
    rng = np.random.default_rng(seed)
    positions = (rng.random() + np.arange(n)) / n
    idx = np.minimum(np.searchsorted(np.cumsum(w), positions), len(w) - 1)
    return from_logit(z.double().numpy()[idx]), ess


def score(draws: np.ndarray, truth: np.ndarray, names: list[str]) -> dict:
    """Coverage (90 %), its checks and the median width per parameter."""
    cal = check(draws, truth, names)
    widths = median_width(draws, names)
    return {
        "coverage": {c.parameter: c.coverage for c in cal},
        "passed": {c.parameter: bool(c.passed) for c in cal},
        "sbc_p": {c.parameter: c.sbc_p for c in cal},
        "width_pct": widths,
        "n_passed": int(sum(c.passed for c in cal)),
        "n_in_band": int(sum(0.85 <= c.coverage <= 0.95 for c in cal)),
    }


def main() -> None:
    ap = parser(__doc__)
    add_common_arguments(ap, "bench/results/posterior_estimators.json")
    ap.add_argument(
        "--long", type=positive_int, default=200, help="held-out records of several sections"
    )
    ap.add_argument("--long-length", type=positive_float, default=120.0, help="their length, s")
    ap.add_argument("--statistics", default="en14363", help="the families the run's files hold")
    ap.add_argument("--read", default="en14363", help="the families the estimators read")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--samples", type=positive_int, default=1000, help="draws per record")
    ap.add_argument(
        "--proposal",
        type=positive_int,
        default=20_000,
        help="NLE/NRE: importance draws per record and round",
    )
    ap.add_argument(
        "--guide",
        default="npe",
        help="NLE/NRE over several sections: importance proposal 'prior', or 'npe' (two "
        "adaptive rounds started from the NPE fusion's Gaussian, with a share of prior)",
    )
    ap.add_argument("--min-ess", type=float, default=200.0, help="records scored as well sampled")
    ap.add_argument("--hidden", type=positive_int, default=50)
    ap.add_argument("--transforms", type=positive_int, default=5)
    a = ap.parse_args()
    if a.guide not in ("prior", "npe"):
        raise SystemExit(f"--guide {a.guide}: accepted prior or npe")
    methods = [m for m in a.methods.split(",") if m]
    if not methods or any(m not in METHODS for m in methods):
        raise SystemExit(f"--methods {a.methods}: accepted a comma list of {', '.join(METHODS)}")

    longest = max(1, round(a.long_length / a.section))
    common = dict(
        parameters=tuple(a.parameters.split(",")), section_s=a.section, n_train=a.train,
        n_check=a.check, product_sections=(longest,) if longest > 1 else (), n_product=a.long,
        hidden_features=a.hidden, num_transforms=a.transforms,
    )  # fmt: skip
    conditions = bench_conditions(a)
    stored = PosteriorSettings(conditions, statistics=tuple(a.statistics.split(",")), **common)
    read = PosteriorSettings(conditions, statistics=tuple(a.read.split(",")), **common)
    cols_x = read_columns(stored, read)
    cols_p = [MAIN_SUSPENSION.index(p) for p in read.parameters]
    names = list(read.parameters)
    folder = Path(a.run) / "posterior" / "simulations"

    u, x = cached_cases(stored, folder, "train", a.train)
    ok = np.all(np.isfinite(x), axis=1)
    z_train, x_train = to_logit(u[ok][:, cols_p]), x[ok][:, cols_x]
    held = []
    u1, x1 = cached_cases(stored, folder, "check", a.check)
    ok1 = np.all(np.isfinite(x1), axis=1)
    held.append((1, u1[ok1][:, cols_p], x1[ok1][:, None, cols_x]))
    if longest > 1:
        ul, xl = cached_cases(stored, folder, "long", a.long, longest)
        okl = np.all(np.isfinite(xl), axis=(1, 2))
        held.append((longest, ul[okl][:, cols_p], xl[okl][:, :, cols_x]))
    print(f"{len(x_train)} training cases, {x_train.shape[1]} statistics ({a.read}); held out: "
          + ", ".join(f"{len(t)} x {k} sections" for k, t, _ in held))  # fmt: skip

    results = []
    trained = {}
    guided = a.guide == "npe"
    order = ["npe"] + [m for m in methods if m != "npe"] if guided else methods
    for method in order:
        inference, net, t_train, epochs = train_method(
            method, z_train, x_train, a.hidden, a.transforms, read.seed
        )
        trained[method] = (inference, net)
        print(f"\n{method}: trained in {t_train:.0f} s ({epochs} epochs)")
        if method not in methods:
            continue
        flow = PosteriorEstimator(read, [net], []) if method == "npe" else None
        posterior = None if method == "npe" else inference.build_posterior(sample_with="importance")
        npe_flow = PosteriorEstimator(read, [trained["npe"][1]], []) if guided else None
        for k, truth, xs in held:
            t0 = time.perf_counter()
            out, ess = [], []
            proposal = "prior" if method == "npe" or k == 1 or not guided else "adaptive-npe"
            for i, xi in enumerate(xs):
                if method == "npe":
                    d, e = draws_npe(flow, xi, a.samples, read.seed + i)
                else:
                    g = fused_gaussian(npe_flow, xi, read.seed + i) if k > 1 and guided else None
                    d, e = draws_importance(posterior, xi, a.samples, a.proposal, read.seed + i, g)
                out.append(d)
                ess.append(e)
            per_record = (time.perf_counter() - t0) / len(xs)
            row = {"method": method, "sections": k, "length_s": k * a.section, "cases": len(xs),
                   "proposal": proposal if method != "npe" else None,
                   "train_s": t_train, "epochs": epochs, "s_per_record": per_record,
                   "ess_median": float(np.nanmedian(ess)) if method != "npe" else None,
                   "ess_min": float(np.nanmin(ess)) if method != "npe" else None,
                   "ess": [round(e, 1) for e in ess] if method != "npe" else None,
                   **score(np.stack(out), truth, names)}  # fmt: skip
            if method != "npe":
                keep = np.array(ess) >= a.min_ess
                row["well_sampled"] = {"min_ess": a.min_ess, "cases": int(keep.sum())}
                if keep.sum() >= 20:
                    row["well_sampled"].update(score(np.stack(out)[keep], truth[keep], names))
            results.append(row)
            ess_text = (
                f", ESS median {row['ess_median']:.0f}, min {row['ess_min']:.0f}"
                if method != "npe"
                else ""
            )
            print(
                f"  {k * a.section:g} s ({len(xs)} cases, {per_record:.2f} s each{ess_text}): "
                f"{row['n_passed']} of {len(names)} pass"
            )
            good = row.get("well_sampled", {})
            if "coverage" in good:
                cov = " ".join(f"{p} {good['coverage'][p]:.2f}" for p in names)
                print(f"    ESS >= {a.min_ess:g} ({good['cases']} cases): {cov}")
    _tables(results, names)
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "settings_stored": stored.to_dict(),
        "read": a.read,
        "proposal_draws": a.proposal,
        "guide": a.guide,
        "samples": a.samples,
        "results": results,
    }
    write_json(a.out, out)
    print(f"wrote {a.out}")


def _tables(results: list[dict], names: list[str]) -> None:
    for what, key, fmt in (("coverage of the 90 % intervals", "coverage", "{:5.2f}"),
                           ("median 90 % width, % of range", "width_pct", "{:5.1f}")):  # fmt: skip
        print(f"\n{what}, held-out cases")
        print(f"{'method':>6} {'length':>6} " + " ".join(f"{p:>5}" for p in names)
              + "  passed  in 85-95 %")  # fmt: skip
        for r in results:
            cells = " ".join(fmt.format(r[key][p]) for p in names)
            print(f"{r['method']:>6} {r['length_s']:>5g}s {cells}  {r['n_passed']:>2}/{len(names)}"
                  f"    {r['n_in_band']:>2}/{len(names)}")  # fmt: skip


if __name__ == "__main__":
    run_main(main)
