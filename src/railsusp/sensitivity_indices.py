"""Sobol indices from the outputs of a Saltelli design (SALib's Saltelli/Jansen estimators,
bootstrap confidence intervals), one table row per feature and parameter, and the direct
route: a Saltelli-design campaign (``design="sobol"``) analysed as it stands.

Apart from :mod:`railsusp.sensitivity` (which chooses the route for a run directory, checks
its settings and writes ``RUN/sensitivity/``) because these are the estimator and the index
table that both routes share: the metamodel route (:mod:`railsusp.sensitivity_metamodel`)
feeds its Gaussian processes' predictions through the same estimator and table.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd

from railsusp.campaign import Campaign, CampaignError, salib_problem
from railsusp.campaign.design import MIN_SALTELLI_BASE, saltelli_base_too_small, saltelli_issue

INDEX_COLUMNS = (
    "condition",
    "quantity",
    "statistic",
    "parameter",
    "S1",
    "S1_conf",
    "ST",
    "ST_conf",
    "method",
    "cv",
    "r2_holdout",
)


#: base samples N of a Saltelli design analysed directly at the least: below it SALib's
#: estimators are noise (ST = 19.8 +- 54 at N = 2, 1.46 at N = 8: the campaign audit of
#: stop 59); the power of two above the 8 where the estimates still exceeded 1. A campaign
#: is refused fewer when it is made (railsusp.campaign.design.saltelli_issue); both apply
#: the one rule of railsusp.campaign.design.saltelli_base_too_small
MIN_DIRECT_BASE = MIN_SALTELLI_BASE


def sobol_from_samples(
    problem: dict,
    y: np.ndarray,
    *,
    second_order: bool = False,
    num_resamples: int = 200,
    seed: int = 0,
) -> pd.DataFrame:
    """SALib Sobol analysis of outputs ``y`` of a Saltelli design (in design order)."""
    from SALib.analyze import sobol

    y = np.asarray(y, dtype=float)
    bad = ~np.isfinite(y)
    if bad.all():
        raise ValueError("no finite output to analyse")
    if bad.any():  # failed simulations: replace by the mean so the design stays whole
        warnings.warn(f"{int(bad.sum())} failed runs replaced by the mean output", stacklevel=2)
        y = np.where(bad, np.nanmean(y), y)
    # SALib seeds its bootstrap only for a truthy seed (``if seed:``): seed 0 drew unseeded
    # confidence intervals, different on every run; seed + 1 makes every seed reproducible
    res = sobol.analyze(
        problem, y, calc_second_order=second_order, num_resamples=num_resamples, seed=seed + 1
    )
    return pd.DataFrame(
        {
            "parameter": problem["names"],
            "S1": res["S1"],
            "S1_conf": res["S1_conf"],
            "ST": res["ST"],
            "ST_conf": res["ST_conf"],
        }
    )


def _cv(y: np.ndarray) -> float:
    """Coefficient of variation of a feature over the campaign (std / |mean|)."""
    y = y[np.isfinite(y)]
    m = abs(float(np.mean(y))) if y.size else 0.0
    return float(np.std(y) / m) if m > 0 else float("inf")


def with_index_columns(
    df: pd.DataFrame, cond: str, q: str, st: str, y: pd.Series, method: str, r2: float
) -> pd.DataFrame:
    """One feature's Sobol indices (:func:`sobol_from_samples`) with the other columns of
    :data:`INDEX_COLUMNS`: the feature (condition, quantity, statistic), the route
    (``method``), its coefficient of variation over the campaign (of ``y``, every run) and
    the metamodel's held-out R^2 (NaN on the direct route); both routes' tables are made
    here so that they keep the same columns."""
    return df.assign(
        condition=cond,
        quantity=q,
        statistic=st,
        method=method,
        cv=_cv(y.to_numpy()),
        r2_holdout=r2,
    )


def analysed_features(campaign: Campaign, statistics: Sequence[str], quantities: Sequence[str]):
    feats = campaign.features()  # read once for every feature
    for cond in campaign.config.conditions:
        for q in quantities:
            for st in statistics:
                try:
                    y = campaign.feature_matrix(cond.name, q, st, feats)
                except CampaignError:
                    continue
                yield cond.name, q, st, y


def sobol_direct(
    campaign: Campaign,
    statistics: Sequence[str] = ("mean", "p99"),
    quantities: Sequence[str] = ("Y", "Q"),
    num_resamples: int = 200,
    seed: int = 0,
) -> pd.DataFrame:
    """Sobol indices straight from a Saltelli-design campaign."""
    cfg = campaign.config
    if cfg.design != "sobol":
        raise ValueError(f"{campaign.path}: design {cfg.design!r} is not a Saltelli design")
    if saltelli_base_too_small(cfg.samples):  # N < MIN_DIRECT_BASE, as make_config refuses
        raise ValueError(
            f"{campaign.path}: a Saltelli design of N = {cfg.samples} base samples; its Sobol "
            f"indices need N >= {MIN_DIRECT_BASE} (at N = 2 total indices of 10 to 20 came "
            f"out, and were taken as key): a campaign with --samples {MIN_DIRECT_BASE} or more"
        )
    issue = saltelli_issue(cfg)  # made before make_config refused it: per-row variation
    if issue:
        raise ValueError(f"{campaign.path}: {issue}")
    problem = salib_problem(cfg.parameters)
    frames = []
    for cond, q, st, y in analysed_features(campaign, statistics, quantities):
        if len(y) != cfg.n_runs:
            raise ValueError(f"{campaign.path}: campaign incomplete for {cond}")
        df = sobol_from_samples(
            problem,
            y.to_numpy(),
            second_order=cfg.second_order,
            num_resamples=num_resamples,
            seed=seed,
        )
        frames.append(with_index_columns(df, cond, q, st, y, "direct", np.nan))  # no metamodel R^2
    return pd.concat(frames, ignore_index=True)[list(INDEX_COLUMNS)]
