"""The split by track and parameter set, its file, and surrogates scored on held-out tracks."""

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from railsusp.campaign import load_campaign, make_config, run_campaign
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.surrogate import TrainConfig, load, train_surrogate
from railsusp.surrogate.compare import compare, table7
from railsusp.surrogate.split import (
    PARTS,
    Split,
    campaign_split,
    load_split,
    save_split,
    split_by_track_and_parameters,
    split_path,
)

KEYS = ("X13", "X14", "X15")


def _synthetic(n: int, rng: np.random.Generator, n_conditions: int = 2):
    """A design with repeated parameter rows and track tables with repeated seeds, within
    and across conditions."""
    pool = rng.random((3 * n, 2))
    x = pool[rng.integers(0, 3 * n, size=n)]  # some rows repeat another
    design = pd.DataFrame({"sample_id": np.arange(n), "X13": x[:, 0], "X14": x[:, 1]})
    tracks = [
        pd.DataFrame({"sample_id": np.arange(n), "seed": rng.integers(0, 10 * n, size=n)})
        for _ in range(n_conditions)
    ]
    return design, tracks


@pytest.mark.parametrize("seed", range(8))
def test_no_track_seed_or_parameter_set_in_two_parts(seed):
    rng = np.random.default_rng(seed)
    design, tracks = _synthetic(60, rng)
    assert design.duplicated(["X13", "X14"]).any()  # the case the grouping is there for
    assert any(t.seed.duplicated().any() for t in tracks)
    split = split_by_track_and_parameters(design, tracks, seed=seed)
    ids = {p: set(split.part(p).tolist()) for p in PARTS}
    assert set().union(*ids.values()) == set(range(60))
    assert all(ids[p] for p in PARTS)
    owner_seed, owner_row = {}, {}
    for p in PARTS:
        for i in ids[p]:
            for t in tracks:  # a seed in any condition belongs to one part only
                assert owner_seed.setdefault(int(t.seed[i]), p) == p
            row = tuple(design.loc[i, ["X13", "X14"]])
            assert owner_row.setdefault(row, p) == p


def test_distinct_samples_split_near_the_fractions_and_common_seeds_hold_out_parameters():
    n = 100
    design = pd.DataFrame({"sample_id": np.arange(n), "X13": np.arange(n, dtype=float)})
    indep = [pd.DataFrame({"sample_id": np.arange(n), "seed": np.arange(n) + 1000})]
    s = split_by_track_and_parameters(design, indep, seed=1)
    assert (len(s.train), len(s.val), len(s.test)) == (70, 15, 15)
    assert s.held_out_tracks and s.held_out == "tracks and parameters"
    common = [pd.DataFrame({"sample_id": np.arange(n), "seed": np.full(n, 7)})]
    c = split_by_track_and_parameters(design, common, seed=1)
    assert not c.held_out_tracks and len(c.test) == 15  # parameters only, no grouping
    one = pd.DataFrame({"sample_id": np.arange(4), "X13": np.ones(4)})
    with pytest.raises(RailsuspInputError, match="4 samples form 1 distinct"):
        split_by_track_and_parameters(one, [], seed=0)
    with pytest.raises(RailsuspInputError, match="split fractions"):
        split_by_track_and_parameters(design, indep, fractions=(0.5, 0.5, 0.5))


