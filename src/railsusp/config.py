"""Validation of a pipeline configuration, all of it before any stage runs.

The section models of :mod:`railsusp.pipeline_config` type and range-check every field and
refuse unknown keys; this module adds what a field-by-field check cannot see, so that a run
that would fail in its fifth stage fails at once, with a one-line error naming the field:

* the file itself: unreadable, a folder, not UTF-8, not TOML, not a table of tables;
  (values of the wrong type, ``samples = true`` or ``samples = "10"``, are refused by
  the models' strict validation, :func:`railsusp.input_checks.validate_document`);
* every working condition built (names, ranges, ``base``), names distinct;
* parameters: campaign parameters sampled and distinct, ``[field] truth`` symbols known
  and inside their ranges (``truth = {X99 = 1.0}`` used to fail after three stages),
  ``[estimate] held_prior`` ranges known, inside Table 2, low below high, with a refinement;
* combinations: ``refine = true`` and the statistic ``aligned`` need recordings with track
  geometry (``with_track`` for synthetic ones, ``track_geometry`` in the sidecars of a
  ``measured`` folder; never the sections of a long ``recording``), ``aligned`` and
  ``p99.85`` a force model that gives series (not ``gp-stats``), the ``noise`` weighting a
  ``gp-stats`` force model, recordings from
  ``measured`` (a folder with ``index.json``), a long run (``recording``, its files present;
  not with ``measured``, ``truth``, ``conditions`` or ``refine``) or synthetic ones, a
  readable wagon file, a scheduler address, the training device.

The pipeline's :func:`~railsusp.pipeline_config.load_config` calls :func:`read_config` and
:func:`check_config`; this module imports nothing of the pipeline (the models come in as
arguments), so imports flow one way.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from railsusp.errors import RailsuspInputError, repeated_names

#: the statistics a sensitivity analysis can rank on (campaign features)
SENSITIVITY_STATISTICS = ("mean", "rms", "p99", "max")
#: the training devices
DEVICES = ("cpu", "cuda", "auto")
#: the statistic that names the time-aligned comparison (railsusp.estimate.statistics)
ALIGNED = "aligned"


class ConfigError(RailsuspInputError):
    """A pipeline configuration that cannot run as written."""


def read_config(path: str | Path) -> dict[str, Any]:
    """The TOML document of a configuration file, checked to be a readable UTF-8 TOML
    file that sets something (one line naming the file otherwise)."""
    from railsusp.store import read_toml

    try:
        doc = read_toml(Path(path), "configuration")
    except RailsuspInputError as exc:
        raise ConfigError(str(exc)) from None
    if not doc:  # an empty file (or comments alone) ran the whole default pipeline
        raise ConfigError(
            f"configuration {path} is empty: accepted a file with at least one setting or "
            "section (examples/quick.toml; `railsusp demo` runs the default without one)"
        )
    return doc


def validation_message(where: str | Path, exc: Any, model: Any = None) -> str:
    """A pydantic ValidationError as one line: ``where: loc: message; ...``, with field names
    that are not plain identifiers (a key holding a newline, a dot) shown quoted, and a value
    of the wrong type shown as the file wrote it (``campaign.samples = "10": a whole number
    is needed, not a string``). With the ``model`` validated, a value out of bounds gets the
    field's accepted range and an unknown key the section's keys."""
    from railsusp.input_checks import error_detail, type_error_text

    def part(p: Any) -> str:
        s = str(p)
        return s if s.replace("_", "a").isalnum() and s.isascii() else repr(s)

    def one(e: Any) -> str:
        loc = ".".join(part(p) for p in e["loc"]) or "combination"
        wrong_type = type_error_text(e)
        if wrong_type is not None:
            return f"{loc} = {_as_toml(e.get('input'))}: {wrong_type}"
        text = " ".join(e["msg"].removeprefix("Value error, ").split())
        detail = error_detail(model, e) if model is not None else None
        if detail is None:
            return f"{loc}: {text}"
        value = "" if e.get("type") == "extra_forbidden" else f" = {_as_toml(e.get('input'))}"
        return f"{loc}{value}: {detail} ({text})"

    return f"{where}: " + "; ".join(one(e) for e in exc.errors())


def _as_toml(value: Any) -> str:
    """A scalar as a TOML file writes it (``true``, ``"10"``); others as Python shows them."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string escapes as JSON does
    return repr(value)


