"""The synthetic-likelihood posterior in a run directory: fitted from the posterior
estimator's training cases, checked on held-out records of several sections, and applied
to a recording (``long_record = "synthetic-likelihood"``; the method in
:mod:`railsusp.estimate.posterior_synthetic`).

Files, in ``posterior/synthetic/``: ``settings.json`` (the estimator's settings and the
hash of what the emulator learnt from), ``emulator.npz`` (the fitted emulator of all the
statistics), ``projection.npz`` (the informative combinations the likelihood reads, beyond
the EN 14363 summary), with ``statistics_emulator_cases`` ``projected_emulator.npz`` (the
emulator of those combinations alone, on every training case, with its stamp),
``scales.json`` (c, the isotropic m and the model error per direction A with its
shrinkage, fitted on the fusion's calibration records of the longest checked length,
:func:`fit_covariance_scales`) and ``check.json`` (per checked number of sections:
coverage of the 90 % intervals per parameter on held-out records, median width). The check
uses the held-out sets that the fusion's check uses (``check`` for one section; ``long`` of
``product_sections``, :meth:`~railsusp.estimate.posterior_settings.PosteriorSettings.
product_sets`), so both methods are measured on the same records; nothing is fitted on
them: no widening, the verdict is the check. A recording of n sections takes the check of
the smallest checked number >= n; longer than any, it is reported not calibrated.
``check.json`` is sealed (:func:`~railsusp.estimate.posterior_check.seal`) and its stamp
holds the SHA-256 of the emulators' files: ``load`` refuses one edited since, or checked
with another emulator than the folder's.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.calibration import ParameterCalibration, check
from railsusp.estimate.posterior_check import (
    median_width,
    read_sealed,
    seal,
    seal_state,
    stored_record,
)
from railsusp.estimate.posterior_data import cached_cases, to_si, training_support
from railsusp.estimate.posterior_emulator import StatisticsEmulator
from railsusp.estimate.posterior_recordings import recording_summaries, unused_recordings
from railsusp.estimate.posterior_result import PosteriorResult
from railsusp.estimate.posterior_settings import PosteriorSettings, check_seed
from railsusp.estimate.posterior_stamp import check_model_revision
from railsusp.estimate.posterior_support import TrainingSupport, support_notes
from railsusp.estimate.posterior_synthetic import (
    SyntheticLikelihood,
)
from railsusp.estimate.posterior_synthetic_fit import (
    check_stamp,
    emulator_files,
    fit_covariance_scales,
    fit_emulator,
    fit_projected_emulator,
    fit_projection,
    likelihood,
    restamp_settings,
    scale_set,
)
from railsusp.integrity import read_npz
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import read_json, write_json

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SectionsCheck:
    """Coverage check of the synthetic-likelihood posterior at ``sections`` sections."""

    sections: int
    checks: tuple[ParameterCalibration, ...]
    width_pct_range: dict[str, float]

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)

    def to_dict(self) -> dict:
        return {
            "sections": self.sections,
            "cases": self.checks[0].n if self.checks else 0,
            "parameters": [c.to_dict() for c in self.checks],
            "width_pct_range": self.width_pct_range,
            "passed": self.passed,
        }

    @classmethod
    def from_dict(cls, d: dict) -> SectionsCheck:
        checks = tuple(ParameterCalibration(**c) for c in d["parameters"])
        return cls(int(d["sections"]), checks, dict(d["width_pct_range"]))


class Checked:
    """What a checked posterior (its ``settings`` and ``checks``) answers: the estimated
    parameters' columns, the check of a number of sections, the verdict."""

    @property
    def columns(self) -> list[int]:
        return [MAIN_SUSPENSION.index(p) for p in self.settings.parameters]

    def product_for(self, sections: int) -> SectionsCheck | None:
        """The check of the smallest checked number of sections >= ``sections``."""
        return next((c for c in self.checks if c.sections >= sections), None)

    @property
    def calibrated(self) -> bool:
        """One section's check passed."""
        c = self.product_for(1)
        return c is not None and c.sections == 1 and c.passed


