"""A surrogate trained on a campaign's runs and saved as a bundle
(``train_surrogate(run, condition)``, under ``RUN/surrogates/<kind>/<condition>/``): the
conditions, window and feature checks, the split by track and parameters, warm starts from
another network, the training and the record correction."""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from railsusp.errors import RailsuspInputError
from railsusp.store import put_back_aside, read_json
from railsusp.surrogate.bundle import Surrogate, load
from railsusp.surrogate.correction import MIN_RUNS
from railsusp.surrogate.data import Normaliser, load_series
from railsusp.surrogate.features import DEFAULT_TRACK_CHANNELS, FeatureSpec
from railsusp.surrogate.keys import key_parameters
from railsusp.surrogate.models import (
    SEQUENCE_KINDS,
    NetConfig,
    build_network,
    default_window,
)
from railsusp.surrogate.pairs import TwinRuns, load_twins
from railsusp.surrogate.refit import fit_record_correction
from railsusp.surrogate.split import Split, campaign_split, condition_tracks
from railsusp.surrogate.train import TrainConfig, sampler_for, train_network
from railsusp.surrogate.training_scope import family_of
from railsusp.variation import assumed_parameters

log = logging.getLogger("railsusp.surrogate")


def check_conditions(campaign, conditions: Sequence[str] | None) -> list[str]:
    """The campaign's conditions to train on (``None``: all of them), each checked before any
    training: a condition not in the campaign was found by the loop over them, after the
    conditions before it had been trained (and, by ``compare``, their figures drawn)."""
    names = [c.name for c in campaign.config.conditions]
    if conditions is None:
        return names
    chosen = list(conditions)
    bad = [c for c in chosen if c not in names]
    if bad or not chosen:
        raise RailsuspInputError(
            f"conditions {', '.join(repr(c) for c in bad) or '(none)'}: accepted one or more "
            f"of the campaign's {', '.join(names)}"
        )
    twice = sorted({c for c in chosen if chosen.count(c) > 1})
    if twice:
        raise RailsuspInputError(f"conditions {', '.join(twice)}: given twice")
    return chosen


def longest_window(kind: str, n_steps: int, train: TrainConfig | None = None) -> int:
    """The longest window (the washout of a sequence network) a kind trains with on series of
    ``n_steps`` steps: fewer steps than the series, and for a sequence network fewer than its
    training chunks (``train.chunk_steps``), whose first ``washout`` steps leave the loss."""
    if kind in SEQUENCE_KINDS:
        return min(n_steps, (train or TrainConfig()).chunk_steps) - 1
    return n_steps - 1


def check_window(
    campaign, conditions: Sequence[str], kind: str, window: int, train: TrainConfig | None = None
) -> None:
    """Refuse, before any training, a window (washout) that the series of one of the
    ``conditions`` are too short for (one line naming ``window``, the accepted range and the
    condition)."""
    steps = {c.name: c.n_steps for c in campaign.config.conditions}
    for cond in conditions:
        n = steps[cond]
        most = longest_window(kind, n, train)
        if window > most:
            fewer = (
                f"the {n} steps of the series of condition {cond!r}"
                if most == n - 1
                else f"the training chunks' {most + 1} steps (chunk_steps)"
            )
            raise RailsuspInputError(
                f"window = {window} steps: accepted 2 to {most}, fewer than {fewer}"
            )


def replaced_settings(
    folder: str | Path, settings: Mapping[str, Any], window: int, record_correction: bool
) -> list[str]:
    """How the network saved in ``folder`` was trained otherwise than a training with these
    ``settings`` (:meth:`TrainConfig.to_dict`), ``window`` and ``record_correction`` would
    train it (``["window 20 -> 100", ...]``), for the line that says it is replaced; empty
    where none is saved (or one that does not read, which training writes anew), or where
    the same settings resume it. A network saved before the asked record correction was
    recorded counts as asking for one where it has one (else: unknown, not compared). A
    folder a crash left aside mid-swap is put back first (read missing, the note was not
    said): call it only holding the campaign's write lock, as train and compare do, since
    putting back renames a folder."""
    put_back_aside(folder)
    try:
        doc = read_json(Path(folder) / "surrogate.json")
        before = dict(doc["meta"].get("train_config") or {})
        before["window"] = doc["net"].get("window")
        asked = doc["meta"].get("record_correction_asked")
        if asked is None and doc.get("record_correction") is not None:
            asked = True
    except (OSError, RailsuspInputError, AttributeError, KeyError, TypeError):
        return []
    if asked is not None:
        before["record_correction"] = asked
    now = {**settings, "window": window, "record_correction": record_correction}
    if doc["net"].get("kind") in SEQUENCE_KINDS:  # trained on chunks: no window count
        now.pop("batch_size", None)
    changed = [k for k in sorted(now) if k in before and before[k] != now[k]]
    return [f"{k} {before[k]} -> {now[k]}" for k in changed]


