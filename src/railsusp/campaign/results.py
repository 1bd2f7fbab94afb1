"""Reading a campaign run directory back: design, tracks, features and series."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from pydantic import ValidationError

from railsusp.campaign.batch_files import batch_done
from railsusp.campaign.design import (
    CHANNELS,
    CampaignConfig,
    CampaignError,
    batch_paths,
    read_meta,
    track_table,
)
from railsusp.errors import first_listed
from railsusp.store import read_parquet
from railsusp.vehicle.revision import mismatch

#: what to do about a campaign file that is missing or damaged: resumed, the campaign
#: simulates every batch that is not stored whole again
RESUME = "run the same `railsusp campaign` command again (it simulates such a batch again)"


def _read(path: Path) -> pd.DataFrame:
    """A table of a campaign folder, its pages' checksums verified: a damaged one is a
    one-line :class:`CampaignError` naming it and how to make it again."""
    return read_parquet(path, RESUME, error=CampaignError)


def _config_error(meta_path: Path, exc: ValidationError) -> str:
    """One line for a stored configuration that does not validate. Wagon-data fields that
    the stored copy lacks mean an older model (a field added since, e.g. the centre bowl's
    rocking stiffness): its simulations are of that model, so the campaign is to be re-run,
    not repaired."""
    errors = exc.errors()
    missing = [".".join(map(str, e["loc"][1:])) for e in errors if e["type"] == "missing"]
    if missing and len(missing) == len(errors) and all(e["loc"][0] == "wagon" for e in errors):
        return (
            f"{meta_path} was simulated with an older wagon model (its wagon data lacks "
            f"{', '.join(missing)}): re-run the campaign into a new --out"
        )
    first = str(exc).strip().splitlines()[0]
    return f"{meta_path} is corrupt: its configuration does not validate ({first})"


def revision_problem(revision: object, where: Path) -> str | None:
    """One line saying that the campaign at ``where`` was simulated with other force laws
    than this railsusp's (its recorded ``revision``; none recorded: made before revisions
    were, so older), in the words of :func:`railsusp.vehicle.revision.made_with`, and what
    to do; None where ``revision`` is this railsusp's. A newer revision is a newer
    railsusp's campaign, which is not to be simulated again as outdated."""
    again = "run the campaign again into a new --out (or with --force) before using its results"
    said = mismatch(revision, again)
    return None if said is None else f"{where} was simulated with {said}"


def stored_config(meta: dict, meta_path: Path) -> CampaignConfig:
    """The configuration a ``campaign.json`` holds, validated and checked against the hash
    its batches are stamped with (an edited configuration would lend them another design);
    one-line :class:`CampaignError` otherwise. A hash that differs where the campaign
    records other force laws than this railsusp's (or none) is said as that, not as a
    hand edit: a revision that added wagon-data fields with defaults (2026-11-30.2) changed
    the hash of every older campaign, and ``train``, ``sensitivity`` and a resumed
    ``campaign`` asked "edited by hand?" of folders nobody edited (the upgrade audit's M3),
    never reaching :func:`require_complete`'s revision check."""
    try:
        config = CampaignConfig.model_validate(meta["config"])
    except ValidationError as exc:
        raise CampaignError(_config_error(meta_path, exc)) from None
    except (KeyError, TypeError, ValueError) as exc:
        first = str(exc).strip().splitlines()[0]
        raise CampaignError(
            f"{meta_path} is corrupt: its configuration does not validate ({first})"
        ) from None
    if config.hash() != meta.get("config_hash"):  # its batches are stamped with the hash
        problem = revision_problem(meta.get("model_revision"), meta_path)
        if problem is not None:  # the force laws changed, and the configuration with them
            raise CampaignError(problem)
        raise CampaignError(
            f"{meta_path}: its configuration is not the one its batches were simulated "
            f"with (hash {config.hash()}, stamped {meta.get('config_hash')}): "
            "edited by hand? Run the campaign again into a new --out"
        )
    return config


