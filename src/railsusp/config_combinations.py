"""The settings of a pipeline configuration that must agree with one another: the
estimate's options with each other and with the force model (series, a predictive SD, the
statistics it predicts), a network set with the wagon and the conditions, the held prior
with the refinement, the surrogates' window with the conditions, and a measured folder's
recordings with the surrogates that serve them. Each check raises through ``bad``
(:func:`railsusp.config.check_config`'s one-line :class:`~railsusp.config.
ConfigError` naming the settings that conflict), before any stage runs: every one of them
failed a run in a later stage once (the audits' reproductions are in the tests,
tests/test_config_combinations.py).

The checks of the field's recordings themselves (their source and ``[field]`` options, the
measured track they carry, its accuracy, the rate of synthetic ones) are
:mod:`railsusp.config_recordings`. Imports of the stages' modules are local: this module is
read with the configuration, before any stage is loaded.
"""

from __future__ import annotations

from typing import Any

from railsusp.config_recordings import ALIGNED, given_off_default
from railsusp.errors import RailsuspInputError


def check_estimate_options(cfg: Any, bad: Any) -> None:
    """The ``[estimate]`` settings that need one another, or a force model that gives what
    they compare (series, a predictive SD), each refused naming both settings."""
    if cfg.estimate.weighting == "noise" and cfg.surrogate.model != "gp-stats":
        raise bad(
            'estimate.weighting = "noise" needs the predictive SD of surrogate.model = '
            f'"gp-stats" (now {cfg.surrogate.model!r})'
        )
    if (
        cfg.estimate.refine
        and cfg.estimate.refine_screen
        and (cfg.estimate.refine_screen < cfg.estimate.refine_starts)
    ):
        raise bad(
            f"estimate.refine_screen = {cfg.estimate.refine_screen} screens fewer points than "
            f"estimate.refine_starts = {cfg.estimate.refine_starts} starts"
        )
    e = cfg.estimate
    ignored = [  # set and not the default, on a route that reads them nowhere (stop 78's hunt)
        (key, needs)
        for key, needs, used in (
            ("refine_evaluations", "estimate.refine = true", e.refine),
            ("refine_screen", "estimate.refine = true", e.refine),
            ("refine_starts", "estimate.refine = true", e.refine),
            ("preview_s", "estimate.preview_generations above 0", e.preview_generations),
        )
        if not used and given_off_default(e, key)
    ]
    if ignored:
        key, needs = ignored[0]
        raise bad(f"estimate.{key} is read only with {needs}: set that, or leave {key} out")
    if cfg.surrogate.model == "gp-stats" and ALIGNED in cfg.estimate.statistic.split("+"):
        raise bad(
            'estimate.statistic "aligned" compares force series sample by sample; the '
            'statistics GPs of surrogate.model = "gp-stats" predict statistics only: choose a '
            'window surrogate (e.g. "bp") or another statistic'
        )
    if cfg.estimate.channel_gains and ALIGNED not in cfg.estimate.statistic.split("+"):
        raise bad(
            "estimate.channel_gains = true profiles the gains out of the time-aligned "
            f'comparison; estimate.statistic = "{cfg.estimate.statistic}" has none: add "aligned"'
            " or set channel_gains = false"
        )
    from railsusp.estimate.config import (
        CORRECTIONS_RANGE,
        EXPECTED_STATISTICS_TEXT,
        NSGA_RANGES,
        PREVIEW_NEEDS_ALIGNED,
        expected_statistics_ok,
    )

    e = cfg.estimate
    if e.simulator_corrections and e.statistic != ALIGNED:
        raise bad(
            f"estimate.simulator_corrections = {e.simulator_corrections} corrects the "
            f'time-aligned least squares; estimate.statistic = "{e.statistic}": accepted '
            '"aligned" alone, or set simulator_corrections = 0'
        )
    if e.correction_slopes and not e.simulator_corrections:
        raise bad(
            "estimate.correction_slopes = true makes each simulator correction first order; "
            "estimate.simulator_corrections = 0 asks for none: set simulator_corrections 1 "
            f"to {CORRECTIONS_RANGE[1]} or correction_slopes = false"
        )
    if e.slope_update != "simulated" and not e.correction_slopes:
        raise bad(
            f'estimate.slope_update = "{e.slope_update}" updates the slopes of first-order '
            "corrections; estimate.correction_slopes = false asks for none: set "
            'correction_slopes = true or slope_update = "simulated"'
        )
    if e.preview_generations >= e.n_gen:
        raise bad(
            f"estimate.preview_generations = {e.preview_generations}: accepted 0 to "
            f"estimate.n_gen - 1 = {e.n_gen - 1} (the generations after the preview compare "
            "the whole records)"
        )
    if e.preview_generations and ALIGNED not in e.statistic.split("+"):
        raise bad(
            f"estimate.preview_generations = {e.preview_generations} with estimate.statistic "
            f'"{e.statistic}", {PREVIEW_NEEDS_ALIGNED}; or set preview_generations = 0'
        )
    if e.expected_generations and not e.expected_draws:
        raise bad(
            "estimate.expected_generations = true compares expected forces in NSGA-II's "
            "generations; estimate.expected_draws = 0 draws none: set expected_draws 1 to 64 "
            "or expected_generations = false"
        )
    if e.expected_draws and not expected_statistics_ok(e.statistic, e.expected_generations):
        raise bad(
            f"estimate.expected_draws = {e.expected_draws} compares mean predictions "
            f'over drawn tracks; estimate.statistic = "{e.statistic}": accepted '
            f"{EXPECTED_STATISTICS_TEXT[e.expected_generations]} (spread statistics of a mean "
            "series are too low), or set expected_draws = 0"
        )
    if cfg.surrogate.model == "gp-stats" and "p99.85" in cfg.estimate.statistic.split("+"):
        raise bad(
            'estimate.statistic "p99.85" (EN 14363) is computed from force series; the '
            'statistics GPs of surrogate.model = "gp-stats" predict mean, rms, p99 and std only'
        )
    top = int(NSGA_RANGES["seed"][1])
    if e.seed + e.seeds - 1 > top:  # nsga.estimate_seeds refused it after four stages
        raise bad(
            f"estimate.seed = {e.seed} with estimate.seeds = {e.seeds}: accepted seed + seeds "
            f"- 1 at most {top} (run k of the seed spread has seed + k; pymoo's 32-bit seeds)"
        )


