"""Simulation-based posterior of the suspension parameters on track nobody measured.

Amortised neural posterior estimation (``sbi``'s NPE, a masked autoregressive flow): the
network learns q(theta | x), the distribution of the parameters given the geometry-free
summary statistics x of one section per condition (:mod:`railsusp.estimate.summaries`),
from simulated cases whose parameters come from the uniform Table 2 prior and whose track
is a new realisation each (:mod:`railsusp.estimate.posterior_data`). Once trained, a
recording's posterior costs a forward pass, no simulation.

The parameters are inferred as fractions u in [0, 1] of their ranges (a uniform prior on
the unit box), reported in display units. The flows model z = logit(u), whose prior is the
standard logistic distribution: a flow on the unbounded z puts no mass outside the prior
box (one trained on u itself leaked 43-81 % of its mass out of the box, and the truncation
of that density made its intervals too narrow). An ``ensemble`` of flows is their equal
mixture.

**Calibration** is part of training (:mod:`railsusp.estimate.posterior_check`): a spread
correction is fitted on held-out calibration cases and the corrected estimator is checked
on other, untouched held-out cases, per parameter (:mod:`railsusp.estimate.calibration`).
The result stores the correction and the verdict, and the estimate of a recording says
``calibrated = False`` (and warns) for an estimator whose check failed or whose correction
widened a parameter beyond its bound: it is never used silently.

**Long recordings** are cut into sections of the training length, and the sections'
posteriors are fused (:mod:`railsusp.estimate.posterior_fusion`: their informations add, in
Gaussian approximations in logit coordinates; the exact product of the flows' densities
is ruled by their tails). The fusion adds each section's small spurious information too,
so the fused posterior has its own correction and check per number of sections
(``product_sections``, :mod:`railsusp.estimate.posterior_check`); a recording of n sections
uses those of the smallest checked number k >= n, and one longer than any checked number
is reported not calibrated.

The trained estimator itself (its flows, correction and checks; drawing and evaluating the
posterior) is :class:`~railsusp.estimate.posterior_estimator.PosteriorEstimator`, in
:mod:`railsusp.estimate.posterior_estimator`; this module trains one, reads it back and
estimates recordings with it.
"""

from __future__ import annotations

import io
import json
import logging
import time
from contextlib import redirect_stdout
from pathlib import Path
from typing import Any

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.estimate.posterior_check import calibrate
from railsusp.estimate.posterior_data import cached_cases, to_si
from railsusp.estimate.posterior_estimator import PosteriorEstimator, one_thread
from railsusp.estimate.posterior_fusion import logistic_prior, to_logit
from railsusp.estimate.posterior_recordings import recording_summaries, unused_recordings
from railsusp.estimate.posterior_result import PosteriorResult
from railsusp.estimate.posterior_settings import (
    PosteriorSettings,
    check_run_folder,
    check_seed,
    settings_differences,
)
from railsusp.estimate.posterior_stamp import check_model_revision, estimator_stamp
from railsusp.estimate.posterior_support import TrainingSupport, support_notes
from railsusp.integrity import TorchFileCutShort, read_torch_file
from railsusp.params import MAIN_SUSPENSION
from railsusp.store import atomic_write_bytes, canonical_json, content_hash, read_json, write_json

log = logging.getLogger(__name__)


class TrainingLog:
    """sbi's training tracker kept in memory (its default writes TensorBoard logs into the
    working directory): the last value of each metric, for the log."""

    log_dir = None

    def __init__(self) -> None:
        self.metrics: dict[str, float] = {}

    def log_metric(self, name: str, value: float, step: int | None = None) -> None:
        self.metrics[name] = float(value)

    def log_metrics(self, metrics: dict[str, float], step: int | None = None) -> None:
        for name, value in metrics.items():
            self.log_metric(name, value, step)

    def log_params(self, params: dict[str, Any]) -> None:
        pass

    def add_figure(self, name: str, figure: Any, step: int | None = None) -> None:
        pass

    def flush(self) -> None:
        pass


