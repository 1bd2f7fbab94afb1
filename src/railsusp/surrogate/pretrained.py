"""Network sets trained once on many tracks and shipped with railsusp (issue 19, item 5).

Training the study's CNN-GRU on a campaign of many track realisations takes hours on two
cores (bench/README.md, "surrogate_tracks.py"), far beyond a demo's minutes. A *network
set* is such a training's result in a form a pipeline can take as its surrogates:

* ``<condition>/surrogate.json`` and ``model.pt``: one bundle per working condition
  (:mod:`.bundle`), each trained on a track family (FRA class, curve radius, cant drawn
  per run) with the parameters that are not its inputs varied over their ranges;
* ``compare.csv``: those networks on their campaign's held-out tracks and parameters, in
  the layout of the study's Table 7 (:func:`railsusp.surrogate.compare.table7`);
* ``networks.json`` (the manifest): the force laws' revision
  (:data:`railsusp.vehicle.MODEL_REVISION`) and the wagon data (content hash) the networks
  were trained on, their kind and key parameters, the commands that reproduce them, and
  reference predictions that a loaded set must give again.

A set answers only for the model it was trained on: :func:`check_network_set` refuses
another force-law revision, another wagon, another network kind or a working condition
outside the set's training (one line each, before any stage runs), and
:func:`check_references` predicts the stored references again, so that weights damaged or
read by an incompatible torch are caught rather than used.

What a set is on disk (its file names, the manifest read as a
:class:`~railsusp.surrogate.network_set.NetworkSet`, the shipped sets found by name) is
:mod:`railsusp.surrogate.network_set`; this module checks a set against a run, predicts its
references, installs it into a run and writes new sets.
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.store import atomic_folder, content_hash, write_csv, write_json
from railsusp.surrogate.network_set import ACCURACY, BUNDLE_FILES, MANIFEST, NetworkSet

# imported from this module by railsusp.pipeline_inputs, railsusp.pipeline_stages and
# railsusp.config_combinations
from railsusp.surrogate.network_set import read_network_set as read_network_set
from railsusp.surrogate.network_set import resolve_network_set as resolve_network_set

#: reference predictions agree to this relative tolerance (float32 networks; numbers of the
#: same weights on another CPU or torch build differ in the last bits only)
REFERENCE_RTOL = 1e-4


#: a pipeline run's folders whose ``surrogates/`` the estimation reads: a network set's copy,
#: the surrogates' own campaign of the key parameters, or the sensitivity campaign
PRETRAINED_RUN = "surrogate-pretrained"
OWN_CAMPAIGN_RUN = "surrogate-campaign"
SENSITIVITY_RUN = "campaign"


def surrogates_run(pretrained: str | None, samples: int) -> str:
    """The folder of a pipeline run (under its output directory) that holds the surrogates
    of a configuration whose ``[surrogate]`` has ``pretrained`` and ``samples``."""
    if pretrained is not None:
        return PRETRAINED_RUN
    return OWN_CAMPAIGN_RUN if samples else SENSITIVITY_RUN


#: what to do about a network set whose files do not read
SET_REMEDY = "the set's files are damaged: copy the set again (a shipped set: reinstall railsusp)"


def load_bundle(path: Path, field: str = "surrogate.pretrained") -> Any:
    """A set's bundle, or a one-line error naming ``field`` and the bundle when it cannot
    be read (truncated weights, a damaged surrogate.json): torch's own messages run over
    several lines."""
    import pickle

    from railsusp.surrogate.bundle import load

    try:
        return load(path, remedy=SET_REMEDY)
    except RailsuspInputError as exc:
        raise RailsuspInputError(f"{field}: {exc}") from None
    except (OSError, ValueError, KeyError, TypeError, RuntimeError, pickle.UnpicklingError) as e:
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise RailsuspInputError(
            f"{field}: the network in {path} cannot be read ({first})"
        ) from None


def set_hash(ns: NetworkSet) -> str:
    """Content hash of a set: its manifest and the bytes of every bundle file, so that
    weights replaced under an unchanged manifest count as another set."""
    from railsusp.store import file_hash

    files = {f"{c}/{f}": file_hash(ns.bundle(c) / f) for c in ns.conditions for f in BUNDLE_FILES}
    return content_hash({"manifest": ns.to_json(), "files": files})


def wagon_hash(wagon: Any) -> str:
    """The content hash of a wagon's data as the pipeline's stage hashes take it
    (:func:`railsusp.pipeline_inputs.model_identity`), with its profile files' contents."""
    return content_hash(wagon.with_profile_digests(wagon.model_dump(mode="json")))


