"""Network sets trained on many tracks and shipped with railsusp (issue 19, item 5): the
shipped weights load and predict their references, and a set is refused, in one line, for
another model, wagon, network kind or condition, or with damaged weights."""

from __future__ import annotations

import shutil

import pandas as pd
import pytest
import torch

import railsusp.vehicle
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import SurrogateForces
from railsusp.surrogate.network_set import (
    ACCURACY,
    MANIFEST,
    packaged_sets,
    read_network_set,
    resolve_network_set,
)
from railsusp.surrogate.pretrained import (
    OWN_CAMPAIGN_RUN,
    PRETRAINED_RUN,
    SENSITIVITY_RUN,
    check_network_set,
    check_references,
    install_network_set,
    surrogates_run,
    write_network_set,
)
from railsusp.vehicle.wagon import load_wagon

SHIPPED = "c80_k6"


@pytest.fixture(scope="module")
def shipped():
    return read_network_set(resolve_network_set(SHIPPED))


def standard():
    return [get_condition(n) for n in ("straight", "curve", "uphill")]


def test_the_shipped_set_is_the_study_cnn_gru_on_many_tracks(shipped):
    assert SHIPPED in packaged_sets()
    assert shipped.kind == "cnn-gru-seq"
    assert set(shipped.conditions) == {"straight", "curve", "uphill"}
    assert shipped.model_revision == railsusp.vehicle.MODEL_REVISION
    assert shipped.reproduce and all(isinstance(c, str) for c in shipped.reproduce)
    # its accuracy on held-out tracks and parameters, per condition and force
    table = pd.read_csv(shipped.folder / ACCURACY)
    assert set(table.condition) == set(shipped.conditions)
    assert set(table.target) == {"Y", "Q"}
    assert (table.held_out == "tracks and parameters").all()
    # trained with the other main-suspension parameters varied, not held at nominal
    sur = SurrogateForces(shipped.folder).surrogate("straight")
    assumed = {a["symbol"]: a["assumed"] for a in sur.meta["assumed_parameters"]}
    assert set(assumed) == {f"X{i}" for i in range(11, 21)} - set(shipped.parameters)
    assert set(assumed.values()) == {"varied"}


def test_shipped_weights_load_and_predict_their_references(shipped):
    check_references(shipped)  # raises if any condition's predictions moved


def test_the_shipped_set_serves_the_study_conditions_on_this_wagon(shipped):
    check_network_set(shipped, wagon=load_wagon(None), kind="cnn-gru-seq", conditions=standard())


@pytest.mark.parametrize(
    "change, match",
    [
        ({"kind": "bp"}, "holds 'cnn-gru-seq' networks; set surrogate.model"),
        ({"wagon": "tare"}, "another wagon's data"),
        ({"condition": {"speed_kmh": 80.0}}, "speed_kmh = 80.0, outside"),
        ({"condition": {"curve_radius_m": 600.0}}, "curve_radius_m = 600.0, outside"),
        ({"condition": {"name": "bridge"}}, "no network for condition 'bridge'"),
        # 20 s at 100 Hz: the length may differ, the network's time step may not
        ({"condition": {"n_steps": 2000}}, r"sample_interval = 0.01, outside .*0.02 s only"),
    ],
)
def test_a_set_that_cannot_serve_the_run_is_refused_in_one_line(shipped, change, match):
    cond = get_condition("curve")
    if "condition" in change:
        cond = cond.model_copy(update=change["condition"])
    with pytest.raises(RailsuspInputError, match=match) as err:
        check_network_set(
            shipped,
            wagon=load_wagon(change.get("wagon")),
            kind=change.get("kind", "cnn-gru-seq"),
            conditions=[cond],
        )
    assert "\n" not in str(err.value) and "surrogate.pretrained = 'c80_k6'" in str(err.value)


def test_a_set_of_other_force_laws_is_refused(shipped, monkeypatch):
    """Older: retrained or trained here; newer (a newer railsusp's set): used there."""
    made = shipped.model_revision
    for ours, said in (
        ("2099-01-01.1", f"{made}, older than this railsusp's 2099-01-01.1: retrain it"),
        ("2000-01-01.1", f"{made}, newer than this railsusp's 2000-01-01.1: use it with the "
         "railsusp that made it"),
    ):  # fmt: skip
        monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", ours)
        with pytest.raises(RailsuspInputError) as err:
            check_network_set(
                shipped, wagon=load_wagon(None), kind="cnn-gru-seq", conditions=standard()
            )
        assert f"was trained with force-law revision {said}" in str(err.value)
        assert "'c80_k6'" in str(err.value) and "\n" not in str(err.value)
    # the newer set's message names its manifest (the older one's remedy does)
    assert str(shipped.folder / MANIFEST) in str(err.value)


