"""A network set carried over to a new force-law revision (railsusp.surrogate.restamp): the
manifest, the bundles' wagon and the references follow today's simulator, the weights do
not change, and a set trained on a wagon that differs beyond the revision's fields, or not
scored on every condition, is refused."""

from __future__ import annotations

import json
import shutil

import pandas as pd
import pytest

from railsusp.errors import RailsuspInputError
from railsusp.store import file_hash
from railsusp.surrogate import load
from railsusp.surrogate.network_set import (
    ACCURACY,
    MANIFEST,
    read_network_set,
    resolve_network_set,
)
from railsusp.surrogate.pretrained import check_references, wagon_hash, write_network_set
from railsusp.surrogate.restamp import changed_wagon_fields, restamp_network_set
from railsusp.vehicle import MODEL_REVISION
from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_11_30_2, load_wagon

FIELDS = tuple(FORCE_LAWS_BEFORE_2026_11_30_2)


def _old_curve_set(tmp_path):
    """The shipped set's curve network as a set of an older revision, trained on the wagon
    of the fields before 2026-11-30.2."""
    ns = read_network_set(resolve_network_set("c80_k6"))
    folder = tmp_path / "old"
    shutil.copytree(ns.folder, folder)
    for cond in ("straight", "uphill"):
        shutil.rmtree(folder / cond)
    before = load_wagon().with_values(FORCE_LAWS_BEFORE_2026_11_30_2)
    doc = json.loads((folder / "curve" / "surrogate.json").read_text())
    doc["wagon"] = before.model_dump(mode="json")
    doc["meta"]["model_revision"] = "2026-11-30.1"  # as train_surrogate records it
    doc["meta"].pop("restamped", None)  # trained on it, never carried over
    (folder / "curve" / "surrogate.json").write_text(json.dumps(doc))
    manifest = json.loads((folder / MANIFEST).read_text())
    manifest.update(
        conditions=["curve"],
        model_revision="2026-11-30.1",
        wagon_hash=wagon_hash(before),
        references={"curve": manifest["references"]["curve"]},
    )
    (folder / MANIFEST).write_text(json.dumps(manifest))
    return folder


def _scored(condition="curve"):
    """Rows of the accuracy table's layout, as bench/rescore_networks.py writes them."""
    return pd.DataFrame(
        [
            {"condition": condition, "model": "cnn-gru-seq", "target": t, "nrmse": 0.1}
            for t in ("Y", "Q")
        ]
    )


def test_a_carried_over_set_is_of_today_s_revision_and_wagon(tmp_path):
    folder = _old_curve_set(tmp_path)
    weights = file_hash(folder / "curve" / "model.pt")
    rows_before = len(pd.read_csv(folder / ACCURACY))
    ns = restamp_network_set(
        folder, wagon=load_wagon(), fields=FIELDS, accuracy=_scored(), note="scored: 0.6 %"
    )
    assert ns.model_revision == MODEL_REVISION
    assert ns.wagon_hash == wagon_hash(load_wagon())
    assert file_hash(folder / "curve" / "model.pt") == weights  # the weights are the same
    check_references(ns)  # the new references are the networks' on today's simulator
    doc = json.loads((folder / "curve" / "surrogate.json").read_text())
    assert changed_wagon_fields(doc["wagon"], load_wagon()) == []
    stamp = doc["meta"]["restamped"][-1]  # (the shipped set carries its own before it)
    assert stamp["from"] == "2026-11-30.1" and stamp["to"] == MODEL_REVISION
    assert stamp["trained"] == "2026-11-30.1" and doc["meta"]["model_revision"] == MODEL_REVISION
    # the estimation's own check of the bundles' force laws takes the carried-over set
    from railsusp.estimate import SurrogateForces

    SurrogateForces(folder)  # (refused a bundle trained on another revision before)
    manifest = json.loads((folder / MANIFEST).read_text())
    assert manifest["model_revision_note"] == "scored: 0.6 %"
    table = pd.read_csv(folder / ACCURACY)
    assert len(table) == rows_before + 2
    assert set(table.model[rows_before:]) == {f"cnn-gru-seq (revision {MODEL_REVISION})"}
    assert "cnn-gru-seq" not in set(table.model)  # each row says its force laws
    with pytest.raises(RailsuspInputError, match="already"):
        restamp_network_set(folder, wagon=load_wagon(), fields=FIELDS, accuracy=_scored(), note="x")


