"""Train / validation / test split of a campaign by track and by parameter set.

A surrogate's held-out error means something only if the held-out samples are new to it in
everything it is meant to generalise over. Samples are therefore grouped before they are
split: two samples that share an irregularity seed (in any condition: the same seed and
class give the same irregularities) or an identical parameter set fall in the same group,
and whole groups go to train, validation or test. With ``independent_seeds`` every test
sample then runs on a track no network saw, with parameters no network saw, in every
condition (the split is one for the whole campaign, not one per condition). A campaign on
common random numbers (one track for all samples) can only hold out parameter sets; the
split says so (``held_out_tracks``).

The split is stored in the run directory, ``RUN/splits/seed-<N>.json`` (atomic write), with
the campaign's configuration hash, so that training, comparison and evaluation all use the
same one and a later reader can check which runs a network never saw.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsusp.campaign import Campaign
from railsusp.errors import RailsuspInputError
from railsusp.integrity import file_readable
from railsusp.store import read_json, write_json

log = logging.getLogger("railsusp.surrogate")

FORMAT = "railsusp-split/1"
PARTS = ("train", "val", "test")
DEFAULT_FRACTIONS = (0.7, 0.15, 0.15)


@dataclass(frozen=True)
class Split:
    """Sample ids of each part, and how they were drawn."""

    train: np.ndarray
    val: np.ndarray
    test: np.ndarray
    seed: int
    fractions: tuple[float, float, float]
    held_out_tracks: bool
    campaign_hash: str = ""

    def part(self, name: str) -> np.ndarray:
        if name not in PARTS:
            raise ValueError(f"split part {name!r}: accepted {', '.join(PARTS)}")
        return getattr(self, name)

    def positions(self, sample_ids: np.ndarray, name: str) -> np.ndarray:
        """Positions in ``sample_ids`` (one condition's finished samples) of a part's ids."""
        return np.flatnonzero(np.isin(np.asarray(sample_ids), self.part(name)))

    @property
    def held_out(self) -> str:
        """What the test samples hold out, for tables."""
        return "tracks and parameters" if self.held_out_tracks else "parameters (one track)"

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "seed": self.seed,
            "fractions": list(self.fractions),
            "held_out_tracks": self.held_out_tracks,
            "campaign_hash": self.campaign_hash,
            **{p: [int(i) for i in self.part(p)] for p in PARTS},
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> Split:
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise RailsuspInputError(f"not a railsusp split (format {FORMAT} expected)")
        parts = {p: np.asarray(doc[p], dtype=np.int64) for p in PARTS}
        split = cls(
            **parts,
            seed=int(doc["seed"]),
            fractions=tuple(float(f) for f in doc["fractions"]),
            held_out_tracks=bool(doc["held_out_tracks"]),
            campaign_hash=str(doc.get("campaign_hash", "")),
        )
        check_disjoint(split)
        return split


def check_disjoint(split: Split) -> None:
    """Refuse a split whose parts share a sample."""
    for i, a in enumerate(PARTS):
        for b in PARTS[i + 1 :]:
            both = np.intersect1d(split.part(a), split.part(b))
            if both.size:
                raise RailsuspInputError(
                    f"split parts {a} and {b} share samples {both[:5].tolist()}"
                )


def check_covers(split: Split, sample_ids: np.ndarray, path: Path) -> None:
    """Refuse, in one line as another corrupt split, a split stored at ``path`` that is not
    a partition of the campaign's samples ``sample_ids``: a sample it names that the
    campaign does not have, one named twice in a part, or one in no part. (A split edited
    by hand trained and scored on what it said: an unknown sample was passed over, and one
    left out of every part was dropped without a word, the test runs one fewer.)"""
    named = np.concatenate([split.part(p) for p in PARTS])
    unknown = np.setdiff1d(named, sample_ids)
    values, counts = np.unique(named, return_counts=True)
    twice = values[counts > 1]
    missing = np.setdiff1d(sample_ids, named)
    lo, hi = (int(sample_ids.min()), int(sample_ids.max())) if sample_ids.size else (0, -1)
    why = (
        f"samples {unknown[:5].tolist()} are not the campaign's, whose samples are {lo} to {hi}"
        if unknown.size
        else f"samples {twice[:5].tolist()} are named twice in one part"
        if twice.size
        else f"samples {missing[:5].tolist()} are in no part"
        if missing.size
        else ""
    )
    if why:
        raise RailsuspInputError(
            f"{path}: corrupt split ({why}); delete it to draw the split again"
        )


def track_keys(t: pd.DataFrame) -> list[tuple]:
    """What makes each sample's track of one condition (its tracks table: seed,
    irregularity_class, curve_radius_m, cant_mm): its irregularity seed where it has
    irregularities (class -1: perfect track), else its layout, the class, radius and cant
    (the seed then shapes nothing: on perfect track every seed ran the same track, and the
    split said it held 12 tracks out; stop 78's hunt)."""
    n = len(t)
    cls = t["irregularity_class"].to_numpy() if "irregularity_class" in t else np.zeros(n)
    layout = [c for c in ("irregularity_class", "curve_radius_m", "cant_mm") if c in t]
    rows = t[layout].to_numpy(dtype=float) if layout else np.zeros((n, 0))
    seeds = t["seed"].to_numpy()
    return [
        ("seed", int(s)) if c != -1 else ("layout", *np.nan_to_num(r, nan=-1.0).tolist())
        for s, c, r in zip(seeds, cls, rows, strict=True)
    ]


def distinct_tracks(t: pd.DataFrame, sample_ids: np.ndarray | None = None) -> int:
    """The number of distinct tracks (:func:`track_keys`) among ``sample_ids`` (all: None)
    of one condition's tracks table."""
    if sample_ids is not None:
        t = t[t["sample_id"].isin(np.asarray(sample_ids))]
    return len(set(track_keys(t)))


def condition_tracks(campaign: Campaign, condition: str, sample_ids: np.ndarray) -> int:
    """The number of distinct tracks the campaign's ``sample_ids`` ran on in ``condition``
    (:func:`distinct_tracks`; one on a measured track geometry)."""
    cond = next(c for c in campaign.config.conditions if c.name == condition)
    if cond.track_geometry is not None:
        return 1
    return distinct_tracks(campaign.tracks(condition), sample_ids)


def _groups(design: pd.DataFrame, tracks: list[pd.DataFrame]) -> np.ndarray:
    """Group label per design row: rows sharing a seed (any condition's tracks table, same
    sample order; a condition whose samples all share one seed is common random numbers
    and joins nothing) or an identical parameter row are joined (union-find)."""
    n = len(design)
    parent = np.arange(n)

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return int(i)

    def join_equal(keys: list[Any]) -> None:
        first: dict[Any, int] = {}
        for i, k in enumerate(keys):
            j = first.setdefault(k, i)
            if j != i:
                parent[find(i)] = find(j)

    cols = [c for c in design.columns if c != "sample_id"]
    join_equal([tuple(r) for r in design[cols].to_numpy().tolist()])
    track_pos: dict[tuple, int] = {}
    for t in tracks:
        keys = track_keys(t)
        if n > 1 and len(set(keys)) == 1:
            continue  # common random numbers: the one track is in every part
        for i, key in enumerate(keys):
            j = track_pos.setdefault(key, i)
            if j != i:
                parent[find(i)] = find(j)
    return np.array([find(i) for i in range(n)])


def split_by_track_and_parameters(
    design: pd.DataFrame,
    tracks: list[pd.DataFrame],
    *,
    seed: int = 0,
    fractions: tuple[float, float, float] = DEFAULT_FRACTIONS,
) -> Split:
    """Split the design's samples so that no irregularity seed and no parameter set is in
    two parts. ``tracks``: the per-sample track table of each condition (same sample order
    as ``design``). Groups are shuffled (seeded) and dealt to test, then validation, until
    each holds its fraction of the samples; the rest train."""
    fr = tuple(float(f) for f in fractions)
    if len(fr) != 3 or any(f <= 0 for f in fr) or abs(sum(fr) - 1) > 1e-9:
        raise RailsuspInputError(
            f"split fractions {fractions}: accepted three positive numbers summing to 1"
        )
    ids = design["sample_id"].to_numpy()
    for t in tracks:
        if not np.array_equal(t["sample_id"].to_numpy(), ids):
            raise ValueError("every track table must list the design's samples in its order")
    labels = _groups(design, tracks)
    uniq = np.unique(labels)
    if len(uniq) < 3:
        raise RailsuspInputError(
            f"{len(ids)} samples form {len(uniq)} distinct track/parameter groups: at least 3 "
            "are needed to split train, validation and test"
        )
    order = np.random.default_rng(seed).permutation(uniq)
    n = len(ids)
    want = {"test": max(1, round(fr[2] * n)), "val": max(1, round(fr[1] * n))}
    parts: dict[str, list[int]] = {"train": [], "val": [], "test": []}
    k = 0
    reserve = {"test": 2, "val": 1}  # groups kept back for the parts dealt after
    for name in ("test", "val"):
        while len(order) - k > reserve[name] and (not parts[name] or len(parts[name]) < want[name]):
            parts[name].extend(np.flatnonzero(labels == order[k]).tolist())
            k += 1
    for g in order[k:]:
        parts["train"].extend(np.flatnonzero(labels == g).tolist())
    held_out_tracks = bool(tracks) and all(distinct_tracks(t) > 1 for t in tracks)
    split = Split(
        *(np.sort(ids[parts[p]]) for p in PARTS),
        seed=int(seed),
        fractions=fr,
        held_out_tracks=held_out_tracks,
    )
    check_disjoint(split)
    return split


def split_path(run: str | Path, seed: int = 0) -> Path:
    return Path(run) / "splits" / f"seed-{int(seed)}.json"


def save_split(path: str | Path, split: Split) -> Path:
    """Write a split as JSON, atomically."""
    return write_json(path, split.to_dict())


def load_split(path: str | Path) -> Split:
    """Read a split written by :func:`save_split` (one-line error if it is not one)."""
    try:
        return Split.from_dict(read_json(path))
    except (KeyError, TypeError, ValueError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise RailsuspInputError(f"{path}: corrupt split ({first})") from None


def own_split(meta: dict[str, Any], campaign: Campaign, where: str, why: str) -> Split:
    """The split a saved network (its ``meta``, saved at ``where``) was trained with, of the
    campaign it was trained on: refused in one line, ending with ``why`` the network's own
    campaign is needed, for any other ``campaign`` (its test runs may be the network's
    training runs)."""
    if meta.get("campaign_hash") != campaign.config.hash():
        raise RailsuspInputError(
            f"{where}: trained on campaign {meta.get('campaign')!r}, not on {campaign.path}; {why}"
        )
    return campaign_split(campaign, int(meta.get("split", {}).get("seed", 0)))


def saltelli_blocks(campaign: Campaign) -> np.ndarray | None:
    """The base sample of each row of a Saltelli (``sobol``) design, None for another
    design. SALib lays the rows out in blocks of D + 2 (2D + 2 with second order): A_j, the
    AB_ij (A_j with parameter i from B_j), then B_j. An AB_ij whose parameter i is not a
    network input has A_j's inputs exactly, on the same track with common random numbers:
    split apart, 13 of 29 test samples of a 16-sample campaign were training rows (the
    split audit of stop 60). The whole block goes to one part."""
    if campaign.config.design != "sobol":
        return None
    per_base = campaign.config.n_runs // campaign.config.samples
    return np.arange(campaign.config.n_runs) // per_base


def _splits_blocks(split: Split, campaign: Campaign) -> bool:
    """Whether every Saltelli block lies in one part (True for other designs)."""
    blocks = saltelli_blocks(campaign)
    if blocks is None:
        return True
    part = np.full(blocks.size, -1)
    for k, name in enumerate(PARTS):
        ids = split.part(name)
        part[ids[ids < blocks.size]] = k
    frame = pd.DataFrame({"block": blocks, "part": part})
    return bool((frame.groupby("block")["part"].nunique() <= 1).all())


def campaign_split(
    campaign: Campaign,
    seed: int = 0,
    fractions: tuple[float, float, float] = DEFAULT_FRACTIONS,
) -> Split:
    """The campaign's split for ``seed``: read from ``RUN/splits/seed-<N>.json``, or drawn
    by :func:`split_by_track_and_parameters` and stored there on first use. A stored split
    of another campaign configuration or other fractions is refused; one that does not read
    as JSON (a copy cut short) is drawn again, as it was (the draw is seeded)."""
    path = split_path(campaign.path, seed)
    chash = campaign.config.hash()
    if path.exists() and not file_readable(path):
        log.warning("%s is cut short or damaged; the split is drawn again", path)
    elif path.exists():
        split = load_split(path)
        if split.campaign_hash != chash:
            raise RailsuspInputError(
                f"{path} was drawn for another campaign configuration (hash "
                f"{split.campaign_hash}, now {chash}); delete it to draw a new split"
            )
        check_covers(split, campaign.design()["sample_id"].to_numpy(), path)
        if not np.allclose(split.fractions, fractions):
            raise RailsuspInputError(
                f"{path} holds fractions {list(split.fractions)}, asked for {list(fractions)}; "
                "use another split seed or delete the file"
            )
        if not _splits_blocks(split, campaign):
            log.warning(
                "%s splits the rows of a Saltelli base sample between parts (drawn before "
                "stop 60): drawn again, each base sample's rows in one part",
                path,
            )
        else:  # its flag as today's rule reads it (on perfect track every seed is one
            # track: a split drawn before stop 78 said it held tracks out)
            return replace(split, held_out_tracks=_holds_out_tracks(campaign))
    # a parameter set is what a network sees of it: the sampled (key) parameters
    design = campaign.design()[["sample_id", *campaign.config.parameters]]
    blocks = saltelli_blocks(campaign)
    if blocks is not None:  # a Saltelli design: each base sample's rows together
        design = design[["sample_id"]].assign(saltelli_block=blocks)
    synthesised = [c for c in campaign.config.conditions if c.track_geometry is None]
    tracks = [campaign.tracks(c.name) for c in synthesised]
    split = split_by_track_and_parameters(design, tracks, seed=seed, fractions=fractions)
    # the flag by the campaign's rule: a measured track is the same in every part
    split = Split(
        split.train, split.val, split.test, split.seed, split.fractions,
        _holds_out_tracks(campaign), chash,
    )  # fmt: skip
    save_split(path, split)
    return split


def _holds_out_tracks(campaign: Campaign) -> bool:
    """Whether a split's test runs are on tracks its other parts do not hold, by the
    rule of :func:`split_by_track_and_parameters` (every condition synthesised, each of
    more than one track: :func:`distinct_tracks`)."""
    conds = campaign.config.conditions
    return all(c.track_geometry is None for c in conds) and all(
        distinct_tracks(campaign.tracks(c.name)) > 1 for c in conds
    )
