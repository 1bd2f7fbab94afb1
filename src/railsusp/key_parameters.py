"""Key parameters from Sobol indices: the documented rule (:data:`RULE_TEXT`,
:func:`select_key_parameters`) and the ranking beside the study's choice
(:func:`study_comparison`).

The indices come from :mod:`railsusp.sensitivity`; this module only judges them: which
features may speak (enough variation over the campaign, a metamodel that fits), and which
parameters' largest total index clears the threshold.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_real
from railsusp.store import read_json
from railsusp.study import KEY_LATERAL, KEY_VERTICAL

#: ``key_parameters.json``'s stamp of the campaign its indices were computed from: that
#: campaign's configuration hash (its ``campaign.json``'s ``config_hash``). A campaign
#: replaced after its analysis (``railsusp campaign --force`` of another configuration)
#: left an analysis of the old one beside it, read as the new one's
CAMPAIGN_STAMP = "campaign_hash"
#: the same stamp in ``indices.parquet``'s key/value metadata
INDICES_STAMP = "railsusp.campaign_hash"

#: held-out R^2 a feature's Gaussian process needs for its Sobol indices to count in the key
#: rule: the indices split the variance of the process mean, so a process that explains
#: little of the feature still gives ST summing to about 1 (pure noise made every parameter
#: key). Pure noise scores 0.03 or less; common-random-numbers campaigns fit means above 0.8
#: and p99 features at 0.54-0.75; a new track per run gave -0.3 to 0.4; an 8-run toy campaign
#: of the pipeline's tests 0.48. A quarter of the held-out variance explained is the least
#: that counts: below it the indices are mostly the process's noise
MIN_METAMODEL_R2 = 0.25


@dataclass
class KeySelection:
    """Key parameters chosen by the rule, with each parameter's largest ST and its source."""

    keys: list[str]
    threshold: float
    statistics: tuple[str, ...]
    max_keys: int
    min_cv: float
    max_st: dict[str, float] = field(default_factory=dict)
    where: dict[str, str] = field(default_factory=dict)
    ignored: list[str] = field(default_factory=list)
    #: held-out R^2 a metamodel's feature needed to count (None: no metamodel R^2 in the
    #: table, i.e. the direct route, or indices written before it was recorded)
    min_r2: float | None = None
    #: metamodel features left out for their fit ("condition quantity statistic")
    unfitted: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {
            "keys": self.keys,
            "threshold": self.threshold,
            "statistics": list(self.statistics),
            "max_keys": self.max_keys,
            "min_cv": self.min_cv,
            "min_r2": self.min_r2,
            "max_st": self.max_st,
            "where": self.where,
            "ignored_features": self.ignored,
            "unfitted_features": self.unfitted,
            "rule": self.rule(),
        }

    def rule(self) -> str:
        fit = "" if self.min_r2 is None else FIT_TEXT.format(r2=self.min_r2)
        return RULE_TEXT.format(
            t=self.threshold, s="/".join(self.statistics), k=self.max_keys, cv=self.min_cv, fit=fit
        )


RULE_TEXT = (
    "a parameter is key when its total Sobol index ST >= {t} for the lateral (Y) or "
    "vertical (Q) force {s} of the measured wheel in any condition; features varying "
    "by less than {cv:.1%} (coefficient of variation) over the campaign are ignored, "
    "whatever their Sobol split;{fit} at most {k} are kept, ranked by their largest ST"
)
#: the rule's clause on metamodel fits (metamodel route only)
FIT_TEXT = (
    " so are features whose Gaussian-process metamodel scores a held-out R^2 below {r2:g}, "
    "or none (its indices split the variance of a fit that does not explain the feature);"
)


