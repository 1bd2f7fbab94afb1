"""The training and check simulations of the simulation-based posterior, and the summary
statistics of recordings in the same form.

Every simulated case draws all ten main-suspension parameters (X11-X20) from their uniform
Table 2 prior, whichever subset is estimated, and runs every condition on a track
realisation of its own (a new irregularity seed per case and condition): the estimator then
learns the statistics' scatter over track realisations and over the parameters it does not
estimate, and marginalises both. The simulated forces pass the instrument model of the
synthetic recordings (:func:`railsusp.measured.add_sensor_noise`: a 15 Hz bandwidth, a 1 %
gain error, white noise of ``noise`` times the channel RMS) before their statistics are
taken. Simulations are cached in chunks in the run directory (atomic writes), so an
interrupted training resumes without simulating again.
"""

from __future__ import annotations

import io
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError, first_listed
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.statistic_families import (
    section_statistics,
    statistic_names,
)
from railsusp.estimate.summaries import cut_sections
from railsusp.integrity import read_npz
from railsusp.measured.synthetic import bandwidth_filter
from railsusp.params import MAIN_SUSPENSION, bounds
from railsusp.store import atomic_write_bytes

log = logging.getLogger(__name__)

#: simulations per cache file
CHUNK = 50
#: instrument model of the training simulations (as ``add_sensor_noise``)
BANDWIDTH_HZ = 15.0
GAIN_ERROR = 0.01
#: track seeds of the simulated cases start here (the synthetic field uses seed + 1000):
#: training, the untouched coverage test ("check"), the calibration set that fits the
#: correction, the long test cases of several consecutive sections, and the parameter sets
#: of the identification benchmark (bench/posterior.py, drawn in the middle of the ranges),
#: and held-out records simulated again on other tracks (bench/posterior_synthetic.py)
SEED_BASE = {"train": 10_000_000, "check": 20_000_000, "calibration": 30_000_000,
             "long": 40_000_000, "long-calibration": 50_000_000,
             "identification": 60_000_000, "replicate": 70_000_000}  # fmt: skip
#: the track seeds of ``condition_offset`` o > 0 start at o times this (past every kind's;
#: with SEED_BASE it bounds :data:`~railsusp.estimate.posterior_settings.MAX_CONDITION_OFFSET`)
OFFSET_SEED_BASE = 100_000_000


class TrainingWheel:
    """The force model of the training simulations, as
    :func:`railsusp.estimate.problem.check_measured_wheel` asks of one: it records the
    automatically chosen wheel (:func:`railsusp.vehicle.simulation_result.measured_wheel_index`: the
    leading wheelset's outer wheel in a curve, its left wheel on tangent), so a recording
    is compared only where its first wheel is that one."""

    wheel = "auto"


def check_model_revision(stamp: dict, path: Path) -> None:
    """Refuse, in one line, an estimator folder whose ``settings.json`` (``stamp``) was
    simulated with other force laws than :data:`railsusp.vehicle.MODEL_REVISION` (or before
    the revision was recorded there, stop 60), or summarised with other statistics'
    definitions than :data:`railsusp.estimate.summaries.STATISTICS_VERSION` (recorded since
    stop 62): its cached simulations and what was trained on them describe another model,
    and mixing them with new ones would pass unseen."""
    from railsusp.vehicle.revision import Standing, made_with, newer_remedy, standing

    again = f"train again with another --out (or delete {path.parent})"
    revision = stamp.get("model_revision")
    s = standing(revision)
    if s is not Standing.THIS:
        remedy = newer_remedy(revision) if s is Standing.NEWER else again
        raise RailsuspInputError(
            f"{path}: its simulations were made with {made_with(revision)}: {remedy}"
        )
    got, now = stamp.get("statistics_version"), estimator_stamp()["statistics_version"]
    if got != now:
        was = f"version {got}" if got else "a version before 2026-11-30.2 (none recorded)"
        raise RailsuspInputError(
            f"{path}: its summary statistics are of the definitions of {was}, this railsusp "
            f"computes version {now}: {again}"
        )