def test_damaged_weights_are_caught_by_the_references(shipped, tmp_path):
    copy = tmp_path / "set"
    shutil.copytree(shipped.folder, copy)
    weights = copy / "straight" / "model.pt"
    state = torch.load(weights, weights_only=True)
    name = next(k for k in state if k.endswith("weight") and "rnn" not in k)
    state[name] = state[name] * 1.05  # one layer's weights 5 % off
    torch.save(state, weights)
    damaged = read_network_set(copy)
    with pytest.raises(RailsuspInputError, match="straight.*weights are damaged"):
        check_references(damaged, ["straight"])


def test_names_and_folders_resolve_and_bad_ones_are_refused(shipped, tmp_path):
    assert resolve_network_set(str(shipped.folder)) == shipped.folder
    with pytest.raises(RailsuspInputError, match=r"'nowhere': neither .*\(c80_k6\)"):
        resolve_network_set("nowhere")
    (tmp_path / MANIFEST).write_text('{"format": "other"}')
    with pytest.raises(RailsuspInputError, match="format 'other'"):
        read_network_set(tmp_path)
    broken = tmp_path / "broken"
    shutil.copytree(shipped.folder, broken)
    (broken / "uphill" / "model.pt").unlink()
    with pytest.raises(RailsuspInputError, match="'uphill' lacks model.pt"):
        read_network_set(broken)


def test_installed_set_is_a_run_s_surrogates_folder(shipped, tmp_path):
    dest = install_network_set(shipped, tmp_path / "run" / "surrogates")
    assert (dest / ACCURACY).exists() and (dest / MANIFEST).exists()
    model = SurrogateForces(dest / shipped.kind)
    assert model.parameters == shipped.parameters
    assert sorted(model.conditions) == sorted(shipped.conditions)


def test_a_written_set_reproduces_the_references_of_its_networks(shipped, tmp_path):
    table = pd.read_csv(shipped.folder / ACCURACY)
    ns = write_network_set(
        shipped.folder,
        tmp_path / "again",
        name="again",
        conditions=["straight"],
        accuracy=table[table.condition == "straight"],
        reproduce=["railsusp ..."],
    )
    assert ns.conditions == ("straight",) and ns.model_revision == shipped.model_revision
    mine, theirs = ns.references["straight"], shipped.references["straight"]
    assert mine["seed"] == theirs["seed"] and mine["params_si"] == theirs["params_si"]
    for key, values in theirs["statistics"].items():
        assert mine["statistics"][key] == pytest.approx(values, rel=1e-6)
    with pytest.raises(RailsuspInputError, match=r"no network given for condition\(s\) curve"):
        write_network_set(
            {"straight": shipped.bundle("straight")},
            tmp_path / "short",
            name="short",
            conditions=["straight", "curve"],
            accuracy=table,
            reproduce=[],
        )
    assert not (tmp_path / "short").exists()
    with pytest.raises(RailsuspInputError, match="one kind and one parameter list"):
        bp = tmp_path / "mixed"
        shutil.copytree(shipped.folder, bp)
        doc = (bp / "curve" / "surrogate.json").read_text()
        (bp / "curve" / "surrogate.json").write_text(doc.replace('"X19"', '"X17"'))
        write_network_set(
            bp,
            tmp_path / "no",
            name="no",
            conditions=["straight", "curve"],
            accuracy=table,
            reproduce=[],
        )


def test_the_run_folder_of_the_surrogates():
    assert surrogates_run("c80_k6", 128) == PRETRAINED_RUN
    assert surrogates_run(None, 128) == OWN_CAMPAIGN_RUN
    assert surrogates_run(None, 0) == SENSITIVITY_RUN


def test_an_unreadable_network_is_refused_in_one_line(shipped, tmp_path):
    copy = tmp_path / "set"
    shutil.copytree(shipped.folder, copy)
    weights = copy / "curve" / "model.pt"
    weights.write_bytes(weights.read_bytes()[:1000])  # truncated
    cut = r"surrogate.pretrained: surrogate weights .*curve.*model.pt is cut short or damaged"
    with pytest.raises(RailsuspInputError, match=cut):
        check_network_set(
            read_network_set(copy),
            wagon=load_wagon(None),
            kind="cnn-gru-seq",
            conditions=[get_condition("curve")],
        )
    try:
        check_network_set(
            read_network_set(copy),
            wagon=load_wagon(None),
            kind="cnn-gru-seq",
            conditions=[get_condition("curve")],
        )
    except RailsuspInputError as exc:
        assert "\n" not in str(exc)
