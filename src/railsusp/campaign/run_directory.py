"""A campaign's run directory before its batches run: made, or re-opened to resume, and
refused where it holds another configuration's results (another hash, other force laws,
an edited track file, a hand-edited design) unless ``--force`` discards them; a folder
whose ``campaign.json`` is gone or damaged keeps the batches stamped as this
configuration's. Also the stale temporaries a killed campaign left in its own files.
Kept apart from the batch loop (:mod:`railsusp.campaign.run`): what may be resumed and what
must be discarded is decided here, once, before anything is simulated."""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import pandas as pd

from railsusp.campaign.batch_files import (
    batch_count,
    batch_stamp,
    foreign_batches,
    stamped_batch_size,
)
from railsusp.campaign.config_changes import config_changes
from railsusp.campaign.design import (
    CHANNELS,
    CampaignConfig,
    CampaignError,
    batch_paths,
    make_design,
    read_meta,
    track_table,
)
from railsusp.campaign.results import stored_config
from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_output_folder
from railsusp.provenance import provenance
from railsusp.store import (
    parquet_readable,
    read_parquet,
    remove_stale_temporaries,
    write_json,
    write_parquet,
)
from railsusp.vehicle.revision import Standing, made_with, newer_remedy, standing, this_revision
from railsusp.vehicle.track_geometry import geometry_digests

log = logging.getLogger("railsusp.campaign")


def _keep_own_batches(out: Path, config: CampaignConfig, problem: str, force: bool) -> None:
    """A campaign folder whose ``campaign.json`` is gone or damaged (``problem``): its
    batches stamped with this configuration are kept and the files made from the design
    written again (design, tracks, features); what was made from its batches (their
    sensitivity, splits and twins) stays where every batch is this configuration's.
    Other batches are another configuration's, or unknown, and are discarded with
    ``force`` only."""
    foreign, own = foreign_batches(out, config.hash())
    if foreign and not force:
        n = len(foreign)
        raise CampaignError(
            f"{problem}, and {n} of its batches {'is' if n == 1 else 'are'} not "
            "stamped as this configuration's (another campaign's or other force laws', or "
            "written before batches were stamped); use a new --out, or --force to discard them"
            + (f" ({batch_count(own)} of this configuration would be kept)" if own else "")
        )
    made = [n for n in ("features.parquet", *_FROM_BATCHES) if (out / n).exists()]
    if not own and made and not force:  # made from batches no longer there: whose?
        raise CampaignError(
            f"{problem}, and it holds {', '.join(made)} but no batch of this configuration "
            "(another campaign's results); use a new --out, or --force to discard them"
        )
    for files in foreign:
        for f in files:
            f.unlink()
    if foreign or not own:  # what was made from other batches, or from unknown ones, goes
        _remove(out, _FROM_BATCHES)
    _remove(out, _FROM_DESIGN)
    if own:
        log.warning("%s: kept %s stamped as this configuration's", problem, batch_count(own))


#: what a campaign folder holds that follows from its design alone (written again from it)
_FROM_DESIGN = ("features.parquet", "design.parquet", "tracks.parquet")
#: what other work made from its batches
_FROM_BATCHES = (
    "sensitivity",
    "splits",
    "nominal",  # the nominal twins (railsusp.campaign.twins) of the old design
    "perturbed",  # and its perturbed twins (railsusp.campaign.perturbed)
    "surrogates",  # the networks trained on its batches (railsusp train)
)


def _remove(out: Path, names: tuple[str, ...]) -> None:
    """Remove these files or folders of ``out`` where they exist."""
    for name in names:
        p = out / name
        if p.is_dir():
            shutil.rmtree(p)
        elif p.exists():
            p.unlink()


def _discard(out: Path) -> None:
    """Remove the results of a campaign of another configuration."""
    _remove(out, ("batches", *_FROM_DESIGN, *_FROM_BATCHES))


def _edited_track_files(meta: dict, files: dict[str, str]) -> list[str]:
    """The measured track files (``files``: their contents' digests now) whose contents are
    not those ``campaign.json`` (``meta``) records; none recorded (before stop 60): taken
    as now."""
    was = meta.get("track_geometry_files", files)
    return sorted(k for k in files if was.get(k) != files[k])


def _geometry_files(config: CampaignConfig) -> dict:
    """``campaign.json``'s record of the measured track files' contents (none without)."""
    files = geometry_digests(config.conditions)
    return {"track_geometry_files": files} if files else {}


