"""The synthetic-likelihood posterior in a run directory: fitted from the posterior
estimator's training cases, checked on held-out records of several sections, and applied
to a recording (``long_record = "synthetic-likelihood"``; the method in
:mod:`railsusp.estimate.posterior_synthetic`).

Files, in ``posterior/synthetic/``: ``settings.json`` (the estimator's settings and the
hash of what the emulator learnt from), ``emulator.npz`` (the fitted emulator),
``scales.json`` (c, the isotropic m and the model error per direction A with its
shrinkage, fitted on the fusion's calibration records of the longest checked length,
:func:`fit_covariance_scales`) and ``check.json`` (per checked number of sections:
coverage of the 90 % intervals per parameter on held-out records, median width). The check
uses the held-out sets that the fusion's check uses (``check`` for one section; ``long`` of
``product_sections``, :meth:`~railsusp.estimate.posterior_data.PosteriorSettings.
product_sets`), so both methods are measured on the same records; nothing is fitted on
them: no widening, the verdict is the check. A recording of n sections takes the check of
the smallest checked number >= n; longer than any, it is reported not calibrated.
"""

from __future__ import annotations

import io
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.calibration import ParameterCalibration, check
from railsusp.estimate.posterior_check import median_width
from railsusp.estimate.posterior_data import (
    GAIN_ERROR,
    PosteriorSettings,
    cached_cases,
    recording_summaries,
    to_si,
)
from railsusp.estimate.posterior_emulator import StatisticsEmulator, fit
from railsusp.estimate.posterior_result import PosteriorResult
from railsusp.estimate.posterior_synthetic import (
    SyntheticLikelihood,
    fit_model_error,
    fit_scales,
    gain_covariance,
    informative_projection,
)
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import atomic_write_bytes, content_hash, read_json, write_json

log = logging.getLogger(__name__)

#: networks in the emulator's bagged ensemble, and their hidden width
MEMBERS = 10
HIDDEN = 48
#: the training cases the informative projection of statistics beyond the EN 14363 summary
#: is averaged over (:func:`~railsusp.estimate.posterior_synthetic.informative_projection`)
PROJECTION_CASES = 200
#: the settings the emulator depends on (the training cases and their statistics)
TRAINED_ON = ("conditions", "parameters", "section_s", "n_train", "noise", "sum_y", "seed",
              "statistics")  # fmt: skip


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


