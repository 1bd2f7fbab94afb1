"""Emulator of the section statistics' distribution for the synthetic likelihood
(:mod:`railsusp.estimate.posterior_synthetic`): the mean mu(u), the section-to-section
covariance Sigma(u) and the emulator's own uncertainty about mu, as functions of the
parameters u (fractions of their ranges), learnt from the posterior's training cases
(one section per case, all ten parameters from the prior, a new track each).

- **Mean**: a bagged ensemble of small MLPs (``members`` networks, each trained on a
  bootstrap resample of the cases, stopped early on its out-of-bag cases). The spread of
  the members about their mean estimates the sampling error of the fitted mean (the
  bootstrap's estimate of an estimator's variance): it is returned as ``emulator_cov`` and
  enters the likelihood's covariance, so a long record, whose own scatter shrinks as 1/k,
  can never be more certain than the emulator that reads it.
- **Section covariance**: Sigma(u) = S(u) R S(u), with the per-statistic standard
  deviations S(u) from a quadratic regression of the log squared out-of-bag residuals
  (offset by E[log chi2_1] = -1.27, so that it estimates the log variance) and one
  correlation R of the residuals standardised by them. Out-of-bag residuals hold the
  emulator's error too (slightly wider: the honest side).

Everything is numpy at inference (the networks' weights are stored as arrays,
``posterior/synthetic/emulator.npz``); torch is needed only to fit.
"""

from __future__ import annotations

import io
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.store import atomic_write_bytes

#: E[log chi2_1]: a squared standard normal's log mean (the log-variance regression's offset)
LOG_CHI2_1_MEAN = -1.2703628454614782


def quadratic_features(u: np.ndarray) -> np.ndarray:
    """(N, 1 + d + d(d+1)/2) constant, linear and quadratic terms of ``u`` - 0.5."""
    c = np.atleast_2d(np.asarray(u, float)) - 0.5
    i, j = np.triu_indices(c.shape[1])
    return np.concatenate([np.ones((c.shape[0], 1)), c, c[:, i] * c[:, j]], axis=1)


def _ridge(features: np.ndarray, y: np.ndarray, penalty: float = 1e-3) -> np.ndarray:
    a = features.T @ features
    a += penalty * np.trace(a) / a.shape[0] * np.eye(a.shape[0])
    return np.linalg.solve(a, features.T @ y)