def test_on_perfect_track_every_seed_is_one_track_and_layouts_count():
    """Without irregularities (class -1) the seed shapes no track: 100 seeds on perfect
    track were said to hold out tracks ("tracks and parameters", 12 track realisations
    recorded; stop 78's hunt). Then only layouts differ: a family of curve radii holds
    tracks out, samples of one layout are one track and stay in one part."""
    from railsusp.surrogate.split import distinct_tracks

    n = 100
    design = pd.DataFrame({"sample_id": np.arange(n), "X13": np.arange(n, dtype=float)})
    seeds = np.arange(n) + 1000
    perfect = pd.DataFrame(
        {"sample_id": np.arange(n), "seed": seeds, "irregularity_class": -1,
         "curve_radius_m": np.nan, "cant_mm": 0.0}
    )  # fmt: skip
    s = split_by_track_and_parameters(design, [perfect], seed=1)
    assert not s.held_out_tracks and s.held_out == "parameters (one track)"
    assert (
        distinct_tracks(perfect) == 1 and distinct_tracks(perfect.assign(irregularity_class=5)) == n
    )
    radii = perfect.assign(curve_radius_m=np.repeat([300.0, 400.0, 500.0, 600.0, 800.0], 20))
    r = split_by_track_and_parameters(design, [radii], seed=1)
    assert r.held_out_tracks and distinct_tracks(radii, np.arange(10)) == 1
    for part in PARTS:  # each radius (track) in one part only
        for other in PARTS:
            if part != other:
                mine = set(radii.curve_radius_m[r.part(part)])
                assert not mine & set(radii.curve_radius_m[r.part(other)])
    rough = split_by_track_and_parameters(design, [perfect.assign(irregularity_class=5)], seed=1)
    assert rough.held_out_tracks


def test_split_file_round_trip_and_refusals(tmp_path):
    rng = np.random.default_rng(3)
    design, tracks = _synthetic(30, rng)
    split = split_by_track_and_parameters(design, tracks, seed=5)
    path = save_split(tmp_path / "splits" / "seed-5.json", split)
    back = load_split(path)
    for p in PARTS:
        np.testing.assert_array_equal(back.part(p), split.part(p))
    assert (back.seed, back.fractions, back.held_out_tracks) == (5, split.fractions, True)
    doc = json.loads(path.read_text())
    doc["test"].append(doc["train"][0])  # a sample in two parts
    path.write_text(json.dumps(doc))
    with pytest.raises(RailsuspInputError, match="share samples"):
        load_split(path)
    path.write_text("[1, 2]")
    with pytest.raises(RailsuspInputError, match="not a railsusp split"):
        load_split(path)


@pytest.fixture(scope="module")
def many_tracks(tmp_path_factory):
    out = tmp_path_factory.mktemp("tracks") / "run"
    cond = get_condition("curve", duration_s=2.0, n_steps=100)
    cfg = make_config(
        [cond],
        20,
        parameters=KEYS,
        seed=11,
        batch_size=10,
        independent_seeds=True,
        track_family={"curve_radius_m": (250.0, 400.0), "cant_mm": (60.0, 110.0)},
        other_parameters={"X19": (20e6, 40e6)},
    )
    run_campaign(cfg, out)
    return out


def test_campaign_split_is_stored_and_checked(many_tracks, tmp_path):
    camp = load_campaign(many_tracks)
    split = campaign_split(camp, seed=0)
    assert split_path(many_tracks, 0).exists() and split.held_out_tracks
    again = campaign_split(camp, seed=0)
    np.testing.assert_array_equal(again.test, split.test)
    seeds = camp.tracks("curve").set_index("sample_id").seed
    assert not set(seeds[split.test]) & set(seeds[split.train])
    with pytest.raises(RailsuspInputError, match="fractions"):
        campaign_split(camp, seed=0, fractions=(0.6, 0.2, 0.2))
    doc = json.loads(split_path(many_tracks, 0).read_text())
    doc["campaign_hash"] = "0000"
    bad = tmp_path / "bad"
    bad.mkdir()
    for f in ("campaign.json", "design.parquet"):
        (bad / f).write_bytes((many_tracks / f).read_bytes())
    save_path = split_path(bad, 0)
    save_path.parent.mkdir()
    save_path.write_text(json.dumps(doc))
    with pytest.raises(RailsuspInputError, match="another campaign configuration"):
        campaign_split(load_campaign(bad), seed=0)