def check_network_set(cfg: Any, conds: list, bad: Any, what: str = "") -> None:
    """``[surrogate] pretrained``: a network set that exists, was trained on this wagon with
    today's force laws, is of ``surrogate.model``'s kind and covers every condition
    (:func:`railsusp.surrogate.pretrained.check_network_set`)."""
    from railsusp.surrogate.pretrained import (
        check_network_set,
        read_network_set,
        resolve_network_set,
    )
    from railsusp.vehicle.wagon import load_wagon

    try:
        ns = read_network_set(resolve_network_set(cfg.surrogate.pretrained))
        check_network_set(
            ns, wagon=load_wagon(cfg.wagon), kind=cfg.surrogate.model, conditions=conds
        )
    except RailsuspInputError as exc:
        raise bad(f"{what}{exc}") from None


def check_network_window(cfg: Any, conds: list, recordings: list, bad: Any) -> None:
    """``[surrogate] pretrained``: every record its networks predict (a ``[field] measured``
    folder's ``recordings``, else the synthetic recordings of the conditions ``conds``)
    longer than its network's window (the sequence CNN-GRU's washout), as
    :func:`check_surrogate_training` asks of the surrogates a run trains. A shorter one was
    accepted and predicted nothing but NaN: the estimate stage failed after four stages
    with pymoo's "Invalid progress was set by the TerminationCriterion"."""
    from railsusp.surrogate.pretrained import load_bundle, read_network_set, resolve_network_set

    ns = read_network_set(resolve_network_set(cfg.surrogate.pretrained))
    served = [r.condition for r in recordings] if recordings else conds
    windows = {c: load_bundle(ns.bundle(c)).spec.window for c in {s.name for s in served}}
    short = [c for c in served if c.n_steps <= windows[c.name]]
    if short:
        what = "field.measured's recordings" if recordings else "the conditions"
        window = max(windows[c.name] for c in short)
        raise bad(
            f"surrogate.pretrained = {cfg.surrogate.pretrained!r}: its networks read {window} "
            f"steps before their first prediction; {what} "
            f"{', '.join(f'{c.name} (n_steps = {c.n_steps})' for c in short)} have no more "
            f"steps than that: accepted n_steps > {window} (longer records)"
        )


def check_held_prior(cfg: Any, bad: Any) -> None:
    """``[estimate] held_prior``: known main-suspension symbols, [low, high] inside Table 2
    with low < high (:class:`~railsusp.estimate.config.HeldPrior`), and a refinement whose
    intervals use it (NSGA-II alone, or with the refinement as a polish beside it, reports
    the Pareto range, which takes no prior)."""
    from railsusp.estimate.config import HELD_PRIOR_FIELD, HeldPrior

    e = cfg.estimate
    if not e.held_prior:
        return
    try:
        HeldPrior.from_display(e.held_prior, HELD_PRIOR_FIELD)
    except RailsuspInputError as exc:
        raise bad(str(exc)) from None
    if not e.refine:
        aligned = (  # both needs named: the advice alone led to the refusal below
            ' with record statistics (not estimate.statistic "aligned")'
            if ALIGNED in e.statistic.split("+")
            else ""
        )
        raise bad(
            f"{HELD_PRIOR_FIELD} is used by the refinement's intervals only; set "
            f"estimate.refine = true{aligned} or leave held_prior out"
        )
    if ALIGNED in e.statistic.split("+"):
        raise bad(
            f'{HELD_PRIOR_FIELD} with estimate.statistic "aligned": the refinement is then a '
            "polish beside NSGA-II's estimate, whose interval (the Pareto range) uses no "
            "prior; leave held_prior out or choose record statistics"
        )