def _build(settings: PosteriorSettings, u: np.ndarray, x: np.ndarray):
    """The prior of the logit coordinates (independent standard logistic: the image of the
    uniform prior on the box), the flow's builder and the training tensors."""
    import torch
    from sbi.neural_nets import posterior_nn

    prior = logistic_prior(len(settings.parameters))
    builder = posterior_nn(
        "maf", hidden_features=settings.hidden_features, num_transforms=settings.num_transforms
    )
    cols = [MAIN_SUSPENSION.index(p) for p in settings.parameters]
    ok = np.all(np.isfinite(x), axis=1)
    if ok.sum() < max(2, len(x) // 2):  # sbi's own error was a 50-line traceback
        undefined = np.mean(~np.isfinite(x), axis=0) > 0.5
        names = [n for n, bad in zip(settings.summary_names, undefined, strict=True) if bad]
        raise RailsuspInputError(
            f"posterior: {len(x) - int(ok.sum())} of {len(x)} training cases have undefined "
            f"statistics ({', '.join(names[:4]) or 'failed simulations'}"
            f"{', ...' if len(names) > 4 else ''}): with section_s = {settings.section_s:g} s "
            "and these statistics families the estimator cannot learn; accepted longer "
            "sections or other families"
        )
    theta_t = torch.as_tensor(to_logit(u[ok][:, cols]), dtype=torch.float32)
    x_t = torch.as_tensor(x[ok], dtype=torch.float32)
    return prior, builder, theta_t, x_t


def train(
    settings: PosteriorSettings, run: str | Path, *, simulate: bool = True
) -> PosteriorEstimator:
    """Simulate (or read the cached) cases, train the ensemble of flows, fit the spread
    correction on the calibration cases and check the corrected estimator on the untouched
    test cases, all into ``run`` (``posterior/``); every step found finished on disk is
    read back, not repeated. ``simulate`` False (:func:`load`): a training chunk that is not
    on disk whole is an error, not simulated again, and nothing is written into ``run``
    (an estimator folder may be read-only: shared, or another user's). ``settings.json``
    is written only where it is missing or its content is not this training's."""
    import torch
    from sbi.inference import NPE

    folder = Path(run) / "posterior"
    key = content_hash(settings.to_dict())
    # as it reads back (tuples as lists, paths as text): compared with the file's
    stored = json.loads(
        canonical_json({"hash": key, **estimator_stamp(), "settings": settings.to_dict()})
    )
    old = None
    if (folder / "settings.json").exists():
        old = read_json(folder / "settings.json")
        if not isinstance(old, dict):
            raise RailsuspInputError(
                f"{folder / 'settings.json'} holds no estimator settings; give another --out"
            )
        if old.get("hash") != key:
            differ = settings_differences(old.get("settings"), settings.to_dict())
            raise RailsuspInputError(
                f"{folder} holds an estimator trained with other settings"
                f"{' (' + '; '.join(differ) + ')' if differ else ''}; "
                + (
                    "give another --out"
                    if simulate
                    else "train it again (railsusp posterior train)"
                )
            )
        check_model_revision(old, folder / "settings.json")
    if simulate and old != stored:  # rewritten on every estimate before (M2 of the audit)
        write_json(folder / "settings.json", stored)
    u, x = cached_cases(
        settings, folder / "simulations", "train", settings.n_train, simulate=simulate
    )
    prior, builder, theta_t, x_t = _build(settings, u, x)
    weights = folder / "estimator.pt"
    states = _saved_states(weights, settings.ensemble, remake=simulate)
    if states is None and not simulate:
        raise RailsuspInputError(
            f"{weights} does not exist: train first (railsusp posterior train)"
        )
    if states is not None:
        nets = []
        for state in states:
            net = builder(theta_t, x_t)
            try:
                net.load_state_dict(state)
            except (RuntimeError, KeyError, TypeError) as exc:
                first = str(exc).strip().splitlines()[0]
                raise RailsuspInputError(
                    f"posterior estimator {weights} refused: its flows are not those of "
                    f"settings.json ({first}); delete it to train again"
                ) from None
            nets.append(net)
    else:
        nets = []
        for m in range(settings.ensemble):
            t0 = time.perf_counter()
            torch.manual_seed(settings.seed + 1000 * m)  # its own initialisation and split
            inference = NPE(
                prior=prior, density_estimator=builder, show_progress_bars=False,
                tracker=TrainingLog(),
            )  # fmt: skip
            # sbi prints its convergence line with "\r" and no newline, which the next line
            # of the terminal then runs into; the log line below says the same
            with one_thread(), redirect_stdout(io.StringIO()):
                inference.append_simulations(theta_t, x_t)
                nets.append(inference.train(show_train_summary=False))
            log.info(
                "posterior: flow %d of %d trained on %d cases in %.0f s (%d epochs)",
                m + 1, settings.ensemble, len(x_t), time.perf_counter() - t0,
                inference.summary["epochs_trained"][-1],
            )  # fmt: skip
        buf = io.BytesIO()
        torch.save([net.state_dict() for net in nets], buf)
        atomic_write_bytes(weights, buf.getvalue())
    for net in nets:
        net.eval()
    est = PosteriorEstimator(settings, nets, [], None, Path(run))
    est.support = TrainingSupport.of(settings.summary_names, x)
    # read back only if made on these weights (a remade estimator.pt is checked afresh)
    est.correction, est.calibration, est.products = calibrate(est, folder, remake=simulate)
    return est


def _saved_states(weights: Path, ensemble: int, remake: bool = True) -> list | None:
    """The flows' saved states, or None where there are none or, with ``remake``, the file
    is cut short (a copy interrupted or a full disk: trained again rather than a traceback;
    the weights are written atomically, so a killed training never leaves such a file;
    without ``remake``, :func:`load`'s, it is refused). A file that reads but is not a list
    of states (a pickle that would run code, another program's file) is refused in one
    line, as the surrogates' checkpoints are (:func:`railsusp.integrity.read_torch_file`)."""
    if not weights.is_file():
        return None
    remedy = "delete it to train again (railsusp posterior train)"
    try:
        states = read_torch_file(weights, "posterior estimator", remedy)
    except TorchFileCutShort:
        if not remake:
            raise RailsuspInputError(
                f"{weights} is cut short or damaged: train again (railsusp posterior train)"
            ) from None
        log.warning("posterior: %s is cut short or damaged; training again", weights.name)
        return None
    if not isinstance(states, list) or not all(isinstance(x, dict) for x in states):
        raise RailsuspInputError(
            f"posterior estimator {weights} refused: not a list of the flows' states; {remedy}"
        )
    if len(states) != ensemble:
        raise RailsuspInputError(
            f"posterior estimator {weights} refused: {len(states)} flows saved, settings.json "
            f"asks for an ensemble of {ensemble}; {remedy}"
        )
    return states


def load(run: str | Path) -> PosteriorEstimator:
    """The trained estimator of a run directory (nothing is simulated or trained: a run
    without a finished estimator is an error; ``run`` not a path is refused in one line)."""
    folder = check_run_folder(run) / "posterior"
    for name in ("settings.json", "estimator.pt", "calibration.json"):
        if not (folder / name).exists():
            raise RailsuspInputError(
                f"{folder / name} does not exist: train first (railsusp posterior train)"
            )
    stored = read_json(folder / "settings.json")
    if not isinstance(stored, dict) or not isinstance(stored.get("settings"), dict):
        raise RailsuspInputError(
            f"{folder / 'settings.json'} holds no estimator settings: train again "
            "(railsusp posterior train)"
        )
    settings = PosteriorSettings.from_dict(stored["settings"])
    return train(settings, run, simulate=False)  # reads; a file cut short is refused


def estimate(est: PosteriorEstimator, recordings, seed: int = 0) -> PosteriorResult:
    """Posterior of the recordings (one per trained condition, any length of at least one
    section): one section's, or the sections' fused (module docstring), each with the
    correction and the check that belong to its number of sections. ``recordings``: a list
    of :class:`~railsusp.measured.Recording`; ``seed``: of the draws, 0 to
    :data:`~railsusp.estimate.posterior_settings.MAX_SEED`; either refused in one line
    naming it."""
    seed = check_seed(seed)
    x, used = recording_summaries(est.settings, recordings)
    s = est.settings
    n = len(x)
    outside, notes = support_notes(est.support, x)
    notes += unused_recordings(recordings, [c.name for c in s.conditions])
    correction, checks, checked_as = est.correction, est.calibration, 1
    u = est.sample(x, s.samples, seed)
    if n > 1:
        product = est.product_for(n)
        if product is None:
            checked_as = None
            longest = max((p.sections for p in est.products), default=1)
            notes.append(
                f"the posterior of {n} sections (their informations fused) is NOT "
                f"calibrated: the estimator was checked up to {longest} section(s) "
                "(--product-sections); the fusion adds each section's small spurious "
                "information, so a longer record's intervals may be too narrow"
            )
        else:
            correction, checks, checked_as = (
                product.correction,
                list(product.checks),
                product.sections,
            )
    label = f" of {checked_as} sections" if n > 1 and checked_as else ""
    bad = [c.parameter for c in checks if not c.passed]
    if bad:
        notes.append(
            f"the estimator FAILED its coverage check{label} on held-out simulations for "
            f"{', '.join(bad)}: its intervals are too narrow; do not use them as they are"
        )
    wide = correction.excessive if correction else []
    if wide:
        factors = dict(zip(correction.parameters, correction.factors, strict=True))
        notes.append(
            f"the estimator needed its intervals{label} widened by more than "
            f"{correction.max_inflation:g} times to hold the truth on the calibration "
            f"cases for {', '.join(f'{p} ({factors[p]:.1f})' for p in wide)}: its posterior "
            "is misshapen there, not only too narrow; train on more simulations"
        )
    for note in notes:
        log.warning("posterior: %s", note)
    return PosteriorResult(
        s.parameters, to_si(u, s.parameters), checks, used, n, notes, correction, checked_as,
        outside_training=outside,
    )  # fmt: skip