def check_network_set(
    ns: NetworkSet,
    *,
    wagon: Any,
    kind: str,
    conditions: Sequence[WorkingCondition],
    field: str = "surrogate.pretrained",
) -> None:
    """Refuse, in one line naming ``field``, a network set that cannot serve this run:
    trained with another force-law revision, on another wagon, of another network kind
    than ``kind``, without a network for one of ``conditions``, or with one whose training
    does not cover that condition (:meth:`~railsusp.surrogate.bundle.Surrogate.untrained_fields`:
    speed, grade, coupler force, or FRA class, radius or cant outside the track family)."""
    from railsusp.vehicle.revision import Standing, made_with, newer_remedy, standing

    where = f"{field} = {ns.name!r}"
    s = standing(ns.model_revision)
    if s is Standing.NEWER:
        where += f" ({ns.folder / MANIFEST})"
    if s is not Standing.THIS:
        remedy = (
            newer_remedy(ns.model_revision)
            if s is Standing.NEWER
            else f"retrain it ({ns.folder / MANIFEST}, 'reproduce') or train the surrogates here"
        )
        raise RailsuspInputError(
            f"{where} was trained with {made_with(ns.model_revision)}: {remedy}"
        )
    if ns.wagon_hash != wagon_hash(wagon):
        raise RailsuspInputError(
            f"{where} was trained on another wagon's data (hash {ns.wagon_hash}, not "
            f"{wagon_hash(wagon)}): it serves that wagon only ({ns.description or ns.name}); "
            "choose that wagon or train the surrogates for this one"
        )
    if ns.kind != kind:
        raise RailsuspInputError(
            f"{where} holds {ns.kind!r} networks; set surrogate.model = {ns.kind!r}"
        )
    for cond in conditions:
        if cond.name not in ns.conditions:
            raise RailsuspInputError(
                f"{where} has no network for condition {cond.name!r} (has "
                f"{', '.join(ns.conditions)})"
            )
        outside = load_bundle(ns.bundle(cond.name), field).untrained_fields(cond)
        if outside:
            name, value, trained = outside[0]
            raise RailsuspInputError(
                f"{where}: condition {cond.name!r} has {name} = {value!r}, outside what its "
                f"network was trained on ({trained})"
            )


def reference_statistics(series: np.ndarray) -> dict[str, list[float]]:
    """What a reference keeps of predicted series (n, T, 2): per set, the mean of |Y| and
    of Q and the RMS of Y over the steps past the washout, kN."""
    s = np.asarray(series, dtype=float)
    ok = ~np.isnan(s[..., 0])
    out: dict[str, list[float]] = {"mean_abs_Y": [], "mean_Q": [], "rms_Y": []}
    for i in range(s.shape[0]):
        y, q = s[i, ok[i], 0], s[i, ok[i], 1]
        out["mean_abs_Y"].append(float(np.mean(np.abs(y))))
        out["mean_Q"].append(float(np.mean(q)))
        out["rms_Y"].append(float(np.sqrt(np.mean(y**2))))
    return out


def predict_reference(bundle: Path, seed: int, params_si: np.ndarray) -> np.ndarray:
    """The bundle's series for ``params_si`` on its own condition at track seed ``seed``
    (the nominal wagon simulated on that track where the network reads it)."""
    sur = load_bundle(bundle)
    cond = sur.condition.model_copy(update={"seed": int(seed)})
    return sur.predict(np.asarray(params_si, dtype=float), condition=cond)


def make_references(
    folder: Path, conditions: Sequence[str], parameters: Sequence[str], seed: int = 11
) -> dict[str, dict[str, Any]]:
    """References for a new set: per condition the nominal wagon and one set with every key
    parameter at 25 % of its range, on the track of ``seed`` (any fixed seed: that it is
    not one of the training campaign's track seeds was checked for c80_k6, not required)."""
    from railsusp.params import bounds

    lo, hi = bounds(parameters)
    nominal = lo + 0.5 * (hi - lo)
    low = lo + 0.25 * (hi - lo)
    x = np.vstack([nominal, low])
    return {
        c: {
            "seed": seed,
            "params_si": x.tolist(),
            "statistics": reference_statistics(predict_reference(folder / c, seed, x)),
        }
        for c in conditions
    }


def check_references(ns: NetworkSet, conditions: Sequence[str] | None = None) -> None:
    """Predict the manifest's references again and refuse (one line) a set whose networks
    no longer give them to :data:`REFERENCE_RTOL`: damaged weights, or a torch that reads
    them otherwise."""
    for cond in conditions or ns.conditions:
        ref = ns.references.get(cond)
        if ref is None:
            raise RailsuspInputError(f"network set {ns.name!r}: no reference for {cond!r}")
        got = reference_statistics(
            predict_reference(ns.bundle(cond), ref["seed"], np.asarray(ref["params_si"]))
        )
        for key, want in ref["statistics"].items():
            a, b = np.asarray(got[key]), np.asarray(want)
            if not np.allclose(a, b, rtol=REFERENCE_RTOL, atol=0.0):
                worst = float(np.max(np.abs(a - b) / np.abs(b)))
                raise RailsuspInputError(
                    f"network set {ns.name!r}, condition {cond!r}: {key} predicted "
                    f"{a.tolist()} against the reference {b.tolist()} (relative difference "
                    f"{worst:.1e}, accepted {REFERENCE_RTOL:g}): its weights are damaged or "
                    "this torch reads them otherwise"
                )