def prepare_run_directory(config: CampaignConfig, out: Path, force: bool) -> pd.DataFrame:
    """Create or re-open a run directory; refuse a different configuration unless forced."""
    check_output_folder(out)
    meta_path = out / "campaign.json"
    if meta_path.exists():
        try:
            meta = read_meta(meta_path)
            stored_config(meta, meta_path)  # valid, and the one its batches are stamped with
        except RailsuspInputError as exc:  # damaged: the batches' stamps say whose they are
            _keep_own_batches(out, config, str(exc), force)
        else:
            revision = meta.get("model_revision", this_revision())  # unstated: older files
            if "model_revision" not in meta:
                log.warning(
                    "%s states no force-law revision (made before 2026-11-30): its batches "
                    "may be of other force laws; where its conditions run below 58 km/h or "
                    "with lead-ins under 40 m, start it again in a new --out",
                    meta_path,
                )
            if standing(revision) is Standing.NEWER:  # a newer railsusp's: never discarded
                raise CampaignError(
                    f"{out} holds a campaign simulated with {made_with(revision)}: "
                    f"{newer_remedy(revision)}, or use a new --out (--force does not discard "
                    "a newer railsusp's results)"
                )
            if revision != this_revision() and not force:  # its batches: other force laws
                raise CampaignError(
                    f"{out} holds a campaign simulated with {made_with(revision)}: use a new "
                    "--out, or --force to discard the old results (resumed, its batches would "
                    "mix the two)"
                )
            files = geometry_digests(config.conditions)
            edited = _edited_track_files(meta, files)
            if edited and meta.get("config_hash") == config.hash() and not force:
                raise CampaignError(
                    f"{out} holds a campaign simulated on other contents of its track geometry "
                    f"file(s) {', '.join(edited)} (edited since); use a new --out, or --force "
                    "to discard the old results"
                )
            if meta.get("config_hash") != config.hash() or revision != this_revision() or edited:
                if not force:
                    changes = config_changes(meta.get("config"), config)
                    raise CampaignError(
                        f"{out} holds a campaign with another configuration ("
                        + (f"{changes}; " if changes else "")
                        + f"hash {meta.get('config_hash')}, now {config.hash()}); use a new "
                        "--out, or --force to discard the old results"
                    )
                _discard(out)
            elif parquet_readable(out / "design.parquet", pages=True):
                stored = _stored_design(out, config)
                if stored is not None:  # it follows from the configuration
                    if files and "track_geometry_files" not in meta:  # made before stop 60:
                        # recorded now, so that a later edit is seen (the review of stop 60)
                        write_json(meta_path, {**meta, "track_geometry_files": files})
                    return stored
                if not force:  # its batches were simulated on one of the two: which?
                    raise CampaignError(
                        f"{out / 'design.parquet'} is not this configuration's design "
                        "(edited by hand, or made by another SciPy or SALib), so its batches "
                        "cannot be paired with their parameters; use a new --out, or --force "
                        "to start the campaign again"
                    )
                _discard(out)
            # (a design that is gone or does not read is made again below: it follows from
            # the configuration, as the batches that campaign.json vouches for do)
    elif any((out / sub).exists() for sub in ("batches", "features.parquet")):
        # results without the configuration that made them: only batches stamped with this
        # configuration are taken in (others would pair forces of one design with another's
        # parameters)
        _keep_own_batches(out, config, f"{out} holds campaign results but no campaign.json", force)
    design = make_design(config)
    write_parquet(out / "design.parquet", design)
    write_parquet(
        out / "tracks.parquet",
        pd.concat(
            [track_table(config, c).assign(condition=c.name) for c in config.conditions],
            ignore_index=True,
        ),
    )
    write_json(
        meta_path,
        {
            "kind": "railsusp campaign",
            "config_hash": config.hash(),
            "model_revision": this_revision(),
            "config": config.model_dump(mode="json"),
            **_geometry_files(config),
            "n_runs": config.n_runs,
            "n_batches": config.n_batches,
            "channels": list(CHANNELS),
            "created": provenance(),
        },
    )
    return design


def _stored_design(out: Path, config: CampaignConfig) -> pd.DataFrame | None:
    """``out``'s design where it is the one ``config`` makes (its batches are then paired
    with their parameters), else None (edited by hand, made by another SciPy or SALib)."""
    stored = read_parquet(out / "design.parquet")
    return stored if stored.equals(make_design(config)) else None


