"""Train every surrogate on the same campaign split and compare them on the same held-out runs
(the study's Table 7 and Figures 10/11, per condition, with NRMSE and R² added)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.campaign import load_campaign, require_complete
from railsusp.errors import RailsuspInputError
from railsusp.store import write_csv, write_json
from railsusp.surrogate.baselines import RBFWindowModel, StatisticsGP
from railsusp.surrogate.data import Normaliser, load_series
from railsusp.surrogate.evaluate import (
    accuracy,
    pooled_error,
    predict_series,
    predict_with_alone,
)
from railsusp.surrogate.fit import (
    check_conditions,
    feature_spec,
    longest_window,
    replaced_settings,
    train_surrogate,
)
from railsusp.surrogate.keys import key_parameters
from railsusp.surrogate.models import DEFAULT_WASHOUT, KINDS, SEQUENCE_KINDS
from railsusp.surrogate.split import campaign_split, condition_tracks
from railsusp.surrogate.train import TrainConfig

ALL_MODELS = ("cnn-gru", "cnn-gru-seq", "cnn-lstm", "cnn-bilstm", "bp", "rbf", "gp-stats")


def compare(
    run: str | Path,
    *,
    models: Sequence[str] = ALL_MODELS,
    conditions: Sequence[str] | None = None,
    train: TrainConfig | None = None,
    window: int = 20,
    washout: int | None = None,
    split_seed: int = 0,
    progress: Callable[[str], None] | None = None,
    note_replaced: Callable[[Path, list[str]], None] | None = None,
) -> pd.DataFrame:
    """Train ``models`` per condition and return the accuracy table (also written to
    ``RUN/surrogates/compare.csv`` / ``.json`` with overlay figures).

    Every model trains on the campaign's stored split (:mod:`.split`) and is scored on its
    test samples; the table says what they hold out (``held_out``: tracks and parameters
    with a many-track campaign) and on how many distinct tracks (``test_tracks``).

    ``window`` is the window networks' window; the sequence CNN-GRU (``cnn-gru-seq``) keeps
    ``washout`` (default :data:`~railsusp.surrogate.models.DEFAULT_WASHOUT`, 2 s). All
    models are scored from the same first step (column ``first_step``), the longest window
    or washout among them, so that their errors cover the same samples; the records of
    every condition must be longer than that, which is checked, with the conditions, before
    any training. The random models (``rbf``'s centres, the GPs' restarts) take
    ``train.seed`` as the networks do. ``note_replaced(folder, changes)`` is told of each
    saved network of other settings that is about to be trained afresh (by ``railsusp
    train``, say; :func:`~railsusp.surrogate.replaced_settings`)."""
    from railsusp.report import plot_surrogate_overlay

    camp = require_complete(load_campaign(run))  # never train on part of a campaign
    conds = check_conditions(camp, list(conditions) if conditions else None)
    tcfg = TrainConfig() if train is None else train
    unknown = [k for k in models if k not in ALL_MODELS]
    if unknown or not models:
        raise RailsuspInputError(
            f"models {', '.join(unknown) or '(none)'}: accepted one or more of "
            f"{', '.join(ALL_MODELS)}"
        )
    seq_washout = DEFAULT_WASHOUT if washout is None else washout
    first = max([window] + [seq_washout for k in models if k in SEQUENCE_KINDS])
    _check_records(camp, conds, models, window, seq_washout, first, tcfg)
    params = key_parameters(run)
    spec = feature_spec(camp, params, window)
    split = campaign_split(camp, split_seed)
    rows = []
    out_dir = camp.path / "surrogates"
    figures = []  # drawn once every condition is done: none beside an older compare.csv
    # the older table describes networks about to be trained afresh: taken away first, so
    # that an interrupted compare leaves no finished stage's mark beside networks it no
    # longer describes (written again last)
    for name in ("compare.csv", "compare.json"):
        (out_dir / name).unlink(missing_ok=True)
    for cond in conds:
        data = load_series(camp, cond, spec)
        tr_i, te_i = (
            split.positions(data.sample_ids, "train"),
            split.positions(data.sample_ids, "test"),
        )
        if len(tr_i) == 0 or len(te_i) == 0:
            raise ValueError(
                f"condition {cond!r}: the split leaves {len(tr_i)} training and {len(te_i)} "
                "test samples that ran"
            )
        train_data, test = data.subset(tr_i), data.subset(te_i)
        # test runs that failed (derailed, diverged) are left out of every figure: counted,
        # since they gather at extreme parameters (the split audit of stop 60)
        failed = int(np.setdiff1d(split.test, data.sample_ids).size)
        held = {
            "held_out": split.held_out,
            "test_tracks": condition_tracks(camp, cond, test.sample_ids),
            "test_failed": failed,
        }
        norm = Normaliser.fit(train_data)
        overlays, alone = {}, {}
        for kind in models:
            if progress:
                progress(f"{cond}: {kind}")
            if kind in KINDS:  # the networks, trained through train_surrogate
                steps = seq_washout if kind in SEQUENCE_KINDS else window
                changed = replaced_settings(out_dir / kind / cond, tcfg.to_dict(), steps, True)
                if changed and note_replaced is not None:
                    note_replaced(out_dir / kind / cond, changed)
                sur = train_surrogate(
                    run,
                    cond,
                    kind=kind,
                    parameters=params,
                    window=steps,
                    train=tcfg,
                    split_seed=split_seed,
                )
                pred, raw = predict_with_alone(sur, test)
                if raw is not None:
                    alone[kind] = accuracy(test.targets.astype(float), raw, spec.targets, first)
            elif kind == "rbf":
                sur = RBFWindowModel(spec, norm, seed=tcfg.seed).fit(train_data)
                pred = predict_series(sur, test)
            elif kind == "gp-stats":
                # its statistics from the same first step as the others' (it took its own
                # window's: the split audit of stop 60)
                gp_spec = replace(spec, window=first)
                gp = StatisticsGP(gp_spec, seed=tcfg.seed).fit(train_data)
                m, _ = gp.predict_statistics(test.params_unit)
                sim = StatisticsGP.statistics(test, gp_spec)
                for j, name in enumerate(spec.targets):
                    rel = np.abs(m[:, j] - sim[:, j]) / np.abs(sim[:, j])
                    ss = np.sum((sim[:, j] - sim[:, j].mean()) ** 2)
                    rows.append(
                        {
                            "condition": cond,
                            "model": kind,
                            "target": name,
                            "simulated_mean_kN": float(sim[:, j].mean()),
                            "predicted_mean_kN": float(m[:, j].mean()),
                            "relative_error_of_mean": float(rel.mean()),
                            "relative_error_of_mean_max": float(rel.max()),
                            "relative_error_of_pooled_mean": pooled_error(sim[:, j], m[:, j]),
                            "nrmse": float("nan"),
                            "r2": float("nan"),
                            "r2_of_statistic": float(1 - np.sum((m[:, j] - sim[:, j]) ** 2) / ss)
                            if ss > 0
                            else float("nan"),
                            "n_samples": int(test.n_samples),
                            **held,
                            "first_step": first,
                        }
                    )
                continue
            else:
                raise ValueError(f"unknown model {kind!r}; accepted {', '.join(ALL_MODELS)}")
            overlays[kind] = pred[0]
            rows_alone = alone.get(kind)
            for j, r in enumerate(accuracy(test.targets.astype(float), pred, spec.targets, first)):
                # the network's own error, before its record correction (:mod:`.correction`)
                r["relative_error_of_mean_network_alone"] = (
                    rows_alone[j]["relative_error_of_mean"] if rows_alone else float("nan")
                )
                rows.append({"condition": cond, "model": kind, **r, **held, "first_step": first})
        if overlays:
            title = f"{cond}: held-out sample {int(test.sample_ids[0])}"
            figures.append((test.targets[0], overlays, test.condition, cond, title))
    table = pd.DataFrame(rows)
    out_dir.mkdir(parents=True, exist_ok=True)
    for simulated, overlays, condition, cond, title in figures:
        path = out_dir / f"overlay-{cond}.png"
        dt = condition.sample_interval
        plot_surrogate_overlay(simulated, overlays, spec.targets, dt, path, title=title)
    # NaN (a statistic a kind does not give) as null: JSON has no NaN, strict parsers refuse it
    records = table.astype(object).where(table.notna(), None).to_dict(orient="records")
    write_json(out_dir / "compare.json", records)
    write_csv(out_dir / "compare.csv", table)  # last: the pipeline's mark of a finished stage
    return table


def _check_records(camp, conds, models, window, washout, first, train: TrainConfig) -> None:
    """Refuse, before any training, models whose window or washout the records of a
    condition are too short for, and records too short to score from the common first
    step (an empty slice: NumPy's "Degrees of freedom <= 0" and NaN errors), in one line
    naming the models."""
    steps = {c.name: c.n_steps for c in camp.config.conditions}
    for cond in conds:
        n = steps[cond]
        for kind in models:
            if kind not in KINDS:
                continue
            w = washout if kind in SEQUENCE_KINDS else window
            most = longest_window(kind, n, train)
            if w > most:
                what = "washout" if kind in SEQUENCE_KINDS else "window"
                longer = (
                    f"condition {cond!r} has {n}"
                    if most == n - 1
                    else f"its training chunks have chunk_steps = {train.chunk_steps}"
                )
                raise RailsuspInputError(
                    f"models {kind}: its {what} of {w} steps needs records longer than {w} "
                    f"steps; {longer}"
                )
        if first >= n:
            raise RailsuspInputError(
                f"models {', '.join(models)}: scored from step {first} (the longest window "
                f"or washout among them), which needs records longer than {first} steps; "
                f"condition {cond!r} has {n}"
            )


def table7(table: pd.DataFrame) -> pd.DataFrame:
    """The study's Table 7 layout: per condition and model, vertical then lateral force:
    simulated, predicted, relative error (%)."""
    rows = []
    for (cond, model), g in table.groupby(["condition", "model"], sort=False):
        q = g[g.target == "Q"].iloc[0]
        y = g[g.target == "Y"].iloc[0]
        rows.append(
            {
                "condition": cond,
                "model": model,
                "Q simulated kN": q.simulated_mean_kN,
                "Q predicted kN": q.predicted_mean_kN,
                "Q rel. error %": 100 * q.relative_error_of_mean,
                "Q pooled rel. error %": 100 * q.relative_error_of_pooled_mean,
                "Y simulated kN": y.simulated_mean_kN,
                "Y predicted kN": y.predicted_mean_kN,
                "Y rel. error %": 100 * y.relative_error_of_mean,
                "Y pooled rel. error %": 100 * y.relative_error_of_pooled_mean,
                "Y rel. error, network alone %": 100
                * y.get("relative_error_of_mean_network_alone", float("nan")),
                "Q NRMSE": q.nrmse,
                "Y NRMSE": y.nrmse,
                "Q R2": q.r2,
                "Y R2": y.r2,
                "held out": q.get("held_out", ""),
                "test tracks": q.get("test_tracks", float("nan")),
                "test runs failed": q.get("test_failed", float("nan")),
            }
        )
    return pd.DataFrame(rows)
