"""The fitted pieces of the synthetic-likelihood posterior, each fitted once and cached in
``posterior/synthetic/`` under a stamp of what it learnt from (:mod:`railsusp.estimate.
posterior_synthetic_run` trains, checks and loads them): the emulator of all the
statistics, the informative projection, the emulator of the projected combinations alone
and the covariance's scales fitted on calibration records."""

from __future__ import annotations

import io
import logging
import time
import warnings
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.posterior_data import GAIN_ERROR, cached_cases
from railsusp.estimate.posterior_emulator import StatisticsEmulator, fit
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.posterior_stamp import check_model_revision, estimator_stamp
from railsusp.estimate.posterior_synthetic import SyntheticLikelihood, gain_covariance
from railsusp.estimate.posterior_synthetic_information import informative_projection
from railsusp.estimate.posterior_synthetic_model_error import fit_model_error, fit_scales
from railsusp.integrity import read_npz
from railsusp.store import (
    atomic_write_bytes,
    content_hash,
    file_hash_cached,
    read_json,
    write_json,
)

log = logging.getLogger(__name__)

#: networks in the emulators' bagged ensembles, and their hidden width
MEMBERS = 10
HIDDEN = 64
#: how both emulators (of all the statistics, and of the projected combinations alone)
#: are trained since stop 32: each network learns, in mini-batches, what its resample's
#: linear trend leaves (:func:`~railsusp.estimate.posterior_emulator.fit`). Measured on
#: the 32 000 training cases of stops 30-31 (bench/README.md, stop 32): full-batch
#: networks of 48 left the first combination (X18's, moved by 25-30 sections' standard
#: deviations over X18's range) a wave of up to 0.44 section standard deviations along
#: X18, the same shape in the straight-and-curve and the grade estimators, so that a
#: joint posterior of the two added it; the emulator of all statistics trained so chose
#: combinations whose estimators passed their checks at 20, 120 and 600 s
TRAINING = {"batch": 256, "trend": True}
#: the hidden width of the emulator of the projected combinations
PROJECTED_HIDDEN = HIDDEN
#: the training cases the informative projection of statistics beyond the EN 14363 summary
#: is averaged over (``informative_projection`` of
#: :mod:`railsusp.estimate.posterior_synthetic_information`)
PROJECTION_CASES = 200
#: the settings the emulator depends on (the training cases and their statistics; the
#: condition offset, their tracks, only where it is set: the hashes of before stay)
TRAINED_ON = ("conditions", "parameters", "section_s", "n_train", "noise", "sum_y", "seed",
              "statistics", "condition_offset")  # fmt: skip