def estimator_stamp() -> dict[str, str]:
    """What an estimator folder's ``settings.json`` records of the code that made its cached
    simulations and statistics (:func:`check_model_revision` checks it)."""
    from railsusp.estimate.summaries import STATISTICS_VERSION
    from railsusp.vehicle import MODEL_REVISION

    return {"model_revision": MODEL_REVISION, "statistics_version": STATISTICS_VERSION}


def prior_draws(settings: PosteriorSettings, kind: str, n: int) -> np.ndarray:
    """(n, 10) draws of X11-X20 in [0, 1] (fraction of each range), reproducible from the
    settings' seed. Training cases are independent uniform draws; the held-out sets are a
    Latin hypercube (each parameter's n truths one in each of n equal strata of its range,
    in random order): still the prior for every case, but a set cannot hold by chance many
    truths near the ends of a range, where a posterior that learnt little about the
    parameter (close to the prior) cannot hold them; with 200 independent draws that alone
    moves its coverage by +-2 %, and by 8 % in the first test set measured."""
    from scipy.stats import qmc

    rng = np.random.default_rng([settings.seed, list(SEED_BASE).index(kind)])
    if kind == "train":
        return rng.random((n, len(MAIN_SUSPENSION)))
    return qmc.LatinHypercube(d=len(MAIN_SUSPENSION), seed=rng).random(n)


def to_si(u: np.ndarray, symbols=MAIN_SUSPENSION) -> np.ndarray:
    """Fractions of the ranges -> SI values."""
    lo, hi = bounds(symbols)
    return lo + np.asarray(u) * (hi - lo)


def _instrument(x: np.ndarray, fs: float, rng: np.random.Generator, noise: float) -> np.ndarray:
    y = bandwidth_filter(x, fs, BANDWIDTH_HZ) * (1.0 + GAIN_ERROR * rng.standard_normal())
    return y + noise * np.sqrt(np.mean(x**2)) * rng.standard_normal(x.size)


def simulate_cases(settings: PosteriorSettings, u: np.ndarray, first: int, kind: str):
    """Summary vectors (n, D) of the cases ``u`` (n, 10 fractions of X11-X20), case
    indices from ``first`` (their track seeds and noise); NaN rows for failed runs."""
    return simulate_long_cases(settings, u, first, kind, 1)[:, 0, :]


def track_seeds(settings: PosteriorSettings, kind: str, idx: np.ndarray, c: int) -> np.ndarray:
    """The irregularity seeds of cases ``idx`` of ``kind`` in condition ``c`` (of the
    settings' conditions): each case and condition its own track. With a
    ``condition_offset`` o > 0 they start at o x :data:`OFFSET_SEED_BASE`, clear of the
    seeds at every other offset while a kind's cases times conditions stay under 10 000 000
    (the kinds' bases are that far apart, as at offset 0), so that an estimator of further
    conditions for the same cases never shares a track with another's."""
    base = SEED_BASE[kind] + settings.condition_offset * OFFSET_SEED_BASE
    return base + np.asarray(idx) * len(settings.conditions) + c


def noise_rng(settings: PosteriorSettings, kind: str, case: int, c: int) -> np.random.Generator:
    """The instrument's random stream (gain error, then noise) of case ``case`` of ``kind`` in
    condition ``c``: keyed by the condition's index in the joint design (``condition_offset``
    + c), so that estimators joined by :mod:`railsusp.estimate.posterior_joint` never share
    a stream; at offset 0 the key of every estimator before the offset existed."""
    return np.random.default_rng(
        [settings.seed, SEED_BASE[kind], case, settings.condition_offset + c]
    )


