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

**Several sections.** With ``product_sections`` (k_1 < k_2 < ...), the same is done for
the fused posterior of k consecutive sections (:mod:`railsusp.estimate.posterior_fusion`):
``n_product`` calibration cases (``long-calibration``) and ``n_product`` test cases
(``long``), each of k_max consecutive sections on one track, give a correction and a
check per k (:class:`ProductCalibration`); with ``product_cases`` each k has its own
count, and the k of one count share a set simulated for the longest of them. The fusion
adds each section's small spurious information, so its factors grow with k; a recording
of n sections uses the correction of the smallest checked k >= n (wider than n needs, if
the factors grow with k), and one longer than k_max is not calibrated.

Everything goes into ``posterior/calibration.json`` with the stamp of what the check was
made on (:func:`check_stamp`: the hash of the flows' saved weights, the settings' hash, the
force laws' revision), which a re-run reads back only while the stamp is the folder's: an
``estimator.pt`` deleted and trained again (the remedy our refusals give), or copied in
from another training, is checked afresh, not given the verdict and widening of the flows
it replaced. The record is sealed (:func:`seal`: the content hash of the rest of it, as
``synthetic/check.json`` and ``joint.json`` are): one edited since its check wrote it (a
verdict set to passed, factors set to 1) is refused by ``load`` and checked again by a
re-run, as a record cut short or of another content is.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.calibration import LEVEL, ParameterCalibration, SpreadCorrection, check
from railsusp.estimate.posterior_data import cached_cases
from railsusp.estimate.posterior_fusion import SectionSampler, from_logit, fused_samples, to_logit
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import content_hash, file_hash, read_json, write_json

log = logging.getLogger(__name__)


class Estimator(SectionSampler, Protocol):
    """What the check needs of an estimator (:class:`railsusp.estimate.posterior_estimator.
    PosteriorEstimator`): its settings and uncorrected draws (the corrections are fitted
    here, before the estimator has any)."""


@dataclass(frozen=True)
class ProductCalibration:
    """Correction and check of the fused posterior of ``sections`` sections."""

    sections: int
    correction: SpreadCorrection
    checks: tuple[ParameterCalibration, ...]

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks) and not self.correction.excessive


def raw_draws(est: Estimator, folder: Path, kind: str, n: int):
    """The flows' uncorrected draws (cases, S, d) for the first ``n`` cases of ``kind``,
    their truths (cases, d) and the number of failed simulations left out."""
    s = est.settings
    u, x = cached_cases(s, folder / "simulations", kind, n)
    ok = np.all(np.isfinite(x), axis=1)
    cols = [MAIN_SUSPENSION.index(p) for p in s.parameters]
    draws = est.sample_raw(x[ok], s.samples, seed=s.seed)
    return draws, u[ok][:, cols], int((~ok).sum())


def median_width(draws: np.ndarray, names: list[str]) -> dict[str, float]:
    """Median over cases of the central 90 % interval's width, % of the prior range."""
    q = np.quantile(draws, [(1 - LEVEL) / 2, (1 + LEVEL) / 2], axis=1)
    return dict(zip(names, np.round(100 * np.median(q[1] - q[0], axis=0), 1).tolist(), strict=True))


def fused_draws(est: Estimator, folder: Path, kind: str):
    """Per checked number of sections k, the uncorrected fused draws (cases, S, d) of the
    first k sections of the cases of ``kind`` in k's held-out set
    (:meth:`~railsusp.estimate.posterior_settings.PosteriorSettings.product_sets`), and their
    truths (cases, d)."""
    s = est.settings
    cols = [MAIN_SUSPENSION.index(p) for p in s.parameters]
    draws, truths = {}, {}
    for n, longest, ks in s.product_sets():
        u, x = cached_cases(s, folder / "simulations", kind, n, longest)
        ok = np.all(np.isfinite(x), axis=(1, 2))
        for k in ks:
            draws[k] = np.stack(
                [fused_samples(est, xi[:k], s.samples, np.random.default_rng([s.seed, i, k]))
                 for i, xi in enumerate(x[ok])]
            )  # fmt: skip
            truths[k] = u[ok][:, cols]
    return draws, truths


def _products(est: Estimator, folder: Path) -> tuple[list[ProductCalibration], list]:
    """The correction and check of every checked number of sections, and their record."""
    names = list(est.settings.parameters)
    cal, t_cal = fused_draws(est, folder, "long-calibration")
    test, t_test = fused_draws(est, folder, "long")
    out, record = [], []
    for k in est.settings.product_sections:
        corr = SpreadCorrection.fit(to_logit(cal[k]), to_logit(t_cal[k]), names)
        widened = widen(corr, test[k])
        checks = tuple(check_widened(corr, test[k], t_test[k], names))
        out.append(ProductCalibration(k, corr, checks))
        record.append(
            {
                "sections": k,
                "calibration_cases": len(t_cal[k]),
                "cases": len(t_test[k]),
                "correction": corr.to_dict(),
                "before": [c.to_dict() for c in check_widened(None, test[k], t_test[k], names)],
                "parameters": [c.to_dict() for c in checks],
                "width_pct_range": median_width(widened, names),
                "calibration_after": [
                    c.to_dict() for c in check_widened(corr, cal[k], t_cal[k], names)
                ],
                "passed": out[-1].passed,
            }
        )
    return out, record