@dataclass
class StatisticsEmulator:
    """Fitted emulator (module docstring). Inputs are fractions of range u (N, d); the
    outputs are in the statistics' own units. ``weights``: per member, the layers' (W, b)
    acting on 2u - 1 and returning standardised statistics (x - x_mean) / x_scale."""

    weights: list[list[tuple[np.ndarray, np.ndarray]]]
    x_mean: np.ndarray  # (D,)
    x_scale: np.ndarray  # (D,)
    logvar_coef: np.ndarray  # (F, D) quadratic regression of the log section variance
    correlation: np.ndarray  # (D, D)
    cases: int = 0
    stamp: str = ""  # what it learnt from, stored with it (a hash; "" for none)

    @property
    def members(self) -> int:
        return len(self.weights)

    @property
    def dim(self) -> int:
        return self.x_mean.size

    @property
    def inputs(self) -> int:
        """The number of parameters the emulator reads (d)."""
        return self.weights[0][0][0].shape[0]

    def member_means(self, u: np.ndarray) -> np.ndarray:
        """(members, N, D) each network's mean statistics at ``u`` (N, d)."""
        h0 = 2.0 * np.atleast_2d(np.asarray(u, float)) - 1.0
        out = []
        for layers in self.weights:
            h = h0
            for i, (w, b) in enumerate(layers):
                h = h @ w + b
                if i < len(layers) - 1:
                    h = np.tanh(h)
            out.append(h)
        return np.stack(out) * self.x_scale + self.x_mean

    def mean(self, u: np.ndarray) -> np.ndarray:
        """(N, D) the mean statistics at ``u`` (N, d): the members' average, without the
        covariances of :meth:`moments` (which cost N D^2 memory)."""
        return self.member_means(u).mean(axis=0)

    def section_sd(self, u: np.ndarray) -> np.ndarray:
        """(N, D) standard deviation of one section's statistics at ``u``."""
        logvar = quadratic_features(u) @ self.logvar_coef
        return np.exp(0.5 * np.clip(logvar, -60.0, 60.0))

    def moments(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """At ``u`` (N, d): the mean (N, D), one section's covariance (N, D, D) and the
        emulator's covariance of its mean (N, D, D; the members' spread)."""
        m = self.member_means(u)
        mean = m.mean(axis=0)
        dev = m - mean
        emulator = np.einsum("mni,mnj->nij", dev, dev) / max(self.members - 1, 1)
        sd = self.section_sd(u)
        section = sd[:, :, None] * self.correlation * sd[:, None, :]
        return mean, section, emulator

    # -- storage ---------------------------------------------------------------------------

    def save(self, path: str | Path) -> Path:
        """All arrays in one .npz (atomic)."""
        arrays: dict[str, np.ndarray] = {
            "x_mean": self.x_mean,
            "x_scale": self.x_scale,
            "logvar_coef": self.logvar_coef,
            "correlation": self.correlation,
            "cases": np.array(self.cases),
            "layout": np.array([[len(layers) for layers in self.weights]]),
        }
        if self.stamp:
            arrays["stamp"] = np.array(self.stamp)
        for m, layers in enumerate(self.weights):
            for i, (w, b) in enumerate(layers):
                arrays[f"w_{m}_{i}"], arrays[f"b_{m}_{i}"] = w, b
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        return atomic_write_bytes(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> StatisticsEmulator:
        path = Path(path)
        if not path.exists():
            raise RailsuspInputError(
                f"{path} does not exist: fit the synthetic likelihood first "
                "(railsusp posterior train --long-record synthetic-likelihood)"
            )
        with np.load(path, allow_pickle=False) as z:
            layout = z["layout"][0]
            weights = [
                [(z[f"w_{m}_{i}"], z[f"b_{m}_{i}"]) for i in range(int(n))]
                for m, n in enumerate(layout)
            ]
            return cls(
                weights,
                z["x_mean"],
                z["x_scale"],
                z["logvar_coef"],
                z["correlation"],
                int(z["cases"]),
                str(z["stamp"]) if "stamp" in z.files else "",
            )


def _fit_member(u, y, train, valid, hidden, seed, max_epochs=3000, patience=150):
    """One MLP (two tanh layers) on the cases ``train``, early-stopped on ``valid``
    (full-batch Adam, weight decay; the best out-of-bag state is kept)."""
    import torch

    torch.manual_seed(seed)
    d, out = u.shape[1], y.shape[1]
    net = torch.nn.Sequential(
        torch.nn.Linear(d, hidden),
        torch.nn.Tanh(),
        torch.nn.Linear(hidden, hidden),
        torch.nn.Tanh(),
        torch.nn.Linear(hidden, out),
    ).double()
    xt = torch.as_tensor(2.0 * u - 1.0)
    yt = torch.as_tensor(y)
    opt = torch.optim.Adam(net.parameters(), lr=3e-3, weight_decay=1e-5)
    best, best_state, since = np.inf, None, 0
    for _ in range(max_epochs):
        opt.zero_grad()
        loss = torch.mean((net(xt[train]) - yt[train]) ** 2)
        loss.backward()
        opt.step()
        with torch.no_grad():
            v = float(torch.mean((net(xt[valid]) - yt[valid]) ** 2))
        if v < best - 1e-7:
            best, since = v, 0
            best_state = [p.detach().clone() for p in net.parameters()]
        else:
            since += 1
            if since > patience:
                break
    with torch.no_grad():
        for p, q in zip(net.parameters(), best_state, strict=True):
            p.copy_(q)
    linear = [m for m in net if isinstance(m, torch.nn.Linear)]
    return [(m.weight.detach().numpy().T.copy(), m.bias.detach().numpy().copy()) for m in linear]


def fit(
    u: np.ndarray,
    x: np.ndarray,
    members: int = 10,
    hidden: int = 48,
    seed: int = 0,
    log=None,
) -> StatisticsEmulator:
    """Fit the emulator to cases ``u`` (N, d, fractions of range) and their one-section
    statistics ``x`` (N, D); rows with a non-finite statistic are left out."""
    from railsusp.estimate.posterior import one_thread

    u = np.asarray(u, float)
    x = np.asarray(x, float)
    ok = np.all(np.isfinite(x), axis=1) & np.all(np.isfinite(u), axis=1)
    u, x = u[ok], x[ok]
    n = len(u)
    if n < 20 or members < 2:
        raise RailsuspInputError(
            f"synthetic likelihood: {n} usable cases and {members} members; accepted at "
            "least 20 cases and 2 members"
        )
    x_mean = x.mean(axis=0)
    x_scale = np.maximum(x.std(axis=0), 1e-12)
    y = (x - x_mean) / x_scale
    rng = np.random.default_rng(seed)
    weights, oob_sum, oob_count = [], np.zeros_like(y), np.zeros(n)
    with one_thread():
        for m in range(members):
            t0 = time.perf_counter()
            boot = rng.integers(0, n, n)
            valid = np.setdiff1d(np.arange(n), boot)
            layers = _fit_member(u, y, boot, valid, hidden, seed + 7919 * (m + 1))
            weights.append(layers)
            part = StatisticsEmulator([layers], np.zeros(y.shape[1]), np.ones(y.shape[1]),
                                      np.zeros((1, 1)), np.eye(1))  # fmt: skip
            oob_sum[valid] += part.member_means(u[valid])[0]
            oob_count[valid] += 1
            if log is not None:
                log.info("synthetic likelihood: member %d of %d fitted in %.0f s",
                         m + 1, members, time.perf_counter() - t0)  # fmt: skip
    seen = oob_count > 0
    resid = (y[seen] - oob_sum[seen] / oob_count[seen, None]) * x_scale
    feats = quadratic_features(u[seen])
    coef = _ridge(feats, np.log(resid**2 + 1e-30 * x_scale**2))
    coef[0] -= LOG_CHI2_1_MEAN
    emu = StatisticsEmulator(weights, x_mean, x_scale, coef, np.eye(x.shape[1]), n)
    z = resid / emu.section_sd(u[seen])
    emu.correlation = np.cov(z.T)
    return emu