def feature_spec(
    campaign,
    parameters: Sequence[str],
    window: int = 20,
    nominal_response: bool = False,
    nominal_context: Sequence[str] = (),
) -> FeatureSpec:
    """The window features for a campaign: the track channels gain the cant at each axle
    when the campaign's track family varies the cant (the curvature cannot tell it), and
    with ``nominal_response`` the nominal wagon's forces on the track, after its
    ``nominal_context`` channels (:mod:`.nominal`)."""
    fam = campaign.config.track_family
    channels = DEFAULT_TRACK_CHANNELS
    if fam is not None and fam.cant_mm is not None and fam.cant_mm[0] != fam.cant_mm[1]:
        channels = (*channels, "cant")
    return FeatureSpec(
        parameters=tuple(parameters),
        track_channels=channels,
        window=window,
        nominal_response=nominal_response,
        nominal_context=tuple(nominal_context),
    )


def check_unseen_tracks(start: Surrogate, path: Any, test: Any) -> None:
    """Refuse, in one line, continuing ``start`` (saved at ``path``) on a campaign whose test
    runs lie on tracks it learnt from: campaigns of the same design seed share their first
    track seeds, so about 15 % of a new campaign's "held-out" runs could be tracks the
    starting network trained on (the split audit of stop 60). A network saved before the
    seeds were recorded cannot be checked: warned of."""
    seen = start.meta.get("seen_track_seeds")
    if not test.n_samples or start.condition.name != test.condition.name:
        return
    if seen is None:
        log.warning(
            "%s records no track seeds (saved before stop 60): whether this campaign's test "
            "runs lie on tracks it learnt from cannot be checked; give the campaign another "
            "design seed than the one it was trained on",
            path,
        )
        return
    shared = sorted(set(np.unique(test.seeds).tolist()) & set(seen))
    if shared:
        raise RailsuspInputError(
            f"init_from {path}: {len(shared)} of this campaign's test tracks (seeds "
            f"{', '.join(map(str, shared[:3]))}{', ...' if len(shared) > 3 else ''}) are "
            "tracks that network learnt from: its held-out scores would be optimistic; run "
            "the campaign with another design seed"
        )


def split_meta(split: Split, data) -> dict:
    """What a surrogate records of its split: the ids per part, what the test holds out, and
    the track seeds it learnt from (train and validation), so that a network continued on
    another campaign can be kept from scoring on tracks it saw (:func:`check_unseen_tracks`)."""
    pos = {p: split.positions(data.sample_ids, p) for p in ("train", "val", "test")}
    seen = data.seeds[np.concatenate([pos["train"], pos["val"]])]
    return {
        "seen_track_seeds": sorted({int(s) for s in seen}),
        "train_ids": data.sample_ids[pos["train"]].tolist(),
        "val_ids": data.sample_ids[pos["val"]].tolist(),
        "test_ids": data.sample_ids[pos["test"]].tolist(),
        "split": {
            "seed": split.seed,
            "fractions": list(split.fractions),
            "held_out": split.held_out,
            "held_out_tracks": split.held_out_tracks,
        },
    }


def _part(twins: TwinRuns | None, idx: np.ndarray) -> TwinRuns | None:
    return None if twins is None else twins.subset(idx)


def warm_start(
    src: Surrogate, path: str | Path, cfg: NetConfig, spec: FeatureSpec, norm: Normaliser
) -> dict[str, torch.Tensor]:
    """The weights of the surrogate ``src`` (saved at ``path``), refused in one line unless
    it is the same network (configuration), reads the same features and was normalised the
    same way (to 1e-5 of each standard deviation: the features of one campaign, rebuilt,
    agree to about 1e-7): weights of another network would start the training from a state
    that means nothing."""
    for what, same in (
        ("network", cfg == src.net_config),
        ("features", spec == src.spec),
        ("normalisation", _same_normalisation(norm, src.normaliser)),
    ):
        if not same:
            raise RailsuspInputError(
                f"init_from {path}: its {what} differs from this training's; accepted a "
                "surrogate of the same network, features and training data (init_inputs: "
                "one of another campaign of the same family)"
            )
    return {k: v.detach().clone() for k, v in src.net.state_dict().items()}