def check_config(cfg: Any, where: str = "configuration") -> None:
    """Check a validated :class:`~railsusp.pipeline_config.PipelineConfig` as a whole; raise
    :class:`ConfigError` (one line, naming the field) at the first thing that would make a
    stage fail."""
    from railsusp.condition_files import check_track_file
    from railsusp.params import ParameterSet, spec
    from railsusp.vehicle.wagon import load_wagon

    def bad(message: str) -> ConfigError:
        return ConfigError(f"{where}: {message}")

    # a long run to cut into sections: its files, and what it excludes
    if cfg.field.recording is not None:
        _check_recording_keys(cfg, bad)
    else:
        for key in ("channel_map", "line", "sections"):
            if getattr(cfg.field, key) is not None:
                raise bad(f"field.{key} needs field.recording (the long run it applies to)")

    # conditions: each one builds, names distinct (a recording's: its cut)
    try:
        conds = cfg.working_conditions()
    except RailsuspInputError as exc:
        raise bad(f"conditions: {exc}") from None
    if not conds:
        raise bad("conditions: at least one condition is needed")
    names = [c.name for c in conds]
    dupes = repeated_names(names)  # case ignored: folder names on a case-blind disk
    if dupes:
        raise bad(f"conditions: names repeat ({', '.join(dupes)}); give each a distinct name")
    for c in conds:  # read only in the campaign stage: a missing file would stop it there
        try:
            check_track_file(c)
        except RailsuspInputError as exc:
            raise bad(f"conditions: {exc}") from None

    # parameters
    sampled: list[str] = []
    for p in cfg.campaign.parameters:
        try:
            s = spec(p)
        except RailsuspInputError as exc:
            raise bad(f"campaign.parameters: {exc}") from None
        if not s.is_sampled:
            raise bad(f"campaign.parameters: {s.symbol} is fixed; sampled ones are X11..X20")
        if s.symbol in sampled:
            raise bad(f"campaign.parameters: {s.symbol} is given twice")
        sampled.append(s.symbol)
    if not cfg.campaign.parameters:
        raise bad("campaign.parameters: none given; accepted one or more of X11..X20")
    if not cfg.sensitivity.statistics:
        raise bad(
            f"sensitivity.statistics: none given; accepted one or more of "
            f"{', '.join(SENSITIVITY_STATISTICS)}"
        )
    for st in cfg.sensitivity.statistics:
        if st not in SENSITIVITY_STATISTICS:
            raise bad(
                f"sensitivity.statistics: {st!r} unknown; accepted "
                f"{', '.join(SENSITIVITY_STATISTICS)}"
            )
    f = cfg.field
    if f.truth:
        try:
            ParameterSet(f.truth, units="display")
        except RailsuspInputError as exc:
            raise bad(f"field.truth: {exc}") from None

    # recordings
    recordings: list = []  # a measured folder's, read whole
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

        try:  # every recording read and checked now, not in the field stage after the
            # campaign, the sensitivity and the surrogates; against the run's wagon
            recordings = read_field(folder, wagon=load_wagon(cfg.wagon))
        except RailsuspInputError as exc:
            raise bad(f"field.measured: {exc}") from None
    blind = [r.condition.name for r in recordings if r.condition.track_geometry is None]
    own_tracks = _own_tracks(cfg, conds)
    _check_measured_track(cfg, bad, blind, own_tracks)
    if (f.with_track or f.track_noise_mm) and (f.measured or f.recording) is not None:
        raise bad("field.with_track and field.track_noise_mm apply to synthetic recordings only")
    # set and not the default: a run's recorded configuration (pipeline.json, every field
    # written out) runs again
    given = sorted(
        k
        for k in ("noise", "seed")
        if k in f.model_fields_set and getattr(f, k) != type(f).model_fields[k].default
    )
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

    # estimation, surrogates, wagon, scheduler
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
    _check_held_prior(cfg, bad)
    _check_one_track_surrogate(cfg, bad, own_tracks)
    if cfg.surrogate.device not in DEVICES:
        raise bad(f"surrogate.device = {cfg.surrogate.device!r}: accepted {', '.join(DEVICES)}")
    if cfg.surrogate.pretrained is None:
        _check_surrogate_training(cfg, conds, bad)
    if cfg.wagon is not None:
        from railsusp.summary import read_tolerances

        try:
            load_wagon(cfg.wagon)
            read_tolerances(cfg.wagon)  # the report's verdicts: refused now, not after the run
        except RailsuspInputError as exc:
            raise bad(f"wagon: {exc}") from None
    if cfg.surrogate.pretrained is not None:
        _check_network_set(cfg, conds, bad)
    if cfg.scheduler is not None:
        from railsusp.campaign.dask_cluster import check_scheduler_address

        try:
            check_scheduler_address(cfg.scheduler, "scheduler =")
        except RailsuspInputError as exc:
            raise bad(str(exc)) from None


def _check_network_set(cfg: Any, conds: list, bad: Any) -> None:
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
        raise bad(str(exc)) from None


def _check_held_prior(cfg: Any, bad: Any) -> None:
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
        raise bad(
            f"{HELD_PRIOR_FIELD} is used by the refinement's intervals only; set "
            "estimate.refine = true or leave held_prior out"
        )
    if ALIGNED in e.statistic.split("+"):
        raise bad(
            f'{HELD_PRIOR_FIELD} with estimate.statistic "aligned": the refinement is then a '
            "polish beside NSGA-II's estimate, whose interval (the Pareto range) uses no "
            "prior; leave held_prior out or choose record statistics"
        )


def _check_surrogate_training(cfg: Any, conds: list, bad: Any) -> None:
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


def check_cuda(cfg: Any, where: str, surrogate_done: bool) -> None:
    """Refuse ``[surrogate] device = "cuda"`` on a machine without a CUDA device, before any
    stage, where the surrogate stage has still to train (``surrogate_done`` False); a run
    whose surrogates are trained is resumed or estimated again anywhere."""
    if cfg.surrogate.device != "cuda" or cfg.surrogate.pretrained is not None or surrogate_done:
        return
    import torch

    if not torch.cuda.is_available():
        raise ConfigError(
            f'{where}: surrogate.device = "cuda": no CUDA device is available on this '
            'machine, and the surrogates are still to train; accepted "cpu", or "auto" (a '
            "GPU where there is one)"
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


def _check_one_track_surrogate(cfg: Any, bad: Any, own_tracks: bool) -> None:
    """The statistic ``aligned`` (and so ``expected_draws``, which needs it) needs a surrogate
    that predicts on any track, ``surrogate.pretrained``: a run's campaign is on each
    condition's one track realisation, so the networks it trains predict that track only
    (docs/surrogates.md), neither the recordings' measured track nor drawn ones
    (estimate/problem.py refused it at the estimate stage, after every other stage had
    run)."""
    if cfg.surrogate.pretrained is not None or cfg.surrogate.model == "gp-stats":
        return  # a set trained on a track family; the statistics GPs have their own check
    if own_tracks and not cfg.field.track_noise_mm:  # trained on the conditions'
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


def _check_recording_keys(cfg: Any, bad: Any) -> None:
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
