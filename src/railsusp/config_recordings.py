"""The settings of a pipeline configuration about its field recordings, checked against the
rest before any stage runs: where the recordings come from (a ``[field] measured`` folder,
read whole now; a long run's ``recording`` and the files that cut it; synthetic ones), the
``[field]`` options each source takes, whether the recordings carry the measured track that
the time-aligned comparison and a network set need, its stated accuracy for
``expected_draws``, and the rate of synthetic recordings. Each check raises through ``bad``
(:func:`railsusp.config.check_config`'s one-line :class:`~railsusp.config.ConfigError`);
every one of them failed a run in a later stage once (tests/test_config_combinations.py).

They are apart from :mod:`railsusp.config_combinations`, which holds the checks of the
estimate's and the surrogates' settings, because these are about the recordings' source and
track and call none of those; that module imports :data:`ALIGNED` from here. Imports of the
stages' modules are local: this module is read with the configuration, before any stage is
loaded.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from railsusp.errors import RailsuspInputError

#: the statistic that names the time-aligned comparison (railsusp.estimate.statistics)
ALIGNED = "aligned"


def given_off_default(section: Any, key: str) -> bool:
    """Whether the configuration section's setting ``key`` was given and is not its default:
    a run's recorded configuration (pipeline.json, every field written out) gives each one
    at its default, and runs again, so a setting a route reads nowhere is refused only
    when it would change something."""
    return key in section.model_fields_set and (
        getattr(section, key) != type(section).model_fields[key].default
    )


def measured_recordings(cfg: Any, bad: Any) -> list:
    """A ``[field] measured`` folder's recordings, read whole and checked against the run's
    wagon now, not in the field stage after the campaign, the sensitivity and the
    surrogates (none without the setting)."""
    f = cfg.field
    recordings: list = []
    if f.measured is not None:
        if f.truth:
            raise bad("field: give measured or truth, not both")
        folder = Path(f.measured)
        if not folder.is_dir():
            raise bad(f"field.measured = {f.measured!r} is not a folder")
        if not (folder / "index.json").is_file():
            raise bad(f"field.measured = {f.measured!r} holds no index.json of recordings")
        from railsusp.measured import read_field
        from railsusp.vehicle.wagon import load_wagon

        try:  # a wagon that does not load is the wagon's error, not the folder's (it was
            # said as "field.measured: wagon file ... does not exist")
            wagon = load_wagon(cfg.wagon)
        except RailsuspInputError as exc:
            raise bad(f"wagon: {exc}") from None
        try:  # every recording read and checked now, not in the field stage after the
            # campaign, the sensitivity and the surrogates; against the run's wagon
            recordings = read_field(folder, wagon=wagon)
        except RailsuspInputError as exc:
            raise bad(f"field.measured: {exc}") from None
    return recordings


def check_field_options(cfg: Any, conds: list, recordings: list, bad: Any) -> None:
    """The ``[field]`` settings against the recordings they apply to (synthetic, a measured
    folder's ``recordings``, a long run's sections) and the comparisons that need their
    measured track."""
    f = cfg.field
    blind = [r.condition.name for r in recordings if r.condition.track_geometry is None]
    own_tracks = _own_tracks(cfg, conds)
    _check_measured_track(cfg, bad, blind, own_tracks)
    _check_measured_time_base(cfg, recordings, bad)
    _check_measured_wheels(cfg, recordings, bad)
    if (f.with_track or f.track_noise_mm) and (f.measured or f.recording) is not None:
        raise bad("field.with_track and field.track_noise_mm apply to synthetic recordings only")
    given = sorted(k for k in ("noise", "seed") if given_off_default(f, k))
    if given and (f.measured or f.recording) is not None:  # ignored, silently (audit, stop 60)
        source = "field.measured" if f.measured is not None else "field.recording"
        raise bad(
            f"field.{' and field.'.join(given)} set the synthetic recordings' instrument noise "
            f"and draw; {source} gives measured ones: leave {' and '.join(given)} out"
        )
    if f.track_noise_mm and not f.with_track:
        raise bad("field.track_noise_mm needs field.with_track = true")
    if f.with_track and f.recording is None and f.measured is None:
        perfect = [c.name for c in conds if c.irregularity_class is None and not c.track_geometry]
        if perfect:  # nothing to write: the field stage failed on it after three stages
            raise bad(
                f"field.with_track = true: {', '.join(perfect)} on perfect track "
                '(irregularity_class = "none") have no track geometry to write; give them a '
                "class, or set with_track = false"
            )


def _own_tracks(cfg: Any, conds: list) -> bool:
    """Whether the recordings are synthetic and every condition (``conds``, the run's) names
    its own ``track_geometry``: the recordings then carry a copy of it (with ``with_track``
    or without), so they carry their measured track."""
    f = cfg.field
    return (
        f.measured is None
        and f.recording is None
        and all(c.track_geometry is not None for c in conds)
    )


def check_one_track_surrogate(cfg: Any, conds: list, bad: Any) -> None:
    """The statistic ``aligned`` (and so ``expected_draws``, which needs it) needs a surrogate
    that predicts on any track, ``surrogate.pretrained``: a run's campaign is on each
    condition's one track realisation, so the networks it trains predict that track only
    (docs/surrogates.md), neither the recordings' measured track nor drawn ones
    (estimate/problem.py refused it at the estimate stage, after every other stage had
    run)."""
    if cfg.surrogate.pretrained is not None or cfg.surrogate.model == "gp-stats":
        return  # a set trained on a track family; the statistics GPs have their own check
    if _own_tracks(cfg, conds) and not cfg.field.track_noise_mm:  # trained on the conditions'
        return  # own tracks, which the synthetic recordings carry (same_measured_track);
    # with a measurement error added the recordings' copies are other tracks
    if ALIGNED in cfg.estimate.statistic.split("+"):
        raise bad(
            'estimate.statistic "aligned" needs surrogate.pretrained: the surrogates a run '
            "trains are trained on one track realisation per condition and cannot predict "
            "the recordings' measured track; set surrogate.pretrained (a network set trained "
            "on a track family, docs/surrogates.md) or another statistic"
        )


def _check_measured_track(cfg: Any, bad: Any, blind: list[str], own_tracks: bool) -> None:
    """The settings that compare time-aligned series on the recordings' measured track
    (``estimate.refine``, the statistic ``aligned``) need recordings that carry it: not the
    sections of a long run, not synthetic recordings without ``with_track`` (unless every
    condition has its own track, ``own_tracks``), not a ``measured`` folder's recordings
    without ``track_geometry`` (``blind``, their names)."""
    f = cfg.field
    needs = []
    if cfg.estimate.refine:
        needs.append(("estimate.refine = true", "refine = false"))
    if ALIGNED in cfg.estimate.statistic.split("+"):
        needs.append(('estimate.statistic "aligned"', "another statistic"))
    if (
        cfg.surrogate.pretrained is not None
        and (
            (f.measured is not None and blind)
            or (f.measured is None and (f.recording is not None or not f.with_track))
        )
        and not own_tracks
    ):
        raise bad(
            "surrogate.pretrained needs recordings with their measured track geometry (the "
            "set's networks read the track they predict on): synthetic ones with "
            "field.with_track = true, or measured ones whose sidecars give track_geometry; "
            "else leave surrogate.pretrained out and train the surrogates here"
        )
    for what, instead in needs:
        if f.recording is not None:
            raise bad(
                f"{what} with field.recording: the sections of a long run carry no measured "
                f"track geometry, which time-aligned comparison needs; set {instead}"
            )
        if f.measured is None and not f.with_track and not own_tracks:
            raise bad(
                f"{what} with field.with_track = false: time-aligned comparison needs the "
                "recordings' measured track geometry; set field.with_track = true "
                f"(or {instead})"
            )
        if f.measured is not None and blind:
            raise bad(
                f"{what} with field.measured = {f.measured!r}: {', '.join(blind)} carry "
                "no track geometry (condition.track_geometry, docs/data-format.md), which "
                f"time-aligned comparison needs; set {instead}"
            )


def _check_measured_time_base(cfg: Any, recordings: list, bad: Any) -> None:
    """A measured folder's recordings compared sample by sample (``estimate.refine``, the
    statistic ``aligned``) need each sidecar's ``condition.n_steps`` to be its table's rows
    (:func:`~railsusp.estimate.comparison.check_time_base`): refused now, not at the
    estimate stage after the campaign, the sensitivity, the surrogates and the field."""
    if cfg.field.measured is None or not recordings:
        return
    from railsusp.estimate.comparison import check_time_base

    if cfg.estimate.refine:  # (one check serves both: the refinement named first)
        use = "estimate.refine (the output-error refinement)"
    elif ALIGNED in cfg.estimate.statistic.split("+"):
        use = "the time-aligned comparison (statistic 'aligned')"
    else:
        return
    try:
        check_time_base(recordings, use)
    except RailsuspInputError as exc:
        raise bad(f"field.measured = {cfg.field.measured!r}: {exc}") from None


class _AutoWheel:
    """A force model giving the automatically chosen wheel (the leading wheelset's left
    wheel on tangent, its outer wheel in a curve): the simulator's, and the surrogates a
    run trains (its campaign's wheel is the automatic one)."""

    wheel = "auto"


def _check_measured_wheels(cfg: Any, recordings: list, bad: Any) -> None:
    """A measured folder's recordings whose first wheel is not the one the force model
    gives where that matters (:func:`~railsusp.estimate.problem.check_measured_wheel`: in a
    curve, and in any time-aligned comparison): the surrogates this run trains (NSGA-II),
    and the simulator of the refinement and the simulator corrections, which compare
    sample by sample. Refused now; they failed at the estimate stage after four stages (a
    curve's inner wheel, or on tangent the other wheel with the refinement, after NSGA-II
    had run: stop 78's hunt). A network set's own wheel is checked when it is loaded."""
    if cfg.field.measured is None or not recordings:
        return
    from railsusp.estimate.problem import check_measured_wheel

    e = cfg.estimate
    comparisons = []
    if cfg.surrogate.pretrained is None:
        comparisons.append(ALIGNED in e.statistic.split("+"))  # NSGA-II's
    if e.refine or e.simulator_corrections:
        comparisons.append(True)  # the simulator's, sample by sample
    for aligned in comparisons:
        try:
            check_measured_wheel(_AutoWheel(), recordings, aligned)
        except RailsuspInputError as exc:
            raise bad(f"field.measured = {cfg.field.measured!r}: {exc}") from None


def check_recording_keys(cfg: Any, bad: Any) -> None:
    """``[field] recording``: the files exist, the keys that exclude it are absent; the
    recording itself is read (and checked) when the conditions are built from its cut."""
    f = cfg.field
    default = type(cfg).model_fields["conditions"].get_default(call_default_factory=True)
    if "conditions" in cfg.model_fields_set and cfg.conditions != default:
        raise bad(
            "conditions: with field.recording the conditions are the recording's sections; "
            "leave conditions out"
        )
    if f.measured is not None:
        raise bad("field: give recording or measured, not both")
    if f.truth:
        raise bad("field: give recording or truth (synthetic recordings), not both")
    if f.line is not None and f.sections is not None:
        raise bad("field: give line or sections (the cut of the recording), not both")
    for key in ("recording", "channel_map", "line", "sections"):
        value = getattr(f, key)
        if value is not None and not Path(value).is_file():
            raise bad(f"field.{key} = {value!r}: no such file")


def _no_stated_accuracy(cfg: Any, recordings: list) -> tuple[str, str]:
    """(why the recordings state no track-geometry accuracy to draw errors by, the setting
    that would give one); ('', '') where one does. Synthetic recordings state
    ``field.track_noise_mm`` (0: their geometry exact), a measured folder's their sidecars'
    accuracy, a long run's sections no track geometry at all."""
    f = cfg.field
    if f.recording is not None:
        return "the sections of field.recording carry no track geometry", ""
    if f.measured is not None:
        if any(r.condition.track_geometry and r.condition.track_accuracy_mm for r in recordings):
            return "", ""
        return (
            f"no recording of field.measured = {f.measured!r} states its geometry's "
            "track_accuracy_mm (docs/data-format.md)",
            "",
        )
    if f.track_noise_mm:
        return "", ""
    return (
        "field.track_noise_mm = 0 gives the synthetic recordings exact geometry",
        "field.track_noise_mm > 0 (with with_track = true)",
    )


def check_expected_draws(cfg: Any, recordings: list, bad: Any) -> None:
    """``estimate.expected_draws`` draws true tracks about each recording's measured one by
    its stated accuracy (``track_accuracy_mm``): with recordings that state none the draws
    were skipped with a warning at the estimate stage, the run otherwise complete and the
    estimate not polished as the configuration asked."""
    e = cfg.estimate
    if not e.expected_draws:
        return
    why, fix = _no_stated_accuracy(cfg, recordings)
    if why:
        instead = f"{fix} or expected_draws = 0" if fix else "expected_draws = 0"
        raise bad(
            f"estimate.expected_draws = {e.expected_draws} draws true tracks about the "
            f"recordings' measured one by its stated accuracy; {why}, so none would be drawn: "
            f"set {instead}"
        )


def check_geometry_draws(cfg: Any, recordings: list, bad: Any) -> None:
    """``estimate.geometry_draws`` and ``remove_geometry_bias``, set and not at their
    defaults, on a route where no step draws the recordings' geometry error: they were
    accepted and changed nothing (stop 78's hunt; ``railsusp estimate`` warns of the same,
    :func:`railsusp.estimate.nsga_geometry.geometry_draws_unused`, whose reasons these
    are). The draws need a stated accuracy, are not used with ``expected_draws`` (whose
    comparison takes the error in), and are made by NSGA-II's time-aligned estimate
    (statistic ``aligned`` alone) or by the refinement."""
    e = cfg.estimate
    given = []  # 0 draws asks for none: nothing is ignored where none are drawn
    if e.geometry_draws and given_off_default(e, "geometry_draws"):
        given.append(f"estimate.geometry_draws = {e.geometry_draws}")
    if given_off_default(e, "remove_geometry_bias"):
        given.append("estimate.remove_geometry_bias = false")
    if not given:
        return
    why, fix = _no_stated_accuracy(cfg, recordings)
    if why and fix:
        why = f"{why} (it would with {fix})"
    if not why and e.expected_draws:
        why = (
            f"with estimate.expected_draws = {e.expected_draws} the geometry's error is in the "
            "comparison (the mean over drawn true tracks) instead"
        )
    if not why and not e.geometry_draws:
        why = "estimate.geometry_draws = 0 draws none, so no bias is estimated to keep"
    if not why and not e.refine and e.statistic != ALIGNED:
        why = (
            f'NSGA-II on estimate.statistic = "{e.statistic}" draws none (only "aligned" '
            "alone does) and estimate.refine = false"
        )
    if why:
        raise bad(
            f"{' and '.join(given)}: no step draws the track geometry's error, {why}; leave it out"
        )


def check_synthetic_rate(cfg: Any, conds: list, bad: Any) -> None:
    """Synthetic recordings are written at each condition's ``n_steps / duration_s``; the
    field and estimate stages read recordings at
    :data:`~railsusp.conditions.RECORDING_MIN_RATE_HZ` or more. A condition of 50 steps
    over 1.2 s ran the campaign, the sensitivity, the surrogates and the field stage, and
    failed at the estimate stage naming a generated file."""
    from railsusp.conditions import RECORDING_MIN_RATE_HZ

    if cfg.field.measured is not None or cfg.field.recording is not None:
        return
    for k, c in enumerate(conds):
        rate = c.n_steps / c.duration_s
        if rate < RECORDING_MIN_RATE_HZ * (1.0 - 1e-9):
            least = math.ceil(RECORDING_MIN_RATE_HZ * c.duration_s - 1e-9)
            raise bad(
                f"conditions[{k}] ({c.name!r}): n_steps = {c.n_steps} over duration_s = "
                f"{c.duration_s:g} s gives synthetic recordings of {rate:.4g} Hz, below the "
                f"{RECORDING_MIN_RATE_HZ:g} Hz the estimate reads; accepted n_steps at least "
                f"{least} (or a shorter duration_s)"
            )