class Campaign:
    """A campaign run directory opened for reading."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        meta_path = self.path / "campaign.json"
        if not meta_path.exists():
            raise CampaignError(f"{self.path} is not a campaign run directory (no campaign.json)")
        self.meta = read_meta(meta_path)
        self.config = stored_config(self.meta, meta_path)

    @property
    def complete(self) -> bool:
        return "completed" in self.meta

    @property
    def model_revision(self) -> str | None:
        """The force laws' revision the campaign was simulated with (None: not recorded,
        made before 2026-11-30)."""
        got = self.meta.get("model_revision")
        return None if got is None else str(got)

    def design(self) -> pd.DataFrame:
        return _read(self.path / "design.parquet")

    def tracks(self, condition: str) -> pd.DataFrame:
        """The track of every sample of one condition (seed, FRA class, radius, cant),
        recomputed from the configuration (``tracks.parquet`` holds the same)."""
        cond = next((c for c in self.config.conditions if c.name == condition), None)
        if cond is None:
            raise CampaignError(f"no condition {condition!r} in {self.path}")
        return track_table(self.config, cond)

    def features(self) -> pd.DataFrame:
        """All tidy features (complete or not: read from the finished batches)."""
        p = self.path / "features.parquet"
        if p.exists():
            return _read(p)
        files = sorted((self.path / "batches").glob("*/batch-*.features.parquet"))
        done = [f for f in files if f.with_name(f.name.replace(".features", "")).exists()]
        if not done:
            raise CampaignError(f"{self.path}: no finished batch yet")
        return pd.concat([_read(f) for f in done], ignore_index=True)

    def feature_matrix(
        self, condition: str, quantity: str, statistic: str, features: pd.DataFrame | None = None
    ) -> pd.Series:
        """One feature for all samples (index sample_id); NaN for failed samples.
        ``features``: the table of :meth:`features` when already read (many lookups)."""
        f = self.features() if features is None else features
        sel = f[(f.condition == condition) & (f.quantity == quantity) & (f.statistic == statistic)]
        if sel.empty:
            raise CampaignError(f"no feature {quantity}/{statistic} in condition {condition!r}")
        return sel.set_index("sample_id")["value"].sort_index()

    def series(self, condition: str) -> tuple[np.ndarray, np.ndarray]:
        """(sample_ids, series (n, channels, n_t)) of one condition from the finished batches."""
        return read_series(self.path, condition)


def read_series(root: Path, condition: str) -> tuple[np.ndarray, np.ndarray]:
    """(sample_ids, series (n, channels, n_t)) of one condition from the finished batches
    under ``root/batches`` (a run directory, or its nominal twins), each file's pages'
    checksums verified (a damaged batch is a one-line error, not changed numbers). Whether
    every batch of the design is there is :func:`incomplete`'s question."""
    folder = root / "batches" / condition
    files = sorted(f for f in folder.glob("batch-*.parquet") if ".features" not in f.name)
    if not files:
        raise CampaignError(f"{root}: no series for condition {condition!r}")
    df = pd.concat([_read(f) for f in files], ignore_index=True)
    ids = np.unique(df["sample_id"].to_numpy())
    n_t = int(df["step"].max()) + 1
    arr = df[list(CHANNELS)].to_numpy().reshape(len(ids), n_t, len(CHANNELS))
    return ids, arr.transpose(0, 2, 1)


def require_complete(campaign: Campaign) -> Campaign:
    """``campaign`` if every batch of it is stored and it was simulated with this railsusp's
    force laws; a one-line error saying how to finish it, or to simulate it again, otherwise
    (a surrogate trained on part of a campaign would silently see fewer runs; one trained on
    a campaign of other force laws learnt another model: the interrupt/resume audit of stop
    60 trained on one silently). A campaign that states no revision (made before
    2026-11-30) is of older force laws than any revision, and refused too: it was only
    warned of, and the surrogates trained on it were then refused by ``estimate
    --surrogate`` (:func:`railsusp.estimate.forces.check_force_laws`) after the training."""
    problem = revision_problem(campaign.model_revision, campaign.path)
    if problem is not None:  # first: finishing it would be refused (railsusp campaign)
        raise CampaignError(problem)
    missing = incomplete(campaign)
    if missing:
        raise CampaignError(missing)
    return campaign


def incomplete(
    campaign: Campaign, finish: str = "run the same `railsusp campaign` command again"
) -> str | None:
    """None where every batch of ``campaign``'s design is stored (both files, footers that
    read, this configuration's stamp: :func:`~railsusp.campaign.batch_files.batch_done`
    without reading the pages, which the readers verify) and the campaign finished, else
    one line saying how many are and how to ``finish`` it. ``completed`` in campaign.json
    alone is not trusted: a batch lost or damaged since (a copy of part of the folder) left
    it "complete", and a surrogate trained on 38 of its 40 series without a word (the
    run-directory store audit); such batches are named."""
    cfg = campaign.config
    stamp = cfg.hash()
    missing = [
        batch_paths(campaign.path, c.name, b)[0]
        for c in cfg.conditions
        for b in range(cfg.n_batches)
        if not batch_done(campaign.path, c.name, b, stamp, pages=False)
    ]
    if campaign.complete and not missing:
        return None
    total = cfg.n_batches * len(cfg.conditions)
    if not campaign.complete:
        return (
            f"{campaign.path}: the campaign is incomplete ({total - len(missing)} of "
            f"{total} batches); {finish} to finish it"
        )
    names = first_listed([p.relative_to(campaign.path).as_posix() for p in missing], 3)
    return (
        f"{campaign.path}: the campaign is incomplete: {len(missing)} of its {total} batches "
        f"{'is' if len(missing) == 1 else 'are'} missing or damaged ({names}); "
        f"{finish} to simulate {'it' if len(missing) == 1 else 'them'} again"
    )


def failed_runs(path: str | Path) -> pd.DataFrame:
    """The failed simulations (derailed, diverged) of a run directory's finished batches:
    one row per condition and sample, with its status code."""
    return failed_of(Campaign(path).features())


def failed_of(feats: pd.DataFrame) -> pd.DataFrame:
    """:func:`failed_runs` of a campaign's features already read."""
    failed = feats[feats["status"] != 0]
    return (
        failed[["condition", "sample_id", "status"]]
        .drop_duplicates()
        .sort_values(["condition", "sample_id"])
        .reset_index(drop=True)
    )


def load_campaign(path: str | Path) -> Campaign:
    """Open a campaign run directory."""
    return Campaign(path)