def _check_served_rate(cfg: Any, condition: Any, recording: Any, bad: Any) -> None:
    """A statistic that depends on the sampling rate (p99, rms, std), on a measured
    recording sampled at another rate than the run's condition whose surrogate it trains
    (the surrogate predicts its training record at the condition's rate): refused now, as
    the estimate stage's :func:`~railsusp.estimate.problem.check_sampling` refuses it after
    four stages (the duration and n_steps are the record length the surrogates do not
    see, so a change of rate passed the condition's comparison; stop 78's hunt)."""
    from railsusp.estimate.statistics import check_rate, parse_statistics

    try:
        check_rate(
            parse_statistics(cfg.estimate.statistic),
            1.0 / condition.sample_interval,
            recording,
            f"the surrogate this run trains on condition {condition.name!r} predicts its "
            "training record",
            "the mean or p99.85, a recording at the condition's rate, or the condition's "
            "n_steps at the recording's rate",
        )
    except RailsuspInputError as exc:
        raise bad(f"field.measured = {cfg.field.measured!r}: {exc}") from None


def check_surrogate_training(cfg: Any, conds: list, bad: Any) -> None:
    """What the surrogate stage's training needs of the conditions and the machine, checked
    before the campaign rather than after it: every condition's series longer than the
    network's window (the sequence CNN-GRU's washout of 100 steps; the window networks' 20).
    (A CUDA device for ``device = "cuda"`` is checked by :func:`check_cuda` where the stage
    is still to run: a run trained on a GPU is estimated again on a machine without one.)"""
    from railsusp.surrogate.models import default_window

    kind = "bp" if cfg.surrogate.model == "gp-stats" else cfg.surrogate.model
    window = default_window(kind)
    short = [c.name for c in conds if c.n_steps <= window]
    if short:
        raise bad(
            f'surrogate.model = "{cfg.surrogate.model}" reads {window} steps before its first '
            f"prediction; the conditions {', '.join(short)} have no more steps than that: "
            f"accepted n_steps > {window} (or another model)"
        )


def check_recordings_served(cfg: Any, conds: list, recordings: list, bad: Any) -> None:
    """A ``[field] measured`` folder's recordings against the force model that will serve
    them: a network set's networks (:func:`check_network_set` on the recordings'
    conditions), or the surrogates this run trains on its conditions, which serve a
    recording of the same name that differs only in its track and record length
    (:meth:`~railsusp.surrogate.bundle.Surrogate.untrained_fields`). A recording of another
    condition, or at another speed, failed at the estimate stage after four stages ("no
    surrogate of that condition", with the advice to remake the surrogates)."""
    if not recordings:
        return
    if cfg.surrogate.pretrained is not None:
        check_network_set(cfg, [r.condition for r in recordings], bad, "field.measured: ")
        return
    from railsusp.conditions import TRACK_AND_LENGTH_FIELDS

    by_name = {c.name: c for c in conds}
    for r in recordings:
        rc = r.condition
        c = by_name.get(rc.name)
        if c is None:
            raise bad(
                f"field.measured = {cfg.field.measured!r}: recording {rc.name!r} is of none "
                f"of the run's conditions ({', '.join(by_name)}), whose surrogates it trains; "
                "accepted recordings named as a condition of the run (set conditions to the "
                "recordings' conditions)"
            )
        if cfg.surrogate.model == "gp-stats":  # the statistics GPs' own check, run now
            from railsusp.estimate.statistics import parse_statistics
            from railsusp.estimate.statistics_forces import check_served_condition

            try:
                check_served_condition(c, rc, parse_statistics(cfg.estimate.statistic))
            except RailsuspInputError as exc:
                raise bad(f"field.measured = {cfg.field.measured!r}: {exc}") from None
            continue
        _check_served_rate(cfg, c, rc, bad)
        differ = c.differences(rc, TRACK_AND_LENGTH_FIELDS)
        if differ:
            name = differ[0]
            raise bad(
                f"field.measured = {cfg.field.measured!r}: recording {rc.name!r} has {name} "
                f"= {getattr(rc, name)!r}, the run's condition {c.name!r} "
                f"{getattr(c, name)!r}, on which its surrogate is trained; accepted "
                "recordings that differ from their condition only in the track and the "
                "record length (set the condition's fields to the recording's)"
            )