def simulate_long_cases(
    settings: PosteriorSettings, u: np.ndarray, first: int, kind: str, sections: int
) -> np.ndarray:
    """Summary vectors (n, sections, D) of the cases ``u``: each case runs every condition
    for ``sections`` consecutive training sections on one track realisation (as a
    recording is cut), the instrument model over the whole run; NaN for failed runs."""
    from railsusp.vehicle.simulate import simulate_batch

    n = u.shape[0]
    theta = to_si(u)
    width = len(statistic_names(settings.statistics, settings.sum_y))
    per_condition = []
    for c, cond in enumerate(settings.conditions):
        idx = np.arange(first, first + n)
        seeds = track_seeds(settings, kind, idx, c)
        run = cond if sections == 1 else cond.with_duration(sections * settings.section_s)
        res = simulate_batch(
            theta, run, symbols=MAIN_SUSPENSION, seeds=list(seeds), wagon=settings.wagon
        )
        j = res.measured_wheel(TrainingWheel.wheel)
        fs = 1.0 / cond.sample_interval
        out = np.full((n, sections, width), np.nan)
        for i in range(n):
            if not res.ok[i]:
                continue
            rng = noise_rng(settings, kind, int(idx[i]), c)
            Y, Q = (_instrument(a[i, j] / 1e3, fs, rng, settings.noise) for a in (res.Y, res.Q))
            # the partner's channels draw their noise after the measured wheel's, Y then Q:
            # Y alone (sum_y) keeps the draws of estimators trained before Q was added
            Yp = (
                _instrument(res.Y[i, j ^ 1] / 1e3, fs, rng, settings.noise)
                if settings.partner
                else None
            )
            Qp = (
                _instrument(res.Q[i, j ^ 1] / 1e3, fs, rng, settings.noise)
                if settings.partner_q
                else None
            )
            for k, s in enumerate(cut_sections(Y.size, cond.n_steps)[:sections]):
                out[i, k] = section_statistics(
                    settings.statistics,
                    Y[s],
                    Q[s],
                    fs,
                    cond.speed,
                    None if Yp is None else Yp[s],
                    None if Qp is None else Qp[s],
                    settings.sum_y,
                )
        per_condition.append(out)
    return np.concatenate(per_condition, axis=2)


