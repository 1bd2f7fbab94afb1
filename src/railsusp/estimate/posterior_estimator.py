"""A trained posterior estimator of the suspension parameters, and how it is used.

:class:`PosteriorEstimator` holds the ensemble of flows q(z | x) over the logit coordinates
of the parameters, the spread correction and coverage checks fitted on held-out cases, and
the training cases' range of statistics; it draws the posterior of one section's summary
statistics, or of several sections fused, and evaluates its density. It is apart from
:mod:`railsusp.estimate.posterior`, which trains an estimator (simulating or reading its
cases), saves and reads it back, and estimates recordings with it, because using a trained
estimator needs none of that (the statistics emulator, which trains its networks on one
thread, :func:`one_thread`, uses this part alone).
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from railsusp.estimate.calibration import ParameterCalibration, SpreadCorrection
from railsusp.estimate.posterior_check import ProductCalibration, widen
from railsusp.estimate.posterior_fusion import from_logit, fused_samples, to_logit
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.posterior_support import TrainingSupport


def one_thread() -> AbstractContextManager[None]:
    """Torch on one thread while the flows train or sample: their networks are small, and
    on a shared 2-core machine two threads contend (sampling measured 7 times slower)."""
    from railsusp.surrogate.recurrence import torch_threads

    return torch_threads(1)


@dataclass
class PosteriorEstimator:
    """A trained estimator: settings, its ensemble of flows q(z | x) over the logit
    coordinates z of the parameters, the spread correction fitted on the calibration cases
    (None: not corrected) and the coverage check of the corrected estimator on the
    untouched test cases."""

    settings: PosteriorSettings
    members: list[Any]  # sbi conditional density estimators of z = logit(u)
    calibration: list[ParameterCalibration]
    correction: SpreadCorrection | None = None
    run: Path | None = None
    products: list[ProductCalibration] = field(default_factory=list)
    #: the range of the training cases' statistics, which a recording's are compared with
    support: TrainingSupport | None = None

    @property
    def calibrated(self) -> bool:
        """The coverage check passed for every parameter and no correction was excessive."""
        excessive = self.correction.excessive if self.correction else []
        return all(c.passed for c in self.calibration) and not excessive

    def sample_raw(self, x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
        """(n, d) draws (unit box) of the ensemble's q(u | x) for a summary vector ``x``
        (D,), uncorrected; ``x`` (cases, D) gives (cases, n, d)."""
        import torch

        x = np.asarray(x, dtype=float)
        xt = torch.as_tensor(np.atleast_2d(x), dtype=torch.float32)
        counts = np.random.default_rng(seed).multinomial(
            n, [1 / len(self.members)] * len(self.members)
        )
        torch.manual_seed(seed)
        parts = []
        with one_thread(), torch.no_grad():
            for flow, k in zip(self.members, counts, strict=True):
                if k:
                    parts.append(np.swapaxes(flow.sample((int(k),), condition=xt).numpy(), 0, 1))
        draws = from_logit(np.concatenate(parts, axis=1).astype(float))  # (cases, n, d)
        draws = draws[:, np.random.default_rng(seed + 1).permutation(n)]  # members mixed
        return draws if x.ndim == 2 else draws[0]

    def correct(self, u: np.ndarray) -> np.ndarray:
        """Draws (..., S, d) on the unit box widened by the spread correction (in logit
        coordinates, about their median), or as they are without one."""
        return widen(self.correction, u)

    def product_for(self, sections: int) -> ProductCalibration | None:
        """The correction and check of the smallest checked number of sections >= the
        given one (None: none that long)."""
        return next((p for p in self.products if p.sections >= sections), None)

    def sample(self, x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
        """(n, d) corrected draws (unit box) of the posterior of one summary vector ``x``
        (D,) or of the sections ``x`` (sections, D) fused, with the correction of their
        number of sections (:meth:`product_for`; the one-section correction when none)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if x.shape[0] == 1:
            return self.correct(self.sample_raw(x[0], n, seed))
        raw = fused_samples(self, x, n, np.random.default_rng(seed))
        product = self.product_for(x.shape[0])
        return widen(product.correction, raw) if product else self.correct(raw)

    def log_qz(self, z: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(M, sections) log q(z | x_i) of the ensemble (the mean of its flows' densities)
        over logit coordinates, for (M, d) ``z`` and the sections ``x`` (sections, D)."""
        import torch

        zt = torch.as_tensor(np.asarray(z, float), dtype=torch.float32)
        xt = torch.as_tensor(np.atleast_2d(x), dtype=torch.float32)
        with one_thread(), torch.no_grad():
            lp = torch.stack(
                [f.log_prob(zt[:, None, :].expand(-1, xt.shape[0], -1), condition=xt).double()
                 for f in self.members]
            )  # fmt: skip
        return torch.logsumexp(lp, dim=0).numpy() - np.log(len(self.members))

    def log_q(self, u: np.ndarray, x: np.ndarray) -> np.ndarray:
        """log q(u | x_i), the density on the unit box (with the Jacobian of the logit),
        summed over the sections ``x`` (sections, D), for (M, d) ``u``; -inf outside the
        open box."""
        u = np.asarray(u, dtype=float)
        inside = np.all((u > 0) & (u < 1), axis=1)
        safe = np.where(inside[:, None], u, 0.5)
        per_section = self.log_qz(to_logit(safe), x)
        jacobian = -np.sum(np.log(safe) + np.log1p(-safe), axis=1)
        out = per_section.sum(axis=1) + per_section.shape[1] * jacobian
        out[~inside] = -np.inf
        return out