def test_many_track_training_is_scored_on_unseen_tracks(many_tracks):
    """A tiny end to end: many-track campaign -> CNN-GRU for two epochs, and RBF ->
    Table 7 on the test samples, whose tracks and parameters no network saw."""
    tcfg = TrainConfig(epochs=2, batches_per_epoch=4, batch_size=32, val_windows=200)
    table = compare(many_tracks, models=("cnn-gru", "rbf"), train=tcfg)
    split = campaign_split(load_campaign(many_tracks))
    assert set(table.held_out) == {"tracks and parameters"}
    assert (table.test_tracks == len(split.test)).all()
    assert (table.n_samples == len(split.test)).all()
    assert np.isfinite(table.relative_error_of_mean).all() and np.isfinite(table.nrmse).all()
    t7 = table7(table)
    assert set(t7["held out"]) == {"tracks and parameters"} and len(t7) == 2
    assert (t7["test runs failed"] == 0).all()  # counted (none here), not dropped unsaid
    sur_seen = load(many_tracks / "surrogates" / "cnn-gru" / "curve").meta["seen_track_seeds"]
    test_seeds = (
        load_campaign(many_tracks).tracks("curve").set_index("sample_id").loc[split.test, "seed"]
    )
    assert sur_seen and not set(sur_seen) & set(test_seeds.tolist())
    sur = load(many_tracks / "surrogates" / "cnn-gru" / "curve")
    assert sur.meta["test_ids"] == split.test.tolist()
    assert sur.meta["split"]["held_out_tracks"] and sur.meta["track_realisations"] == 20
    from railsusp.vehicle import MODEL_REVISION

    assert sur.meta["model_revision"] == MODEL_REVISION  # the force laws it learnt
    assert "cant" in sur.spec.track_channels  # the cant varies, so the windows carry it
    assumed = {r["symbol"]: r["assumed"] for r in sur.meta["assumed_parameters"]}
    assert assumed["X19"] == "varied" and assumed["X20"] == "nominal"
    # it serves its condition anywhere in the family, and refuses outside it
    cond = sur.condition.with_changes(curve_radius_m=300.0, cant_mm=80.0, seed=99)
    x = np.array([[16.1e6, 8.3e6, 170e6]])
    assert np.isfinite(sur.predict(x, cond)[0, 20:]).all()
    with pytest.raises(ValueError, match="differs in curve_radius_m"):
        sur.predict(x, cond.with_changes(curve_radius_m=600.0))
    # a family field is checked against the family even where it equals the surrogate's own
    # condition: with the family's cant up to 100 mm, the condition's own 110 mm is outside
    sur.meta["track_family"]["cant_mm"] = [60.0, 100.0]
    assert sur.condition.cant_mm == 110.0
    with pytest.raises(
        ValueError, match=r"cant_mm = 110.0 \(trained on the track family 60 to 100\)"
    ):
        sur.predict(x, sur.condition)
    assert np.isfinite(sur.predict(x, sur.condition.with_changes(cant_mm=90.0))[0, 20:]).all()


def test_train_surrogate_uses_the_stored_split(many_tracks):
    tcfg = TrainConfig(epochs=1, batches_per_epoch=4, batch_size=64, val_windows=300)
    sur = train_surrogate(
        many_tracks, "curve", kind="bp", train=tcfg, split_seed=3, record_correction=False
    )
    split = load_split(split_path(many_tracks, 3))
    assert sur.meta["train_ids"] == split.train.tolist()
    assert sur.meta["val_ids"] == split.val.tolist()


