"""Sobol global sensitivity of the wheel-rail force features to the suspension parameters.

Two routes, both through SALib (Saltelli/Jansen estimators, bootstrap confidence intervals):

* direct: a campaign with a Saltelli design (``design="sobol"``) is analysed as it stands,
  N (D + 2) simulations per condition (N (2D + 2) with second-order indices);
* metamodel: a Latin-hypercube campaign is fitted, feature by feature, with a Gaussian
  process (scikit-learn, Matern 5/2 with automatic relevance determination plus noise), and
  the Sobol indices are computed on the process mean with a large Saltelli design. The
  confidence intervals then cover the Sobol estimator only, not the metamodel error; the
  held-out R^2 of each process is reported, and a feature whose process does not fit
  (R^2 below :data:`~railsusp.key_parameters.MIN_METAMODEL_R2`) is left out of the key
  rule: its indices split the variance of a mean that explains little of the feature (pure
  noise gave ST summing to 1).

Key parameters are chosen from the indices by a documented rule and set beside the study's
choice (:mod:`railsusp.key_parameters`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.campaign import STATISTICS, Campaign, CampaignError, salib_problem
from railsusp.campaign.design import MIN_SALTELLI_BASE, saltelli_base_too_small, saltelli_issue
from railsusp.errors import RailsuspInputError
from railsusp.key_parameters import (
    CAMPAIGN_STAMP,
    INDICES_STAMP,
    select_key_parameters,
    study_comparison,
)
from railsusp.params import bounds
from railsusp.store import (
    atomic_folder,
    remove_stale_temporaries,
    write_csv,
    write_json,
    write_parquet,
)

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

#: successful runs a condition's Gaussian-process metamodel needs at the least (one per fold
#: of the cross-validation that scores it)
MIN_METAMODEL_RUNS = 5

#: below this many points a single held-out fifth scores a process on one to nine points
#: (R^2 undefined on one; -83 on the two of a 12-run campaign's feature that a 5-fold
#: cross-validation scores at 0.98): the R^2 is then of a 5-fold cross-validation
MIN_SINGLE_HOLDOUT = 50


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


def _indexed(
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


def _features(campaign: Campaign, statistics: Sequence[str], quantities: Sequence[str]):
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
    for cond, q, st, y in _features(campaign, statistics, quantities):
        if len(y) != cfg.n_runs:
            raise ValueError(f"{campaign.path}: campaign incomplete for {cond}")
        df = sobol_from_samples(
            problem,
            y.to_numpy(),
            second_order=cfg.second_order,
            num_resamples=num_resamples,
            seed=seed,
        )
        frames.append(_indexed(df, cond, q, st, y, "direct", np.nan))  # no metamodel R^2
    return pd.concat(frames, ignore_index=True)[list(INDEX_COLUMNS)]


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
    for cond, q, st, y in _features(campaign, statistics, quantities):
        ids = y.index.to_numpy()
        yv = y.to_numpy()
        ok = np.isfinite(yv)
        if ok.sum() < MIN_METAMODEL_RUNS:  # a Gaussian process on nothing: sklearn's error
            failed = len(yv) - int(ok.sum())
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
        frames.append(_indexed(df, cond, q, st, y, "metamodel", r2))
        fits.append(MetamodelFit(cond, q, st, r2, len(yv)))
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


def agreement(a: pd.DataFrame, b: pd.DataFrame) -> pd.DataFrame:
    """How two index tables agree, per feature: max |dST|, max |dS1|, Spearman rank of ST."""
    from scipy.stats import spearmanr

    keys = ["condition", "quantity", "statistic"]
    m = a.merge(b, on=[*keys, "parameter"], suffixes=("_a", "_b"))
    rows = []
    for k, g in m.groupby(keys):
        rho = spearmanr(g.ST_a, g.ST_b).statistic if len(g) > 2 else float("nan")
        rows.append(
            {
                **dict(zip(keys, k, strict=True)),
                "max_abs_dST": float(np.max(np.abs(g.ST_a - g.ST_b))),
                "max_abs_dS1": float(np.max(np.abs(g.S1_a - g.S1_b))),
                "spearman_ST": float(rho),
            }
        )
    return pd.DataFrame(rows)


#: the accepted Saltelli base samples N of an analysis on the metamodel (N (2d + 2)
#: evaluations: 65 536 with ten parameters is 1.4 million); the configuration's
#: ``[sensitivity] base_samples`` has the same bounds
BASE_SAMPLES = (64, 65_536)
#: the Saltelli N on the metamodels when none is given
DEFAULT_BASE_SAMPLES = 2048


def check_settings(
    statistics: Sequence[str],
    threshold: float,
    key_statistics: Sequence[str],
    max_keys: int,
    min_cv: float,
    base_samples: int,
    seed: int,
) -> None:
    """Refuse, in one line naming the setting and its accepted range, an analysis setting
    that would write a meaningless ``key_parameters.json`` (before any file is touched).
    The statistics are the campaign's features' (:data:`railsusp.campaign.STATISTICS`);
    the key rule's are among those analysed (one that is not had no indices: the keys
    rested on the others while the rule text named it)."""
    # the key rule's first: the command line adds them to the statistics analysed, so that
    # an unknown one was named as the ``--statistics`` the user did not type
    for name, chosen in (("key_statistics", key_statistics), ("statistics", statistics)):
        unknown = [st for st in chosen if st not in STATISTICS]
        if not chosen or unknown:
            raise RailsuspInputError(
                f"{name} {','.join(unknown) or '(none)'}: accepted one or more of "
                f"{', '.join(STATISTICS)}"
            )
    unanalysed = [st for st in key_statistics if st not in statistics]
    if unanalysed:
        raise RailsuspInputError(
            f"key_statistics {','.join(unanalysed)}: accepted only statistics analysed "
            f"(statistics {','.join(statistics)})"
        )
    if not 0.0 < threshold < 1.0:  # NaN fails too
        raise RailsuspInputError(f"threshold {threshold:g}: accepted above 0 and below 1")
    if not 1 <= max_keys <= 10:
        raise RailsuspInputError(f"max_keys {max_keys}: accepted 1 to 10")
    if not 0.0 <= min_cv < 1.0:
        raise RailsuspInputError(f"min_cv {min_cv:g}: accepted 0 to below 1")
    if not BASE_SAMPLES[0] <= base_samples <= BASE_SAMPLES[1]:
        raise RailsuspInputError(
            f"base_samples {base_samples}: accepted {BASE_SAMPLES[0]} to {BASE_SAMPLES[1]}"
        )
    if seed < 0:
        raise RailsuspInputError(f"seed {seed}: accepted 0 or more")


def _compared(compare: str | Path, check):
    """``check(compare)``, its campaign error naming the setting ``compare``."""
    try:
        return check(compare)
    except CampaignError as exc:
        raise CampaignError(f"compare {compare}: {exc}") from None


def analyse(
    run: str | Path,
    *,
    statistics: Sequence[str] = ("mean", "p99"),
    threshold: float = 0.05,
    key_statistics: Sequence[str] = ("mean", "p99"),
    max_keys: int = 6,
    min_cv: float = 0.005,
    base_samples: int | None = None,
    seed: int = 0,
    compare: str | Path | None = None,
) -> dict:
    """Sobol analysis of a run directory; writes ``RUN/sensitivity/`` and returns a summary.

    A Saltelli campaign is analysed directly, any other through metamodels. Key parameters by
    :func:`select_key_parameters` over ``key_statistics``. ``compare``: a second run
    directory analysed the same way, whose indices are set against these.
    ``base_samples``: the Saltelli N on the metamodels (default
    :data:`DEFAULT_BASE_SAMPLES`); refused where no campaign analysed has one (Saltelli
    campaigns alone are read directly, so a value given would go unused).
    """
    from railsusp.campaign import load_campaign, require_complete

    n_base = DEFAULT_BASE_SAMPLES if base_samples is None else base_samples
    check_settings(statistics, threshold, key_statistics, max_keys, min_cv, n_base, seed)
    camp = load_campaign(run)
    # the comparison campaign checked before any analysis: a --compare naming no campaign,
    # or an unfinished one, was found after this campaign's analysis, without its option
    other = None if compare is None else _compared(compare, load_campaign)
    if base_samples is not None and all(
        c.config.design == "sobol" for c in (camp, other) if c is not None
    ):
        raise RailsuspInputError(
            f"base_samples {base_samples}: accepted only where a campaign is analysed "
            f"through metamodels (an LHS design); {camp.path} is a Saltelli (sobol design) "
            "campaign, analysed directly"
        )
    base_samples = n_base
    require_complete(camp)  # part of it: a condition left out silently
    if other is not None:
        _compared(compare, lambda _: require_complete(other))
    out = camp.path / "sensitivity"
    fits: list[MetamodelFit] = []

    def indices_of(c: Campaign):
        if c.config.design == "sobol":
            return sobol_direct(c, statistics, seed=seed), []
        return sobol_metamodel(c, statistics, base_samples=base_samples, seed=seed)

    idx, fits = indices_of(camp)
    selection = select_key_parameters(idx, threshold, key_statistics, max_keys, min_cv=min_cv)
    comparison = study_comparison(selection)
    summary = {
        "run": str(camp.path),
        # the campaign analysed: its readers refuse the file beside another campaign
        CAMPAIGN_STAMP: camp.config.hash(),
        "method": idx.method.iloc[0],
        "key_parameters": selection.to_dict(),
        "metamodel_r2": [f.__dict__ for f in fits],
    }
    # the comparison before anything is written: a failed one left the folder half new;
    # checked as this campaign is (an unfinished one was compared on the batches it had,
    # conditions without any dropped; one of other force laws compared another model)
    agree = None
    if compare is not None:
        agree = agreement(idx, indices_of(other)[0])
    from railsusp.report import plot_sobol

    # the folder written as one artefact: a failure part-way (a full disk) left new indices
    # beside the old key parameters, or the old figures beside the new ones, and the folder
    # read as one finished analysis (the disk audit); now the old analysis stays whole. An
    # earlier analysis's comparison and its figures (of statistics analysed then) are not
    # this one's: not carried. Temporaries an analysis killed while it wrote left here are
    # removed first, not carried (the CLI and the pipeline hold the campaign's lock)
    remove_stale_temporaries(out)
    with atomic_folder(out, drop=("sobol-*.png", "agreement.csv")) as tmp:
        meta = {INDICES_STAMP: camp.config.hash()}
        write_parquet(tmp / "indices.parquet", idx, metadata=meta)
        write_csv(tmp / "indices.csv", idx)
        write_json(tmp / "indices.json", idx.to_dict(orient="records"))
        write_csv(tmp / "study_comparison.csv", comparison)
        if agree is not None:
            write_csv(tmp / "agreement.csv", agree)
            summary["agreement"] = agree.to_dict(orient="records")
        # the key parameters: the pipeline reads this file as the stage's completion mark
        write_json(tmp / "key_parameters.json", summary)
        for st in statistics:
            plot_sobol(idx, tmp / f"sobol-{st}.png", statistic=st)
    summary["indices"] = idx
    summary["comparison"] = comparison
    return summary
