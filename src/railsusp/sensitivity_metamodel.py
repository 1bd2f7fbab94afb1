"""The metamodel route of the Sobol analysis: a Latin-hypercube (or any) campaign fitted,
feature by feature, with a Gaussian process (scikit-learn, Matern 5/2 with automatic relevance
determination plus noise), each process scored on points it was not fitted to, and the Sobol
indices computed on the process mean with a large Saltelli design.

Apart from :mod:`railsusp.sensitivity` (the analysis of a run directory, which picks this route
for a campaign that is not a Saltelli design) and from :mod:`railsusp.sensitivity_indices`
(the estimator and index table it shares with the direct route) because fitting and scoring
the processes is a job of its own; :func:`fit_gp` is also the surrogates' Gaussian process
(:mod:`railsusp.surrogate.baselines`, :mod:`railsusp.surrogate.correction`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from railsusp.campaign import Campaign
from railsusp.params import bounds
from railsusp.sensitivity_indices import (
    INDEX_COLUMNS,
    analysed_features,
    sobol_from_samples,
    with_index_columns,
)

#: successful runs a condition's Gaussian-process metamodel needs at the least (one per fold
#: of the cross-validation that scores it)
MIN_METAMODEL_RUNS = 5

#: below this many points a single held-out fifth scores a process on one to nine points
#: (R^2 undefined on one; -83 on the two of a 12-run campaign's feature that a 5-fold
#: cross-validation scores at 0.98): the R^2 is then of a 5-fold cross-validation
MIN_SINGLE_HOLDOUT = 50


@dataclass
class MetamodelFit:
    """Held-out quality of one Gaussian-process metamodel (R^2 on a held-out fifth, or of a
    5-fold cross-validation below :data:`MIN_SINGLE_HOLDOUT` points; NaN: the feature is
    constant, nothing to score)."""

    condition: str
    quantity: str
    statistic: str
    r2_holdout: float
    n_train: int
    #: the condition's simulations that failed (e.g. derailed), left out of the fit
    n_failed: int = 0


def fit_gp(x_unit: np.ndarray, y: np.ndarray, seed: int = 0, theta: np.ndarray | None = None):
    """Gaussian process on unit-cube inputs: Matern 5/2 ARD + white noise, normalised y.

    Length scales are bounded below by 0.1 of the range and the noise starts at 10 % of the
    variance: on noisy statistics (independent track seeds) a free optimiser otherwise
    collapses the length scales onto the samples (held-out R² about 0 instead of 0.4-0.8).
    ``theta``: fixed kernel hyperparameters (log scale, as ``gp.kernel_.theta``) instead of
    maximising the likelihood: rebuilds a saved GP exactly."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    d = x_unit.shape[1]
    kernel = ConstantKernel(1.0, (1e-3, 1e3)) * Matern(
        length_scale=np.ones(d), length_scale_bounds=(0.1, 1e3), nu=2.5
    ) + WhiteKernel(0.1, (1e-8, 1.0))
    if theta is not None:
        kernel = kernel.clone_with_theta(np.asarray(theta, dtype=float))
    gp = GaussianProcessRegressor(
        kernel=kernel,
        normalize_y=True,
        n_restarts_optimizer=0,
        random_state=seed,
        optimizer=None if theta is not None else "fmin_l_bfgs_b",
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gp.fit(x_unit, y)
    return gp


def sobol_metamodel(
    campaign: Campaign,
    statistics: Sequence[str] = ("mean", "p99"),
    quantities: Sequence[str] = ("Y", "Q"),
    base_samples: int = 2048,
    num_resamples: int = 200,
    seed: int = 0,
    max_train: int = 500,
) -> tuple[pd.DataFrame, list[MetamodelFit]]:
    """Sobol indices of Gaussian-process metamodels fitted to an LHS (or any) campaign."""
    from SALib.sample import sobol as sobol_sample

    cfg = campaign.config
    params = list(cfg.parameters)
    lo, hi = bounds(params)
    design = campaign.design().set_index("sample_id").sort_index()
    unit_all = (design[params].to_numpy() - lo) / (hi - lo)
    problem_unit = {"num_vars": len(params), "names": params, "bounds": [[0.0, 1.0]] * len(params)}
    xs = sobol_sample.sample(problem_unit, base_samples, calc_second_order=False, seed=seed)
    rng = np.random.default_rng(seed)
    frames, fits = [], []
    left_out: dict[str, tuple[int, int]] = {}  # condition: (failed, simulated)
    for cond, q, st, y in analysed_features(campaign, statistics, quantities):
        ids = y.index.to_numpy()
        yv = y.to_numpy()
        ok = np.isfinite(yv)
        failed = len(yv) - int(ok.sum())
        if failed:
            left_out[cond] = max(left_out.get(cond, (0, 0)), (failed, len(yv)))
        if ok.sum() < MIN_METAMODEL_RUNS:  # a Gaussian process on nothing: sklearn's error
            remedy = (
                "check the condition (speed against curve radius and cant) or the parameter ranges"
                if failed
                else f"a campaign of {MIN_METAMODEL_RUNS} samples or more"
            )
            raise ValueError(
                f"{campaign.path}: condition {cond!r}: {int(ok.sum())} of {len(yv)} simulations "
                f"ran through ({failed} failed, e.g. derailed); the metamodel needs at least "
                f"{MIN_METAMODEL_RUNS}: {remedy}"
            )
        xu, yv = unit_all[ids[ok]], yv[ok]
        if len(yv) > max_train:
            keep = rng.choice(len(yv), max_train, replace=False)
            xu, yv = xu[keep], yv[keep]
        r2 = _holdout_r2(xu, yv, rng.permutation(len(yv)), seed)
        gp = fit_gp(xu, yv, seed)  # final fit on all points
        ym = gp.predict(xs)
        df = sobol_from_samples(problem_unit, ym, num_resamples=num_resamples, seed=seed)
        frames.append(with_index_columns(df, cond, q, st, y, "metamodel", r2))
        fits.append(MetamodelFit(cond, q, st, r2, len(yv), failed))
    for cond, (failed, n) in left_out.items():  # said, not only a smaller n_train
        warnings.warn(
            f"condition {cond!r}: {failed} of {n} simulations failed (e.g. derailed) and are "
            "left out of its metamodels; its indices are over the whole parameter ranges, "
            "where those runs failed too (key_parameters.json failed_runs)",
            stacklevel=2,
        )
    return pd.concat(frames, ignore_index=True)[list(INDEX_COLUMNS)], fits


def _holdout_r2(xu: np.ndarray, yv: np.ndarray, perm: np.ndarray, seed: int) -> float:
    """R^2 of Gaussian processes on points they were not fitted to, the points taken in the
    order ``perm``: from :data:`MIN_SINGLE_HOLDOUT` points up, the first fifth held out;
    below, each of five folds predicted by a process fitted to the other four, pooled over
    every point (a fifth of 5-49 points is 1-9 points: R^2 undefined, or noise). NaN where
    the scored values are constant."""
    n = len(yv)
    if n >= MIN_SINGLE_HOLDOUT:
        folds = [perm[: n // 5]]
    else:
        folds = np.array_split(perm, 5)
    scored = np.concatenate(folds)
    pred = np.empty(n)
    for hold in folds:
        train = perm[~np.isin(perm, hold)]  # in perm's order, as fitted before
        pred[hold] = fit_gp(xu[train], yv[train], seed).predict(xu[hold])
    ys = yv[scored]
    ss = np.sum((ys - ys.mean()) ** 2)
    return float(1.0 - np.sum((ys - pred[scored]) ** 2) / ss) if ss > 0 else float("nan")