def stored_batch_size(config: CampaignConfig, out: Path) -> int | None:
    """The batch size of the campaign stored in ``out`` where it is ``config`` in everything
    but ``batch_size`` and its batches are kept as they are (simulated with this railsusp's
    force laws on the track files' present contents, from the design ``config`` makes, at
    least one of them whole); None where it is the same, or another campaign, or none, or
    one with nothing to keep (:func:`prepare_run_directory` then says what it does with
    it, and a campaign simulated again takes the batch size asked). Where ``campaign.json``
    is gone or does not read, the batches' own stamps decide (:func:`_stamped_batch_size`).

    The batch size groups the design's rows into stored files and nothing else: the same
    rows are simulated on the same tracks whatever it is. It is in the configuration's
    hash, which stamps every batch, so a campaign asked for again with another batch size
    was refused (or, with ``--force`` and in the pipeline, simulated again: hours for a
    fleet's campaign, to regroup the same results). Such a campaign is resumed in its
    stored batches instead (:func:`in_stored_batches`)."""
    meta_path = out / "campaign.json"
    if not meta_path.is_file():  # gone: its batches' stamps say whose they are
        return _stamped_batch_size(config, out)
    try:
        meta = read_meta(meta_path)
        stored = stored_config(meta, meta_path)
    except RailsuspInputError:  # damaged: likewise
        return _stamped_batch_size(config, out)
    if stored.batch_size == config.batch_size:
        return None
    if meta.get("model_revision", this_revision()) != this_revision():  # its own refusal
        return None
    if stored.model_copy(update={"batch_size": config.batch_size}).hash() != config.hash():
        return None
    if _edited_track_files(meta, geometry_digests(config.conditions)):  # discarded
        return None
    if foreign_batches(out, stored.hash())[1] == 0:  # nothing stored whole: nothing to keep
        return None
    design = out / "design.parquet"
    if parquet_readable(design, pages=True) and _stored_design(out, stored) is None:
        return None  # paired with another design's parameters: discarded
    return stored.batch_size


def _stamped_batch_size(config: CampaignConfig, out: Path) -> int | None:
    """Where ``campaign.json`` is gone or damaged: the batch size of the batches stored, if
    they are ``config``'s in another batch size (None otherwise). A condition's first batch
    says it: its batch-size stamp (since stop 69), or else, where the condition has a second
    batch, its samples (the first batch holds a whole batch's). Its configuration stamp (the
    hash, which holds the batch size) says whether ``config`` in that batch size made it.
    A campaign of one batch per condition written before the batch-size stamp keeps its
    batch size unread (any size above its samples makes the same batch): its batches count
    as another configuration's, as they did before."""
    for cond in config.conditions:
        first = batch_paths(out, cond.name, 0)[1]  # the features file: a row per statistic
        stamp = batch_stamp(first)
        if stamp is None:
            continue
        size = stamped_batch_size(first)
        if size is None:
            if not batch_paths(out, cond.name, 1)[1].is_file():
                continue
            try:
                size = int(read_parquet(first, columns=["sample_id"])["sample_id"].nunique())
            except RailsuspInputError:
                continue
        if size == config.batch_size:
            return None
        if config.model_copy(update={"batch_size": size}).hash() != stamp:
            return None
        # kept only where a batch is kept: whole, of this railsusp's force laws (which the
        # stamp does not hold), as where campaign.json reads (the review of stop 68)
        return size if foreign_batches(out, stamp)[1] > 0 else None
    return None


def in_stored_batches(config: CampaignConfig, out: Path) -> CampaignConfig:
    """``config``, with the batch size of the campaign stored in ``out`` where that
    campaign is ``config`` in everything else (:func:`stored_batch_size`), said in a
    warning: its batches are kept and the rest run in the same grouping."""
    kept = stored_batch_size(config, out)
    if kept is None:
        return config
    log.warning(
        "%s holds this campaign in batches of %d: resumed in them (batch_size %d groups the "
        "same simulations otherwise; it applies to a new --out)",
        out,
        kept,
        config.batch_size,
    )
    return config.model_copy(update={"batch_size": kept})


def remove_campaign_temporaries(out: Path) -> None:
    """The temporaries a campaign killed while writing left (:func:`~railsusp.store.
    remove_stale_temporaries`): of its own files at the top of ``out`` and of its batches in
    ``out/batches/<condition>/``, the folders the campaign's lock keeps to it. The rest of
    the folder is other work's (a network training under ``surrogates/`` saves its
    checkpoint through a temporary of its own), and is not entered."""
    remove_stale_temporaries(out, targets=("campaign.json", *_FROM_DESIGN))
    batches = out / "batches"
    for folder in sorted(batches.iterdir()) if batches.is_dir() else []:
        if folder.is_dir() and not folder.is_symlink():
            remove_stale_temporaries(folder)
