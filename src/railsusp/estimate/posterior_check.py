"""The calibration step of a trained posterior estimator: fit its spread correction on one
set of held-out simulations and check the corrected estimator on another, untouched one.

Three disjoint sets of simulated cases, drawn alike from the prior on new track
realisations (:mod:`railsusp.estimate.posterior_data`, their own seeds):

1. ``train``: the flows learn from these;
2. ``calibration`` (``n_calibration`` cases): the split-conformal widening factor of each
   parameter is fitted on the flows' draws for these
   (:class:`railsusp.estimate.calibration.SpreadCorrection`, in logit coordinates of the
   fraction of range, so the widened draws stay inside the prior box);
3. ``check`` (``n_check`` cases): the coverage and SBC check of the estimator before and
   after the correction. Nothing was fitted on these, so the check after the correction is
   an honest one; it decides ``calibrated``, together with the bound on the widening
   (a factor above ``MAX_INFLATION`` is flagged, whatever the coverage).

Everything goes into ``posterior/calibration.json``, which a re-run reads back.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from railsusp.estimate.calibration import LEVEL, ParameterCalibration, SpreadCorrection, check
from railsusp.estimate.posterior_data import cached_cases
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import read_json, write_json

if TYPE_CHECKING:
    from railsusp.estimate.posterior import PosteriorEstimator


def raw_draws(est: PosteriorEstimator, folder: Path, kind: str, n: int):
    """The flows' uncorrected draws (cases, S, d) for the first ``n`` cases of ``kind``,
    their truths (cases, d) and the number of failed simulations left out."""
    s = est.settings
    u, x = cached_cases(s, folder / "simulations", kind, n)
    ok = np.all(np.isfinite(x), axis=1)
    cols = [MAIN_SUSPENSION.index(p) for p in s.parameters]
    draws = est.sample_raw(x[ok], s.samples, seed=s.seed)
    return draws, u[ok][:, cols], int((~ok).sum())


def calibrate(
    est: PosteriorEstimator, folder: Path
) -> tuple[SpreadCorrection | None, list[ParameterCalibration]]:
    """The correction (None with ``n_calibration = 0``) and the check of the corrected
    estimator on the untouched test cases; read from ``calibration.json`` when there."""
    path = folder / "calibration.json"
    if path.exists():
        data = read_json(path)
        corr = data.get("correction")
        return (
            None if corr is None else SpreadCorrection.from_dict(corr),
            [ParameterCalibration(**c) for c in data["parameters"]],
        )
    s = est.settings
    names = list(s.parameters)
    record: dict = {"level": LEVEL}
    correction = None
    if s.n_calibration:
        draws, truth, failed = raw_draws(est, folder, "calibration", s.n_calibration)
        correction = SpreadCorrection.fit(draws, truth, names)
        record["calibration_set"] = {
            "cases": len(truth),
            "failed_simulations": failed,
            "before": [c.to_dict() for c in check(draws, truth, names)],
            "after": [c.to_dict() for c in check(est.correct(draws), truth, names)],
        }
    draws, truth, failed = raw_draws(est, folder, "check", s.n_check)
    before = check(draws, truth, names)
    after = check(est.correct(draws), truth, names) if correction else before
    excessive = correction.excessive if correction else []
    record.update(
        {
            "cases": len(truth),
            "failed_simulations": failed,
            "correction": None if correction is None else correction.to_dict(),
            "before": [c.to_dict() for c in before],
            "parameters": [c.to_dict() for c in after],
            "excessive_correction": excessive,
            "passed": all(c.passed for c in after) and not excessive,
        }
    )
    write_json(path, record)
    return correction, after
