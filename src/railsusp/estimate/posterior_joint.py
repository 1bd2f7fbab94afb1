"""One posterior from synthetic-likelihood estimators of different working conditions of the
same wagon (issue 20): their likelihoods multiply.

Why it is exact: each condition of a recording runs on its own stretch of track, and the
instrument's gain error and noise are drawn per condition (:mod:`railsusp.estimate.
posterior_data`), so given the parameters the conditions' statistics are independent, and
the likelihood of all of them is the product of each estimator's (Wood 2010's synthetic
likelihood of each condition's section mean). An estimator of the straight and the curve
and another of the grade, trained apart on the same parameter draws (the same ``seed``,
the second with ``condition_offset`` past the first's conditions, so that its tracks and
noise are its own), then give the posterior of a recording of all three conditions: the
conditions' costs add instead of one estimator's emulator learning all their statistics
together, and the first estimator is not trained again (a recording of fewer conditions
takes a join of the estimators of its conditions).

A product of posteriors that each passed its own coverage check is not checked by those
checks, so the joint posterior is checked again (:func:`train`) on the parts' held-out
records (the same parameter draws in every part: the shared seed and counts), read from
the parts' caches only (nothing is simulated: a missing record is a one-line error), and
stored in ``posterior/joint.json`` of its own folder with the parts' folders and the stamps
of their checks (which hold the SHA-256 of the parts' emulators' files): a part trained
again afterwards makes the joint's check stale, and :func:`load` refuses it in one line, as
it refuses a ``joint.json`` edited since it was written (its seal,
:func:`~railsusp.estimate.posterior_check.seal`).

The sampler is the parts' own (:meth:`~railsusp.estimate.posterior_synthetic.
SyntheticLikelihood.sample`): a first tempered SMC run on the sum of the parts' first
log-likelihoods, a second with each part's covariance held at the first run's mean.

**Widening, fitted and checked.** Each part's emulator error is modelled on its own
calibration records, but an error both emulators make alike at the same parameters does
not average out in their product, and each part's own small over-confidence carries into
it (measured at 600 s: with full-batch emulators X18's 90 % intervals held 77 % of 100
test truths; with the emulators fitted on their linear trend (stop 32) every parameter
passed, but the ten held 0.86 pooled, bench/README.md). So, as the flows' estimator does
(:class:`~railsusp.estimate.calibration.SpreadCorrection`), the joint posterior's draws
are widened per parameter and per checked number of sections, in logit coordinates about
their median, by split-conformal factors fitted on the parts' calibration records (the
first k sections of each, never the test records); the check then runs on the widened
draws, and a factor above 2 flags the parameter as not calibrated.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.calibration import SpreadCorrection
from railsusp.estimate.posterior_check import read_sealed, seal, seal_state, stored_record, widen
from railsusp.estimate.posterior_data import cached_cases
from railsusp.estimate.posterior_fusion import to_logit
from railsusp.estimate.posterior_recordings import (
    MissingRecording,
    recording_summaries,
    unused_recordings,
)
from railsusp.estimate.posterior_result import PosteriorResult
from railsusp.estimate.posterior_settings import check_run_folder, check_seed
from railsusp.estimate.posterior_smc import smc_sample
from railsusp.estimate.posterior_support import TrainingSupport
from railsusp.estimate.posterior_synthetic_fit import scale_set
from railsusp.estimate.posterior_synthetic_run import (
    Checked,
    SectionsCheck,
    SyntheticPosterior,
    check_sets,
    held_out_sets,
    plain_sets,
    result_of,
)
from railsusp.estimate.posterior_synthetic_run import load as load_part
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import read_json, write_json

log = logging.getLogger(__name__)

#: the settings every part must share: what is estimated, how records are cut and
#: checked, and the draws of every kind of case (the seed)
SHARED = ("parameters", "section_s", "seed", "noise", "samples", "n_check", "product_sections",
          "n_product", "product_cases")  # fmt: skip


@dataclass
class JointPosterior(Checked):
    """The product of the synthetic likelihoods of ``parts`` (module docstring); the
    summary vector is the parts' one after the other, as an estimator of all their
    conditions would hold them."""

    parts: tuple[SyntheticPosterior, ...]
    checks: list[SectionsCheck] = field(default_factory=list)
    #: the widening per checked number of sections (module docstring; none: the raw draws)
    corrections: dict[int, SpreadCorrection] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_parts(self.parts)

    @property
    def settings(self):
        """The first part's settings: the shared ones (:data:`SHARED`) are every part's, but
        its ``conditions`` and ``summary_names`` are the first part's only."""
        return self.parts[0].settings

    @property
    def support(self) -> TrainingSupport | None:
        """The parts' training ranges, their statistics one after the other."""
        return TrainingSupport.joined([p.support for p in self.parts])

    @property
    def widths(self) -> list[int]:
        """The number of statistics each part reads from the summary vector."""
        return [p.likelihood.emulator.dim for p in self.parts]

    def split(self, x: np.ndarray) -> list[np.ndarray]:
        """The parts' sections (k, D_i) of the summary vectors ``x`` (k, sum D_i)."""
        x = np.atleast_2d(np.asarray(x, float))
        if x.ndim != 2 or x.shape[1] != sum(self.widths):
            raise RailsuspInputError(
                f"sections {x.shape}: accepted summaries (k, {sum(self.widths)}), the parts' "
                f"{' + '.join(map(str, self.widths))} one after the other"
            )
        return np.split(x, np.cumsum(self.widths)[:-1], axis=1)

    def raw_sample(self, x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
        """(n, d) draws (unit box) of the estimated parameters for the sections ``x``,
        before any widening."""
        return sample_product([p.likelihood for p in self.parts], self.split(x), n, seed)[
            :, self.columns
        ]

    def sample(self, x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
        """(n, d) draws (unit box) for the sections ``x``, widened by the correction of
        their number of sections (:meth:`correction_for`) where there is one."""
        return widen(self.correction_for(len(np.atleast_2d(x))), self.raw_sample(x, n, seed))

    def correction_for(self, sections: int) -> SpreadCorrection | None:
        """The widening of the smallest corrected number of sections >= ``sections``; for
        more sections than any corrected, the largest's, the nearest measured (none was
        applied, so a longer record got narrower intervals than a checked one, where the
        fusion route keeps its one-section widening: stop 78's hunt). None without any."""
        k = min((k for k in self.corrections if k >= sections), default=None)
        if k is None:
            k = max(self.corrections, default=None)
        return None if k is None else self.corrections[k]


def sample_product(likelihoods, sections, n: int, seed: int = 0) -> np.ndarray:
    """(n, d) draws on the unit box of the posterior whose likelihood is the product of
    ``likelihoods``' of their ``sections`` (each (k_i, D_i): the parts may hold different
    numbers of sections): two SMC runs as :meth:`SyntheticLikelihood.sample`, which this
    is, draw for draw, for one part."""
    readings = [sl.reading(x) for sl, x in zip(likelihoods, sections, strict=True)]
    d = likelihoods[0].emulator.inputs
    rng = np.random.default_rng(seed)
    pairs = list(zip(likelihoods, readings, strict=True))
    first = [sl.first_log_likelihood(s, k) for sl, (s, k) in pairs]
    draws = smc_sample(_total(first), d, n, rng)
    if not any(sl.plug_in_covariance for sl in likelihoods):
        return draws
    u0 = draws.mean(axis=0)
    second = [sl.second_log_likelihood(u0, s, k) for sl, (s, k) in pairs]
    return smc_sample(_total(second), d, n, rng)


def _total(logliks):
    """The sum of log-likelihoods (each (N, d) -> (N,)); one is returned as it is."""
    if len(logliks) == 1:
        return logliks[0]
    return lambda u: sum(f(u) for f in logliks)


def check_parts(parts) -> None:
    """A one-line error unless ``parts`` (at least two) share :data:`SHARED`, read all ten
    parameters, hold disjoint conditions and their tracks are their own (disjoint
    ``condition_offset`` ranges)."""
    if len(parts) < 2:
        raise RailsuspInputError(
            f"joint posterior of {len(parts)} estimator(s): accepted two or more"
        )
    first = parts[0].settings.to_dict()
    for i, p in enumerate(parts[1:], start=2):
        other = p.settings.to_dict()
        for name in SHARED:
            if first.get(name) != other.get(name):
                raise RailsuspInputError(
                    f"joint posterior: estimator {i}'s {name} = {other.get(name)} differs from "
                    f"the first's ({first.get(name)}); accepted the same in every estimator"
                )
        if first.get("wagon") != other.get("wagon"):  # one wagon's conditions only
            names = [
                "the packaged loaded C80/K6" if w is None else repr(w["wagon"]["name"])
                for w in (first.get("wagon"), other.get("wagon"))
            ]
            raise RailsuspInputError(
                f"joint posterior: estimator {i} simulated another wagon ({names[1]}) than the "
                f"first ({names[0]}); accepted estimators of the same wagon"
            )
    seen: dict[str, int] = {}
    slots: dict[int, int] = {}
    for i, p in enumerate(parts, start=1):
        s = p.settings
        if p.likelihood.emulator.inputs != len(MAIN_SUSPENSION):
            raise RailsuspInputError(
                f"joint posterior: estimator {i} reads {p.likelihood.emulator.inputs} "
                f"parameters; accepted all {len(MAIN_SUSPENSION)}"
            )
        for c in s.conditions:
            if c.name in seen:
                raise RailsuspInputError(
                    f"joint posterior: condition {c.name!r} in estimators {seen[c.name]} and "
                    f"{i}; accepted each condition in one estimator"
                )
            seen[c.name] = i
        for slot in range(s.condition_offset, s.condition_offset + len(s.conditions)):
            if slot in slots:
                raise RailsuspInputError(
                    f"joint posterior: estimators {slots[slot]} and {i} both hold condition "
                    f"index {slot} (condition_offset = {s.condition_offset}): they share "
                    "tracks or instrument noise; accepted a condition_offset past the other's "
                    "conditions"
                )
            slots[slot] = i


def joint_cases(parts, runs, kind: str, n: int, sections: int, draws=None):
    """(u, x) of the held-out cases ``kind`` (``draws``: at these parameter sets, as
    :func:`~railsusp.estimate.posterior_data.cached_cases`) in every part's run folder, x
    the parts' statistics one after the other. Read only: a case a part has not cached is
    a one-line error (it would be simulated otherwise), as are parts whose cases are other
    parameter sets (they cannot be, with the seed and counts :func:`check_parts` requires:
    a guard against a cache changed by hand)."""
    us, xs = [], []
    for p, run in zip(parts, runs, strict=True):
        folder = Path(run) / "posterior" / "simulations"
        u, x = cached_cases(p.settings, folder, kind, n, sections, draws=draws, simulate=False)
        us.append(u)
        xs.append(x)
    for i, u in enumerate(us[1:], start=2):
        if not np.array_equal(u, us[0]):
            raise RailsuspInputError(
                f"joint posterior: estimator {i}'s {kind} cases are other parameter sets than "
                "the first's; accepted estimators trained with the same seed"
            )
    return us[0], np.concatenate(xs, axis=-1)


def part_stamps(runs) -> list:
    """Each part's check stamp (``check.json``'s ``emulator``)."""
    return [read_json(Path(r) / "posterior" / "synthetic" / "check.json").get("emulator")
            for r in runs]  # fmt: skip


def train(runs, out: str | Path, sets=None, calibration="default") -> JointPosterior:
    """The joint posterior of the trained estimators in ``runs``: its widening fitted on
    the parts' ``calibration`` records ((kind, records, sections); "default": the records
    the parts' covariance scales are fitted on, :func:`~railsusp.estimate.
    posterior_synthetic_fit.scale_set`; None: no widening) and its check on their
    held-out records (``sets`` as :func:`held_out_sets`; default the first part's), into
    ``out``/posterior/joint.json; a stored check of the same parts, sets and calibration
    records is read. ``out`` must not be an estimator's folder (it would read as the joint
    posterior afterwards)."""
    runs = [str(Path(r).resolve()) for r in runs]
    target = Path(out).resolve()
    if (
        any(target == Path(r) or Path(r) in target.parents for r in runs)  # or inside one
        or (target / "posterior" / "settings.json").exists()
        or (target / "posterior" / "synthetic").exists()
    ):
        raise RailsuspInputError(
            f"--out {out}: an estimator's folder; accepted a folder of its own for the joint "
            "posterior"
        )
    missing = [r for r in runs if not Path(r).is_dir()]
    if missing:
        raise RailsuspInputError(f"--estimators: {missing[0]}: no such folder")
    parts = tuple(load_part(r) for r in runs)
    joint = JointPosterior(parts)
    sets = sets or held_out_sets(joint.settings)
    if calibration == "default":
        calibration = scale_set(joint.settings)
    where = None if calibration is None else list(calibration)
    path = Path(out) / "posterior" / "joint.json"
    stamps = part_stamps(runs)
    old = stored_record(path, "the joint check")
    if old is not None:
        same = old.get("runs") == runs and old.get("stamps") == stamps
        if same and old.get("sets") == plain_sets(sets) and old.get("calibration") == where:
            if seal_state(old) == "unsealed":  # written before records were sealed
                write_json(path, seal(old))
            return _from_record(joint, old)
    cases = lambda kind, n, k: joint_cases(parts, runs, kind, n, k)  # noqa: E731
    if calibration is not None:
        ks = sorted({k for *_, checked in sets for k in checked})
        joint.corrections = fit_corrections(joint, cases, calibration, ks)
    joint.checks = flag_excessive(joint, check_sets(joint, cases, sets))
    write_json(path, seal({
        "method": "joint-synthetic-likelihood", "runs": runs, "stamps": stamps,
        "sets": plain_sets(sets), "calibration": where,
        "corrections": {str(k): c.to_dict() for k, c in joint.corrections.items()},
        "checks": [c.to_dict() for c in joint.checks],
    }))  # fmt: skip
    return joint


def fit_corrections(joint: JointPosterior, cases, where, ks) -> dict[int, SpreadCorrection]:
    """Split-conformal widenings (logit coordinates) per number of sections ``ks`` from the
    raw draws of the first k sections of the calibration records ``where`` ((kind,
    records, sections), read by ``cases``); numbers beyond the records' sections are
    left without one."""
    kind, n, longest = where
    u, x = cases(kind, int(n), int(longest))
    x = x[:, None, :] if x.ndim == 2 else x
    ok = np.all(np.isfinite(x), axis=(1, 2))
    truth = to_logit(u[ok][:, joint.columns])
    s = joint.settings
    out = {}
    for k in ks:
        if k > x.shape[1]:
            continue
        draws = np.stack([joint.raw_sample(xi[:k], s.samples, seed=s.seed + i)
                          for i, xi in enumerate(x[ok])])  # fmt: skip
        out[k] = SpreadCorrection.fit(to_logit(draws), truth, list(s.parameters))
        log.info("joint posterior: %d sections widened by %s on %d %s records", k,
                 ", ".join(f"{f:.2f}" for f in out[k].factors), int(ok.sum()), kind)  # fmt: skip
    return out


def flag_excessive(joint: JointPosterior, checks: list[SectionsCheck]) -> list[SectionsCheck]:
    """The checks with every parameter whose widening exceeds the bound (its shape, not only
    its spread, is wrong) marked as not passed."""
    out = []
    for c in checks:
        correction = joint.correction_for(c.sections)
        bad = set(correction.excessive) if correction is not None else set()
        params = tuple(replace(p, passed=p.passed and p.parameter not in bad) for p in c.checks)
        out.append(SectionsCheck(c.sections, params, c.width_pct_range))
    return out


def _from_record(joint: JointPosterior, record: dict) -> JointPosterior:
    joint.checks = [SectionsCheck.from_dict(c) for c in record["checks"]]
    joint.corrections = {int(k): SpreadCorrection.from_dict(c)
                         for k, c in (record.get("corrections") or {}).items()}  # fmt: skip
    return joint


def load(out: str | Path) -> JointPosterior:
    """The joint posterior stored in ``out`` (:func:`train`); a one-line error when a
    part was trained again (or moved) since its check, or the file is not a joint check."""
    check_run_folder(out, "out")
    path = Path(out) / "posterior" / "joint.json"
    if not path.exists():
        raise RailsuspInputError(f"{path} does not exist: check the joint posterior first")
    record, _ = read_sealed(path, "the joint posterior's check")
    if not all(key in record for key in ("runs", "stamps", "checks")):
        raise RailsuspInputError(
            f"{path}: not a joint posterior's check (runs, stamps, checks); run railsusp "
            "posterior join again"
        )
    runs = record["runs"]
    moved = [r for r in runs if not (Path(r) / "posterior" / "synthetic" / "check.json").exists()]
    if moved:
        raise RailsuspInputError(
            f"{path}: the estimator {moved[0]} is not there (moved or removed); run railsusp "
            "posterior join again on the estimators' folders"
        )
    if part_stamps(runs) != record["stamps"]:
        raise RailsuspInputError(
            f"{path}: an estimator of {', '.join(runs)} was trained again after the joint "
            "check (or its check record sealed since: a train on a folder of before); run "
            "railsusp posterior join again"
        )
    return _from_record(JointPosterior(tuple(load_part(r) for r in runs)), record)


def recording_sections(joint: JointPosterior, recordings) -> tuple[np.ndarray, dict]:
    """(k, sum D_i) summary vectors of recordings of every part's conditions, each part's
    sections (:func:`~railsusp.estimate.posterior_recordings.recording_summaries`) with the part
    of the fewest setting their number, and the recordings' use per condition."""
    xs, used = [], {}
    trained = [c.name for p in joint.parts for c in p.settings.conditions]
    for p in joint.parts:
        try:
            x, u = recording_summaries(p.settings, recordings)
        except MissingRecording as exc:  # the joint's conditions, not the part's alone
            raise exc.of_estimator(trained) from None
        xs.append(x)
        used.update(u)
    k = min(len(x) for x in xs)
    section = joint.settings.section_s
    for info in used.values():  # a part's sections beyond the fewest are left out too
        info["seconds_left_out"] = round(
            info["seconds_left_out"] + (info["sections"] - k) * section, 3
        )
        info["sections"] = k
    return np.concatenate([x[:k] for x in xs], axis=1), used


def estimate(joint: JointPosterior, recordings, seed: int = 0) -> PosteriorResult:
    """The joint posterior of recordings of every part's conditions (one per condition),
    with the joint check of its number of sections; ``seed``: of the draws (0 to
    :data:`~railsusp.estimate.posterior_settings.MAX_SEED`, refused in one line else)."""
    check_seed(seed)
    x, used = recording_sections(joint, recordings)
    trained = [c.name for p in joint.parts for c in p.settings.conditions]
    return result_of(joint, x, used, seed, unused_recordings(recordings, trained))
