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
  Optionally (``trend``, ``batch``) each member first takes its own least-squares linear
  trend in u out of its resample and its network learns the rest in mini-batches: a
  statistic that one parameter moves by tens of section standard deviations (the wedge
  friction X18's first projected combination) is then fitted to a small part of a
  section's scatter, where full-batch training left a wave of +-0.4 of it along the
  parameter (bench/README.md, stop 32).
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
from railsusp.integrity import read_npz
from railsusp.store import atomic_write_bytes

#: E[log chi2_1]: a squared standard normal's log mean (the log-variance regression's offset)
LOG_CHI2_1_MEAN = -1.2703628454614782


#: points read at a time by :meth:`StatisticsEmulator.member_means`: all ten members' hidden
#: activations of 1000 points at once (2.5 MB in single precision) outgrew a core's cache,
#: and read so they took 2.4 times as long as in blocks of 200 (bench/emulator_reading.py)
_ROWS = 200


def quadratic_features(u: np.ndarray) -> np.ndarray:
    """(N, 1 + d + d(d+1)/2) constant, linear and quadratic terms of ``u`` - 0.5."""
    c = np.atleast_2d(np.asarray(u, float)) - 0.5
    i, j = np.triu_indices(c.shape[1])
    return np.concatenate([np.ones((c.shape[0], 1)), c, c[:, i] * c[:, j]], axis=1)


def linear_features(u: np.ndarray) -> np.ndarray:
    """(N, 1 + d) constant and linear terms of 2u - 1 (the inputs the networks read)."""
    c = 2.0 * np.atleast_2d(np.asarray(u, float)) - 1.0
    return np.concatenate([np.ones((c.shape[0], 1)), c], axis=1)


def _forward(layers: list[tuple[np.ndarray, np.ndarray]], h: np.ndarray) -> np.ndarray:
    """One network's output for inputs ``h`` (N, d) in its own precision: tanh layers, a
    linear last one."""
    for i, (w, b) in enumerate(layers):
        h = h @ w + b
        if i < len(layers) - 1:
            h = np.tanh(h)
    return h


def _ridge(features: np.ndarray, y: np.ndarray, penalty: float = 1e-3) -> np.ndarray:
    a = features.T @ features
    a += penalty * np.trace(a) / a.shape[0] * np.eye(a.shape[0])
    return np.linalg.solve(a, features.T @ y)


@dataclass
class StatisticsEmulator:
    """Fitted emulator (module docstring). Inputs are fractions of range u (N, d); the
    outputs are in the statistics' own units. ``weights``: per member, the layers' (W, b)
    acting on 2u - 1 and returning standardised statistics (x - x_mean) / x_scale; arrays
    are replaced, not edited in place (they are read through a stack made once per set of
    arrays: :meth:`member_means`)."""

    weights: list[list[tuple[np.ndarray, np.ndarray]]]
    x_mean: np.ndarray  # (D,)
    x_scale: np.ndarray  # (D,)
    logvar_coef: np.ndarray  # (F, D) quadratic regression of the log section variance
    correlation: np.ndarray  # (D, D)
    cases: int = 0
    stamp: str = ""  # what it learnt from, stored with it (a hash; "" for none)
    #: (members, 1 + d, D) each member's linear trend on :func:`linear_features`, in
    #: standardised units, added to its network's output; None: networks alone
    trends: np.ndarray | None = None

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

    def _stacked(self) -> list[tuple[np.ndarray, np.ndarray]] | None:
        """The members' layers stacked, (members, in, out) and (members, 1, out), in single
        precision, made once for the arrays ``weights`` holds (again where they are
        replaced); None where the members' layouts differ (then read one by one)."""
        arrays = [a for layers in self.weights for pair in layers for a in pair]
        cached = self.__dict__.get("_stack")  # (the arrays it was made of, the stack)
        if (
            cached is not None
            and len(cached[0]) == len(arrays)
            and all(a is b for a, b in zip(cached[0], arrays, strict=True))
        ):
            return cached[1]
        shapes = {tuple((w.shape, b.shape) for w, b in layers) for layers in self.weights}
        stacked = None
        if len(shapes) == 1:
            stacked = [
                (
                    np.stack([layers[i][0] for layers in self.weights]).astype(np.float32),
                    np.stack([layers[i][1] for layers in self.weights])[:, None].astype(np.float32),
                )
                for i in range(len(self.weights[0]))
            ]
        self.__dict__["_stack"] = (arrays, stacked)
        return stacked

    def member_means(self, u: np.ndarray) -> np.ndarray:
        """(members, N, D) each network's mean statistics at ``u`` (N, d).

        The networks are read in single precision, all members in one product per layer:
        four times faster than double (numpy's float64 tanh is not vectorised; this is most
        of a synthetic-likelihood posterior's time) and within ~1e-6 of a statistic's
        spread over the prior (``x_scale``) of the networks in double precision, a
        fraction of a section's scatter that no record length approaches (checked by
        tests/estimate/test_posterior_emulator.py)."""
        u = np.atleast_2d(np.asarray(u, float))
        stacked = self._stacked()
        if stacked is None:
            h = np.stack([_forward(layers, 2.0 * u - 1.0) for layers in self.weights])
        else:
            x = (2.0 * u - 1.0).astype(np.float32)
            h = np.empty((len(stacked[-1][0]), len(x), stacked[-1][0].shape[2]))
            for lo in range(0, len(x), _ROWS):  # in blocks whose activations stay in cache
                hb = x[None, lo : lo + _ROWS]
                for i, (w, b) in enumerate(stacked):
                    hb = np.matmul(hb, w)
                    hb += b
                    if i < len(stacked) - 1:
                        np.tanh(hb, out=hb)
                h[:, lo : lo + _ROWS] = hb
        if self.trends is not None:
            h += np.matmul(linear_features(u)[None], self.trends)
        return h * self.x_scale + self.x_mean

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
        # (N, D, M) @ (N, M, D): a batched product, 4-7 times einsum's "mni,mnj->nij"
        emulator = np.matmul(dev.transpose(1, 2, 0), dev.transpose(1, 0, 2))
        emulator /= max(self.members - 1, 1)
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
        if self.trends is not None:
            arrays["trends"] = self.trends
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
        z = read_npz(path, "the statistics emulator", "delete it and train again to fit it anew")
        try:
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
                str(z["stamp"]) if "stamp" in z else "",
                z["trends"] if "trends" in z else None,
            )
        except (KeyError, IndexError, ValueError) as exc:
            raise RailsuspInputError(
                f"the statistics emulator {path} is not one railsusp wrote (missing {exc}); "
                "delete it and train again to fit it anew"
            ) from None