@dataclass
class SyntheticPosterior:
    """The synthetic likelihood of a trained estimator's settings, and its checks."""

    settings: PosteriorSettings
    likelihood: SyntheticLikelihood
    checks: list[SectionsCheck] = field(default_factory=list)

    @property
    def columns(self) -> list[int]:
        return [MAIN_SUSPENSION.index(p) for p in self.settings.parameters]

    def sample(self, x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
        """(n, d) draws (unit box) of the estimated parameters for the sections ``x``
        (k, D) or one section (D,)."""
        return self.likelihood.sample(np.atleast_2d(x), n, seed)[:, self.columns]

    def product_for(self, sections: int) -> SectionsCheck | None:
        """The check of the smallest checked number of sections >= ``sections``."""
        return next((c for c in self.checks if c.sections >= sections), None)

    @property
    def calibrated(self) -> bool:
        """One section's check passed."""
        c = self.product_for(1)
        return c is not None and c.sections == 1 and c.passed


def likelihood(
    settings: PosteriorSettings,
    emulator: StatisticsEmulator,
    scales: dict | None = None,
    projection: np.ndarray | None = None,
) -> SyntheticLikelihood:
    """The likelihood of these settings' statistics: the gain error shared by a record's
    sections is the instrument model's (the training simulations'); ``scales``: the
    covariance's fitted scales (``scales.json``; none: 1); ``projection``: the likelihood
    of these combinations of the statistics (:func:`fit_projection`). With statistics
    families beyond the EN 14363 summary (hundreds of statistics) the first of a
    posterior's two SMC runs holds the covariance at the box's centre
    (:meth:`SyntheticLikelihood.sample`)."""
    scales = scales or {}
    matrix = scales.get("model_error_matrix")
    return SyntheticLikelihood(
        emulator,
        gain_covariance(settings.summary_names, GAIN_ERROR),
        within_scale=float(scales.get("within_scale", 1.0)),
        model_error=float(scales.get("model_error", 0.0)),
        model_error_matrix=None if matrix is None else np.asarray(matrix, float),
        first_pass_at_centre=settings.statistics != ("en14363",),
        projection=projection,
    )


def fit_projection(settings: PosteriorSettings, emulator: StatisticsEmulator, run) -> dict:
    """The informative projection of statistics beyond the EN 14363 summary
    (``settings.projection_rank`` combinations for the mean of the longest checked number of
    sections, averaged over the first :data:`PROJECTION_CASES` training cases), fitted once
    per emulator into ``posterior/synthetic/projection.npz``; ``{}`` for the EN 14363
    summary alone (its 17 per condition are read as they are)."""
    if settings.statistics == ("en14363",):
        return {}
    path = Path(run) / "posterior" / "synthetic" / "projection.npz"
    k = max(settings.product_sections, default=1)
    stamp = content_hash({"emulator": _stamp(run), "rank": settings.projection_rank, "sections": k,
                          "cases": PROJECTION_CASES})  # fmt: skip
    if path.exists():
        with np.load(path, allow_pickle=False) as z:
            if str(z["stamp"]) == stamp:
                return {"matrix": z["matrix"], "kept": float(z["kept"]), "stamp": stamp}
    u, _ = cached_cases(settings, Path(run) / "posterior" / "simulations", "train",
                        settings.n_train)  # fmt: skip
    base = likelihood(settings, emulator)
    rank = settings.projection_rank
    matrix, kept = informative_projection(base, u[:PROJECTION_CASES], k, rank)
    buf = io.BytesIO()
    np.savez(buf, matrix=matrix, kept=np.array(kept), stamp=np.array(stamp))
    atomic_write_bytes(path, buf.getvalue())
    log.info("synthetic likelihood: %d of %d combinations keep %.4f of the information",
             rank, emulator.dim, kept)  # fmt: skip
    return {"matrix": matrix, "kept": kept, "stamp": stamp}


def scale_set(settings: PosteriorSettings) -> tuple[str, int, int] | None:
    """(kind, records, sections) the scales are fitted on: the fusion's calibration
    records (``long-calibration``) of the longest checked number of sections; None
    without ``product_sections``."""
    if not settings.product_sections:
        return None
    n, longest, _ = settings.product_sets()[-1]
    return ("long-calibration", n, longest)


def fit_covariance_scales(post: SyntheticPosterior, run: str | Path, where) -> dict:
    """Fit (or read) the covariance's scales on the held-out records ``where`` ((kind,
    records, sections), or None: scales 1), into ``posterior/synthetic/scales.json``."""
    path = Path(run) / "posterior" / "synthetic" / "scales.json"
    record = {"records": None, "within_scale": 1.0, "model_error": 0.0}
    if where is not None:
        kind, n, k = where
        record["records"] = [kind, int(n), int(k)]
        record["emulator"] = _stamp(run)
        if post.likelihood.projection is not None:
            record["projection"] = content_hash({"p": post.likelihood.projection.tolist()})
        if path.exists():
            old = read_json(path)
            if (
                old.get("records") == record["records"]
                and old.get("emulator") == record["emulator"]
                and old.get("projection") == record.get("projection")
                and "model_error_matrix" in old
            ):
                return old
        s = post.settings
        u, x = cached_cases(s, Path(run) / "posterior" / "simulations", kind, n, k)
        ok = np.all(np.isfinite(x), axis=(1, 2))
        within, model = fit_scales(post.likelihood, u[ok], x[ok])
        matrix, rho = fit_model_error(post.likelihood, u[ok], x[ok], within)
        record.update(within_scale=within, model_error=model, used=int(ok.sum()),
                      model_error_matrix=matrix.tolist(), shrinkage=rho)  # fmt: skip
        log.info("synthetic likelihood: sections' scatter x %.2f, model error %.4f of it "
                 "(isotropic), per direction %.4f to %.4f (shrinkage %.2f)", within, model,
                 *np.linalg.eigvalsh(matrix)[[0, -1]], rho)  # fmt: skip
    write_json(path, record)
    return record


def fit_emulator(settings: PosteriorSettings, run: str | Path) -> StatisticsEmulator:
    """The emulator of the run's training cases (simulated if not cached), fitted once and
    stored in ``posterior/synthetic/emulator.npz``; read back when there."""
    folder = Path(run) / "posterior"
    path = folder / "synthetic" / "emulator.npz"
    trained_on = {k: v for k, v in settings.to_dict().items() if k in TRAINED_ON}
    key = content_hash({"settings": trained_on, "members": MEMBERS, "hidden": HIDDEN})
    stamp = folder / "synthetic" / "settings.json"
    if path.exists() and stamp.exists() and read_json(stamp).get("hash") == key:
        return StatisticsEmulator.load(path)
    u, x = cached_cases(settings, folder / "simulations", "train", settings.n_train)
    t0 = time.perf_counter()
    emu = fit(u, x, members=MEMBERS, hidden=HIDDEN, seed=settings.seed, log=log)
    log.info("synthetic likelihood: emulator fitted in %.0f s", time.perf_counter() - t0)
    emu.save(path)
    write_json(stamp, {"hash": key, "members": MEMBERS, "hidden": HIDDEN,
                       "settings": settings.to_dict()})  # fmt: skip
    return emu


def held_out_sets(settings: PosteriorSettings) -> list[tuple[str, int, int, tuple[int, ...]]]:
    """(kind, cases, sections simulated, numbers of sections checked) of the settings'
    held-out sets: one section on ``check``, the fusion's ``long`` sets for the rest."""
    sets = [("check", settings.n_check, 1, (1,))]
    return sets + [("long", n, longest, ks) for n, longest, ks in settings.product_sets()]


def run_checks(post: SyntheticPosterior, run: str | Path, sets=None) -> list[SectionsCheck]:
    """Coverage of the posterior on held-out records: per set (``held_out_sets``'s
    form; default the settings'), the first k sections of each record for each k."""
    s = post.settings
    names = list(s.parameters)
    folder = Path(run) / "posterior" / "simulations"
    out = []
    for kind, n, longest, ks in sets or held_out_sets(s):
        u, x = cached_cases(s, folder, kind, n, longest)
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
    _restamp_settings(settings, run)
    fitted = fit_projection(settings, emulator, run)
    projection = fitted.get("matrix")
    post = SyntheticPosterior(settings, likelihood(settings, emulator, None, projection))
    where = scale_set(settings) if scales_on == "default" else scales_on
    scales = fit_covariance_scales(post, run, where)
    post.likelihood = likelihood(settings, emulator, scales, projection)
    path = Path(run) / "posterior" / "synthetic" / "check.json"
    sets = [list(map(_plain, st)) for st in (sets or held_out_sets(settings))]
    matrix = content_hash({"model_error_matrix": scales.get("model_error_matrix")})
    plug_in = post.likelihood.plug_in_covariance
    stamp = [_stamp(run), scales["within_scale"], scales["model_error"], matrix, plug_in]
    if projection is not None:  # the projection's own stamp: emulator, rank, sections
        stamp.append(fitted["stamp"])
    if path.exists():
        old = read_json(path)
        if old.get("sets") == sets and old.get("emulator") == stamp:
            post.checks = [SectionsCheck.from_dict(c) for c in old["checks"]]
            return post
    post.checks = run_checks(post, run, sets)
    write_json(path, {"method": "synthetic-likelihood", "sets": sets, "emulator": stamp,
                      "checks": [c.to_dict() for c in post.checks]})  # fmt: skip
    return post


def _plain(v):
    return list(v) if isinstance(v, tuple) else v


def _restamp_settings(settings: PosteriorSettings, run: str | Path) -> None:
    """Write the settings being trained into ``settings.json`` (keeping the emulator's
    hash): settings the emulator does not depend on (``projection_rank``) change what
    :func:`load` must rebuild."""
    path = Path(run) / "posterior" / "synthetic" / "settings.json"
    record = read_json(path)
    if record.get("settings") != settings.to_dict():
        write_json(path, {**record, "settings": settings.to_dict()})


def _stamp(run: str | Path) -> str | None:
    path = Path(run) / "posterior" / "synthetic" / "settings.json"
    return read_json(path).get("hash") if path.exists() else None


def load(run: str | Path) -> SyntheticPosterior:
    """The fitted and checked synthetic likelihood of a run (nothing is fitted here)."""
    folder = Path(run) / "posterior" / "synthetic"
    for name in ("settings.json", "emulator.npz", "scales.json", "check.json"):
        if not (folder / name).exists():
            raise RailsuspInputError(
                f"{folder / name} does not exist: fit the synthetic likelihood first "
                "(railsusp posterior train --long-record synthetic-likelihood)"
            )
    settings = PosteriorSettings.from_dict(read_json(folder / "settings.json")["settings"])
    emulator = StatisticsEmulator.load(folder / "emulator.npz")
    scales = read_json(folder / "scales.json")
    checked = read_json(folder / "check.json")
    projection = None
    if settings.statistics != ("en14363",):
        path = folder / "projection.npz"
        stamp = None
        if path.exists():
            with np.load(path, allow_pickle=False) as z:
                projection, stamp = z["matrix"], str(z["stamp"])
        if stamp is None or checked.get("emulator", [None])[-1] != stamp:
            raise RailsuspInputError(
                f"{path} does not belong to the check in {folder / 'check.json'} (an "
                "interrupted or other training): run railsusp posterior train "
                "--long-record synthetic-likelihood again on this folder"
            )
    post = SyntheticPosterior(settings, likelihood(settings, emulator, scales, projection))
    post.checks = [SectionsCheck.from_dict(c) for c in checked["checks"]]
    return post


def estimate(post: SyntheticPosterior, recordings, seed: int = 0) -> PosteriorResult:
    """Posterior of the recordings (one per trained condition) from the mean of their
    sections' statistics, with the check of its number of sections."""
    x, used = recording_summaries(post.settings, recordings)
    s = post.settings
    n = len(x)
    u = post.sample(x, s.samples, seed)
    chk = post.product_for(n)
    notes = []
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
    return PosteriorResult(s.parameters, to_si(u, s.parameters), checks, used, n, notes,
                           None, None if chk is None else chk.sections,
                           "synthetic-likelihood")  # fmt: skip