def test_estimate_lists_the_parameters_it_did_not_estimate(many_tracks, tmp_path):
    """What the force model assumed of the parameters not estimated goes into the estimate's
    record and the summary table: X19 varied over its prior in training, X20 at nominal."""
    from railsusp import summary
    from railsusp.store import write_json
    from railsusp.surrogate import not_estimated

    tcfg = TrainConfig(epochs=1, batches_per_epoch=2, batch_size=32, val_windows=200)
    train_surrogate(many_tracks, "curve", kind="bp", train=tcfg, record_correction=False)
    rows = {r["symbol"]: r for r in not_estimated(many_tracks / "surrogates" / "bp", KEYS)}
    assert set(rows) == {"X11", "X12", "X16", "X17", "X18", "X19", "X20"}
    assert (rows["X19"]["low"], rows["X19"]["high"]) == pytest.approx((20000, 40000))
    assert rows["X20"]["assumed"] == "nominal"
    held = not_estimated(None, KEYS)  # the simulator holds the others at nominal
    assert {r["assumed"] for r in held} == {"nominal"} and len(held) == 7
    run = tmp_path / "run"
    write_json(
        run / "estimate" / "estimate.json",
        {
            "parameters": list(KEYS),
            "estimate_display": {"X13": 16.1, "X14": 8.3, "X15": 170.0},
            "not_estimated": list(rows.values()),
        },
    )
    t = summary.estimate_table(run)
    # NSGA-II on the network alone simulated nothing: the validation's simulations held it
    # (the table said "the estimate's simulations" on every route)
    assert t.loc["X19", "verdict"] == (
        "not estimated: held at 30000 kN/m in the validation's simulations "
        "(varied over 20000-40000 kN/m in the surrogate's training)"
    )
    assert t.loc["X20", "verdict"].startswith("not estimated: held at 1000 MN/m")
    doc = json.loads((run / "estimate" / "estimate.json").read_text())
    # a polish by a refinement that compared the surrogate simulated nothing either
    doc["refinement"] = {
        "compared_model": "the window surrogates in s",
        "standard_error_pct_range": {},
    }
    doc["polished_display"] = {"X13": 16.0}
    write_json(run / "estimate" / "estimate.json", doc)
    assert "in the validation's simulations" in summary.estimate_table(run).loc["X19", "verdict"]
    doc["refinement"] = {"compared_model": "the simulator", "standard_error_pct_range": {}}
    write_json(run / "estimate" / "estimate.json", doc)
    assert summary.estimate_table(run).loc["X19", "verdict"] == (
        "not estimated: held at 30000 kN/m in the estimate's simulations and the validation "
        "(varied over 20000-40000 kN/m in the surrogate's training)"
    )


def test_the_sequence_network_is_compared_on_the_same_steps_as_the_others(many_tracks):
    """compare() trains the sequence CNN-GRU beside the baselines and scores every model
    from the longest washout, so all rows cover the same samples (the statistics GPs took
    their own window's first step until the split audit of stop 60)."""
    tcfg = TrainConfig(epochs=1, batches_per_epoch=2, chunk_steps=60, chunks_per_batch=4)
    table = compare(
        many_tracks, models=("cnn-gru-seq", "rbf", "gp-stats"), conditions=["curve"],
        train=tcfg, washout=40,
    )  # fmt: skip
    assert set(table.model) == {"cnn-gru-seq", "rbf", "gp-stats"}
    assert (table.first_step == 40).all()
    assert np.isfinite(table.relative_error_of_mean).all()
    sur = load(many_tracks / "surrogates" / "cnn-gru-seq" / "curve")
    assert sur.kind == "cnn-gru-seq" and sur.spec.window == 40


def test_a_saltelli_base_samples_rows_are_never_split_between_parts(tmp_path):
    """A Saltelli row AB_ij whose changed parameter is not a network input has A_j's inputs
    exactly, on A_j's track: the split grouped by every sampled parameter and put 13 of 29
    test samples' inputs in training too (the split audit of stop 60). Each base sample's
    block now goes to one part; a stored split that straddles blocks is drawn again."""
    from railsusp.surrogate.split import _splits_blocks, saltelli_blocks

    cond = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    cfg = make_config([cond], 16, design="sobol", parameters=("X13", "X14"), batch_size=64)
    run_campaign(cfg, tmp_path / "camp", max_batches=0)  # the design alone is enough
    camp = load_campaign(tmp_path / "camp")
    blocks = saltelli_blocks(camp)
    assert blocks.size == 16 * 4 and np.array_equal(blocks[:5], [0, 0, 0, 0, 1])
    split = campaign_split(camp)
    assert _splits_blocks(split, camp)
    for name in ("train", "val", "test"):
        assert len(split.part(name)) % 4 == 0  # whole blocks
    # a split of one row per group (as drawn before) is drawn again
    rows = np.arange(64)
    leaky = Split(rows[:44], rows[44:54], rows[54:], 0, (0.7, 0.15, 0.15), False, cfg.hash())
    assert not _splits_blocks(leaky, camp)
    save_split(split_path(camp.path, 0), leaky)
    assert _splits_blocks(campaign_split(camp), camp)