def widen(correction: SpreadCorrection | None, draws: np.ndarray) -> np.ndarray:
    """Draws on the unit box widened by ``correction`` in logit coordinates (as is: None)."""
    return draws if correction is None else from_logit(correction.apply(to_logit(draws)))


def check_widened(
    correction: SpreadCorrection | None, draws: np.ndarray, truth: np.ndarray, names: list[str]
) -> list[ParameterCalibration]:
    """Coverage and SBC check (:func:`~railsusp.estimate.calibration.check`) of the draws
    (cases, S, d) on the unit box widened by ``correction`` (None: as they are), against the
    ``truth`` (cases, d), counted in the logit coordinates the correction is fitted and
    applied in. The ranks are the same in either coordinates; the interval ends are not:
    a quantile interpolates between two draws, and the end interpolated in logit
    coordinates and mapped back is not the end interpolated between the mapped draws. The
    factor puts the truth of its defining calibration case on the widened interval's end
    in logit coordinates, so counted on the unit box that case fell just outside: the
    calibration set's coverage after the correction read 18 of 20 where the factor, the
    19th smallest score, holds 19."""
    z = to_logit(draws)
    widened = z if correction is None else correction.apply(z)
    return check(widened, to_logit(truth), names)


def _read_products(data: dict) -> list[ProductCalibration]:
    return [
        ProductCalibration(
            p["sections"],
            SpreadCorrection.from_dict(p["correction"]),
            tuple(ParameterCalibration(**c) for c in p["parameters"]),
        )
        for p in data.get("products", [])
    ]


def check_stamp(folder: Path) -> dict:
    """What a check in ``folder`` was made on, stored in ``calibration.json``: the SHA-256
    of the flows' saved weights (``estimator.pt``; None where there is none), and the hash
    of the settings, the force laws' revision and the statistics' version that
    ``settings.json`` holds, which fix
    the held-out cases (their draws, tracks, noise and simulated forces, cached in
    ``simulations/``) and how many draws each is checked with."""
    weights = folder / "estimator.pt"
    stored = read_json(folder / "settings.json") if (folder / "settings.json").exists() else {}
    stored = stored if isinstance(stored, dict) else {}
    return {
        "estimator": file_hash(weights) if weights.is_file() else None,
        "settings": stored.get("hash"),
        "model_revision": stored.get("model_revision"),
        "statistics_version": stored.get("statistics_version"),
    }


#: the key of a check record's seal (:func:`seal`)
SEAL = "sealed"


def seal(record: dict) -> dict:
    """The check ``record`` with its seal: the content hash of the rest of it (what was
    made, as made), under :data:`SEAL`. A record edited afterwards no longer matches its
    seal (:func:`seal_state`), as the flows' weights no longer match their SHA-256."""
    body = {k: v for k, v in record.items() if k != SEAL}
    return {**body, SEAL: content_hash(body)}


def seal_state(record) -> str:
    """``"sealed"`` (the content is the one sealed), ``"unsealed"`` (no seal: a record
    written before records were sealed) or ``"broken"`` (changed since it was sealed)."""
    if not isinstance(record, dict) or SEAL not in record:
        return "unsealed"
    body = {k: v for k, v in record.items() if k != SEAL}
    return "sealed" if record[SEAL] == content_hash(body) else "broken"


def stored_record(path: Path, what: str) -> dict | None:
    """A stored check record ``path`` as it reads, for a training to keep, or None where
    there is none or it is cut short, not a JSON object, or changed since it was sealed
    (said in a warning: ``what``, the check, runs again)."""
    if not path.exists():
        return None
    try:
        old = read_json(path)
    except RailsuspInputError as exc:
        log.warning("%s; %s runs again", exc, what)
        return None
    if not isinstance(old, dict) or seal_state(old) == "broken":
        log.warning("%s is not %s that was written there; %s runs again", path, what, what)
        return None
    return old


def read_sealed(path: Path, what: str) -> tuple[dict, bool]:
    """A sealed check record ``path`` (``what``: which, for the messages) and whether it
    is sealed; a one-line error, naming the file and the remedy, where it is not readable
    JSON (cut short), not a JSON object, or was changed since it was sealed. A record
    without a seal (written before records were sealed) is read as it stands, and said
    in a warning: a training on the folder seals it."""
    data = read_json(path)
    if not isinstance(data, dict):
        raise RailsuspInputError(f"{path} is not {what}: {_again(path)}")
    state = seal_state(data)
    if state == "broken":
        raise RailsuspInputError(
            f"{path} was changed after {what} was written (its content does not match its "
            f"seal): {_again(path)}"
        )
    if state == "unsealed":
        warn_unsealed(path)
    return data, state == "sealed"


