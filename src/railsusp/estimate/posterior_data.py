"""The training and check simulations of the simulation-based posterior: the parameter
sets drawn from the prior, the simulated cases with their tracks and instrument noise, and
their cache in the run directory.

Every simulated case draws all ten main-suspension parameters (X11-X20) from their uniform
Table 2 prior, whichever subset is estimated, and runs every condition on a track
realisation of its own (a new irregularity seed per case and condition): the estimator then
learns the statistics' scatter over track realisations and over the parameters it does not
estimate, and marginalises both. The simulated forces pass the instrument model of the
synthetic recordings (:func:`railsusp.measured.add_sensor_noise`: a 15 Hz bandwidth, a 1 %
gain error, white noise of ``noise`` times the channel RMS) before their statistics are
taken. Simulations are cached in chunks in the run directory (atomic writes), so an
interrupted training resumes without simulating again.

The summary statistics of recordings in the same form are
:mod:`railsusp.estimate.posterior_recordings`; the range of the training cases a recording
is compared with, :mod:`railsusp.estimate.posterior_support` (its two thresholds stay
importable from here too, where docs/posterior.md named them before); the code stamp of an estimator
folder, :mod:`railsusp.estimate.posterior_stamp`.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.posterior_support import MIN_SUPPORT_CASES as MIN_SUPPORT_CASES
from railsusp.estimate.posterior_support import OUTSIDE_MARGIN_SD as OUTSIDE_MARGIN_SD
from railsusp.estimate.posterior_support import TrainingSupport
from railsusp.estimate.statistic_families import (
    section_statistics,
    statistic_names,
)
from railsusp.estimate.summaries import cut_sections
from railsusp.integrity import NpzDamaged, read_npz
from railsusp.interrupts import stop_if_interrupted
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


#: how to make a training's chunks again, in the refusals of a reading that simulates nothing
TRAIN_AGAIN = (
    "run railsusp posterior train on this folder again, with the options it was trained with "
    "(its posterior/settings.json), to simulate them"
)


def _read_chunk(path: Path, simulate: bool = True) -> tuple[np.ndarray, np.ndarray] | None:
    """A cached chunk's draws and statistics, or None where it is missing or, with
    ``simulate``, unreadable (a file cut short by a copy or a full disk is simulated again,
    said in a warning, not a traceback). Without ``simulate`` (an estimate, which simulates
    nothing) an unreadable chunk is refused in one line naming it, what is wrong with it and
    the command that makes it again (it was said to be "simulated again", then "not
    cached")."""
    if not path.is_file():
        return None
    try:
        z = read_npz(path, "cached chunk", "simulated again")
        return np.asarray(z["u"]), np.asarray(z["x"])
    except (NpzDamaged, KeyError) as exc:
        if not simulate:
            reason = exc.reason if isinstance(exc, NpzDamaged) else f"no array {exc}"
            raise RailsuspInputError(
                f"{path} is not cached whole (damaged: {reason}): {TRAIN_AGAIN}"
            ) from None
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
        cached = _read_chunk(path, simulate)
        # else missing, unreadable (cut short), another design or other settings: simulate
        if cached is not None and np.array_equal(cached[0], u_all[lo:hi]):
            if cached[1].shape[-1] == width:
                xs.append(cached[1])
                continue
        if not simulate:
            raise RailsuspInputError(
                f"{path} is not cached (cases {lo + 1}-{hi} of {n} {name}, these draws): "
                f"{TRAIN_AGAIN}"
            )
        log.info("posterior: simulating %s cases %d-%d of %d", name, lo + 1, hi, n)
        x = simulate_long_cases(settings, u_all[lo:hi], lo, kind, sections)
        x = x[:, 0, :] if sections == 1 else x
        buf = io.BytesIO()
        np.savez(buf, u=u_all[lo:hi], x=x)
        atomic_write_bytes(path, buf.getvalue())
        stop_if_interrupted()  # a swallowed Ctrl-C: stop here, with this chunk cached
        xs.append(x)
    return u_all, np.concatenate(xs)


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
