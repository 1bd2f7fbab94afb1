"""bench/surrogate_tracks.py: Table 7 on held-out tracks and parameters from a tiny many-track
campaign (short records, one short epoch), and the campaign it makes."""

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import bench_script
from railsusp.campaign import load_campaign, run_campaign
from railsusp.errors import RailsuspInputError
from railsusp.params import MAIN_SUSPENSION
from railsusp.surrogate import TrainConfig, load
from railsusp.surrogate.split import campaign_split

#: the network set shipped with railsusp (the sequence CNN-GRU reading the nominal response)
SHIPPED = str(Path(__file__).parents[2] / "src" / "railsusp" / "data" / "networks" / "c80_k6")


@pytest.fixture(scope="module")
def bench():
    return bench_script("surrogate_tracks")


@pytest.fixture(scope="module")
def tiny_run(bench, tmp_path_factory):
    out = tmp_path_factory.mktemp("tracks") / "run"
    cfg = bench.tracks_config(20, conditions=("straight",), duration_s=2.0, seed=3, batch_size=10)
    run_campaign(cfg, out)
    return out


def test_the_campaign_varies_tracks_and_every_parameter_not_a_key(bench):
    cfg = bench.tracks_config(16, duration_s=3.0)
    assert cfg.independent_seeds and cfg.parameters == bench.KEYS
    assert set(cfg.other_parameters) == set(MAIN_SUSPENSION) - set(bench.KEYS)
    assert cfg.track_family.ranges()["curve_radius_m"] == [250.0, 400.0]
    assert [c.name for c in cfg.conditions] == ["straight", "curve", "uphill"]
    assert all(c.duration_s == 3.0 for c in cfg.conditions)
    with pytest.raises(RailsuspInputError, match="curve_radius_m"):
        bench.tracks_config(16, radius_m=(10.0, 400.0))


def test_table7_on_held_out_tracks(bench, tiny_run):
    tcfg = TrainConfig(epochs=1, batches_per_epoch=2, batch_size=32, val_windows=200)
    table = bench.table_on_tracks(tiny_run, models=("bp", "rbf"), train=tcfg, variant_window=30)
    t7 = bench.table7_per_run(table)
    assert list(t7.model) == ["bp", "rbf", "cnn-gru w30"]
    camp = load_campaign(tiny_run)
    split = campaign_split(camp)
    seeds = camp.tracks("straight").set_index("sample_id").seed
    assert not set(seeds[split.test]) & (set(seeds[split.train]) | set(seeds[split.val]))
    assert (t7["test runs"] == len(split.test)).all()
    assert (t7["test tracks"] == len(split.test)).all()  # every test run on its own track
    assert set(t7["held out"]) == {"tracks and parameters"}
    errors = t7[[c for c in t7.columns if c.endswith("%") and "alone" not in c]]
    assert np.isfinite(errors.to_numpy()).all() and (errors.to_numpy() >= 0).all()
    assert (t7["Y worst run %"] >= t7["Y per run %"]).all()
    assert (t7["Q worst run %"] >= t7["Q per run %"]).all()
    var = load(tiny_run / "surrogates" / "cnn-gru-w30" / "straight")
    assert var.spec.window == 30 and var.meta["test_ids"] == split.test.tolist()
    rates = bench.inference_rates(tiny_run, "straight", ["bp"], threads=1, repeats=1)
    assert rates["bp"] > 0 and np.isfinite(rates["bp"])


def test_nominal_variant_and_the_nominal_wagon_alone(bench, tiny_run):
    """``nominal=True`` makes the nominal twins, trains the CNN-GRU that reads them and
    scores the nominal wagon's own forces as a prediction beside it."""
    from railsusp.campaign.twins import twins_complete

    tcfg = TrainConfig(epochs=1, batches_per_epoch=2, batch_size=32, val_windows=200)
    table = bench.table_on_tracks(tiny_run, models=("bp",), train=tcfg, nominal=True)
    assert twins_complete(tiny_run)
    t7 = bench.table7_per_run(table)
    assert list(t7.model) == ["bp", "cnn-gru-nominal", "nominal wagon"]
    alone = t7[t7.model == "nominal wagon"].iloc[0]
    # the nominal wagon explains part of each test run, not all of it (parameters differ)
    assert 0.0 < alone["Y per run %"] < 100.0 and alone["Y R2"] < 1.0
    sur = load(tiny_run / "surrogates" / "cnn-gru-nominal" / "straight")
    assert sur.spec.nominal_response
    rates = bench.inference_rates(tiny_run, "straight", ["cnn-gru-nominal"], threads=1, repeats=1)
    assert rates["cnn-gru-nominal"] > 0