def _network(d: int, hidden: int, out: int):
    """The member's MLP: two tanh layers of ``hidden`` (double precision)."""
    import torch

    return torch.nn.Sequential(
        torch.nn.Linear(d, hidden),
        torch.nn.Tanh(),
        torch.nn.Linear(hidden, hidden),
        torch.nn.Tanh(),
        torch.nn.Linear(hidden, out),
    ).double()


def _fit_member(u, y, train, valid, hidden, seed, batch=None):
    """One MLP on the cases ``train``, early-stopped on ``valid`` (the best out-of-bag
    state is kept). ``batch`` None: full-batch Adam with weight decay, up to 3000 steps
    (the emulators fitted before stop 32); an int: mini-batches of that size, the step
    halved after 9 epochs without a relative gain of 1e-4 in the out-of-bag loss
    (``ReduceLROnPlateau``), stopped at the 31st epoch without a new best (up to 400
    epochs)."""
    import torch

    torch.manual_seed(seed)
    net = _network(u.shape[1], hidden, y.shape[1])
    xt = torch.as_tensor(2.0 * u - 1.0)
    yt = torch.as_tensor(y)

    def valid_loss() -> float:
        with torch.no_grad():
            return float(torch.mean((net(xt[valid]) - yt[valid]) ** 2))

    best, best_state, since = np.inf, None, 0

    def keep(v: float) -> bool:
        """Keep the state when it is the best so far; True while training goes on."""
        nonlocal best, best_state, since
        if v < best - 1e-7:
            best, since = v, 0
            best_state = [p.detach().clone() for p in net.parameters()]
        else:
            since += 1
        return since <= (150 if batch is None else 30)

    if batch is None:
        opt = torch.optim.Adam(net.parameters(), lr=3e-3, weight_decay=1e-5)
        for _ in range(3000):
            opt.zero_grad()
            torch.mean((net(xt[train]) - yt[train]) ** 2).backward()
            opt.step()
            if not keep(valid_loss()):
                break
    else:
        opt = torch.optim.Adam(net.parameters(), lr=3e-3)
        plateau = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=0.5, patience=8)
        order = torch.Generator().manual_seed(seed)
        cases = torch.as_tensor(np.asarray(train))
        for _ in range(400):
            shuffled = cases[torch.randperm(len(cases), generator=order)]
            for k in range(0, len(shuffled), batch):
                b = shuffled[k : k + batch]
                opt.zero_grad()
                torch.mean((net(xt[b]) - yt[b]) ** 2).backward()
                opt.step()
            v = valid_loss()
            plateau.step(v)
            if not keep(v):
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
    batch: int | None = None,
    trend: bool = False,
) -> StatisticsEmulator:
    """Fit the emulator to cases ``u`` (N, d, fractions of range) and their one-section
    statistics ``x`` (N, D); rows with a non-finite statistic are left out. ``batch``:
    the networks' mini-batch size, at most N/16 (at least 32) so that a small training
    set still takes 16 steps an epoch (None: full batch); ``trend``: each member's
    network learns what its resample's least-squares linear trend leaves (module
    docstring)."""
    from railsusp.estimate.posterior_estimator import one_thread

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
    if batch is not None:
        batch = min(batch, max(32, n // 16))
    rng = np.random.default_rng(seed)
    weights, trends, oob_sum, oob_count = [], [], np.zeros_like(y), np.zeros(n)
    features = linear_features(u) if trend else None
    with one_thread():
        for m in range(members):
            t0 = time.perf_counter()
            boot = rng.integers(0, n, n)
            valid = np.setdiff1d(np.arange(n), boot)
            rest = y
            if trend:
                trends.append(np.linalg.lstsq(features[boot], y[boot], rcond=None)[0])
                rest = y - features @ trends[-1]
            layers = _fit_member(u, rest, boot, valid, hidden, seed + 7919 * (m + 1), batch)
            weights.append(layers)
            # out-of-bag outputs in double precision, as the networks were trained
            out = _forward(layers, 2.0 * u[valid] - 1.0)
            oob_sum[valid] += out + features[valid] @ trends[-1] if trend else out
            oob_count[valid] += 1
            if log is not None:
                log.info("synthetic likelihood: member %d of %d fitted in %.0f s",
                         m + 1, members, time.perf_counter() - t0)  # fmt: skip
    seen = oob_count > 0
    resid = (y[seen] - oob_sum[seen] / oob_count[seen, None]) * x_scale
    feats = quadratic_features(u[seen])
    coef = _ridge(feats, np.log(resid**2 + 1e-30 * x_scale**2))
    coef[0] -= LOG_CHI2_1_MEAN
    emu = StatisticsEmulator(weights, x_mean, x_scale, coef, np.eye(x.shape[1]), n,
                             trends=np.stack(trends) if trend else None)  # fmt: skip
    z = resid / emu.section_sd(u[seen])
    emu.correlation = np.cov(z.T)
    return emu
