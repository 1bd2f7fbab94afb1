"""Simulation-based posterior of the suspension parameters on track nobody measured.

Amortised neural posterior estimation (``sbi``'s NPE, a masked autoregressive flow): the
network learns q(theta | x), the distribution of the parameters given the geometry-free
summary statistics x of one section per condition (:mod:`railsusp.estimate.summaries`),
from simulated cases whose parameters come from the uniform Table 2 prior and whose track
is a new realisation each (:mod:`railsusp.estimate.posterior_data`). Once trained, a
recording's posterior costs a forward pass, no simulation.

The parameters are inferred as fractions u in [0, 1] of their ranges (a uniform prior on
the unit box), reported in display units.

**Calibration** is part of training: held-out simulated cases, drawn as the training ones,
are estimated, and the coverage of their 90 % intervals and the SBC ranks are checked per
parameter (:mod:`railsusp.estimate.calibration`). The result stores the verdict, and the
estimate of a recording says ``calibrated = False`` (and warns) for an estimator whose
check failed: it is never used silently.

**Long recordings** are cut into sections of the training length, and the posterior of
the whole is the product of the sections' likelihoods: p(theta | x_1..x_n) is proportional
to prior(theta) prod_i p(x_i | theta), and with a uniform prior and q(theta | x_i)
proportional to p(x_i | theta) on the box, to prod_i q(theta | x_i). Sections far apart
on the track see nearly independent irregularities, so their statistics are nearly
independent given theta, and this is the posterior a long record supports: its width
shrinks with the number of sections, unlike an average of the sections' statistics, whose
smaller scatter the estimator trained on one section would not know (its posterior would
keep the width of one section). The product is sampled by adaptive importance sampling
(Student-t proposals refitted to the weighted draws, Cappé et al. 2004, "Population Monte
Carlo"), and its effective sample size is reported: a product of approximate densities
amplifies their errors, so its coverage is checked in bench/posterior.py per record length.
"""

from __future__ import annotations

import io
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsusp.errors import RailsuspInputError
from railsusp.estimate.calibration import LEVEL, ParameterCalibration
from railsusp.estimate.calibration import check as check_calibration
from railsusp.estimate.intervals import Intervals, from_samples
from railsusp.estimate.posterior_data import (
    PosteriorSettings,
    cached_cases,
    recording_summaries,
    to_si,
)
from railsusp.params import MAIN_SUSPENSION, spec
from railsusp.store import atomic_write_bytes, content_hash, read_json, write_json

log = logging.getLogger(__name__)

#: effective sample size below which a combined posterior is flagged
MIN_ESS = 200.0