def check_source_inputs(
    src: Surrogate, path: str | Path, spec: FeatureSpec, condition: str, wagon: Any
) -> None:
    """Refuse in one line the surrogate ``src`` (saved at ``path``) as the one whose inputs
    (features and normalisation) a training on another campaign keeps
    (``train_surrogate(init_inputs=True)``) unless it is of this ``condition`` and
    ``wagon`` and its features differ from this campaign's ``spec`` in the track channels
    alone (e.g. the cant channel of a family with curves, which a campaign of the grade
    alone has no use for): any other difference (parameters, window, nominal response) is
    a setting of this training it would override."""
    if src.condition.name != condition or src.wagon != wagon:
        what = "condition" if src.condition.name != condition else "wagon"
        raise RailsuspInputError(
            f"init_from {path}: its {what} differs from this training's; accepted with "
            "init_inputs a surrogate of the same condition and wagon"
        )
    for field in ("parameters", "axles", "window", "targets", "nominal_response",
                  "nominal_context"):  # fmt: skip
        if getattr(src.spec, field) != getattr(spec, field):
            raise RailsuspInputError(
                f"init_from {path}: its {field} {getattr(src.spec, field)!r}; accepted with "
                f"init_inputs a surrogate of this training's {getattr(spec, field)!r}"
            )


def _same_normalisation(a: Normaliser, b: Normaliser, tol: float = 1e-5) -> bool:
    """Whether two normalisations agree to ``tol`` of each channel's standard deviation."""
    for mean, std in (("track_mean", "track_std"), ("target_mean", "target_std")):
        ma, mb = np.asarray(getattr(a, mean)), np.asarray(getattr(b, mean))
        sa, sb = np.asarray(getattr(a, std)), np.asarray(getattr(b, std))
        if ma.shape != mb.shape or sa.shape != sb.shape:
            return False
        if np.any(np.abs(ma - mb) > tol * sa) or np.any(np.abs(sa - sb) > tol * sa):
            return False
    return True


