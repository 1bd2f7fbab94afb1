"""What each stage of the pipeline depends on: the part of the configuration a stage hashes
(:func:`stage_section`, with :func:`model_identity`, the wagon data and force laws every
simulated stage depends on) and the stages whose outputs it reads (:func:`stage_inputs`,
:func:`stage_dependents`). :func:`railsusp.pipeline.stage_hashes` hashes them into the
record that decides whether a stage runs again; :mod:`railsusp.pipeline_stages` runs them.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from railsusp.errors import RailsuspInputError
from railsusp.estimate.config import BROYDEN_MIN_STEP
from railsusp.pipeline_config import PipelineConfig
from railsusp.stages import STAGES

if TYPE_CHECKING:
    from railsusp.campaign import CampaignConfig

log = logging.getLogger("railsusp.pipeline")


def model_identity(config: PipelineConfig) -> dict[str, str]:
    """What the simulated stages' results depend on beyond the configuration: the wagon's
    data as read (a wagon file edited in place, or the embedded data of another railsusp)
    and the force laws' revision (:data:`railsusp.vehicle.MODEL_REVISION`). In the stage
    hashes, so that a run directory made with another model is simulated again instead of
    being reused (the demo's did, and its estimate stage then failed reading surrogates
    saved with an older wagon description)."""
    from railsusp.surrogate.pretrained import wagon_hash
    from railsusp.vehicle import MODEL_REVISION
    from railsusp.vehicle.wagon import load_wagon

    return {"wagon_data": wagon_hash(load_wagon(config.wagon)), "model_revision": MODEL_REVISION}


def _measured_state(config: PipelineConfig, legacy: bool = False) -> dict:
    """What the field stage's copy of a ``[field] measured`` folder depends on beyond its
    path: every file's path in it and its contents' SHA-256 (read once per file and run).
    Without them a folder whose recordings were replaced kept the old copy, and the
    estimate on it, up to date. Before stop 66 the files' sizes and modification times
    stood for their contents (``legacy``): a ``touch`` ran the field stage and every stage
    after it again, and a ``cp -p`` of other recordings of the same size was not seen.
    Empty (so the stage hashes as before) without a measured folder."""
    from railsusp.store import file_hash_cached

    if config.field.measured is None:
        return {}
    files = []
    for name, p in _measured_files(config):
        if legacy:
            st = p.stat()
            files.append((name, st.st_size, st.st_mtime_ns))
        else:
            files.append((name, file_hash_cached(p)))
    return {"measured_files": files}


def _measured_files(config: PipelineConfig) -> list[tuple[str, Path]]:
    """The files of the ``[field] measured`` folder the field stage's hash counts, each by
    its path in the folder (POSIX form), in path order: hidden ones (a lock file,
    ``.DS_Store``) left out; none without a measured folder or where it is missing."""
    if config.field.measured is None:
        return []
    folder = Path(config.field.measured)
    found = []
    for p in sorted(folder.rglob("*")) if folder.is_dir() else []:
        rel = p.relative_to(folder)
        if p.is_file() and not any(part.startswith(".") for part in rel.parts):
            found.append((rel.as_posix(), p))
    return found


def measured_copy_matches(config: PipelineConfig, out: Path, entry: dict) -> bool:
    """Whether the field stage's record ``entry`` in ``pipeline.json`` holds a copy of the
    ``[field] measured`` folder as it is now: each of its files' SHA-256 as recorded for its
    copy under ``field/``, and no other. A legacy field hash (before stop 66) took the
    files by size and modification time, so it is taken only where this holds. True
    without a measured folder (nothing to check)."""
    from railsusp.store import file_hash_cached

    if config.field.measured is None:
        return True
    recorded = entry.get("sha256")
    if not isinstance(recorded, dict):
        return False
    now = {f"field/{name}": file_hash_cached(p) for name, p in _measured_files(config)}
    copies = {
        k: v
        for k, v in recorded.items()
        if k.startswith("field/") and not any(part.startswith(".") for part in k.split("/"))
    }
    return now == copies


def _tolerances_state(config: PipelineConfig) -> dict:
    """The wagon data's ``[tolerances]`` the report judges the estimate by, where they are
    not the defaults: the wagon's hash leaves them out (they are no model input), so an
    edited table left the report of the old ones up to date (the rerun audit of stop 65);
    with where they come from, which the report's sentence names. Empty for railsusp's
    defaults, so the report stage hashes as before."""
    from railsusp.suspension_tolerances import Tolerances, read_tolerances

    tol = read_tolerances(config.wagon).to_dict()  # as pipeline.json records them
    return {} if tol == Tolerances().to_dict() else {"tolerances": tol}


def lhs_campaign(
    config: PipelineConfig, samples: int, seed: int, parameters: tuple[str, ...]
) -> CampaignConfig:
    """The campaign configuration of an LHS campaign of ``parameters`` (the others nominal)
    in every condition the run simulates, on its wagon, in ``[campaign]``'s design and
    batch size: the campaign stage's, and a trained surrogate's own samples."""
    from railsusp.campaign import make_config
    from railsusp.vehicle.wagon import load_wagon

    c = config.campaign
    return make_config(
        config.working_conditions(),
        samples,
        design=c.design,
        seed=seed,
        batch_size=c.batch_size,
        parameters=parameters,
        wagon=load_wagon(config.wagon),
    )


def in_stored_batches(config: PipelineConfig, out: Path, say: bool = True) -> PipelineConfig:
    """``config``, with ``[campaign] batch_size`` that of the run directory's campaign where
    that campaign is the configured one in everything else
    (:func:`railsusp.campaign.run_directory.stored_batch_size`), said in a warning. The
    batch size only groups the same simulations into files, yet it is in the campaign
    stage's hash: changed on a finished run, it simulated the campaign again and ran every
    stage after it (the stop 67 note). Hashed as stored, the stages stay up to date, and a
    campaign stopped part way resumes in its own batches. ``say``: warn (once per run: the
    run's look before its lock is taken does not)."""
    from railsusp.campaign.run_directory import stored_batch_size

    folder = out / "campaign"
    if not folder.is_dir():
        return config
    c = config.campaign
    try:
        kept = stored_batch_size(lhs_campaign(config, c.samples, c.seed, c.parameters), folder)
    except RailsuspInputError:  # the campaign stage says it, when it runs
        return config
    if kept is None:
        return config
    if say:
        log.warning(
            "%s holds the campaign in batches of %d: kept (batch_size = %d under [campaign] "
            "groups the same simulations otherwise; it applies to a new run directory)",
            folder,
            kept,
            c.batch_size,
        )
    return config.model_copy(update={"campaign": c.model_copy(update={"batch_size": kept})})


def stage_inputs(config: PipelineConfig, stage: str) -> tuple[str, ...]:
    """The earlier stages whose outputs ``stage`` reads: it runs again when one of them
    ran, and not when another did (before stop 66 every earlier stage counted, so a
    changed ``[campaign]`` estimated again with a network set that never reads the
    campaign). The sensitivity reads the campaign; a trained surrogate the campaign and
    its key parameters (a network set neither); the field nothing; the estimate the
    surrogates, the recordings and, without a network set, the key parameters (checked
    against the campaign they were found on); the validation the estimate, the recordings
    (and their truth) and the sensitivity's indices (checked against the campaign); the
    report every stage. Checked against what each stage opens by
    tests/test_pipeline_reads.py."""
    return stage_inputs_trained(config.surrogate.pretrained is None, stage)


def stage_inputs_trained(trained: bool, stage: str) -> tuple[str, ...]:
    """:func:`stage_inputs` by whether the surrogates are trained in the run (``trained``)
    or a network set: what a run directory's reader (:class:`~railsusp.run_result.
    RunResult`) takes from the configuration pipeline.json recorded."""
    inputs = {
        "campaign": (),
        "sensitivity": ("campaign",),
        "surrogate": ("campaign", "sensitivity") if trained else (),
        "field": (),
        "estimate": (("campaign", "sensitivity") if trained else ()) + ("surrogate", "field"),
        "validate": ("campaign", "sensitivity", "field", "estimate"),
        "report": STAGES[:-1],
    }
    return inputs[stage]


def stage_dependents(config: PipelineConfig, stage: str) -> tuple[str, ...]:
    """The later stages that read ``stage``'s outputs, directly or through another stage
    (:func:`stage_inputs`): those that run again after it, in order."""
    reached = {stage}
    for later in STAGES[STAGES.index(stage) + 1 :]:
        if reached.intersection(stage_inputs(config, later)):
            reached.add(later)
    return tuple(s for s in STAGES if s in reached and s != stage)


#: the revision of how railsusp computes a stage's results from the same inputs, for the
#: stages whose computation changed after their hashes were first recorded: in their
#: sections, so that a run directory of before makes them again (its estimate and
#: validation kept the record statistics of before 9f0bf17, whose 20 s segments were
#: counted otherwise, and its report the Markdown of before 27b4f74: the upgrade audit of
#: stop 66). Raised with such a change; the simulated stages follow
#: :data:`railsusp.vehicle.MODEL_REVISION` instead.
METHOD_REVISIONS = {"estimate": "2026-11-30", "validate": "2026-11-30", "report": "2026-11-30"}


def stage_section(config: PipelineConfig, stage: str, legacy: bool = False) -> Any:
    """The inputs of ``stage`` whose hash decides whether it runs again: the settings it
    reads, on the route it takes (a setting it never reads ran it again, and the stages
    after it, before stop 66: ``[field] rate_hz`` with a synthetic truth, ``refine_*``
    without the refinement). The conditions are those the run simulates, resolved (a
    packaged condition's values, a ``base``'s, the recording's cut), with the contents of
    their measured track-geometry files: before stop 60 they were hashed as written, so a
    packaged condition changed by an upgrade, or a geometry file edited in place, left
    every stage up to date on the old results. The wagon counts by its data as read
    (:func:`model_identity`), not by how the configuration names it (``"loaded"`` and a
    path to a copy of that file simulated the campaign again before stop 66); the estimate,
    which records the name, holds it too; the estimate, validation and report their
    :data:`METHOD_REVISIONS`. ``legacy``: the sections as hashed before stop 66, which
    :func:`railsusp.pipeline.stage_hashes` still accepts from a run directory for the stages
    without a method revision."""
    from railsusp.vehicle.track_geometry import geometry_digests
    from railsusp.vehicle.wagon import wagon_reference

    conditions = config.working_conditions()
    base: dict[str, Any] = {"wagon": config.wagon} if legacy else {}
    base["conditions"] = [c.model_dump(mode="json") for c in conditions]
    base["model"] = model_identity(config)
    files = geometry_digests(conditions)
    if files:
        base["track_geometry_files"] = files
    source = config.run_source()
    if source is not None:  # the conditions, and the field, come from the recording's cut
        base["recording"] = repr(source.state())
    if stage == "campaign":
        return {**base, **config.campaign.model_dump()}
    if stage == "sensitivity":
        return config.sensitivity.model_dump()
    if stage == "surrogate":
        section = _surrogate_section(config)
        if config.surrogate.pretrained is not None and not legacy:
            # checked against the conditions' names and the wagon (no other stage's are)
            section["conditions"] = [c.name for c in conditions]
            section["model_identity"] = base["model"]
        return section
    if stage == "field":
        return {**base, **_field_settings(config, legacy), **_measured_state(config, legacy)}
    if stage == "estimate":
        section = _estimate_section(config, legacy)
        if not legacy:
            section["wagon"] = wagon_reference(config.wagon)
    elif stage == "validate":
        section = {}
    elif stage == "report":
        section = {"name": config.name, **_tolerances_state(config)}
    else:
        raise KeyError(stage)
    if not legacy:
        section["method_revision"] = METHOD_REVISIONS[stage]
    return section


#: the ``[field]`` settings each of its routes reads (:func:`~railsusp.pipeline_field.
#: field_stage`); the cut's settings are also in the recording's state
_FIELD_ROUTES = {
    "recording": (
        "recording",
        "channel_map",
        "line",
        "sections",
        "speed_tolerance",
        "min_length_m",
        "max_duration_s",
        "rate_hz",
    ),
    "measured": ("measured",),
    "truth": ("truth", "seed", "noise", "with_track", "track_noise_mm"),
}


def _field_settings(config: PipelineConfig, legacy: bool) -> dict:
    """The ``[field]`` settings of the route the field stage takes (a long run's cut, a
    measured folder's copy, or synthetic recordings of the truth, in that order); all of
    them for ``legacy``."""
    f = config.field
    if legacy:
        return f.model_dump()
    route = "recording" if f.recording else "measured" if f.measured else "truth"
    return {"route": route, **f.model_dump(include=set(_FIELD_ROUTES[route]))}


def _estimate_section(config: PipelineConfig, legacy: bool = False) -> dict:
    """The estimate stage's inputs: its settings (without a held_prior, and with
    channel_gains and expected_draws off, the section hashes as before those existed, so
    runs stay up to date; ``expected_generations`` counts only with expected draws, and
    then always: before 2026-11-29 expected draws meant NSGA-II's generations, now a polish
    after them, so such a run estimates again);
    on time-aligned forces also the route of NSGA-II's estimate, which since 2026-11-28
    takes the geometry error's bias off its choice where the recordings state their
    accuracy, so that such a run estimates again; with ``correction_slopes`` the trust
    region's check (since 2026-11-29 the simulator checks each first-order step's point, and
    the box resizes), so that such a run estimates again; with Broyden's update also its
    step floor (since stop 53 no update across a step under it), for the same reason; with
    a refinement's ``held_prior`` where its parameters are held (since stop 78 at the
    range's centre, not nominal), for the same reason. Without the refinement, its
    settings (``refine_*``, ``held_prior``) are left out since
    stop 66; ``legacy``: the section as hashed before."""
    e = config.estimate
    optional = (
        "held_prior",
        "channel_gains",
        "expected_draws",
        "simulator_corrections",
        "correction_slopes",
    )
    unset = {k for k in optional if not getattr(e, k)}
    if e.slope_update == "simulated":  # as before the setting existed
        unset.add("slope_update")
    if not e.expected_draws:
        unset.add("expected_generations")
    if not e.preview_generations:  # as before the setting existed
        unset |= {"preview_generations", "preview_s"}
    if not e.refine and not legacy:  # the refinement's settings, read by it alone
        unset |= {"refine_evaluations", "refine_screen", "refine_starts", "held_prior"}
    section = e.model_dump(exclude=unset or None)
    if e.statistic == "aligned":
        section["nsga_geometry"] = (
            "expected-forces polish" if e.expected_draws else "first SIMEX step"
        )
    if e.refine and e.held_prior and not legacy:  # since stop 78 held at its centre, not
        # at nominal (HeldPrior.held_at_si): such a run estimates again
        section["held_prior_held_at"] = "centre of the range"
    if e.correction_slopes:
        section["correction_steps"] = "checked by the simulator's cost (trust region)"
        if e.slope_update == "broyden":  # the floor came after Broyden's update: estimate again
            section["broyden_min_step"] = BROYDEN_MIN_STEP
    return section


def _surrogate_section(config: PipelineConfig) -> dict:
    """The surrogate stage's inputs: its settings (without ``pretrained`` when unset, so a
    run made before the option existed stays up to date); with a network set only what
    is used, the model and the set (its manifest and the bytes of its networks), so that
    another set under the same name copies again and training settings change nothing."""
    s = config.surrogate
    if s.pretrained is None:
        return s.model_dump(exclude={"pretrained"})
    from railsusp.surrogate.pretrained import read_network_set, resolve_network_set, set_hash

    ns = read_network_set(resolve_network_set(s.pretrained))
    return {"model": s.model, "pretrained": s.pretrained, "network_set": set_hash(ns)}