@dataclass
class PosteriorEstimator:
    """A trained estimator: settings, the sbi posterior, and its calibration."""

    settings: PosteriorSettings
    posterior: Any  # sbi DirectPosterior on the unit box
    calibration: list[ParameterCalibration]
    run: Path | None = None

    @property
    def calibrated(self) -> bool:
        return all(c.passed for c in self.calibration)

    def sample(self, x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
        """(n, d) draws (unit box) of the posterior of one summary vector ``x`` (D,) or of
        the product over sections, ``x`` (sections, D)."""
        import torch

        x = np.atleast_2d(np.asarray(x, dtype=float))
        torch.manual_seed(seed)
        if x.shape[0] == 1:
            xt = torch.as_tensor(x, dtype=torch.float32)
            return self.posterior.sample((n,), x=xt, show_progress_bars=False).numpy()
        return _product_samples(self, x, n, np.random.default_rng(seed))[0]

    def log_q(self, u: np.ndarray, x: np.ndarray) -> np.ndarray:
        """log q(u | x_i) summed over the sections ``x`` (sections, D), for (M, d) ``u``;
        -inf outside the unit box."""
        import torch

        est = self.posterior.posterior_estimator
        ut = torch.as_tensor(u, dtype=torch.float32)
        xt = torch.as_tensor(np.atleast_2d(x), dtype=torch.float32)
        with torch.no_grad():
            lp = est.log_prob(ut[:, None, :].expand(-1, xt.shape[0], -1), condition=xt)
        out = lp.sum(dim=1).double().numpy()
        out[~np.all((u >= 0) & (u <= 1), axis=1)] = -np.inf
        return out


def _product_samples(est: PosteriorEstimator, x: np.ndarray, n: int, rng, rounds: int = 4):
    """Draws of prod_i q(u | x_i) on the unit box by population Monte Carlo; returns the
    draws (resampled by weight) and the effective sample size of the last round."""
    from scipy.stats import multivariate_t

    pooled = np.concatenate([est.sample(xi, max(50, 2000 // len(x)), seed=i) for i, xi in
                             enumerate(x)])  # fmt: skip
    mean, cov = pooled.mean(axis=0), np.cov(pooled.T) + 1e-6 * np.eye(pooled.shape[1])
    m = 4000
    for r in range(rounds):
        prop = multivariate_t(mean, cov, df=5, seed=rng)
        u = np.atleast_2d(prop.rvs(m if r < rounds - 1 else 2 * m))
        logw = est.log_q(u, x) - prop.logpdf(u)
        w = np.exp(logw - np.max(logw))
        w /= w.sum()
        mean = w @ u
        cov = 2.0 * ((u - mean).T * w) @ (u - mean) + 1e-6 * np.eye(u.shape[1])
    ess = 1.0 / np.sum(w**2)
    pick = rng.choice(u.shape[0], size=n, replace=True, p=w)
    return u[pick], float(ess)


class _TrainingLog:
    """sbi's training tracker kept in memory (its default writes TensorBoard logs into the
    working directory): the last value of each metric, for the log."""

    log_dir = None

    def __init__(self) -> None:
        self.metrics: dict[str, float] = {}

    def log_metric(self, name: str, value: float, step: int | None = None) -> None:
        self.metrics[name] = float(value)

    def log_metrics(self, metrics: dict[str, float], step: int | None = None) -> None:
        for name, value in metrics.items():
            self.log_metric(name, value, step)

    def log_params(self, params: dict[str, Any]) -> None:
        pass

    def add_figure(self, name: str, figure: Any, step: int | None = None) -> None:
        pass

    def flush(self) -> None:
        pass


def _build(settings: PosteriorSettings, u: np.ndarray, x: np.ndarray):
    """The sbi NPE object and the flow's builder for the estimated parameters."""
    import torch
    from sbi.inference import NPE
    from sbi.neural_nets import posterior_nn
    from sbi.utils import BoxUniform

    d = len(settings.parameters)
    prior = BoxUniform(torch.zeros(d), torch.ones(d))
    builder = posterior_nn(
        "maf", hidden_features=settings.hidden_features, num_transforms=settings.num_transforms
    )
    cols = [MAIN_SUSPENSION.index(p) for p in settings.parameters]
    ok = np.all(np.isfinite(x), axis=1)
    theta_t = torch.as_tensor(u[ok][:, cols], dtype=torch.float32)
    x_t = torch.as_tensor(x[ok], dtype=torch.float32)
    return prior, builder, theta_t, x_t, NPE


def train(settings: PosteriorSettings, run: str | Path) -> PosteriorEstimator:
    """Simulate (or read the cached) cases, train the estimator, check its calibration on
    held-out cases, all into ``run`` (``posterior/``); every step found finished on disk is
    read back, not repeated."""
    import torch

    folder = Path(run) / "posterior"
    key = content_hash(settings.to_dict())
    if (folder / "settings.json").exists():
        old = read_json(folder / "settings.json")
        if old.get("hash") != key:
            raise RailsuspInputError(
                f"{folder} holds an estimator trained with other settings; give another --out"
            )
    write_json(folder / "settings.json", {"hash": key, "settings": settings.to_dict()})
    u, x = cached_cases(settings, folder / "simulations", "train", settings.n_train)
    prior, builder, theta_t, x_t, NPE = _build(settings, u, x)
    weights = folder / "estimator.pt"
    torch.manual_seed(settings.seed)
    if weights.exists():
        net = builder(theta_t, x_t)
        net.load_state_dict(torch.load(weights, weights_only=True))
    else:
        t0 = time.perf_counter()
        inference = NPE(
            prior=prior, density_estimator=builder, show_progress_bars=False, tracker=_TrainingLog()
        )
        net = inference.append_simulations(theta_t, x_t).train(show_train_summary=False)
        buf = io.BytesIO()
        torch.save(net.state_dict(), buf)
        atomic_write_bytes(weights, buf.getvalue())
        log.info("posterior: trained on %d cases in %.0f s", len(x_t), time.perf_counter() - t0)
    from sbi.inference import DirectPosterior

    net.eval()
    est = PosteriorEstimator(settings, DirectPosterior(net, prior), [], Path(run))
    est.calibration = _calibrate(est, folder)
    return est


def _calibrate(est: PosteriorEstimator, folder: Path) -> list[ParameterCalibration]:
    """Coverage and SBC ranks on the held-out cases (cached in ``calibration.json``)."""
    path = folder / "calibration.json"
    if path.exists():
        return [ParameterCalibration(**c) for c in read_json(path)["parameters"]]
    s = est.settings
    u, x = cached_cases(s, folder / "simulations", "check", s.n_check)
    ok = np.all(np.isfinite(x), axis=1)
    cols = [MAIN_SUSPENSION.index(p) for p in s.parameters]
    draws = np.stack([est.sample(xi, s.samples, seed=i) for i, xi in enumerate(x[ok])])
    checks = check_calibration(draws, u[ok][:, cols], list(s.parameters))
    write_json(
        path,
        {
            "level": LEVEL,
            "cases": int(ok.sum()),
            "failed_simulations": int((~ok).sum()),
            "parameters": [c.to_dict() for c in checks],
            "passed": all(c.passed for c in checks),
        },
    )
    return checks


def load(run: str | Path) -> PosteriorEstimator:
    """The trained estimator of a run directory (nothing is simulated or trained: a run
    without a finished estimator is an error)."""
    folder = Path(run) / "posterior"
    for name in ("settings.json", "estimator.pt", "calibration.json"):
        if not (folder / name).exists():
            raise RailsuspInputError(
                f"{folder / name} does not exist: train first (railsusp posterior train)"
            )
    settings = PosteriorSettings.from_dict(read_json(folder / "settings.json")["settings"])
    return train(settings, run)


@dataclass
class PosteriorResult:
    """The posterior of a recording: draws (SI) of the estimated parameters, the verdict
    of the estimator's calibration check and how the recording was used."""

    parameters: tuple[str, ...]
    samples: np.ndarray  # (S, d) SI
    calibration: list[ParameterCalibration]
    sections: dict[str, dict]
    ess: float | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def calibrated(self) -> bool:
        return all(c.passed for c in self.calibration)

    def intervals(self, level: float = LEVEL) -> Intervals:
        """Median and central ``level`` credible interval of each parameter (the one
        interval type of every route, :mod:`railsusp.estimate.intervals`)."""
        return from_samples(self.parameters, self.samples, level)

    def to_dataframe(self) -> pd.DataFrame:
        """Per parameter: median and central 90 % interval in display units, the
        interval's width as % of the prior range, and the held-out coverage."""
        rows = []
        lo_q, hi_q = (1 - LEVEL) / 2, (1 + LEVEL) / 2
        iv = self.intervals()
        for j, p in enumerate(self.parameters):
            sp = spec(p)
            lo, hi = sp.bounds
            q = np.quantile(self.samples[:, j], [0.5, lo_q, hi_q])
            rows.append(
                {
                    "parameter": p,
                    "name": sp.name,
                    "unit": sp.display_unit,
                    "median": sp.to_display(q[0]),
                    "lo90": sp.to_display(q[1]),
                    "hi90": sp.to_display(q[2]),
                    "width_pct_range": 100.0 * (q[2] - q[1]) / (hi - lo),
                    "coverage_heldout": self.calibration[j].coverage,
                    "calibrated": self.calibration[j].passed,
                    "median [90 % interval]": iv[p].text(),
                }
            )
        return pd.DataFrame(rows)

    def save(self, path: str | Path) -> Path:
        """The table and the verdict as JSON (atomic)."""
        return write_json(
            path,
            {
                "route": "posterior",
                "parameters": list(self.parameters),
                "estimate_display": {i.parameter: i.value for i in self.intervals().items},
                "intervals": self.intervals().to_dict(),
                "estimates": self.to_dataframe().to_dict(orient="records"),
                "calibrated": self.calibrated,
                "sections": self.sections,
                "effective_sample_size": self.ess,
                "warnings": self.warnings,
            },
        )


def estimate(est: PosteriorEstimator, recordings, seed: int = 0) -> PosteriorResult:
    """Posterior of the recordings (one per trained condition, any length of at least one
    section): the product over their sections (module docstring)."""
    x, used = recording_summaries(est.settings, recordings)
    s = est.settings
    notes = []
    if not est.calibrated:
        bad = [c.parameter for c in est.calibration if not c.passed]
        notes.append(
            "the estimator FAILED its coverage check on held-out simulations for "
            f"{', '.join(bad)}: its intervals are too narrow; do not use them as they are"
        )
    ess = None
    if len(x) == 1:
        u = est.sample(x[0], s.samples, seed)
    else:
        u, ess = _product_samples(est, x, s.samples, np.random.default_rng(seed))
        notes.append(
            f"the product of {len(x)} sections is not what the built-in check tested (one "
            "section): an over-confident section posterior gets more so in the product "
            "(bench/posterior.py measures the coverage against record length)"
        )
        if ess < MIN_ESS:
            notes.append(
                f"the product of {len(x)} sections' posteriors was sampled with an effective "
                f"sample size of {ess:.0f} (< {MIN_ESS:g}): its intervals are rough"
            )
    for note in notes:
        log.warning("posterior: %s", note)
    return PosteriorResult(s.parameters, to_si(u, s.parameters), est.calibration, used, ess, notes)
