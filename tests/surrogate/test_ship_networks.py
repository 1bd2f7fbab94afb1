"""bench/ship_networks.py: a network set made of networks from several campaigns, each
condition's accuracy rows scored on its own campaign's test runs or kept from an existing
set, and its options refused in one line."""

import json
import re
import shutil
from pathlib import Path

import pandas as pd
import pytest

from conftest import bench_script, family_campaign
from railsusp.campaign import load_campaign
from railsusp.conditions import get_condition
from railsusp.surrogate import TrainConfig, load, train_surrogate
from railsusp.surrogate.network_set import ACCURACY, MANIFEST, read_network_set
from railsusp.surrogate.split import campaign_split

SHIPPED = Path(__file__).parents[2] / "src" / "railsusp" / "data" / "networks" / "c80_k6"
KEYS = ("X13", "X14")
CURVE = get_condition("curve", duration_s=2.0, n_steps=100)


@pytest.fixture(scope="module")
def ship():
    return bench_script("ship_networks")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A tiny curve campaign with a sequence CNN-GRU of two keys in surrogates/tiny/."""
    # the cant family holds the condition's own 110 mm, on which the references are made
    run = family_campaign(tmp_path_factory.mktemp("ship") / "run", KEYS, CURVE, cant_mm=(0, 120))
    tcfg = TrainConfig(
        epochs=1, batches_per_epoch=2, chunk_steps=60, chunks_per_batch=4, val_windows=100
    )
    train_surrogate(
        run,
        "curve",
        kind="cnn-gru-seq",
        parameters=KEYS,
        window=20,
        train=tcfg,
        record_correction=False,
        out=run / "surrogates" / "tiny" / "curve",
    )
    return run


def args(tmp_path, *extra):
    reproduce = tmp_path / "reproduce.txt"
    reproduce.write_text("# how\npython train.py\n\n", "utf-8")
    return [
        "--name",
        "mine",
        "--out",
        str(tmp_path / "set"),
        "--reproduce",
        str(reproduce),
        "--results",
        str(tmp_path / "ship.json"),
        *extra,
    ]


def test_kept_conditions_keep_their_bundles_and_rows(ship, tmp_path):
    """``COND=SET``: the set's network and its rows, with the campaign each was scored on
    (from the network's own meta where the set's table does not say)."""
    old = tmp_path / "old"
    shutil.copytree(SHIPPED, old)
    table = pd.read_csv(old / ACCURACY)
    table.drop(columns="scored_on", errors="ignore").to_csv(old / ACCURACY, index=False)
    rc = ship.main(
        args(
            tmp_path,
            "--conditions",
            "straight,uphill",
            "--source",
            f"straight={old}",
            "--source",
            f"uphill={old}",
        )
    )
    assert rc == 0
    ns = read_network_set(tmp_path / "set")
    assert ns.conditions == ("straight", "uphill") and ns.reproduce == ("# how", "python train.py")
    new = pd.read_csv(tmp_path / "set" / ACCURACY)
    # each kept condition's rows: its campaign's, and those of a later revision's scoring
    counts = {c: int((table.condition == c).sum()) for c in ("straight", "uphill")}
    assert list(new.condition) == [c for c, n in counts.items() for _ in range(n)]
    for cond in ns.conditions:
        kept = table[table.condition == cond].drop(columns="scored_on", errors="ignore")
        mine = new[new.condition == cond]
        pd.testing.assert_frame_equal(
            mine[kept.columns].reset_index(drop=True), kept.reset_index(drop=True)
        )
        assert set(mine.scored_on) == {load(old / cond).meta["campaign"]}
        assert (tmp_path / "set" / cond / "model.pt").read_bytes() == (
            old / cond / "model.pt"
        ).read_bytes()
    assert (tmp_path / "ship.json").exists()


def test_a_source_of_another_campaign_is_scored_there(ship, tiny, tmp_path):
    """``COND=RUN:KIND`` with ``--run`` naming nothing else; a folder with ':' in its name
    that holds a set is read as the set."""
    odd = tmp_path / "v1:final"
    assert ship.main(args(tmp_path, "--conditions", "curve", "--source", f"curve={tiny}:tiny")) == 0
    shutil.copytree(tmp_path / "set", odd)
    rows = pd.read_csv(tmp_path / "set" / ACCURACY)
    assert set(rows.scored_on) == {str(tiny)}
    again = tmp_path / "again"
    again.mkdir()
    assert ship.main(args(again, "--conditions", "curve", "--source", f"curve={odd}")) == 0
    kept = pd.read_csv(again / "set" / ACCURACY)
    pd.testing.assert_frame_equal(kept, rows)  # scored_on kept as the set says


def test_a_condition_from_a_campaign_is_scored_on_its_test_runs(ship, tiny, tmp_path):
    assert (
        ship.main(args(tmp_path, "--run", str(tiny), "--kind", "tiny", "--conditions", "curve"))
        == 0
    )
    rows = pd.read_csv(tmp_path / "set" / ACCURACY)
    split = campaign_split(load_campaign(tiny))
    assert set(rows.target) == {"Y", "Q"} and set(rows.scored_on) == {str(tiny)}
    assert (rows.n_samples == len(split.test)).all() and (rows.test_tracks == len(split.test)).all()
    assert (rows.held_out == "tracks and parameters").all()
    assert read_network_set(tmp_path / "set").parameters == KEYS


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--source", "bogie=x"], r"--source 'bogie=x': expected COND=RUN:KIND or COND=SET"),
        (["--source", "straight="], r"--source 'straight=': expected"),
        (["--source", f"straight={SHIPPED}"], r"--run and --kind are needed for curve, uphill"),
        (["--run", "nowhere", "--kind", "k"], r"nowhere"),
        (["--source", "straight=nowhere"], r"--source 'straight=nowhere': nowhere holds no"),
        (
            ["--source", f"straight={SHIPPED}", "--source", f"straight={SHIPPED}"],
            r"straight has a --source already",
        ),
        (
            [
                *(f"--source={c}={SHIPPED}" for c in ("straight", "curve", "uphill")),
                "--run",
                "r",
                "--kind",
                "k",
            ],
            r"--run/--kind: every condition has a --source",
        ),
    ],
)
def test_bad_options_are_refused_in_one_line(ship, tmp_path, capsys, extra, match):
    assert ship.main(args(tmp_path, *extra)) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and re.search(match, err), err
    assert not (tmp_path / "set").exists()


def test_a_set_of_two_parameter_lists_is_refused(ship, tiny, tmp_path, capsys):
    """The tiny campaign's two-key network beside a shipped five-key one."""
    extra = ["--run", str(tiny), "--kind", "tiny", "--conditions", "straight,curve"]
    assert ship.main(args(tmp_path, *extra, "--source", f"straight={SHIPPED}")) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "one kind and one parameter list" in err
    assert not (tmp_path / "set").exists()