def select_key_parameters(
    indices: pd.DataFrame,
    threshold: float = 0.05,
    statistics: str | Sequence[str] = ("mean", "p99"),
    max_keys: int = 6,
    quantities: Sequence[str] = ("Y", "Q"),
    min_cv: float = 0.005,
    min_r2: float = MIN_METAMODEL_R2,
) -> KeySelection:
    """Apply the key-parameter rule (see RULE_TEXT) to a table of Sobol indices.

    The coefficient-of-variation guard matters: the mean vertical force on tangent track is
    the static wheel load whatever the suspension (CV 0.1 %), so its Sobol indices split a
    negligible variance and say nothing a calibration could use. So does the fit guard on
    the metamodel route (rows of method ``metamodel`` with an ``r2_holdout`` column): Sobol
    indices of a Gaussian-process mean are normalised by that mean's variance, so a feature
    the process cannot explain (held-out R^2 below ``min_r2``, or NaN: not scored) gives
    total indices summing to about 1 all the same; such features are left out with a
    warning, and where none is left the selection is refused rather than made from noise.
    """
    stats = (statistics,) if isinstance(statistics, str) else tuple(statistics)
    # one row per label: idxmax's labels are read back with .loc, which on a repeated index
    # (tables concatenated without ignore_index) returned every row of the label
    sel = indices[indices.statistic.isin(stats) & indices.quantity.isin(quantities)]
    sel = sel.reset_index(drop=True)
    if sel.empty:
        raise ValueError(f"no indices for statistics {stats} and quantities {tuple(quantities)}")
    cv = sel["cv"] if "cv" in sel else pd.Series(np.inf, index=sel.index)
    flat = sel[cv < min_cv]
    ignored = sorted(
        {
            f"{c} {q} {s}"
            for c, q, s in zip(flat.condition, flat.quantity, flat.statistic, strict=True)
        }
    )
    sel = sel[cv >= min_cv]
    if sel.empty:
        raise ValueError(f"every feature varies by less than {min_cv:.1%}: nothing to rank")
    scored = "r2_holdout" in sel and "method" in sel and (sel["method"] == "metamodel").any()
    unfitted: list[str] = []
    if scored:
        r2 = sel["r2_holdout"].astype(float)
        poor = (sel["method"] == "metamodel") & ~(r2 >= min_r2)  # NaN: not scored
        bad = sel[poor].drop_duplicates(["condition", "quantity", "statistic"])
        unfitted = sorted(
            f"{c} {q} {s}"
            for c, q, s in zip(bad.condition, bad.quantity, bad.statistic, strict=True)
        )
        told = ", ".join(
            f"{c} {q} {s} ({'not scored' if np.isnan(v) else f'{v:.2f}'})"
            for c, q, s, v in zip(
                bad.condition, bad.quantity, bad.statistic, bad.r2_holdout, strict=True
            )
        )
        sel = sel[~poor]
        if sel.empty:
            raise ValueError(
                f"no feature's Gaussian-process metamodel fits (held-out R^2 >= {min_r2:g}; "
                f"got {told}): their Sobol indices would pick key parameters from noise; a "
                "campaign of more samples, or on one track realisation (common random "
                "numbers), fits them"
            )
        if unfitted:
            warnings.warn(
                f"left out of the key rule, their metamodel's held-out R^2 below {min_r2:g}: "
                f"{told}",
                stacklevel=2,
            )
    best = sel.loc[sel.groupby("parameter")["ST"].idxmax()]
    best = best.sort_values("ST", ascending=False)
    keys = [p for p, st in zip(best.parameter, best.ST, strict=True) if st >= threshold]
    keys = keys[:max_keys]
    order = {p: i for i, p in enumerate(indices.parameter.unique())}
    keys.sort(key=lambda p: order[p])
    return KeySelection(
        keys=keys,
        threshold=threshold,
        statistics=stats,
        max_keys=max_keys,
        min_cv=min_cv,
        max_st={p: float(s) for p, s in zip(best.parameter, best.ST, strict=True)},
        where={
            p: f"{c} {q} {s}"
            for p, c, q, s in zip(
                best.parameter, best.condition, best.quantity, best.statistic, strict=True
            )
        },
        ignored=ignored,
        min_r2=min_r2 if scored else None,
        unfitted=unfitted,
    )


def study_comparison(selection: KeySelection) -> pd.DataFrame:
    """Our ranking beside the study's key parameters (lateral X14 X15 X16 X18; vertical X13
    X15 X17)."""
    rows = []
    ranked = sorted(selection.max_st, key=lambda p: -selection.max_st[p])
    for rank, p in enumerate(ranked, start=1):
        rows.append(
            {
                "parameter": p,
                "our_rank": rank,
                "our_max_ST": selection.max_st[p],
                "where": selection.where[p],
                "ours_key": p in selection.keys,
                "study_lateral": p in KEY_LATERAL,
                "study_vertical": p in KEY_VERTICAL,
            }
        )
    return pd.DataFrame(rows)


def check_made_from(path: str | Path, stamp: str | None, campaign: str | Path) -> None:
    """Refuse, in one line naming ``path`` and the remedy, a sensitivity output stamped with
    another campaign's configuration hash than that of ``campaign`` (the campaign folder
    beside it). Unstamped outputs (made before the stamp) and a folder without a readable
    campaign (nothing to compare with; its readers refuse it themselves) pass."""
    if stamp is None:
        return
    try:
        meta = read_json(Path(campaign) / "campaign.json")
    except RailsuspInputError:
        return
    now = meta.get("config_hash") if isinstance(meta, dict) else None
    if now is not None and now != stamp:
        raise RailsuspInputError(
            f"{path} was computed from another campaign than the one in {campaign} "
            f"(configuration hash {stamp}, the campaign's {now}): run `railsusp sensitivity "
            f"{campaign}` again"
        )


def read_key_parameters(run: str | Path) -> dict:
    """``RUN/sensitivity/key_parameters.json``, checked to be of the campaign in ``run``
    (:func:`check_made_from`); :func:`~railsusp.store.read_json`'s one-line errors."""
    path = Path(run) / "sensitivity" / "key_parameters.json"
    doc = read_selection(path, f"run `railsusp sensitivity {run}` again")
    check_made_from(path, doc.get(CAMPAIGN_STAMP), run)
    return doc