def test_an_architecture_variant_is_saved_under_its_tag_and_loads_as_built(bench, tiny_run):
    """``architecture`` changes the nominal network's sizes and dropout, ``tag`` keeps it
    beside the study's network instead of over it, and the saved network is the one built."""
    tcfg = TrainConfig(
        epochs=1,
        batches_per_epoch=1,
        batch_size=32,
        val_windows=200,
        chunk_steps=60,
        chunks_per_batch=4,
    )
    from railsusp.campaign.twins import run_nominal_twins

    run_nominal_twins(tiny_run)  # made by the test above when it ran first; resumes
    arch = {"dropout": 0.0, "rnn_hidden": (24, 12, 8)}
    rows = bench.nominal_rows(
        tiny_run, "straight", tcfg, 0, "cnn-gru-seq", arch, "-small", window=20
    )
    assert {r["model"] for r in rows} == {"cnn-gru-seq-nominal-small", "nominal wagon"}
    sur = load(tiny_run / "surrogates" / "cnn-gru-seq-nominal-small" / "straight")
    assert sur.net_config.dropout == 0.0 and sur.net_config.rnn_hidden == (24, 12, 8)
    assert sur.spec.nominal_response and sur.net_config.kind == "cnn-gru-seq"
    assert not (tiny_run / "surrogates" / "cnn-gru-seq-nominal").exists()


def test_targets_are_judged_per_run_in_every_condition(bench):
    t7 = pd.DataFrame(
        {
            "model": ["cnn-gru", "cnn-gru", "bp"],
            "Q per run %": [0.5, 1.2, 0.1],
            "Y per run %": [1.0, 1.9, 0.1],
        }
    )
    met = bench.targets_met(t7, {"cnn-gru": 2e5})
    assert not met["vertical_per_run_ok"] and met["lateral_per_run_ok"]
    assert met["windows_per_second_ok"]
    assert not bench.targets_met(t7.iloc[[0, 2]], {"cnn-gru": 9e4})["windows_per_second_ok"]
    assert bench.targets_met(t7.iloc[[0, 2]], {})["vertical_per_run_ok"]
    # a run that trained other networks measured nothing of the CNN-GRU: not "met"
    absent = bench.targets_met(t7[t7.model == "bp"], {"bp": 5e5})
    assert absent["lateral_per_run_ok"] is None and absent["vertical_per_run_ok"] is None
    assert absent["windows_per_second_ok"] is None


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--dense", "64,0", "--nominal", "--tag", "x"], "--dense 64,0: accepted sizes >= 1"),
        (["--pair-weight", "-1", "--tag", "x"], r"pair_weight = -1.0: accepted \[0, 100\]"),
        (["--pair-step", "0.9", "--tag", "x"], r"step = 0.9: accepted a fraction of the range"),
        (["--pair-weight", "1", "--tag", "x"], "--pair-weight: accepted with --nominal"),
        (
            ["--patience", "0", "--tag", "x"],
            "training patience = 0: accepted an integer from 1 to 10000",
        ),
        (
            ["--fine-tune-lr-factor", "2", "--tag", "x"],
            r"fine_tune_lr_factor = 2.0: accepted",
        ),
        (["--init-inputs", "--tag", "x"], "--init-inputs: accepted only with --init-from"),
        # the nominal networks' options without --nominal were ignored (exit 0 after training
        # the others), and an --init-from naming nothing was found after the campaign ran
        (
            ["--dropout", "0.1", "--tag", "x"],
            r"--dropout, --tag: accepted only with --nominal \(they set the networks",
        ),
        (["--nominal-kinds", "cnn-gru"], "error: --nominal-kinds: accepted only with --nominal"),
        (
            ["--init-from", "nothing_here", "--init-inputs", "--tag", "x"],
            "--init-from, --init-inputs, --tag: accepted only with --nominal",
        ),
        (["--nominal-context", "none"], "--nominal-context: accepted only with --nominal"),
        (["--pair-twins", "2"], "--pair-twins: accepted only with --pair-weight above 0"),
        (
            ["--nominal", "--init-from", "nothing_here", "--tag", "x"],
            r"--init-from nothing_here: no network saved under .*nothing_here/<condition>/ for "
            "straight, curve, uphill",
        ),
        (["--score", "/nowhere/set"], "--score /nowhere/set: accepted a folder of saved networks"),
        (["--score", SHIPPED], "its straight network reads the nominal response; accepted with"),
        (
            ["--nominal", "--score", SHIPPED, "--score", SHIPPED],
            "accepted folders of different names",
        ),
    ],
)
def test_bad_options_are_refused_before_the_campaign_runs(
    bench, tmp_path, monkeypatch, capsys, options, message
):
    """Exit 2 with the option named, and no campaign simulated (minutes on a real one)."""
    import re
    import sys

    run = tmp_path / "never"
    monkeypatch.setattr(sys, "argv", ["surrogate_tracks.py", "--run", str(run), *options])

    def ran(*args, **kw):
        raise AssertionError("the campaign ran")

    monkeypatch.setattr(bench, "run_campaign", ran)
    with pytest.raises(SystemExit) as exc:
        bench.main()
    assert exc.value.code == 2
    assert re.search(message, capsys.readouterr().err)
    assert not run.exists()