def test_a_set_of_another_revision_or_without_the_condition_is_refused(ship, tmp_path, capsys):
    old = tmp_path / "old"
    shutil.copytree(SHIPPED, old)
    manifest = json.loads((old / MANIFEST).read_text())
    (old / MANIFEST).write_text(json.dumps({**manifest, "conditions": ["straight", "curve"]}))
    assert ship.main(args(tmp_path, "--conditions", "uphill", "--source", f"uphill={old}")) == 2
    assert "the set holds straight, curve, not uphill" in capsys.readouterr().err
    (old / MANIFEST).write_text(json.dumps({**manifest, "model_revision": "1999-01-01"}))
    assert ship.main(args(tmp_path, "--conditions", "curve", "--source", f"curve={old}")) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "force-law revision '1999-01-01'" in err


def test_a_network_is_scored_only_on_its_own_campaign(ship, tiny, tmp_path, capsys):
    """A network copied into another campaign's folder is not scored on that campaign's
    test runs (they may have been its training runs)."""
    other = family_campaign(tmp_path / "other", KEYS, CURVE, seed=9, cant_mm=(0, 120))
    shutil.copytree(tiny / "surrogates" / "tiny", other / "surrogates" / "tiny")
    assert (
        ship.main(args(tmp_path, "--conditions", "curve", "--source", f"curve={other}:tiny")) == 2
    )
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "not on" in err and "test runs are held out" in err
