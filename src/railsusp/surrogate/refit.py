"""Fitting a network's record correction (:mod:`.correction`) on its campaign's training runs:
at the end of its training, or again on a saved network whose correction was fitted under
an older rule (the :data:`~railsusp.surrogate.correction.MAX_RUNS` cap), its weights
untouched."""

from __future__ import annotations

from pathlib import Path

from railsusp.errors import RailsuspInputError
from railsusp.surrogate.bundle import Surrogate, load
from railsusp.surrogate.correction import MIN_RUNS, RecordCorrection
from railsusp.surrogate.data import SeriesData, load_series
from railsusp.surrogate.evaluate import accuracy, predict_series, predict_with_alone
from railsusp.surrogate.split import own_split


def fit_record_correction(
    sur: Surrogate, train_data: SeriesData, val_data: SeriesData, seed: int
) -> None:
    """Fit ``sur``'s record correction on the training runs' network predictions (the runs
    drawn with ``seed`` where there are more than the cap) and record in its meta the
    validation runs' error of the record mean before and after it."""
    window = sur.spec.window
    raw = predict_series(sur, train_data, corrected=False)
    sur.correction = RecordCorrection.fit(
        train_data.params_unit, train_data.targets, raw, sur.spec.targets, window, seed
    )
    corrected, alone = predict_with_alone(sur, val_data)
    sim = val_data.targets.astype(float)
    sur.meta["record_correction"] = {
        "fitted_on": "train",
        "n_runs": int(train_data.n_samples),
        "n_fitted": len(sur.correction.x_unit),
        **{
            f"validation_error_{name}": {
                r["target"]: r["relative_error_of_mean"]
                for r in accuracy(sim, pred, sur.spec.targets, window)
            }
            for name, pred in (("raw", alone), ("corrected", corrected))
        },
    }


def refit_record_correction(bundle: str | Path, run: str | Path) -> Surrogate:
    """Fit the record correction of the network saved in ``bundle`` again under today's rule,
    on the training runs of the campaign ``run`` it was trained on, and save it in place:
    what a training with today's code would have fitted on these weights. Refused, in one
    line, for another campaign or a network trained without a correction. The network's
    predictions change: a network set holding it must be made again (its references and
    accuracy rows, bench/ship_networks.py)."""
    from railsusp.campaign import load_campaign, require_complete

    sur = load(bundle)
    if sur.correction is None:
        raise RailsuspInputError(
            f"{bundle}: trained without a record correction (record_correction off, or "
            f"fewer than {MIN_RUNS} training runs); nothing to fit again"
        )
    camp = require_complete(load_campaign(run))
    why = "its correction is fitted on its own campaign's training runs"
    split = own_split(sur.meta, camp, str(bundle), why)
    data = load_series(camp, sur.condition.name, sur.spec)
    fit_record_correction(
        sur,
        data.subset(split.positions(data.sample_ids, "train")),
        data.subset(split.positions(data.sample_ids, "val")),
        split.seed,
    )
    sur.save(bundle)
    return sur