def test_a_network_of_another_campaign_trained_on_its_inputs_and_scored(bench, tiny_run, tmp_path):
    """A network trained on a campaign with curves (whose straight network reads the cant
    channel) starts, with ``init_inputs``, a training on this campaign of the straight alone
    (no cant channel of its own): the trained network keeps the cant channel and its
    provenance, its inference rate is measured on inputs of its own features, and the
    first network scored on this campaign's test runs names the campaign it came from."""
    from railsusp.campaign.twins import run_nominal_twins

    other = tmp_path / "curves"
    run_campaign(
        bench.tracks_config(
            12, conditions=("straight", "curve"), duration_s=2.0, seed=4, batch_size=6
        ),
        other,
    )
    run_nominal_twins(other, conditions=["straight"])
    run_nominal_twins(tiny_run)
    tcfg = TrainConfig(epochs=1, batches_per_epoch=2, batch_size=32, val_windows=200)
    bench.nominal_rows(other, "straight", tcfg, 0, "cnn-gru", window=20)
    source = load(other / "surrogates" / "cnn-gru-nominal" / "straight")
    assert "cant" in source.spec.track_channels
    shutil.copytree(other / "surrogates" / "cnn-gru-nominal", tiny_run / "surrogates" / "curves")
    rows = bench.nominal_rows(
        tiny_run,
        "straight",
        tcfg,
        0,
        "cnn-gru",
        tag="-moved",
        window=20,
        init_label="curves",
        init_inputs=True,
    )
    assert {r["model"] for r in rows} == {"cnn-gru-nominal-moved", "nominal wagon"}
    moved = load(tiny_run / "surrogates" / "cnn-gru-nominal-moved" / "straight")
    assert moved.spec == source.spec
    assert moved.meta["init_inputs"]["campaign"] == str(other)
    assert moved.meta["campaign"] == str(tiny_run)
    assert all(np.isfinite(h["val_loss"]) for h in moved.meta["history"])
    rates = bench.inference_rates(
        tiny_run, "straight", ["cnn-gru-nominal-moved"], threads=1, repeats=1
    )
    assert rates["cnn-gru-nominal-moved"] > 0
    scored = bench.scored_networks(
        tiny_run, [str(other / "surrogates" / "cnn-gru-nominal")], ["straight"]
    )
    assert {r["model"] for r in scored} == {"scored:cnn-gru-nominal"}
    assert all(str(other) in r["held_out"] and "design seed 3" in r["held_out"] for r in scored)
    t7 = bench.table7_per_run(pd.concat([pd.DataFrame(rows), pd.DataFrame(scored)]))
    assert np.isfinite(t7["Y per run %"]).all()