def test_a_network_continued_on_a_campaign_is_not_scored_on_tracks_it_learnt(caplog):
    """Campaigns of one design seed share their first track seeds: a network continued on
    another campaign could be scored on tracks it trained on (the split audit of stop 60).
    Refused where the network records the seeds it saw; warned of where it does not."""
    from types import SimpleNamespace

    from railsusp.surrogate import check_unseen_tracks

    cond = get_condition("curve")
    start = SimpleNamespace(meta={"seen_track_seeds": [1, 2, 3]}, condition=cond)
    test = SimpleNamespace(n_samples=2, seeds=np.array([3, 9]), condition=cond)
    with pytest.raises(RailsuspInputError, match=r"1 of this campaign's test tracks \(seeds 3\)"):
        check_unseen_tracks(start, "net", test)
    check_unseen_tracks(start, "net", SimpleNamespace(**{**vars(test), "seeds": np.array([8])}))
    with caplog.at_level("WARNING", logger="railsusp.surrogate"):
        check_unseen_tracks(SimpleNamespace(meta={}, condition=cond), "old-net", test)
    assert "old-net records no track seeds" in caplog.text


def test_the_train_commands_line_names_each_conditions_tracks_and_failed_test_runs(monkeypatch):
    """``railsusp train`` printed one line of test tracks, of the last condition alone, and
    its table counted the test runs that ran with no word of those that failed (derailed),
    which ``compare`` counts (stop 78's hunt). Each condition's line says both."""
    import railsusp.surrogate.split as split_module
    from railsusp.cli.surrogates import _held_out_line

    split = Split(np.arange(6), np.arange(6, 8), np.arange(8, 12), 0, (0.7, 0.15, 0.15), True)
    monkeypatch.setattr(split_module, "campaign_split", lambda camp, seed: split)
    monkeypatch.setattr(split_module, "condition_tracks", lambda camp, cond, ids: len(ids))

    class Test:
        sample_ids = np.array([8, 10, 11])

    sur = type("Sur", (), {"meta": {"split": {"seed": 0}}})()
    assert _held_out_line(None, "fast", sur, Test()) == (
        "fast 3 on 3 distinct track(s), 1 failed (e.g. derailed) and not scored"
    )
    Test.sample_ids = np.arange(8, 12)
    assert _held_out_line(None, "st", sur, Test()) == "st 4 on 4 distinct track(s)"


def test_an_interrupted_compare_leaves_no_table_of_the_networks_it_replaced(many_tracks, tmp_path):
    """compare.csv, the pipeline's mark of a finished stage, was written last but never
    taken away first: a compare interrupted while it trained the networks afresh left the
    older table beside networks it no longer described, until it was run again."""
    run = tmp_path / "run"
    shutil.copytree(many_tracks, run)
    tcfg = TrainConfig(epochs=1, batches_per_epoch=2, batch_size=32, val_windows=200)
    compare(run, models=("bp",), conditions=["curve"], train=tcfg)
    table = run / "surrogates" / "compare.csv"
    assert table.exists() and table.with_suffix(".json").exists()

    def interrupt(message: str) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        compare(run, models=("bp",), conditions=["curve"], train=tcfg, progress=interrupt)
    assert not table.exists() and not table.with_suffix(".json").exists()