def _read_chunk(path: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """A cached chunk's draws and statistics, or None where it is missing or unreadable
    (a file cut short by a copy or a full disk is simulated again, not a traceback)."""
    if not path.is_file():
        return None
    try:
        z = read_npz(path, "cached chunk", "simulated again")
        return np.asarray(z["u"]), np.asarray(z["x"])
    except (RailsuspInputError, KeyError):
        log.warning("posterior: %s unreadable; simulated again", path.name)
        return None


def cached_cases(
    settings: PosteriorSettings,
    folder: Path,
    kind: str,
    n: int,
    sections: int = 1,
    draws: np.ndarray | None = None,
    simulate: bool = True,
):
    """(u (n, 10), x) of the first ``n`` cases of ``kind`` (a key of :data:`SEED_BASE`),
    simulated in chunks of :data:`CHUNK` cached in ``folder`` (``KIND_NNNN_K.npz``; with
    several ``sections`` per case ``KIND-xS_NNNN_K.npz``; with statistics families beyond
    the EN 14363 summary, ``+family`` after the kind); a chunk on disk is read, not
    simulated again. ``x`` is (n, D) for one section, (n, sections, D) for several.
    ``draws`` (n, 10 fractions of the ranges): these parameter sets instead of the
    prior's draws of ``kind`` (whose seeds the tracks keep). ``simulate`` False: only read,
    a one-line error naming the first chunk that is not cached."""
    u_all = prior_draws(settings, kind, n) if draws is None else np.asarray(draws, float)
    if u_all.shape != (n, len(MAIN_SUSPENSION)):
        raise ValueError(f"draws {u_all.shape}: need ({n}, {len(MAIN_SUSPENSION)})")
    name = kind if sections == 1 else f"{kind}-x{sections}"
    if settings.statistics != ("en14363",):  # the default keeps the files of before
        name += "+" + "+".join(settings.statistics[1:])
    if settings.condition_offset:  # other tracks and noise: never the files of offset 0
        name += f"@{settings.condition_offset}"
    width = len(settings.summary_names)
    xs = []
    for k, lo in enumerate(range(0, n, CHUNK)):
        hi = min(n, lo + CHUNK)
        path = folder / f"{name}_{k:04d}_{hi - lo}.npz"
        cached = _read_chunk(path)
        # else missing, unreadable (cut short), another design or other settings: simulate
        if cached is not None and np.array_equal(cached[0], u_all[lo:hi]):
            if cached[1].shape[-1] == width:
                xs.append(cached[1])
                continue
        if not simulate:
            raise RailsuspInputError(
                f"{path} is not cached (cases {lo + 1}-{hi} of {n} {name}, these draws): "
                "simulate them with the estimator's own settings first"
            )
        log.info("posterior: simulating %s cases %d-%d of %d", name, lo + 1, hi, n)
        x = simulate_long_cases(settings, u_all[lo:hi], lo, kind, sections)
        x = x[:, 0, :] if sections == 1 else x
        buf = io.BytesIO()
        np.savez(buf, u=u_all[lo:hi], x=x)
        atomic_write_bytes(path, buf.getvalue())
        xs.append(x)
    return u_all, np.concatenate(xs)


def recording_summaries(settings: PosteriorSettings, recordings) -> tuple[np.ndarray, dict]:
    """(n_sections, D) summary vectors of recordings, one recording per trained condition
    (matched by name, the condition otherwise equal but for duration and track), each cut
    into sections of the training length; a section of the whole is one section of every
    condition, so the shortest condition's count of sections is used. Returns the matrix
    and, per condition, the sections used and the seconds left out.

    A recording's first wheel is the one compared: one that is not the wheel the training
    simulations record (:class:`TrainingWheel`) is refused in one line, as the optimisation
    route refuses it (:func:`railsusp.estimate.problem.check_measured_wheel`: in a curve
    the outer and the inner wheel carry other forces; a recording of a left curve listing
    w1L before w1R was compared as the outer wheel, silently).

    A recording's own condition (its ``lead_in_m``, which may differ from the trained one)
    must put its sections in the steady arc of a curve, as the training conditions' are
    (:func:`~railsusp.estimate.posterior_settings.check_uniform_record`: a record from
    the entry spiral was accepted and reported calibrated, its statistics far from any
    training case), and its stated instrument bandwidth (``filter_bandwidth_hz``) must be
    at least the training's :data:`BANDWIDTH_HZ` (a narrower filter removes the higher
    bands' content, which the flows then extrapolate from): each refused in one line."""
    from railsusp.estimate.posterior_settings import check_uniform_record
    from railsusp.estimate.problem import check_measured_wheel

    by_name = {}
    for r in recordings:
        if r.condition.name in by_name:  # the later one was taken, the other dropped unsaid
            raise RailsuspInputError(
                f"two recordings of condition {r.condition.name!r}; accepted one per "
                "condition (a long run is one recording: its sections are cut here)"
            )
        by_name[r.condition.name] = r
    ignore = ("seed", "duration_s", "n_steps", "lead_in_m", "track_geometry",
              "track_offset_m", "track_accuracy_mm")  # fmt: skip
    per_condition, info = [], {}
    for cond in settings.conditions:
        rec = by_name.get(cond.name)
        if rec is None:
            raise RailsuspInputError(
                f"no recording of condition {cond.name!r}; the estimator was trained on "
                f"{', '.join(c.name for c in settings.conditions)}"
            )
        diff = rec.condition.differences(cond, ignore=ignore)
        if diff:
            raise RailsuspInputError(
                f"recording {cond.name!r} differs from the trained condition in "
                f"{', '.join(diff)}; train an estimator for this condition"
            )
        check_measured_wheel(TrainingWheel(), [rec], aligned=False)
        _check_bandwidth(rec, cond.name)
        fs = 1.0 / cond.sample_interval
        if abs(rec.sampling_rate - fs) > 0.01 * fs:
            rec = rec.resampled(fs)
        w = rec.wheels[0]
        Yp = Qp = None
        if settings.partner:
            from railsusp.vehicle.layout import WHEEL_NAMES

            other = WHEEL_NAMES[WHEEL_NAMES.index(w) ^ 1]
            if other not in rec.Y or (settings.partner_q and other not in rec.Q):
                what = ("the wheelset force sumY" if settings.statistics == ("en14363",)
                        else f"statistics {','.join(settings.statistics)}")  # fmt: skip
                raise RailsuspInputError(
                    f"recording {cond.name!r}: the estimator uses {what} and needs wheel "
                    f"{other} as well as {w}"
                )
            Yp, Qp = rec.Y[other], rec.Q[other] if settings.partner_q else None
        sections = cut_sections(rec.time.size, cond.n_steps)
        if not sections:
            raise RailsuspInputError(
                f"recording {cond.name!r} is {rec.time.size / fs:.1f} s long; the estimator "
                f"needs at least one section of {settings.section_s:g} s"
            )
        check_uniform_record(
            rec.condition, len(sections) * settings.section_s, settings.wagon, recording=True
        )
        rows = [
            section_statistics(
                settings.statistics,
                rec.Y[w][s],
                rec.Q[w][s],
                fs,
                cond.speed,
                None if Yp is None else Yp[s],
                None if Qp is None else Qp[s],
                settings.sum_y,
            )
            for s in sections
        ]
        undefined = np.argwhere(~np.isfinite(rows))
        if undefined.size:  # the training leaves such cases out; a recording's is refused
            k, i = undefined[0]
            name = statistic_names(settings.statistics, settings.sum_y)[i]
            why = " (a wheel unloaded, Q <= 1 kN, in all of it)" if name.startswith("YQ") else ""
            raise RailsuspInputError(
                f"recording {cond.name!r}: statistic {name} undefined in section {k + 1}"
                f"{why}; accepted sections whose every statistic is defined"
            )
        per_condition.append(np.array(rows))
        info[cond.name] = (len(rows), rec.time.size / fs)
    n = min(len(r) for r in per_condition)
    used = {name: {"sections": n, "seconds_left_out": round(t - n * settings.section_s, 3)}
            for name, (_, t) in info.items()}  # fmt: skip
    return np.concatenate([r[:n] for r in per_condition], axis=1), used


def _check_bandwidth(rec, name: str) -> None:
    """Refuse, in one line, a recording whose sidecar states an instrument bandwidth
    (``filter_bandwidth_hz``) below the training simulations' :data:`BANDWIDTH_HZ`: its
    statistics of the higher bands lie outside anything the estimator learnt from
    (measured: a recording low-passed at 4 Hz put Q_band_8-15Hz at -1.33 against the
    training cases' 0.33 to 0.71, and was reported calibrated). None stated: not checked."""
    bw = (rec.meta or {}).get("filter_bandwidth_hz")
    if isinstance(bw, int | float) and not isinstance(bw, bool) and bw < BANDWIDTH_HZ:
        raise RailsuspInputError(
            f"recording {name!r}: filter_bandwidth_hz = {bw:g} Hz is below the "
            f"{BANDWIDTH_HZ:g} Hz instrument bandwidth the estimator was trained with (its "
            f"higher bands are cut); accepted {BANDWIDTH_HZ:g} Hz or more (or none stated)"
        )


#: a recording's statistic is outside what the estimator learnt from where the mean of its
#: sections lies beyond the range of the training cases by more than this many of their
#: standard deviations (docs/posterior.md, "The result"). Measured: the statistics of
#: recordings of the trained conditions lay within 0.2 standard deviations beyond that range
#: (inside it for most); a recording low-passed at 4 Hz 24 beyond, a curve recorded from its
#: entry spiral 9 beyond
OUTSIDE_MARGIN_SD = 1.0
#: fewer training cases than this, and the statistics are not compared with their range:
#: its extremes are too close in (measured on the 34 EN 14363 statistics of stop 63's
#: estimator, held-out simulations, each section compared: 20 cases flagged 30 % of
#: one-section simulations and 73 % of six-section ones, 100 cases 1.5 % and 7.5 %, 2000
#: cases 0.03 % per section, so 11 % of a 2 h recording's 360 sections; the review of stop
#: 65). The sections' mean is compared, which lies inside whatever its sections do
MIN_SUPPORT_CASES = 100


@dataclass(frozen=True)
class TrainingSupport:
    """The range (``low``, ``high``) and standard deviation ``sd`` of each statistic
    (``names``) over an estimator's ``n`` training cases (those with every statistic
    defined), against which a recording's sections are compared (:meth:`outside`)."""

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    sd: np.ndarray
    n: int

    @classmethod
    def of(cls, names, x: np.ndarray) -> TrainingSupport | None:
        """The support of the training cases ``x`` (n, D); None without two usable cases."""
        x = np.asarray(x, float)
        x = x[np.all(np.isfinite(x), axis=1)]
        if len(x) < 2 or x.shape[1] != len(names):
            return None
        return cls(tuple(names), x.min(axis=0), x.max(axis=0), x.std(axis=0), len(x))

    @classmethod
    def joined(cls, parts) -> TrainingSupport | None:
        """The supports of estimators whose statistics stand one after the other (a joint
        posterior's parts; as many cases as the smallest); None where any part has none."""
        if any(p is None for p in parts):
            return None
        return cls(
            tuple(n for p in parts for n in p.names),
            *(np.concatenate([getattr(p, k) for p in parts]) for k in ("low", "high", "sd")),
            min(p.n for p in parts),
        )

    def outside(self, x: np.ndarray) -> list[str]:
        """The statistics whose mean over the sections ``x`` (k, D) lies beyond the
        training range by more than :data:`OUTSIDE_MARGIN_SD` of their standard deviation
        (each section compared, a long recording's many sections flagged in-distribution
        ones: :data:`MIN_SUPPORT_CASES`)."""
        mean = np.atleast_2d(np.asarray(x, float)).mean(axis=0)
        margin = OUTSIDE_MARGIN_SD * self.sd
        beyond = (mean < self.low - margin) | (mean > self.high + margin)
        return [n for n, b in zip(self.names, beyond, strict=True) if b]


def training_support(settings: PosteriorSettings, run: str | Path) -> TrainingSupport | None:
    """The :class:`TrainingSupport` of the training cases cached in ``run``'s
    ``posterior/simulations`` (read only) that the synthetic likelihood's emulator of all
    the statistics learnt from (the first ``statistics_emulator_cases`` where set: tens of
    thousands of cases of hundreds of statistics are not read on every load); None where
    they are not all there."""
    cases = settings.statistics_emulator_cases or settings.n_train
    try:
        _, x = cached_cases(
            settings, Path(run) / "posterior" / "simulations", "train", cases, simulate=False
        )
    except RailsuspInputError:
        return None
    return TrainingSupport.of(settings.summary_names, x)


def support_notes(support: TrainingSupport | None, x: np.ndarray) -> tuple[list[str], list[str]]:
    """(the statistics of the sections ``x`` outside the training cases' ``support``, the
    warning that says so); a warning that nothing was compared where there is no support."""
    if support is None:
        return [], [
            "the recording's statistics were not compared with the range of the "
            "estimator's training cases (not at hand: its folder holds no cached training "
            "cases): whether they lie inside what it learnt from is unknown"
        ]
    if support.n < MIN_SUPPORT_CASES:
        return [], [
            f"the recording's statistics were not compared with the range of the "
            f"estimator's {support.n} training cases (fewer than {MIN_SUPPORT_CASES}: their "
            "extremes flag recordings like them): whether they lie inside what it learnt "
            "from is unknown"
        ]
    outside = support.outside(x)
    if not outside:
        return [], []
    shown = first_listed(outside, 4)
    return outside, [
        f"the recording's statistics {shown} lie outside the range of the estimator's "
        f"training cases (their mean over the sections, by more than {OUTSIDE_MARGIN_SD:g} "
        "of their standard deviation): "
        "the posterior extrapolates beyond what it learnt and is NOT calibrated; check the "
        "recording's condition and instrument against the trained ones"
    ]


def unused_recordings(recordings, trained: list[str]) -> list[str]:
    """The warning naming the recordings of conditions none of the ``trained`` conditions
    is (they were left out unsaid); none where every recording is used."""
    unused = [r.condition.name for r in recordings if r.condition.name not in trained]
    if not unused:
        return []
    return [
        f"recordings of conditions the estimator was not trained on are not used: "
        f"{', '.join(unused)} (trained on {', '.join(trained)})"
    ]