def train_surrogate(
    run: str | Path,
    condition: str,
    *,
    kind: str = "cnn-gru",
    parameters: Sequence[str] | None = None,
    window: int | None = None,
    train: TrainConfig | None = None,
    net: NetConfig | None = None,
    split_seed: int = 0,
    out: str | Path | None = None,
    progress: Callable[[int, float, float], None] | None = None,
    record_correction: bool = True,
    nominal_response: bool = False,
    nominal_context: Sequence[str] = (),
    architecture: Mapping[str, Any] | None = None,
    init_from: str | Path | None = None,
    init_inputs: bool = False,
) -> Surrogate:
    """Train a window surrogate of one condition of a campaign; save and return it.

    ``window``: the window length, or for ``kind="cnn-gru-seq"`` the washout (steps before
    the first prediction); by default 20 and 100 steps (:func:`.models.default_window`).

    Samples are split 70/15/15 into train/validation/test by track and parameter set (the
    campaign's stored split, :func:`~railsusp.surrogate.split.campaign_split`); the test
    samples are recorded in the saved surrogate for :func:`evaluate`. With
    ``record_correction`` (and at least :data:`~railsusp.surrogate.correction.MIN_RUNS`
    training samples) a record correction is fitted on the training samples' predictions
    (at most :data:`~railsusp.surrogate.correction.MAX_RUNS` of them; :mod:`.correction`).
    ``nominal_response``: the network also reads the nominal wagon's forces on each track
    and learns the change from them (:mod:`.nominal`; the campaign's
    nominal twins must exist: :func:`railsusp.campaign.twins.run_nominal_twins`);
    ``nominal_context``: and these more channels of its response
    (:data:`.nominal.CONTEXT_CHANNELS`). ``architecture``: fields of the default
    :class:`NetConfig` to change (e.g. ``{"dropout": 0.0}``), ignored with ``net``.
    ``train.pair_weight`` > 0 trains the sequence network on pairs with the campaign's
    perturbed twins as well (gradient-enhanced, :mod:`.pairs`; make them with
    :func:`railsusp.campaign.perturbed.run_perturbed_twins`). ``init_from``: a saved
    surrogate of the same network, features and normalisation to start from (a warm start;
    e.g. a network trained on the forces alone, then on pairs). ``init_inputs`` (with
    ``init_from``): train on that surrogate's inputs, its features and normalisation,
    instead of those of this campaign (its track channels and a normalisation fitted on its
    training runs), so that its weights mean what they meant: a warm start on another
    campaign of the same family (more tracks and parameter sets, whose own normalisation
    differs and would be refused; a campaign of the grade alone has no cant channel;
    :func:`check_source_inputs`), recorded in ``meta.init_inputs``. The saved surrogate lists the
    parameters it does not take as inputs and what it assumes of them
    (``meta.assumed_parameters``: varied over a range in its training campaign, or held at
    nominal).
    """
    from railsusp.campaign import load_campaign, require_complete

    if init_inputs and init_from is None:
        raise RailsuspInputError("init_inputs: accepted only with init_from")
    camp = require_complete(load_campaign(run))  # never train on part of a campaign
    params = tuple(parameters) if parameters else key_parameters(run)
    window = default_window(kind) if window is None else window
    spec = feature_spec(camp, params, window, nominal_response, nominal_context)
    start = None if init_from is None else load(init_from)  # read once, checked twice
    if init_inputs:
        check_source_inputs(start, init_from, spec, condition, camp.config.wagon)
        spec = start.spec
    tcfg = TrainConfig() if train is None else train
    # no window would fit a series, no washout leave a chunk's step in the loss: refused
    # before the series are read (their tracks' features take minutes)
    names = [c.name for c in camp.config.conditions]
    if condition not in names:
        raise RailsuspInputError(
            f"condition {condition!r}: accepted one of the campaign's {', '.join(names)}"
        )
    check_window(camp, [condition], kind, spec.window, tcfg)  # (init_inputs: the source's)
    data = load_series(camp, condition, spec)
    split = campaign_split(camp, split_seed)
    tr_i, va_i = split.positions(data.sample_ids, "train"), split.positions(data.sample_ids, "val")
    if len(tr_i) == 0 or len(va_i) == 0:
        raise ValueError(
            f"condition {condition!r}: the split leaves {len(tr_i)} training and {len(va_i)} "
            "validation samples that ran (too few samples, or too many failed)"
        )
    train_data, val_data = data.subset(tr_i), data.subset(va_i)
    if start is not None and split.held_out_tracks:  # (one common track holds none out)
        check_unseen_tracks(start, init_from, data.subset(split.positions(data.sample_ids, "test")))
    norm = start.normaliser if init_inputs else Normaliser.fit(train_data)
    cfg = (
        replace(
            NetConfig(
                kind=kind, n_features=spec.n_features, window=window, n_outputs=len(spec.targets)
            ),
            **(architecture or {}),
        )
        if net is None
        else net
    )
    network = build_network(cfg)
    out = Path(out) if out else camp.path / "surrogates" / kind / condition
    # a trained folder a crash left aside mid-swap, back before its checkpoint is read
    put_back_aside(out)
    twins = load_twins(camp, data, spec) if tcfg.pair_weight > 0 else None
    history = train_network(
        network,
        sampler_for(kind, train_data, norm, window, tcfg, _part(twins, tr_i)),
        sampler_for(kind, val_data, norm, window, tcfg, _part(twins, va_i)),
        tcfg,
        checkpoint=out / "checkpoint.pt",
        progress=progress,
        initial=None if start is None else warm_start(start, init_from, cfg, spec, norm),
    )
    seed = int(np.unique(data.seeds)[0]) if len(np.unique(data.seeds)) == 1 else None
    fam = camp.config.track_family
    sur = Surrogate(
        network,
        cfg,
        spec,
        norm,
        data.condition,
        camp.config.wagon,
        data.condition.seed if seed is None else seed,
        meta={
            "campaign": str(camp.path),
            "campaign_hash": camp.config.hash(),
            "model_revision": camp.model_revision,  # the force laws it learnt
            "wheel": camp.config.wheel,  # the wheel whose forces it predicts (load_series)
            "solver": dict(camp.config.solver),  # the nominal response is simulated with it
            **split_meta(split, data),
            "train_config": tcfg.to_dict(),
            # asked for, fitted or not (too few training runs): what a rerun compares
            "record_correction_asked": bool(record_correction),
            # (perfect track: one, whatever the seeds)
            "track_realisations": condition_tracks(camp, data.condition.name, data.sample_ids),
            "track_family": None if fam is None else family_of(fam.ranges(), data.condition),
            "assumed_parameters": assumed_parameters(
                spec.parameters, camp.config.other_parameters, camp.config.parameters
            ),
            "history": history,
        },
    )
    if init_inputs:  # the inputs are another campaign's: say which
        sur.meta["init_inputs"] = {
            "from": str(init_from),
            **{k: start.meta.get(k) for k in ("campaign", "campaign_hash", "track_family")},
        }
    if record_correction and train_data.n_samples >= MIN_RUNS:
        fit_record_correction(sur, train_data, val_data, split_seed)
    sur.save(out)
    return sur