def install_network_set(ns: NetworkSet, dest: str | Path) -> Path:
    """Copy the set's bundles (as ``dest/<kind>/<condition>/``), accuracy table and manifest
    into ``dest``, a run's ``surrogates/`` folder, atomically: the run then looks like one
    whose surrogates were trained in place."""
    dest = Path(dest)
    with atomic_folder(dest, keep=False) as tmp:
        for cond in ns.conditions:
            _copy_bundle(ns.bundle(cond), tmp / ns.kind / cond)
        shutil.copy2(ns.folder / MANIFEST, tmp / MANIFEST)
        # last: the pipeline's mark of a finished stage (the folder is swapped in whole)
        shutil.copy2(ns.folder / ACCURACY, tmp / ACCURACY)
    return dest


def _copy_bundle(source: Path, target: Path) -> None:
    """A condition's bundle files (:data:`BUNDLE_FILES`, no training checkpoint)."""
    target.mkdir(parents=True)
    for f in BUNDLE_FILES:
        shutil.copy2(source / f, target / f)


def write_network_set(
    source: str | Path | Mapping[str, str | Path],
    dest: str | Path,
    *,
    name: str,
    conditions: Sequence[str],
    accuracy: pd.DataFrame,
    reproduce: Sequence[str],
    description: str = "",
) -> NetworkSet:
    """Make a network set in ``dest`` from trained bundles (all of one kind, key parameters
    and wagon), with its accuracy table and the commands that trained them; the manifest
    records today's force-law revision and the references. ``source`` is a folder holding
    ``<condition>/`` bundles, or a mapping from each condition to its bundle folder where
    the conditions' networks come from different campaigns. A bundle that records another
    force-law revision than today's is refused (audit of stop 62: the manifest stamped
    today's whatever the networks had learnt). A bundle carried over to today's revision
    without training (:mod:`railsusp.surrogate.restamp`, its ``meta.restamped``) is taken;
    the manifest then names the conditions so carried (``carried_over``) and their latest
    stamps' notes (``model_revision_note``), so that a set of some networks trained on
    today's force laws and others carried over says which are which (the report reads it)."""
    from railsusp.surrogate.bundle import load
    from railsusp.vehicle import MODEL_REVISION
    from railsusp.vehicle.revision import mismatch

    if isinstance(source, Mapping):
        missing = [c for c in conditions if c not in source]
        if missing:
            raise RailsuspInputError(
                f"source: no network given for condition(s) {', '.join(missing)}"
            )
        bundles = {c: Path(source[c]) for c in conditions}
    else:
        bundles = {c: Path(source) / c for c in conditions}
    surs = {c: load(bundles[c]) for c in conditions}
    first = next(iter(surs.values()))
    for c, s in surs.items():
        if s.kind != first.kind or s.spec.parameters != first.spec.parameters:
            raise RailsuspInputError(
                f"{bundles[c]}: {s.kind} of {s.spec.parameters}, the set's first network is "
                f"{first.kind} of {first.spec.parameters}; a set holds one kind and one "
                "parameter list"
            )
        if wagon_hash(s.wagon) != wagon_hash(first.wagon):
            raise RailsuspInputError(f"{bundles[c]}: trained on another wagon than the set's")
        # the manifest would claim today's force laws for a network of others (one that
        # records none is older than any railsusp that records them: estimate refuses it)
        said = mismatch(
            s.meta.get("model_revision"),
            "train it again, or score it on today's simulator and carry the set over "
            "(railsusp.surrogate.restamp)",
        )
        if said is not None:
            raise RailsuspInputError(f"{bundles[c]}: trained on a campaign simulated with {said}")
    dest = Path(dest)
    with atomic_folder(dest, keep=False) as tmp:
        for c in conditions:
            _copy_bundle(bundles[c], tmp / c)
        write_csv(tmp / ACCURACY, accuracy)
        ns = NetworkSet(
            folder=tmp,
            name=name,
            description=description,
            kind=first.kind,
            model_revision=MODEL_REVISION,
            wagon_hash=wagon_hash(first.wagon),
            parameters=tuple(first.spec.parameters),
            conditions=tuple(conditions),
            reproduce=tuple(reproduce),
            references=make_references(tmp, conditions, first.spec.parameters),
        )
        write_json(tmp / MANIFEST, {**ns.to_json(), **carried_over(surs)})
    return read_network_set(dest)


def carried_over(surs: Mapping[str, Any]) -> dict:
    """The manifest's keys for the networks of ``surs`` (condition -> loaded bundle) carried
    over without training (``meta.restamped``): ``carried_over`` (their conditions) and
    ``model_revision_note`` (each distinct latest note, after the conditions it is of);
    empty where every network was trained on its revision."""
    notes: dict[str, list[str]] = {}
    for cond, sur in surs.items():
        stamps = sur.meta.get("restamped") or []
        if stamps:
            notes.setdefault(str(stamps[-1].get("note", "")), []).append(cond)
    if not notes:
        return {}
    conds = [c for group in notes.values() for c in group]
    text = "; ".join(f"{', '.join(group)}: {note}" for note, group in notes.items())
    return {"carried_over": conds, "model_revision_note": text}