def read_selection(
    path: str | Path,
    remedy: str = "run `railsusp sensitivity RUN` again",
    keys: bool = True,
    max_st: bool = False,
) -> dict:
    """A ``key_parameters.json`` with the fields its readers take checked: ``keys`` a list of
    parameter symbols (``keys``: where the reader takes them), ``max_st`` a table of
    numbers where given (``max_st``: also that it is given; the keys' readers take the
    indices where there are some). A damaged or edited file is one line naming the file and
    the field, ``remedy`` appended (a number made text was a traceback in ``largest_st``,
    and the summary blamed ``estimate.json`` for it)."""
    path = Path(path)
    doc = read_json(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("key_parameters"), dict):
        raise RailsuspInputError(
            f"{path} is not a railsusp sensitivity analysis (no key_parameters): {remedy}"
        )
    listed, st = doc["key_parameters"].get("keys"), doc["key_parameters"].get("max_st")
    if keys and (not isinstance(listed, list) or not all(isinstance(k, str) for k in listed)):
        raise RailsuspInputError(
            f"{path}: key_parameters.keys = {listed!r:.60}: accepted a list of parameter "
            f"symbols; the file is damaged or was edited ({remedy})"
        )
    if st is None and not max_st:
        return doc
    bad = [k for k, v in st.items() if not is_real(v)] if isinstance(st, dict) else None
    if bad is None or bad:
        field = f"max_st.{bad[0]} = {st[bad[0]]!r:.40}" if bad else f"max_st = {st!r:.60}"
        raise RailsuspInputError(
            f"{path}: key_parameters.{field}: accepted a table {{symbol: largest total Sobol "
            f"index}} of numbers; the file is damaged or was edited ({remedy})"
        )
    return doc


def check_sensitivity_output(path: str | Path) -> None:
    """Refuse (:func:`check_made_from`) a sensitivity folder ``RUN/sensitivity``, its
    ``key_parameters.json`` or its ``indices.parquet`` made from another campaign than the
    one in ``RUN``; anything else passes (its reader says what is wrong with it)."""
    path = Path(path)
    if path.is_dir():
        kp = path / "key_parameters.json"
        path = kp if kp.is_file() else path / "indices.parquet"
    run = path.parent.parent
    if path.suffix == ".json" and path.is_file():
        try:
            doc = read_json(path)
        except RailsuspInputError:
            return
        if isinstance(doc, dict):
            check_made_from(path, doc.get(CAMPAIGN_STAMP), run)
    elif path.suffix == ".parquet" and path.is_file():
        import pyarrow.parquet as pq

        try:
            meta = pq.read_schema(path).metadata or {}
        except (OSError, ValueError):
            return
        stamp = meta.get(INDICES_STAMP.encode())
        check_made_from(path, stamp.decode() if stamp is not None else None, run)


#: the key of ``key_parameters.json`` saying the stage's own Sobol
#: figures mark the features the rule left out (:func:`left_out_features`; a stage run
#: before did not, and the report draws them again)
FIGURES_MARKED = "figures_mark_left_out"


def left_out_features(analysis: dict, indices: pd.DataFrame | None) -> dict[str, str]:
    """The features ("condition quantity statistic") the key-parameter rule left out, from
    ``key_parameters.json`` (``analysis``), each with its reason: ``ignored_features`` vary
    by less than the rule's coefficient of variation (their CV from ``indices``), and
    ``unfitted_features`` have a Gaussian-process metamodel whose held-out R^2 is below the
    rule's (from ``metamodel_r2``). The figures plotted their indices unmarked: the tiny
    run's flat vertical force showed X17 at ST 0.32, and X17 "not key"."""
    kp = analysis["key_parameters"]
    cv: dict[str, float] = {}
    if indices is not None and "cv" in indices:
        for r in indices.drop_duplicates(["condition", "quantity", "statistic"]).itertuples():
            cv[f"{r.condition} {r.quantity} {r.statistic}"] = float(r.cv)
    r2 = {
        f"{f['condition']} {f['quantity']} {f['statistic']}": f.get("r2_holdout")
        for f in analysis.get("metamodel_r2") or []
        if isinstance(f, dict) and {"condition", "quantity", "statistic"} <= set(f)
    }
    out = {}
    min_cv = kp.get("min_cv")
    for f in kp.get("ignored_features") or []:
        limit = f" < {min_cv:.1%}" if isinstance(min_cv, (int, float)) else ""
        got = f"coefficient of variation {cv[f]:.2%}" if f in cv else "coefficient of variation"
        out[f] = f"{got}{limit} over the campaign (a flat feature: its indices split a "
        out[f] += "negligible variance)"
    min_r2 = kp.get("min_r2")
    for f in kp.get("unfitted_features") or []:
        v = r2.get(f)
        got = "not scored" if not isinstance(v, (int, float)) or v != v else f"{v:.2f}"
        limit = f" < {min_r2:g}" if isinstance(min_r2, (int, float)) else ""
        out[f] = f"metamodel held-out R² {got}{limit} (its indices split a fit that does not "
        out[f] += "explain the feature)"
    return out
