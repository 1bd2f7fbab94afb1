"""Validation of a pipeline configuration, all of it before any stage runs.

The section models of :mod:`railsusp.config_sections` type and range-check every field and
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

    def union(group: list[Any]) -> str:
        loc = ".".join(part(p) for p in group[0]["loc"][:-1])
        texts = [type_error_text(e) or "" for e in group]
        needed = " or ".join(t.split(" is needed")[0] for t in texts)
        given = texts[0].split(" is needed", 1)[1]  # ", not an integer"
        return f"{loc} = {_as_toml(group[0].get('input'))}: {needed} is needed{given}"

    return f"{where}: " + "; ".join(
        union(g) if len(g) > 1 else one(g[0]) for g in _union_groups(exc.errors())
    )


def _union_groups(errors: list[Any]) -> list[list[Any]]:
    """pydantic's errors grouped so that the type errors of one value against each member of
    a union (``conditions = [1]``: one error at ``conditions.0.str``, one at
    ``conditions.0.'dict[str,any]'``, the members' internal names) become one group, told
    as one error of the value's own location ("a string or a table is needed"); every other
    error a group of its own."""
    from railsusp.input_checks import type_error_text

    out: list[list[Any]] = []
    for e in errors:
        prev = out[-1][-1] if out else None
        if (
            prev is not None
            and len(e["loc"]) > 1
            and tuple(e["loc"][:-1]) == tuple(prev["loc"][:-1])
            and e["loc"][-1] != prev["loc"][-1]
            and e.get("input") is prev.get("input")
            and type_error_text(e) is not None
            and type_error_text(prev) is not None
        ):
            out[-1].append(e)
        else:
            out.append([e])
    return out


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
    stage fail: the sources of the recordings, the conditions, the parameters, then the
    settings that must agree (:mod:`railsusp.config_recordings`,
    :mod:`railsusp.config_combinations`), the wagon, the network set and the scheduler."""
    from railsusp.config_combinations import (
        check_estimate_options,
        check_held_prior,
        check_network_set,
        check_network_window,
        check_recordings_served,
        check_surrogate_training,
    )
    from railsusp.config_recordings import (
        check_expected_draws,
        check_field_options,
        check_geometry_draws,
        check_one_track_surrogate,
        check_recording_keys,
        check_synthetic_rate,
        given_off_default,
        measured_recordings,
    )

    def bad(message: str) -> ConfigError:
        return ConfigError(f"{where}: {message}")

    # a long run to cut into sections: its files, and what it excludes
    if cfg.field.recording is not None:
        check_recording_keys(cfg, bad)
    else:
        for key in ("channel_map", "line", "sections"):
            if getattr(cfg.field, key) is not None:
                raise bad(f"field.{key} needs field.recording (the long run it applies to)")
        f = cfg.field
        for key in ("rate_hz", "speed_tolerance", "min_length_m", "max_duration_s"):
            # the cut's settings were ignored without a long run (stop 78's hunt)
            if given_off_default(f, key):
                raise bad(
                    f"field.{key} sets how field.recording (a long run) is cut into sections; "
                    "without one it is used nowhere: leave it out"
                )
    conds = _conditions(cfg, bad)
    _check_parameters(cfg, bad)
    recordings = measured_recordings(cfg, bad)
    check_field_options(cfg, conds, recordings, bad)
    check_synthetic_rate(cfg, conds, bad)
    check_estimate_options(cfg, bad)
    check_expected_draws(cfg, recordings, bad)
    check_geometry_draws(cfg, recordings, bad)
    check_held_prior(cfg, bad)
    check_one_track_surrogate(cfg, conds, bad)
    if cfg.surrogate.device not in DEVICES:
        raise bad(f"surrogate.device = {cfg.surrogate.device!r}: accepted {', '.join(DEVICES)}")
    if cfg.surrogate.pretrained is None:
        check_surrogate_training(cfg, conds, bad)
    if cfg.wagon is not None:
        from railsusp.suspension_tolerances import read_tolerances
        from railsusp.vehicle.wagon import load_wagon

        try:
            load_wagon(cfg.wagon)
            read_tolerances(cfg.wagon)  # the report's verdicts: refused now, not after the run
        except RailsuspInputError as exc:
            raise bad(f"wagon: {exc}") from None
    if cfg.surrogate.pretrained is not None:
        check_network_set(cfg, conds, bad)
    check_recordings_served(cfg, conds, recordings, bad)
    if cfg.surrogate.pretrained is not None:  # after the set's own checks, which name more
        check_network_window(cfg, conds, recordings, bad)
    if cfg.scheduler is not None:
        from railsusp.campaign.dask_cluster import check_scheduler_address

        try:
            check_scheduler_address(cfg.scheduler, "scheduler =")
        except RailsuspInputError as exc:
            raise bad(str(exc)) from None


def _conditions(cfg: Any, bad: Any) -> list:
    """Every working condition built (a recording's: its cut), names distinct, each one's
    track geometry file readable; returned."""
    from railsusp.condition_files import check_track_file

    try:
        conds = cfg.working_conditions()
    except RailsuspInputError as exc:
        # with a long run the conditions are its cut: what failed is reading field.recording
        # (or the channel map, line or sections it is cut with, which the error names)
        key = "conditions" if cfg.field.recording is None else "field.recording"
        raise bad(f"{key}: {exc}") from None
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
    _check_track_coverage(cfg, conds, bad)
    return conds


def _check_track_coverage(cfg: Any, conds: list, bad: Any) -> None:
    """Each measured track-geometry file read and checked to cover its condition's record
    under every axle of the run's wagon (:func:`~railsusp.vehicle.track_geometry.
    check_coverage`): the campaign stage found a short file, or a lead-in shorter than the
    axle spread, after the configuration check had passed (the rerun audit of stop 65). A
    wagon that does not load is left to the wagon's own check, which names it."""
    measured = [c for c in conds if c.track_geometry is not None]
    if not measured:
        return
    from railsusp.vehicle.setup import axle_spread
    from railsusp.vehicle.track_geometry import check_coverage, read_track_geometry
    from railsusp.vehicle.wagon import load_wagon

    try:
        spread = axle_spread(load_wagon(cfg.wagon))
    except RailsuspInputError:
        return
    for c in measured:
        try:
            check_coverage(read_track_geometry(c.track_geometry), c, spread)
        except RailsuspInputError as exc:
            raise bad(f"conditions: {exc}") from None


def _check_parameters(cfg: Any, bad: Any) -> None:
    """The campaign's parameters (sampled, distinct), the sensitivity's statistics (known,
    distinct) and ``[field] truth`` (known symbols inside their ranges)."""
    from railsusp.params import ParameterSet, spec

    sampled: list[str] = []
    for p in cfg.campaign.parameters:
        try:
            s = spec(p)
        except RailsuspInputError:  # spec's own accepts X1..X20; only X11..X20 are sampled
            raise bad(
                f"campaign.parameters: unknown parameter {p!r}; accepted the sampled ones, "
                "X11..X20, or their names (e.g. X13 or primary_longitudinal_stiffness)"
            ) from None
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
    for k, st in enumerate(cfg.sensitivity.statistics):
        if st in cfg.sensitivity.statistics[:k]:  # ranked twice: duplicate rows of indices
            raise bad(f"sensitivity.statistics: {st!r} is given twice")
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