def test_a_newer_railsusps_set_is_not_carried_back(tmp_path):
    """Only equality was checked: a newer railsusp's set was stamped with this older
    revision, each bundle's ``meta.model_revision`` overwritten. Refused, the set as it
    was."""
    folder = _old_curve_set(tmp_path)
    manifest = json.loads((folder / MANIFEST).read_text())
    (folder / MANIFEST).write_text(json.dumps({**manifest, "model_revision": "2099-01-01.1"}))
    before = {p.name: file_hash(p) for p in folder.rglob("*.json")}
    with pytest.raises(RailsuspInputError) as err:
        restamp_network_set(folder, wagon=load_wagon(), fields=FIELDS, accuracy=_scored(), note="x")
    assert "was trained with force-law revision 2099-01-01.1, newer than" in str(err.value)
    assert "use it with the railsusp that made it" in str(err.value)
    assert {p.name: file_hash(p) for p in folder.rglob("*.json")} == before


def test_a_set_of_another_wagon_or_not_scored_is_not_carried_over(tmp_path):
    folder = _old_curve_set(tmp_path)
    # the first switch only (revision 2026-12-02.1's bowl): the bundle's others refused
    other_fields = r"differs in (\S+, )*car_body.gravity_roll_moment"
    with pytest.raises(RailsuspInputError, match=other_fields):
        restamp_network_set(
            folder, wagon=load_wagon(), fields=FIELDS[:1], accuracy=_scored(), note="x"
        )
    with pytest.raises(RailsuspInputError, match=r"no Y and Q rows of condition\(s\) curve"):
        restamp_network_set(
            folder, wagon=load_wagon(), fields=FIELDS, accuracy=_scored("straight"), note="x"
        )
    heavier = load_wagon().with_values({"car_body.mass": 95_000.0})
    with pytest.raises(RailsuspInputError, match=r"car_body.mass"):
        restamp_network_set(folder, wagon=heavier, fields=FIELDS, accuracy=_scored(), note="x")
    assert json.loads((folder / MANIFEST).read_text())["model_revision"] == "2026-11-30.1"


def test_a_network_of_other_force_laws_is_not_written_into_a_set_of_today_s(tmp_path):
    """write_network_set stamped today's revision whatever its bundles had learnt."""
    ns = read_network_set(resolve_network_set("c80_k6"))
    folder = tmp_path / "bundles"
    shutil.copytree(ns.folder, folder)
    doc = json.loads((folder / "curve" / "surrogate.json").read_text())
    # one that records none (older than any railsusp that records them: estimate refuses
    # it) was stamped today's too (stop 66)
    for revision, told in (
        ("2020-01-01.1", "simulated with force-law revision 2020-01-01.1, older than"),
        (None, "simulated with force laws older than any recorded force-law revision"),
        ("2099-01-01.1", "2099-01-01.1, newer than this railsusp's .*: use it with the railsusp"),
    ):
        doc["meta"]["model_revision"] = revision
        if revision is None:
            del doc["meta"]["model_revision"]
        (folder / "curve" / "surrogate.json").write_text(json.dumps(doc))
        with pytest.raises(RailsuspInputError, match=told):
            write_network_set(
                folder,
                tmp_path / "set",
                name="set",
                conditions=["curve"],
                accuracy=_scored(),
                reproduce=[],
            )


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            ["--restamp", "NOTE", "--wagon-fields", "before-2026-11-30.2"],
            "--restamp with --wagon-fields before-2026-11-30.2: accepted with the campaign of "
            "today's wagon only",
        ),
        (["--restamp", " "], "--restamp NOTE: accepted a note that is not empty"),
        # a set it cannot carry over (here already of today's revision: the shipped one,
        # after the restamp of stop 80): refused by restamp_network_set only after the
        # campaign of 384 runs per condition, the nominal twins and the scoring
        (["--restamp", "NOTE"], f"is of revision {MODEL_REVISION} already: nothing to stamp"),
    ],
)
def test_the_rescore_bench_refuses_a_restamp_before_its_campaign(
    tmp_path, monkeypatch, capsys, options, message
):
    """bench/rescore_networks.py refused --restamp with the wagon of before only after the
    campaign, the nominal twins and the scoring had run (minutes to hours); an empty NOTE
    restamped nothing, silently."""
    import sys

    from conftest import bench_script

    bench = bench_script("rescore_networks")

    def ran(*args, **kw):
        raise AssertionError("the campaign ran")

    monkeypatch.setattr(bench, "run_campaign", ran)
    run = tmp_path / "never"
    argv = ["rescore_networks.py", "--set", resolve_network_set("c80_k6"), "--run", run]
    monkeypatch.setattr(sys, "argv", [str(a) for a in [*argv, *options]])
    with pytest.raises(SystemExit) as exc:
        bench.main()
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
    assert not run.exists()
    assert not run.exists()