def warn_unsealed(path: Path) -> None:
    """Say that a check record written before records were sealed is read as it stands."""
    log.warning(
        "%s was written before check records were sealed: read as it stands (its content "
        "cannot be verified); a re-run of the training that made it seals it (a joint "
        "posterior of that estimator is then joined again)",
        path,
    )


def _again(path: Path) -> str:
    """The remedy of a check record that cannot be read: the training that makes it."""
    if path.name == "joint.json":
        return "run railsusp posterior join again to make it again"
    if path.parent.name == "synthetic":
        return (
            "run railsusp posterior train --long-record synthetic-likelihood again on this "
            "folder to make it again"
        )
    return "run railsusp posterior train again on this folder to make it again"


def _read_record(path: Path):
    """(stamp, (correction, checks, products), the record, whether sealed) of a
    calibration record, or the reason (a sentence naming the file) it is not one: cut
    short or not JSON (it stopped ``train`` before, though docs/posterior.md says such a
    record is made again), valid JSON of another content (another tool's file, a result
    written over it: a traceback on every later run before), or a record changed since its
    check sealed it (:func:`seal`)."""
    try:
        data = read_json(path)
    except RailsuspInputError as exc:
        return str(exc)
    state = seal_state(data)
    if state == "broken":
        return (
            f"{path} was changed after its check was written (its content does not match its seal)"
        )
    try:
        corr = data.get("correction")
        return (
            data.get("stamp"),
            (
                None if corr is None else SpreadCorrection.from_dict(corr),
                [ParameterCalibration(**c) for c in data["parameters"]],
                _read_products(data),
            ),
            data,
            state == "sealed",
        )
    except (AttributeError, KeyError, TypeError, ValueError) as exc:
        return f"{path} is not a calibration record ({type(exc).__name__}: {exc})"


def calibrate(
    est: Estimator, folder: Path, remake: bool = True
) -> tuple[SpreadCorrection | None, list[ParameterCalibration], list[ProductCalibration]]:
    """The correction (None with ``n_calibration = 0``), the check of the corrected
    estimator on the untouched test cases, and the same for the checked numbers of
    sections; read from ``calibration.json`` when there, sealed (:func:`seal`) and made on
    these flows (:func:`check_stamp`), else made again (said in a warning where there was
    a record). ``remake`` False (:func:`railsusp.estimate.posterior.load`, which only
    reads and writes nothing): a record of other flows, cut short, of another content or
    changed since it was sealed is refused in one line; one written before records were
    sealed is read as it stands, with a warning (a re-run of the training seals it)."""
    path = folder / "calibration.json"
    stamp = check_stamp(folder)
    stored = _read_record(path) if path.exists() else None
    if isinstance(stored, str):  # not a record of this check at all
        if not remake:
            raise RailsuspInputError(f"{stored}: {_again(path)}")
        log.warning("%s; the check runs again", stored)
        stored = None
    if stored is not None:
        got, values, data, sealed = stored
        if got == stamp:
            if not sealed and remake:  # written before records were sealed: taken as it is
                write_json(path, seal(data))
                log.info("%s sealed", path)
            elif not sealed:
                warn_unsealed(path)
            return values
        if not remake:
            raise RailsuspInputError(
                f"{path} is the check of other flows than {folder / 'estimator.pt'} (trained "
                "or copied in since): run railsusp posterior train on this folder to check them"
            )
        log.warning("%s is the check of other flows than estimator.pt; the check runs again", path)
    s = est.settings
    names = list(s.parameters)
    record: dict = {"level": LEVEL, "stamp": stamp}
    correction = None
    if s.n_calibration:
        draws, truth, failed = raw_draws(est, folder, "calibration", s.n_calibration)
        correction = SpreadCorrection.fit(to_logit(draws), to_logit(truth), names)  # as applied
        record["calibration_set"] = {
            "cases": len(truth),
            "failed_simulations": failed,
            "before": [c.to_dict() for c in check_widened(None, draws, truth, names)],
            "after": [c.to_dict() for c in check_widened(correction, draws, truth, names)],
        }
    draws, truth, failed = raw_draws(est, folder, "check", s.n_check)
    before = check_widened(None, draws, truth, names)
    after = check_widened(correction, draws, truth, names) if correction else before
    record["width_pct_range"] = median_width(widen(correction, draws), names)
    excessive = correction.excessive if correction else []
    products, product_record = _products(est, folder) if s.product_sections else ([], [])
    record.update(
        {
            "cases": len(truth),
            "failed_simulations": failed,
            "correction": None if correction is None else correction.to_dict(),
            "before": [c.to_dict() for c in before],
            "parameters": [c.to_dict() for c in after],
            "excessive_correction": excessive,
            "passed": all(c.passed for c in after) and not excessive,
            "products": product_record,
        }
    )
    write_json(path, seal(record))
    return correction, after, products