def likelihood(
    settings: PosteriorSettings,
    emulator: StatisticsEmulator,
    scales: dict | None = None,
    projection: np.ndarray | None = None,
    projected: StatisticsEmulator | None = None,
) -> SyntheticLikelihood:
    """The likelihood of these settings' statistics: the gain error shared by a record's
    sections is the instrument model's (the training simulations'); ``scales``: the
    covariance's fitted scales (``scales.json``; none: 1); ``projection``: the likelihood
    of these combinations of the statistics (:func:`fit_projection`), ``projected``
    their own emulator (:func:`fit_projected_emulator`; None: ``emulator`` read through
    the projection). With statistics
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
        projected=projected,
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
    stamp = content_hash({"emulator": emulator_stamp(run), "rank": settings.projection_rank,
                          "sections": k, "cases": PROJECTION_CASES})  # fmt: skip
    if path.exists():
        try:
            z = read_npz(path, "the projection", "computed again")
            if str(z["stamp"]) == stamp:
                return {"matrix": z["matrix"], "kept": float(z["kept"]), "stamp": stamp}
        except (RailsuspInputError, KeyError) as exc:
            log.warning("%s", exc)
    u, _ = cached_cases(settings, Path(run) / "posterior" / "simulations", "train",
                        settings.n_train)  # fmt: skip
    base = likelihood(settings, emulator)
    rank = settings.projection_rank
    if rank > emulator.dim:
        warnings.warn(
            f"posterior: projection_rank (--projection-rank) {rank} is more than the "
            f"{emulator.dim} statistics there are; {emulator.dim} combinations are used "
            f"(accepted: 1 to {emulator.dim} for these statistics)",
            stacklevel=2,
        )
        rank = emulator.dim
    matrix, kept = informative_projection(base, u[:PROJECTION_CASES], k, rank)
    buf = io.BytesIO()
    np.savez(buf, matrix=matrix, kept=np.array(kept), stamp=np.array(stamp))
    atomic_write_bytes(path, buf.getvalue())
    log.info("synthetic likelihood: %d of %d combinations keep %.4f of the information",
             rank, emulator.dim, kept)  # fmt: skip
    return {"matrix": matrix, "kept": kept, "stamp": stamp}


#: a scale of the sections' scatter beyond this is a degenerate fit, said as a warning (on
#: 2 s sections, the 0.3-1.5 Hz band's statistics: a scale of about 8e21, stop 56's audit)
WITHIN_SCALE_WARN = 100.0


def scale_set(settings: PosteriorSettings) -> tuple[str, int, int] | None:
    """(kind, records, sections) the scales are fitted on: the fusion's calibration
    records (``long-calibration``) of the longest checked number of sections; None
    without ``product_sections``."""
    if not settings.product_sections:
        return None
    n, longest, _ = settings.product_sets()[-1]
    return ("long-calibration", n, longest)


def fit_covariance_scales(
    settings: PosteriorSettings,
    sl: SyntheticLikelihood,
    run: str | Path,
    where,
) -> dict:
    """Fit (or read) the covariance's scales of the likelihood ``sl`` on the held-out
    records ``where`` ((kind, records, sections), or None: scales 1), into
    ``posterior/synthetic/scales.json``, stamped with the emulators (their settings' hash
    and their files' SHA-256, :func:`emulator_files`) and the projection."""
    path = Path(run) / "posterior" / "synthetic" / "scales.json"
    record = {"records": None, "within_scale": 1.0, "model_error": 0.0}
    if where is not None:
        kind, n, k = where
        record["records"] = [kind, int(n), int(k)]
        record["emulator"] = emulator_stamp(run)
        if sl.projection is not None:
            record["projection"] = content_hash({"p": sl.projection.tolist()})
        if sl.projected is not None:
            record["projected"] = sl.projected.stamp
        record["files"] = emulator_files(run, sl)
        if path.exists():
            old = read_json(path)
            if (
                isinstance(old, dict)
                and old.get("records") == record["records"]
                and old.get("emulator") == record["emulator"]
                and old.get("projection") == record.get("projection")
                and old.get("projected") == record.get("projected")
                and old.get("files") == record["files"]
                and "model_error_matrix" in old
            ):
                return old
        u, x = cached_cases(settings, Path(run) / "posterior" / "simulations", kind, n, k)
        ok = np.all(np.isfinite(x), axis=(1, 2))
        within, model = fit_scales(sl, u[ok], x[ok])
        matrix, rho = fit_model_error(sl, u[ok], x[ok], within)
        record.update(within_scale=within, model_error=model, used=int(ok.sum()),
                      model_error_matrix=matrix.tolist(), shrinkage=rho)  # fmt: skip
        log.info("synthetic likelihood: sections' scatter x %.2f, model error %.4f of it "
                 "(isotropic), per direction %.4f to %.4f (shrinkage %.2f)", within, model,
                 *np.linalg.eigvalsh(matrix)[[0, -1]], rho)  # fmt: skip
        if within > WITHIN_SCALE_WARN:
            warnings.warn(
                f"synthetic likelihood: the sections scatter {within:.3g} times as much as "
                "the emulator expects, so some statistic hardly varies between its training "
                f"cases (a frequency band longer than the {settings.section_s:g} s section?); "
                "the check below says whether the posterior holds; a longer --section helps",
                UserWarning,
                stacklevel=2,
            )
    write_json(path, record)
    return record


def emulator_key(settings: PosteriorSettings) -> str:
    """The hash of what the emulator of all the statistics learns from: the training
    settings with the cases it reads (``statistics_emulator_cases`` when set, else
    ``n_train``), so that it is the hash of an emulator of as many cases trained before
    the setting existed, the network size and its training."""
    trained_on = _trained_on(settings)
    trained_on["n_train"] = settings.statistics_emulator_cases or settings.n_train
    return content_hash({"settings": trained_on, "members": MEMBERS, "hidden": HIDDEN,
                         "training": TRAINING})  # fmt: skip


def _trained_on(settings: PosteriorSettings) -> dict:
    """The settings an emulator depends on (:data:`TRAINED_ON`), for its hash."""
    return {k: v for k, v in settings.to_dict().items() if k in TRAINED_ON}


def _cached(path: Path) -> StatisticsEmulator | None:
    """A stored emulator, or None (with a warning) where its file is damaged: training fits
    it again rather than stopping (a file cut short by a copy or a full disk)."""
    try:
        return StatisticsEmulator.load(path)
    except RailsuspInputError as exc:
        fix = "delete it and train again to fit it anew"
        log.warning("%s", str(exc).replace(fix, "fitted again"))
        return None


def fit_emulator(settings: PosteriorSettings, run: str | Path) -> StatisticsEmulator:
    """The emulator of all the statistics, on the run's training cases (simulated if not
    cached; the first ``statistics_emulator_cases`` of them when set), fitted once and
    stored in ``posterior/synthetic/emulator.npz``; read back when there."""
    folder = Path(run) / "posterior"
    path = folder / "synthetic" / "emulator.npz"
    cases = settings.statistics_emulator_cases or settings.n_train
    key = emulator_key(settings)
    stamp = folder / "synthetic" / "settings.json"
    if path.exists() and stamp.exists() and read_json(stamp).get("hash") == key:
        check_model_revision(read_json(stamp), stamp)
        cached = _cached(path)
        if cached is not None:
            return cached
    u, x = cached_cases(settings, folder / "simulations", "train", cases)
    t0 = time.perf_counter()
    emu = fit(u, x, members=MEMBERS, hidden=HIDDEN, seed=settings.seed, log=log, **TRAINING)
    log.info("synthetic likelihood: emulator fitted in %.0f s", time.perf_counter() - t0)
    emu.save(path)
    write_json(stamp, {"hash": key, **estimator_stamp(), "members": MEMBERS,
                       "hidden": HIDDEN, "training": TRAINING,
                       "settings": settings.to_dict()})  # fmt: skip
    return emu


def fit_projected_emulator(
    settings: PosteriorSettings, run: str | Path, fitted: dict
) -> StatisticsEmulator | None:
    """With ``statistics_emulator_cases``: the emulator of the projected combinations P x
    on all ``n_train`` training cases, fitted once per projection into
    ``posterior/synthetic/projected_emulator.npz`` with its stamp inside; None without (or
    without a projection).

    Why: the record's mean of 30 sections scatters by 1/30 of a section's variance, and
    the emulator's error must be small beside that. Measured on the 8000-case emulator of
    the four families with ``cross-spectra`` (bench/README.md): the record means of 250
    held-out records of 600 s lay 0.10 of a section's variance from it, against 0.033 for
    their own scatter, and 50 replicate records at the same parameters on other tracks
    agreed to 0.032: the excess is the emulator's error at those parameters, not a
    record's randomness, so only more training cases shrink it; an emulator of 750
    statistics on tens of thousands of cases costs hours, one of 15 combinations minutes."""
    if not settings.statistics_emulator_cases or "matrix" not in fitted:
        return None
    folder = Path(run) / "posterior"
    path = folder / "synthetic" / "projected_emulator.npz"
    key = content_hash({"settings": _trained_on(settings), "projection": fitted["stamp"],
                        "members": MEMBERS, "hidden": PROJECTED_HIDDEN,
                        "training": TRAINING})  # fmt: skip
    emu = _cached(path) if path.exists() else None
    if emu is not None and emu.stamp == key:
        return emu
    u, x = cached_cases(settings, folder / "simulations", "train", settings.n_train)
    t0 = time.perf_counter()
    emu = fit(u, x @ fitted["matrix"].T, members=MEMBERS, hidden=PROJECTED_HIDDEN,
              seed=settings.seed, log=log, **TRAINING)  # fmt: skip
    log.info("synthetic likelihood: emulator of %d combinations on %d cases fitted in %.0f s",
             emu.dim, emu.cases, time.perf_counter() - t0)  # fmt: skip
    emu.stamp = key
    emu.save(path)
    return emu


def emulator_files(run: str | Path, sl: SyntheticLikelihood) -> dict[str, str]:
    """The SHA-256 of the emulators' files the likelihood ``sl`` reads (``emulator.npz``,
    and ``projected_emulator.npz`` where it has one), by name: their stamps are hashes of
    the settings they were fitted with, which another training's file of the same
    settings (or one edited) shares; the files' contents are the emulators'."""
    folder = Path(run) / "posterior" / "synthetic"
    names = ["emulator.npz"] + (["projected_emulator.npz"] if sl.projected is not None else [])
    # (read once per version of a file: the scales' record and the check's stamp ask both)
    return {n: file_hash_cached(folder / n) for n in names if (folder / n).is_file()}


def check_stamp(
    run: str | Path,
    scales: dict,
    sl: SyntheticLikelihood,
    projection: str | None,
    files: bool = True,
) -> list:
    """What a coverage check of the likelihood ``sl`` was made with, stored in
    ``check.json`` and required by ``load``: the emulator's hash, the covariance's scales
    (c, m, A's hash), whether the covariance is plugged in, the SHA-256 of the emulators'
    files (:func:`emulator_files`; ``files`` False: the stamp of a check written before
    they were stamped, without them), the projected emulator's stamp and the projection's
    (``projection``, from ``projection.npz``), when there are these."""
    matrix = content_hash({"model_error_matrix": scales.get("model_error_matrix")})
    stamp = [emulator_stamp(run), scales["within_scale"], scales["model_error"], matrix,
             sl.plug_in_covariance]  # fmt: skip
    if files:  # before the optional stamps: load reads the projection's as the last
        stamp.append(emulator_files(run, sl))
    if sl.projected is not None:  # the projected combinations' own emulator
        stamp.append(sl.projected.stamp)
    if projection is not None:  # the projection's own stamp: emulator, rank, sections
        stamp.append(projection)
    return stamp


def restamp_settings(settings: PosteriorSettings, run: str | Path) -> None:
    """Write the settings being trained into ``settings.json`` (keeping the emulator's
    hash): settings the emulator does not depend on (``projection_rank``) change what
    :func:`load` must rebuild."""
    path = Path(run) / "posterior" / "synthetic" / "settings.json"
    record = read_json(path)
    if record.get("settings") != settings.to_dict():
        write_json(path, {**record, "settings": settings.to_dict()})


def emulator_stamp(run: str | Path) -> str | None:
    path = Path(run) / "posterior" / "synthetic" / "settings.json"
    return read_json(path).get("hash") if path.exists() else None