def _trained_straight_set(tmp_path):
    """The shipped set with its straight network as one trained on today's force laws (its
    carried-over stamps taken off), curve and uphill carried over: the shipped set's state
    from stop 75 to stop 80, when revision 2026-12-03.1 carried the straight network over
    too."""
    ns = read_network_set(resolve_network_set("c80_k6"))
    folder = tmp_path / "shipped"
    shutil.copytree(ns.folder, folder)
    path = folder / "straight" / "surrogate.json"
    doc = json.loads(path.read_text())
    doc["meta"].pop("restamped", None)
    path.write_text(json.dumps(doc))
    return read_network_set(folder)


def _mixed_set(ns, folder):
    """A set of ``ns``'s straight network (trained on today's laws) and its curve one
    (carried over) in ``folder``, as bench/ship_networks.py writes one."""
    return write_network_set(
        ns.folder,
        folder,
        name="mixed",
        conditions=["straight", "curve"],
        accuracy=pd.concat([_scored("straight"), _scored("curve")]),
        reproduce=["python train.py"],
    )


def test_a_set_of_trained_and_carried_over_networks_says_which_are_which(tmp_path):
    """A set with a network trained on today's force laws and others carried over
    (meta.restamped), as the shipped set was from stop 75 to stop 80. write_network_set
    wrote a manifest without any note, so the report called the whole set trained on
    today's laws; it now names the carried-over conditions and their stamps' note, and the
    report says which networks were trained on the laws and which were carried over."""
    from railsusp.report_doc import Doc
    from railsusp.report_method import _network_set_text

    ns = _trained_straight_set(tmp_path)
    assert not load(ns.bundle("straight")).meta.get("restamped")  # trained on today's
    assert load(ns.bundle("curve")).meta.get("restamped")
    made = _mixed_set(ns, tmp_path / "set")
    manifest = json.loads((made.folder / MANIFEST).read_text())
    assert manifest["carried_over"] == ["curve"]
    stamp = load(ns.bundle("curve")).meta["restamped"][-1]["note"]
    assert manifest["model_revision_note"] == f"curve: {stamp}"
    doc = Doc(tmp_path)
    _network_set_text(doc, manifest, [])
    text = " ".join(" ".join(doc.md).split())
    serves = f"It serves the force laws of revision {MODEL_REVISION}: its straight network"
    assert f"{serves} was" in text
    assert "trained on them, its curve network was carried over to them without training" in text
    only_trained = write_network_set(
        ns.folder,
        tmp_path / "trained",
        name="trained",
        conditions=["straight"],
        accuracy=_scored("straight"),
        reproduce=[],
    )
    plain = json.loads((only_trained.folder / MANIFEST).read_text())
    assert "carried_over" not in plain and "model_revision_note" not in plain


def test_a_restamp_carries_every_network_of_the_set_over(tmp_path):
    """Stop 80 carried the shipped set over to revision 2026-12-03.1 while its straight
    network had been trained on the laws of the revision before: the manifest kept
    ``carried_over = [curve, uphill]``, so the report called the straight network trained
    on the new laws. After a restamp every network is carried over, and the report says
    so of the whole set."""
    from railsusp.report_doc import Doc
    from railsusp.report_method import _network_set_text

    made = _mixed_set(_trained_straight_set(tmp_path), tmp_path / "mixed")
    assert json.loads((made.folder / MANIFEST).read_text())["carried_over"] == ["curve"]
    older = "2026-12-02.1"  # the set as of the revision before today's
    for cond in ("straight", "curve"):
        path = made.folder / cond / "surrogate.json"
        doc = json.loads(path.read_text())
        doc["meta"]["model_revision"] = older
        path.write_text(json.dumps(doc))
    manifest = json.loads((made.folder / MANIFEST).read_text())
    manifest["model_revision"] = older
    (made.folder / MANIFEST).write_text(json.dumps(manifest))
    restamp_network_set(
        made.folder,
        wagon=load_wagon(),
        fields=FIELDS,
        accuracy=pd.concat([_scored("straight"), _scored("curve")]),
        note="scored again on today's laws",
    )
    manifest = json.loads((made.folder / MANIFEST).read_text())
    assert manifest["carried_over"] == ["straight", "curve"]
    # each stamp names the revision the network was trained on, not the one it served last
    # (the curve network's first stamp's; one written before stamps recorded it: its "from")
    stamps = {
        cond: json.loads((made.folder / cond / "surrogate.json").read_text())["meta"]["restamped"]
        for cond in ("straight", "curve")
    }
    assert stamps["straight"][-1]["trained"] == older
    first = stamps["curve"][0]
    assert stamps["curve"][-1]["trained"] == (first.get("trained") or first["from"]) != older
    doc = Doc(tmp_path)
    _network_set_text(doc, manifest, [])
    text = " ".join(" ".join(doc.md).split())
    assert "to which it was carried over without training: scored again" in text
    assert "trained on them" not in text