@dataclass
class SyntheticPosterior(Checked):
    """The synthetic likelihood of a trained estimator's settings, and its checks."""

    settings: PosteriorSettings
    likelihood: SyntheticLikelihood
    checks: list[SectionsCheck] = field(default_factory=list)
    #: the range of the training cases' statistics, which a recording's are compared with
    support: TrainingSupport | None = None

    def sample(self, x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
        """(n, d) draws (unit box) of the estimated parameters for the sections ``x``
        (k, D) or one section (D,)."""
        return self.likelihood.sample(np.atleast_2d(x), n, seed)[:, self.columns]


def held_out_sets(settings: PosteriorSettings) -> list[tuple[str, int, int, tuple[int, ...]]]:
    """(kind, cases, sections simulated, numbers of sections checked) of the settings'
    held-out sets: one section on ``check``, the fusion's ``long`` sets for the rest."""
    sets = [("check", settings.n_check, 1, (1,))]
    return sets + [("long", n, longest, ks) for n, longest, ks in settings.product_sets()]


def run_checks(post: SyntheticPosterior, run: str | Path, sets=None) -> list[SectionsCheck]:
    """Coverage of the posterior on held-out records: per set (``held_out_sets``'s
    form; default the settings'), the first k sections of each record for each k."""
    s = post.settings
    folder = Path(run) / "posterior" / "simulations"
    return check_sets(post, lambda kind, n, longest: cached_cases(s, folder, kind, n, longest),
                      sets or held_out_sets(s))  # fmt: skip


def check_sets(post, cases, sets) -> list[SectionsCheck]:
    """:func:`run_checks` of a posterior ``post`` (its ``settings`` and ``sample``) whose
    held-out cases ``cases(kind, n, sections)`` gives as (u, x)."""
    s = post.settings
    names = list(s.parameters)
    out = []
    for kind, n, longest, ks in sets:
        u, x = cases(kind, n, longest)
        x = x[:, None, :] if x.ndim == 2 else x
        ok = np.all(np.isfinite(x), axis=(1, 2))
        truth = u[ok][:, post.columns]
        for k in ks:
            t0 = time.perf_counter()
            draws = np.stack(
                [post.sample(xi[:k], s.samples, seed=s.seed + i) for i, xi in enumerate(x[ok])]
            )
            out.append(SectionsCheck(k, tuple(check(draws, truth, names)),
                                     median_width(draws, names)))  # fmt: skip
            log.info("synthetic likelihood: %d sections checked on %d %s cases in %.0f s",
                     k, len(truth), kind, time.perf_counter() - t0)  # fmt: skip
    return sorted(out, key=lambda c: c.sections)


def train(
    settings: PosteriorSettings, run: str | Path, sets=None, scales_on="default"
) -> SyntheticPosterior:
    """Fit (or read) the emulator, its covariance scales (on ``scales_on``: (kind,
    records, sections); "default": :func:`scale_set`; None: not fitted, 1) and check (or
    read the check of) the posterior; ``posterior/synthetic/``."""
    emulator = fit_emulator(settings, run)
    restamp_settings(settings, run)
    fitted = fit_projection(settings, emulator, run)
    projection = fitted.get("matrix")
    projected = fit_projected_emulator(settings, run, fitted)
    post = SyntheticPosterior(settings, likelihood(settings, emulator, None, projection,
                                                   projected))  # fmt: skip
    where = scale_set(settings) if scales_on == "default" else scales_on
    scales = fit_covariance_scales(settings, post.likelihood, run, where)
    post.likelihood = likelihood(settings, emulator, scales, projection, projected)
    post.support = training_support(settings, run)
    path = Path(run) / "posterior" / "synthetic" / "check.json"
    sets = plain_sets(sets or held_out_sets(settings))
    stamp = check_stamp(run, scales, post.likelihood, fitted.get("stamp"))
    old = stored_record(path, "the check")
    if old is not None and old.get("sets") == sets:
        if seal_state(old) == "sealed" and old.get("emulator") == stamp:
            post.checks = [SectionsCheck.from_dict(c) for c in old["checks"]]
            return post
        before = check_stamp(run, scales, post.likelihood, fitted.get("stamp"), files=False)
        if seal_state(old) == "unsealed" and old.get("emulator") == before:
            # written before records were sealed and the emulators' files stamped: taken as
            # it stands (as it was read before), sealed with the files it was made with
            post.checks = [SectionsCheck.from_dict(c) for c in old["checks"]]
            write_json(path, seal({**old, "emulator": stamp}))
            return post
    post.checks = run_checks(post, run, sets)
    write_json(path, seal({"method": "synthetic-likelihood", "sets": sets, "emulator": stamp,
                           "checks": [c.to_dict() for c in post.checks]}))  # fmt: skip
    return post


def _plain(v):
    return list(v) if isinstance(v, tuple) else v


def plain_sets(sets) -> list:
    """Held-out sets (:func:`held_out_sets`' form) as JSON stores them (lists)."""
    return [list(map(_plain, st)) for st in sets]


def load(run: str | Path) -> SyntheticPosterior:
    """The fitted and checked synthetic likelihood of a run (nothing is fitted here)."""
    folder = Path(run) / "posterior" / "synthetic"
    for name in ("settings.json", "emulator.npz", "scales.json", "check.json"):
        if not (folder / name).exists():
            raise RailsuspInputError(
                f"{folder / name} does not exist: fit the synthetic likelihood first "
                "(railsusp posterior train --long-record synthetic-likelihood)"
            )
    stamp = read_json(folder / "settings.json")
    check_model_revision(stamp, folder / "settings.json")
    settings = PosteriorSettings.from_dict(stamp["settings"])
    emulator = StatisticsEmulator.load(folder / "emulator.npz")
    scales = read_json(folder / "scales.json")
    checked, sealed = read_sealed(folder / "check.json", "the synthetic likelihood's check")
    projection, projection_stamp = None, None
    if settings.statistics != ("en14363",):
        path = folder / "projection.npz"
        if path.exists():
            z = read_npz(path, "the projection", "delete it and train again to compute it")
            projection, projection_stamp = z.get("matrix"), str(z.get("stamp"))
        if projection_stamp is None or checked.get("emulator", [None])[-1] != projection_stamp:
            raise _not_checked(path, folder)
    projected = None
    if settings.statistics_emulator_cases:
        path = folder / "projected_emulator.npz"
        projected = StatisticsEmulator.load(path) if path.exists() else None
        if projected is None or projected.stamp not in checked.get("emulator", []):
            raise _not_checked(path, folder)
    post = SyntheticPosterior(
        settings, likelihood(settings, emulator, scales, projection, projected)
    )
    stamp = checked.get("emulator")
    if sealed:  # the emulators' files are those the check was made with (another
        # training's emulator.npz of the same settings was accepted before)
        files = emulator_files(run, post.likelihood)
        made = stamp[5] if isinstance(stamp, list) and len(stamp) > 5 else {}
        for name, sha in files.items():
            if not isinstance(made, dict) or made.get(name) != sha:
                raise _not_checked(folder / name, folder)
    made_with = check_stamp(run, scales, post.likelihood, projection_stamp, files=sealed)
    if stamp != made_with:  # emulator, scales or settings of another training
        raise _not_checked(folder / "scales.json", folder)
    post.checks = [SectionsCheck.from_dict(c) for c in checked["checks"]]
    post.support = training_support(settings, run)
    return post


def _not_checked(path: Path, folder: Path) -> RailsuspInputError:
    return RailsuspInputError(
        f"{path} does not belong to the check in {folder / 'check.json'} (an interrupted or "
        "other training): run railsusp posterior train --long-record synthetic-likelihood "
        "again on this folder"
    )


def estimate(post: SyntheticPosterior, recordings, seed: int = 0) -> PosteriorResult:
    """Posterior of the recordings (one per trained condition) from the mean of their
    sections' statistics, with the check of its number of sections; ``seed``: of the draws
    (refused in one line outside its range: numpy's own error before)."""
    seed = check_seed(seed)
    x, used = recording_summaries(post.settings, recordings)
    notes = unused_recordings(recordings, [c.name for c in post.settings.conditions])
    return result_of(post, x, used, seed, notes)


def result_of(
    post, x: np.ndarray, used: dict, seed: int = 0, notes: list[str] | None = None
) -> PosteriorResult:
    """The posterior result of the sections ``x`` (k, D) of a posterior ``post`` (its
    ``settings``, ``sample``, ``product_for``, ``support``: one estimator or a joint one),
    ``used`` the recordings' use per condition, with the check of its number of sections;
    ``notes``: warnings of the recordings' reading, said first. Sections outside the
    training cases' range flag the result not calibrated
    (:func:`~railsusp.estimate.posterior_support.support_notes`)."""
    s = post.settings
    n = len(x)
    outside, said = support_notes(getattr(post, "support", None), x)
    notes = [*(notes or []), *said]
    u = post.sample(x, s.samples, seed)
    chk = post.product_for(n)
    if chk is None:
        longest = max((c.sections for c in post.checks), default=0)
        notes.append(
            f"the synthetic-likelihood posterior of {n} sections is NOT calibrated: it was "
            f"checked up to {longest} section(s) (--product-sections)"
        )
        checks = [ParameterCalibration(p, 0, float("nan"), float("nan"), float("nan"), False)
                  for p in s.parameters]  # fmt: skip
    else:
        checks = list(chk.checks)
        bad = [c.parameter for c in checks if not c.passed]
        if bad:
            notes.append(
                f"the synthetic-likelihood posterior FAILED its coverage check of "
                f"{chk.sections} sections on held-out simulations for {', '.join(bad)}: its "
                "intervals are too narrow; do not use them as they are"
            )
    for note in notes:
        log.warning("posterior: %s", note)
    widening = getattr(post, "correction_for", None)  # a joint posterior's
    correction = None if widening is None else widening(n)  # (applied, checked or not)
    return PosteriorResult(s.parameters, to_si(u, s.parameters), checks, used, n, notes,
                           correction, None if chk is None else chk.sections,
                           "synthetic-likelihood", outside)  # fmt: skip
