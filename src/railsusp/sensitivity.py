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

This module is the analysis of a run directory: its settings checked, the route chosen, two
campaigns' indices compared, ``RUN/sensitivity/`` written. The estimator, the index table and
the direct route are :mod:`railsusp.sensitivity_indices`; the Gaussian-process metamodel route
is :mod:`railsusp.sensitivity_metamodel`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.campaign import STATISTICS, Campaign, CampaignError
from railsusp.errors import RailsuspInputError
from railsusp.key_parameters import (
    CAMPAIGN_STAMP,
    FIGURES_MARKED,
    INDICES_STAMP,
    left_out_features,
    select_key_parameters,
    study_comparison,
)
from railsusp.sensitivity_indices import sobol_direct
from railsusp.sensitivity_metamodel import MetamodelFit, sobol_metamodel
from railsusp.store import (
    atomic_folder,
    remove_stale_temporaries,
    write_csv,
    write_json,
    write_parquet,
)


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


def check_comparable(camp: Campaign, other: Campaign, compare: str | Path) -> None:
    """Refuse, in one line, a comparison campaign with no condition of this one's name (an
    empty agreement table was written and read as a comparison made); warn where a
    condition of the same name is defined otherwise there (its features are others: a 1 s
    "straight" against a 20 s one read max |dST| 0.95 as a disagreement of the methods).
    The irregularity seed may differ (campaigns of other track realisations)."""
    import warnings

    mine = {c.name: c for c in camp.config.conditions}
    theirs = {c.name: c for c in other.config.conditions}
    common = [n for n in mine if n in theirs]
    if not common:
        raise RailsuspInputError(
            f"compare {compare}: no condition in common with {camp.path} (its "
            f"{', '.join(theirs)} against {', '.join(mine)}); accepted a campaign of at least "
            "one condition of the same name"
        )
    for name in common:
        a, b = mine[name].model_dump(), theirs[name].model_dump()
        differ = [k for k in a if k != "seed" and a[k] != b.get(k)]
        if differ:
            said = ", ".join(f"{k} {b.get(k)!r} against {a[k]!r}" for k in differ[:3])
            warnings.warn(
                f"compare {compare}: condition {name!r} is defined otherwise there ({said}): "
                "its agreement compares other features",
                stacklevel=3,
            )


#: a total index above this is the Sobol estimator's noise, not a share of the variance
ST_NOISE_BOUND = 1.0


def _warn_beyond_one(idx: pd.DataFrame, base_samples: int) -> None:
    """Warn where a total index exceeds 1: a share of the variance cannot, so the Saltelli
    estimate is that noisy (a 16-run campaign's metamodels at N = 64 gave 1.087, and a
    threshold of 0.99 kept it as key: stop 78's hunt); more base samples narrow it."""
    import warnings

    over = idx[idx["ST"] > ST_NOISE_BOUND]
    if over.empty:
        return
    top = over.loc[over["ST"].idxmax()]
    remedy = (
        f"at base_samples N = {base_samples} on the metamodels; raise base_samples"
        if str(top.method) == "metamodel"
        else "with this Saltelli campaign's samples; a larger campaign narrows it"
    )
    warnings.warn(
        f"{len(over)} total Sobol index(es) above 1, up to {float(top.ST):.3f} "
        f"({top.parameter}, {top.condition} {top.quantity} {top.statistic}): the estimate is "
        f"that noisy {remedy} (each ST's 95 % interval: indices.csv, ST_conf)",
        stacklevel=3,
    )


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
        check_comparable(camp, other, compare)  # before any analysis
    out = camp.path / "sensitivity"
    fits: list[MetamodelFit] = []

    def indices_of(c: Campaign):
        if c.config.design == "sobol":
            return sobol_direct(c, statistics, seed=seed), []
        return sobol_metamodel(c, statistics, base_samples=base_samples, seed=seed)

    idx, fits = indices_of(camp)
    _warn_beyond_one(idx, base_samples)
    selection = select_key_parameters(idx, threshold, key_statistics, max_keys, min_cv=min_cv)
    comparison = study_comparison(selection)
    summary = {
        "run": str(camp.path),
        # the campaign analysed: its readers refuse the file beside another campaign
        CAMPAIGN_STAMP: camp.config.hash(),
        "method": idx.method.iloc[0],
        "key_parameters": selection.to_dict(),
        "metamodel_r2": [f.__dict__ for f in fits],
        # simulations left out of each condition's metamodels (failed, e.g. derailed)
        "failed_runs": {f.condition: f.n_failed for f in fits if f.n_failed},
    }
    # the comparison before anything is written: a failed one left the folder half new;
    # checked as this campaign is (an unfinished one was compared on the batches it had,
    # conditions without any dropped; one of other force laws compared another model)
    agree = None
    if compare is not None:
        agree = agreement(idx, indices_of(other)[0])
        if agree.empty:  # (conditions in common, but no parameter or statistic)
            raise RailsuspInputError(
                f"compare {compare}: no feature and parameter in common with {camp.path}; "
                "accepted a campaign of the same parameters and statistics"
            )
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
        summary[FIGURES_MARKED] = True  # (the figures below)
        write_json(tmp / "key_parameters.json", summary)
        left_out = left_out_features(summary, idx)  # their panels grey, with the reason
        for st in statistics:
            plot_sobol(idx, tmp / f"sobol-{st}.png", statistic=st, left_out=left_out)
    summary["indices"] = idx
    summary["comparison"] = comparison
    return summary
