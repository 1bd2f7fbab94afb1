"""Campaigns: design properties, run directory, resume, Dask equivalence, features."""

import json
import shutil

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from railsusp.campaign import (
    CampaignError,
    load_campaign,
    make_config,
    make_design,
    run_campaign,
)
from railsusp.campaign.batch_files import BATCH_SIZE_KEY
from railsusp.campaign.design import batch_paths
from railsusp.conditions import get_condition
from railsusp.params import MAIN_SUSPENSION, bounds
from test_store_checksums import flip_a_bit_in_a_page

TINY = [
    get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0),
    get_condition("curve", duration_s=1.0, n_steps=50),
]


def _sorted(df: pd.DataFrame) -> pd.DataFrame:
    return df.sort_values(["condition", "quantity", "statistic", "sample_id"]).reset_index(
        drop=True
    )


@pytest.mark.parametrize("design", ["lhs", "lhs-optimised"])
def test_lhs_stratification(design):
    """Latin hypercube: each of the n equal strata of every parameter holds exactly one
    sample, and all values lie inside the Table 2 ranges."""
    cfg = make_config(TINY, 50, design=design, seed=4)
    x = make_design(cfg)[list(MAIN_SUSPENSION)].to_numpy()
    lo, hi = bounds(MAIN_SUSPENSION)
    u = (x - lo) / (hi - lo)
    assert np.all((u >= 0) & (u < 1))
    for j in range(u.shape[1]):
        strata = np.floor(u[:, j] * 50).astype(int)
        assert sorted(strata) == list(range(50))


def test_design_is_seeded_and_subset_keeps_others_nominal():
    a = make_design(make_config(TINY, 20, seed=1, parameters=("X13", "X17")))
    b = make_design(make_config(TINY, 20, seed=1, parameters=("X13", "X17")))
    pd.testing.assert_frame_equal(a, b)
    assert list(a.columns) == ["sample_id", "X13", "X17"]
    c = make_design(make_config(TINY, 20, seed=2, parameters=("X13", "X17")))
    assert not np.allclose(a.X13, c.X13)


def test_saltelli_design_size_and_power_of_two():
    cfg = make_config(TINY, 16, design="sobol", parameters=("X13", "X14", "X15"))
    assert cfg.n_runs == 16 * (3 + 2) == len(make_design(cfg))
    cfg2 = make_config(TINY, 16, design="sobol", second_order=True, parameters=("X13", "X14"))
    assert cfg2.n_runs == 16 * (2 * 2 + 2)
    with pytest.raises(CampaignError, match="power of two, got 12"):
        make_config(TINY, 12, design="sobol")


def test_bad_configurations_name_the_field():
    with pytest.raises(CampaignError, match="parameters.*X3 is a fixed parameter"):
        make_config(TINY, 10, parameters=("X3",))
    with pytest.raises(CampaignError, match="samples"):
        make_config(TINY, 0)
    with pytest.raises(CampaignError, match="wheel 'w0'"):
        make_config(TINY, 10, wheel="w0")


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "full"
    cfg = make_config(TINY, 10, batch_size=4, seed=3)
    run_campaign(cfg, out)
    return cfg, out


def test_run_directory_layout_and_features(full_run):
    cfg, out = full_run
    meta = json.loads((out / "campaign.json").read_text())
    assert meta["config_hash"] == cfg.hash() and meta["n_batches"] == 3
    assert "completed" in meta and meta["created"]["railsusp"]
    camp = load_campaign(out)
    assert camp.complete
    f = camp.features()
    # 10 samples x 2 conditions x (2 forces x 4 statistics + Y/Q max + dQ/Q max)
    assert len(f) == 10 * 2 * 10
    assert set(f.quantity) == {"Y", "Q", "YQ", "dQQ"}
    assert (f.status == 0).all()
    q_mean = camp.feature_matrix("straight", "Q", "mean")
    assert q_mean.between(110, 135).all()  # kN, around the 121.9 kN static wheel load
    assert set(f[f.condition == "curve"].wheel) == {"w1R"}
    ids, series = camp.series("curve")
    assert list(ids) == list(range(10)) and series.shape == (10, 18, 50)
    assert series.dtype == np.float32


def test_resume_after_interruption_gives_identical_store(full_run, tmp_path):
    cfg, out = full_run
    part = tmp_path / "part"
    run_campaign(cfg, part, max_batches=2)  # "killed" after two batches
    assert not load_campaign(part).complete
    assert len(list((part / "batches").glob("*/batch-?????.parquet"))) == 2
    calls = []
    run_campaign(cfg, part, progress=lambda d, t: calls.append(d))
    assert calls[0] == 8  # the two stored batches (4 + 4 runs) are not recomputed
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(part).features()), _sorted(load_campaign(out).features())
    )
    for cond in ("straight", "curve"):
        np.testing.assert_array_equal(
            load_campaign(part).series(cond)[1], load_campaign(out).series(cond)[1]
        )


def test_a_swallowed_ctrl_c_stops_the_campaign_after_the_batch_it_stored(full_run, tmp_path):
    """A Ctrl-C that Python swallowed (recorded by the command line's handler,
    railsusp.interrupts) stopped a campaign only at the pipeline's next stage boundary: every
    remaining batch was simulated first. It stops after the batch being stored, which the
    resume keeps."""
    from railsusp.interrupts import catch_interrupts, record_interrupt

    cfg, out = full_run
    part = tmp_path / "part"
    seen = []

    def swallowed(done: int, total: int) -> None:
        seen.append(done)
        if done:  # during the first batch, its KeyboardInterrupt then lost
            record_interrupt()

    restore = catch_interrupts()
    try:
        with pytest.raises(KeyboardInterrupt):
            run_campaign(cfg, part, progress=swallowed)
    finally:
        restore()
    assert seen == [0, 4]  # stopped with the first batch stored, none simulated after it
    assert len(list((part / "batches").glob("*/batch-?????.parquet"))) == 1
    run_campaign(cfg, part)  # the handler restored: the record forgotten, the resume ends
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(part).features()), _sorted(load_campaign(out).features())
    )


def test_another_batch_size_resumes_in_the_stored_batches(full_run, tmp_path, caplog):
    """The batch size only groups the design's rows into files: asked for again with another
    one, a campaign keeps its batches (before, it was refused as another configuration,
    and simulated again with --force) and a part-run one is finished in its own grouping,
    with the same results; changed with anything else, it is still another campaign."""
    cfg, out = full_run
    part = tmp_path / "part"
    run_campaign(cfg, part, max_batches=2)
    meta = (part / "campaign.json").read_text()
    regrouped = make_config(TINY, 10, batch_size=3, seed=3)
    calls = []
    with caplog.at_level("WARNING", logger="railsusp.campaign"):
        run_campaign(regrouped, part, force=True, progress=lambda d, t: calls.append(d))
    assert calls[0] == 8  # the two stored batches of 4 are kept, with --force too
    assert "in batches of 4: resumed in them (batch_size 3" in caplog.text
    assert json.loads((part / "campaign.json").read_text())["config_hash"] == cfg.hash()
    assert json.loads(meta)["config"] == json.loads((part / "campaign.json").read_text())["config"]
    assert sorted(p.name for p in (part / "batches" / "curve").glob("batch-?????.parquet")) == [
        "batch-00000.parquet",
        "batch-00001.parquet",
        "batch-00002.parquet",
    ]
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(part).features()), _sorted(load_campaign(out).features())
    )
    calls.clear()
    run_campaign(
        make_config(TINY, 10, batch_size=7, seed=3), part, progress=lambda d, t: calls.append(d)
    )
    assert calls == [20]  # complete: nothing simulated
    with pytest.raises(CampaignError, match="another configuration"):
        run_campaign(make_config(TINY, 10, batch_size=3, seed=4), part)


def _batch_size(out) -> int:
    return json.loads((out / "campaign.json").read_text())["config"]["batch_size"]


def test_a_campaign_with_nothing_to_keep_takes_the_batch_size_asked(full_run, tmp_path, caplog):
    """The stored batch size is kept only for batches that are kept: a campaign simulated
    again (another seed, other force laws, with --force) or with no batch stored yet (the
    first one ran out of memory: the batch size is what the user changes) is simulated in
    the batch size asked for, without a word of resuming (the review of stop 68: the old
    one was kept, after a warning that said "resumed")."""
    cfg, out = full_run
    reseeded = tmp_path / "reseeded"
    shutil.copytree(out, reseeded)
    run_campaign(make_config(TINY, 10, batch_size=3, seed=4), reseeded, force=True, max_batches=0)
    assert _batch_size(reseeded) == 3
    older = tmp_path / "older"
    shutil.copytree(out, older)
    meta = json.loads((older / "campaign.json").read_text())
    (older / "campaign.json").write_text(json.dumps({**meta, "model_revision": "2020-01-01.1"}))
    run_campaign(make_config(TINY, 10, batch_size=3, seed=3), older, force=True, max_batches=0)
    assert _batch_size(older) == 3
    empty = tmp_path / "empty"
    run_campaign(cfg, empty, max_batches=0)
    with caplog.at_level("WARNING", logger="railsusp.campaign"):
        run_campaign(make_config(TINY, 10, batch_size=3, seed=3), empty, force=True, max_batches=1)
    assert _batch_size(empty) == 3
    assert "resumed in them" not in caplog.text
    assert len(list((empty / "batches").rglob("batch-?????.parquet"))) == 1


@pytest.mark.parametrize("lost", ["gone", "damaged"])
def test_batches_of_another_batch_size_are_kept_when_campaign_json_is_lost(
    full_run, tmp_path, caplog, lost
):
    """With campaign.json gone or damaged the batches' stamps say whose they are; asked for
    in another batch size they counted as another configuration's, and --force (or the
    pipeline, which forces) discarded every one. The first batch's samples give the batch
    size its stamp is checked with: they are kept, and nothing is simulated again."""
    _, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    if lost == "gone":
        (copy / "campaign.json").unlink()
    else:
        (copy / "campaign.json").write_text("{")
    calls = []
    with caplog.at_level("WARNING", logger="railsusp.campaign"):
        run_campaign(
            make_config(TINY, 10, batch_size=3, seed=3),
            copy,
            force=True,
            progress=lambda d, t: calls.append(d),
        )
    assert calls == [20]  # every batch kept
    assert "in batches of 4: resumed in them (batch_size 3" in caplog.text
    assert _batch_size(copy) == 4
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(copy).features()), _sorted(load_campaign(out).features())
    )
    # with nothing to keep (no batch whole), the batch size asked is taken
    (copy / "campaign.json").unlink()
    for series in (copy / "batches").glob("*/batch-?????.parquet"):
        series.unlink()
    run_campaign(make_config(TINY, 10, batch_size=3, seed=3), copy, force=True, max_batches=0)
    assert _batch_size(copy) == 3


def _without_batch_size_stamps(out) -> None:
    """``out``'s batch files as a railsusp before stop 69 wrote them: no batch-size stamp."""
    for path in (out / "batches").rglob("batch-*.parquet"):
        table = pq.read_table(path)
        stamps = dict(table.schema.metadata or {})
        assert stamps.pop(BATCH_SIZE_KEY.encode()) is not None
        pq.write_table(table.replace_schema_metadata(stamps), path)


def test_a_one_batch_campaign_keeps_its_batches_when_campaign_json_is_lost(tmp_path, caplog):
    """Stop 68 left this open: with campaign.json gone, a campaign of one batch per
    condition said its batch size nowhere (its samples fit any larger one), so asked for in
    another batch size its batches counted as another configuration's and --force (or the
    pipeline) simulated them all again. Each batch is stamped with its batch size now (the
    stamp's hash vouches for it): they are kept. Written without that stamp (before stop
    69), they are simulated again, as before."""
    cfg = make_config(TINY, 4, batch_size=8, seed=5)
    out = tmp_path / "one"
    run_campaign(cfg, out)
    (out / "campaign.json").unlink()
    older = tmp_path / "older"
    shutil.copytree(out, older)
    asked = make_config(TINY, 4, batch_size=3, seed=5)
    calls = []
    with caplog.at_level("WARNING", logger="railsusp.campaign"):
        run_campaign(asked, out, force=True, progress=lambda d, t: calls.append(d))
    assert calls == [8]  # every batch kept: nothing simulated
    assert "in batches of 8: resumed in them (batch_size 3" in caplog.text
    assert _batch_size(out) == 8
    _without_batch_size_stamps(older)
    calls.clear()
    run_campaign(asked, older, force=True, progress=lambda d, t: calls.append(d))
    assert calls[-1] == 8 and len(calls) > 1  # simulated again, in batches of 3
    assert _batch_size(older) == 3


def test_batches_without_a_batch_size_stamp_give_it_by_their_samples(full_run, tmp_path):
    """Batches written before the batch-size stamp (stop 69): with campaign.json gone, the
    first batch's samples give the batch size where a condition has a second batch."""
    _, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "campaign.json").unlink()
    _without_batch_size_stamps(copy)
    calls = []
    run_campaign(
        make_config(TINY, 10, batch_size=3, seed=3),
        copy,
        force=True,
        progress=lambda d, t: calls.append(d),
    )
    assert calls == [20]
    assert _batch_size(copy) == 4


def test_changed_configuration_refuses_to_mix(full_run, tmp_path):
    cfg, out = full_run
    other = make_config(TINY, 10, batch_size=4, seed=99)
    with pytest.raises(CampaignError, match="another configuration"):
        run_campaign(other, out)
    copy = tmp_path / "copy"
    run_campaign(cfg, copy, max_batches=1)
    run_campaign(other, copy, force=True, max_batches=1)
    assert json.loads((copy / "campaign.json").read_text())["config_hash"] == other.hash()


def test_independent_seeds_differ_from_common_random_numbers(full_run, tmp_path):
    _cfg, out = full_run
    indep = make_config(TINY, 10, batch_size=4, seed=3, independent_seeds=True)
    run_campaign(indep, tmp_path / "indep", max_batches=1)
    a = load_campaign(out).feature_matrix("straight", "Y", "rms").iloc[:4].to_numpy()
    b = load_campaign(tmp_path / "indep").feature_matrix("straight", "Y", "rms").to_numpy()
    assert not np.allclose(a, b)


def test_dask_local_cluster_gives_identical_results(full_run, tmp_path):
    cfg, out = full_run
    run_campaign(cfg, tmp_path / "dask", workers=2)
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(tmp_path / "dask").features()), _sorted(load_campaign(out).features())
    )


def test_results_without_their_campaign_json_are_not_taken_in(full_run, tmp_path):
    """The kill/resume pass (stop 54): with campaign.json gone, a campaign of another seed
    took in the old batches as its own (seed-5 parameters paired with seed-3 forces)."""
    _cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "campaign.json").unlink()
    other = make_config(TINY, 10, batch_size=4, seed=5)
    with pytest.raises(CampaignError, match="holds campaign results but no campaign.json"):
        run_campaign(other, copy)
    run_campaign(other, copy, force=True, max_batches=1)
    assert len(list((copy / "batches").glob("*/batch-?????.parquet"))) == 1  # old ones gone


@pytest.mark.parametrize("damage", ["cut", "gone"])
def test_a_lost_or_damaged_campaign_json_keeps_the_batches_stamped_as_this_configurations(
    full_run, tmp_path, damage
):
    """Stop 54 left this open: a campaign.json cut short could only be --force'd, which
    discarded every intact batch, and one that was gone refused the run. Each batch file now
    carries its configuration's hash; the batches of this configuration are kept, the rest is
    made again, and the result equals the uninterrupted campaign's."""
    from railsusp.campaign.batch_files import batch_stamp

    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    assert {batch_stamp(p) for p in (copy / "batches").rglob("*.parquet")} == {cfg.hash()}
    meta = copy / "campaign.json"
    meta.write_bytes(meta.read_bytes()[:50]) if damage == "cut" else meta.unlink()
    (copy / "design.parquet").write_bytes(b"PAR1 cut")  # made again from the configuration
    path = batch_paths(copy, "curve", 1)[0]
    path.write_bytes(path.read_bytes()[:300])  # and one batch damaged as well
    (copy / "nominal").mkdir()  # twins of this design (hours of simulation in a real one)
    (copy / "nominal" / "kept").write_text("")
    calls = []
    run_campaign(cfg, copy, progress=lambda d, t: calls.append(d))
    assert calls[0] == 16  # all but the damaged batch of 4
    assert json.loads(meta.read_text())["config_hash"] == cfg.hash()
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(copy).features()), _sorted(load_campaign(out).features())
    )
    pd.testing.assert_frame_equal(load_campaign(copy).design(), load_campaign(out).design())
    assert (copy / "nominal" / "kept").exists()  # what was made from its own batches stays


def test_with_campaign_json_damaged_force_discards_only_other_configurations_batches(
    full_run, tmp_path
):
    """Batches of another seed (stamped with its hash) beside this configuration's: refused,
    naming how many are whose; --force discards those alone."""
    cfg, out = full_run
    copy = tmp_path / "copy"
    other = make_config(TINY, 10, batch_size=4, seed=5)
    run_campaign(other, copy, max_batches=2)  # the first batches of both conditions
    for p in sorted((out / "batches").rglob("batch-00002*.parquet")):  # and two of cfg's
        (copy / p.relative_to(out)).parent.mkdir(exist_ok=True)
        shutil.copy2(p, copy / p.relative_to(out))
    (copy / "campaign.json").write_text("{")
    kept = r"\(2 batches of this configuration would be kept\)"
    with pytest.raises(CampaignError, match=r"2 of its batches are not stamped .*" + kept):
        run_campaign(cfg, copy)
    calls = []
    run_campaign(cfg, copy, force=True, progress=lambda d, t: calls.append(d))
    assert calls[0] == 4  # the kept batches: the last of each condition, of 2 samples
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(copy).features()), _sorted(load_campaign(out).features())
    )


def test_a_folder_of_another_campaigns_results_without_batches_is_not_emptied(full_run, tmp_path):
    """The campaign audit of stop 59: results copied without their batches or campaign.json
    (features, sensitivity) were deleted without --force and the design overwritten."""
    _cfg, out = full_run
    arch = tmp_path / "arch"
    arch.mkdir()
    for name in ("features.parquet", "design.parquet"):
        shutil.copy2(out / name, arch / name)
    (arch / "sensitivity").mkdir()
    (arch / "sensitivity" / "indices.csv").write_text("kept")
    other = make_config(TINY, 10, batch_size=4, seed=5)
    with pytest.raises(CampaignError, match=r"features.parquet, sensitivity but no batch of"):
        run_campaign(other, arch, max_batches=0)
    assert (arch / "sensitivity" / "indices.csv").read_text() == "kept"
    assert (arch / "design.parquet").read_bytes() == (out / "design.parquet").read_bytes()
    run_campaign(other, arch, max_batches=0, force=True)
    assert not (arch / "sensitivity").exists()


def test_a_batch_of_another_configuration_copied_in_is_simulated_again(full_run, tmp_path):
    """With campaign.json intact a batch stamped with another configuration was taken as
    done: seed-5 forces paired with seed-3 parameters, 2 kN off in the series."""
    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    other = make_config(TINY, 10, batch_size=4, seed=5)
    foreign = tmp_path / "foreign"
    run_campaign(other, foreign, max_batches=1)  # the first batch of the straight
    for src, dst in zip(batch_paths(foreign, "straight", 0), batch_paths(copy, "straight", 0),
                        strict=True):  # fmt: skip
        shutil.copy2(src, dst)
    calls = []
    run_campaign(cfg, copy, progress=lambda d, t: calls.append(d))
    assert calls[0] == 16  # the foreign batch is not counted as done
    np.testing.assert_array_equal(
        load_campaign(copy).series("straight")[1], load_campaign(out).series("straight")[1]
    )


def test_an_edited_design_or_configuration_is_not_taken_as_the_campaigns(full_run, tmp_path):
    """A design.parquet edited by hand was kept (sensitivity then paired it with the forces
    of the original design): refused now, --force starts again; a campaign.json whose
    configuration was edited under its hash lent its batches another configuration (other
    tracks): its batches are kept by their stamps and its configuration written again."""
    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    design = pd.read_parquet(copy / "design.parquet")
    design.loc[0, "X13"] = 20.9e6
    design.to_parquet(copy / "design.parquet", compression="gzip")
    with pytest.raises(CampaignError, match="is not this configuration's design"):
        run_campaign(cfg, copy)
    run_campaign(cfg, copy, force=True)  # started again
    pd.testing.assert_frame_equal(load_campaign(copy).design(), load_campaign(out).design())
    meta = json.loads((copy / "campaign.json").read_text())
    meta["config"]["seed"] = 11
    (copy / "campaign.json").write_text(json.dumps(meta))
    with pytest.raises(CampaignError, match="not the one its batches were simulated with"):
        load_campaign(copy)
    calls = []
    run_campaign(cfg, copy, progress=lambda d, t: calls.append(d))  # its stamps say whose
    assert calls[0] == 20 and load_campaign(copy).config.hash() == cfg.hash()
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(copy).features()), _sorted(load_campaign(out).features())
    )


def test_force_discards_the_surrogates_trained_on_the_old_batches(full_run, tmp_path):
    _cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "surrogates" / "bp").mkdir(parents=True)
    other = make_config(TINY, 10, batch_size=4, seed=5)
    run_campaign(other, copy, force=True, max_batches=0)
    assert not (copy / "surrogates").exists()


@pytest.mark.parametrize("which", [0, 1])  # the series file, the features file
def test_a_batch_file_cut_short_is_simulated_again(full_run, tmp_path, which):
    """Before: a truncated series file counted as done (found only by training); a truncated
    features file crashed the resume with pyarrow's traceback."""
    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    path = batch_paths(copy, "curve", 1)[which]
    path.write_bytes(path.read_bytes()[:300])
    calls = []
    run_campaign(cfg, copy, progress=lambda d, t: calls.append(d))
    assert calls[0] == 16  # all but the damaged batch of 4
    pd.testing.assert_frame_equal(
        _sorted(load_campaign(copy).features()), _sorted(load_campaign(out).features())
    )
    np.testing.assert_array_equal(
        load_campaign(copy).series("curve")[1], load_campaign(out).series("curve")[1]
    )


def test_condition_names_equal_but_for_case_are_refused():
    """Their batches go to batches/A and batches/a: one folder on a case-blind disk, so one
    condition's batches would count as the other's (stop 56's review)."""
    from railsusp.campaign import CampaignError, make_config
    from railsusp.conditions import get_condition

    straight = get_condition("straight")
    conds = [straight.with_changes(name="A"), straight.with_changes(name="a", seed=4)]
    with pytest.raises(CampaignError, match=r"condition names repeat \(A, a, case ignored\)"):
        make_config(conds, 4, parameters=("X13",))


def test_workers_and_a_scheduler_together_are_refused(tmp_path):
    """--workers was silently ignored when --scheduler was given too."""
    cfg = make_config(TINY, 4, batch_size=4, seed=3)
    with pytest.raises(CampaignError, match="--workers 2 with --scheduler tcp://h:8786"):
        run_campaign(cfg, tmp_path / "x", scheduler="tcp://h:8786", workers=2)
    assert not (tmp_path / "x").exists()


def test_a_campaign_of_other_force_laws_is_not_resumed_into(full_run, tmp_path):
    """The campaign's hash held its configuration only: resumed after the force laws
    changed, its batches would have mixed two models (the pipeline's stage hashes hold the
    revision; a standalone campaign did not)."""
    from railsusp.vehicle import MODEL_REVISION

    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    meta = json.loads((copy / "campaign.json").read_text())
    assert meta["model_revision"] == MODEL_REVISION
    meta["model_revision"] = "2020-01-01"
    (copy / "campaign.json").write_text(json.dumps(meta))
    with pytest.raises(CampaignError, match="force-law revision 2020-01-01, older than"):
        run_campaign(cfg, copy)
    run_campaign(cfg, copy, force=True, max_batches=0)
    assert json.loads((copy / "campaign.json").read_text())["model_revision"] == MODEL_REVISION
    assert not (copy / "batches").exists() or not any((copy / "batches").rglob("*.parquet"))


def test_the_force_laws_revision_is_read_when_the_campaign_runs(full_run, tmp_path, monkeypatch):
    """The campaign's checks and stamps read this railsusp's revision when they run, as the
    wording of its refusals does: they compared with the revision of their import, so a
    railsusp whose revision is set later (a test's, or a reload) resumed into a campaign of
    other force laws while its own error line named two revisions that were equal."""
    import railsusp.vehicle
    from railsusp.campaign.batch_files import REVISION_KEY

    cfg, out = full_run
    made = railsusp.vehicle.MODEL_REVISION
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", "2099-01-01.1")
    said = f"force-law revision {made}, older than this railsusp's 2099-01-01.1"
    with pytest.raises(CampaignError, match=said):
        run_campaign(cfg, copy)
    run_campaign(cfg, copy, force=True, max_batches=1)
    assert json.loads((copy / "campaign.json").read_text())["model_revision"] == "2099-01-01.1"
    (stamped,) = [p for p in (copy / "batches").rglob("*.parquet") if "features" not in p.name]
    assert pq_meta(stamped)[REVISION_KEY.encode()] == b"2099-01-01.1"


def test_a_second_campaign_in_a_folder_is_refused_while_one_works(full_run, tmp_path):
    """Two processes on one campaign folder simulated the same batches twice, and one with
    --force (or another configuration) deleted what the other was writing: the second is
    refused in one line, nothing touched, and the folder is free again afterwards."""
    import os

    from railsusp.errors import RailsuspInputError
    from railsusp.run_lock import run_lock

    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    before = sorted(p.relative_to(copy) for p in copy.rglob("*") if p.name != ".railsusp.lock")
    other = make_config(TINY, 10, batch_size=4, seed=99)
    with run_lock(copy, "--out"):  # as another process holds it while it runs
        with pytest.raises(RailsuspInputError) as info:
            run_campaign(other, copy, force=True)
    assert "another railsusp run is working in this folder" in str(info.value)
    assert f"(process {os.getpid()})" in str(info.value)
    after = sorted(p.relative_to(copy) for p in copy.rglob("*") if p.name != ".railsusp.lock")
    assert after == before  # nothing discarded
    assert run_campaign(cfg, copy) == copy  # released: the next one goes on


def test_a_track_geometry_file_edited_in_place_is_not_resumed_into(tmp_path):
    """A campaign on measured track geometry kept its results when the file was edited in
    place (its configuration names the file, not its contents: interrupt/resume audit of
    stop 60): it is refused now, and --force simulates the edited track."""
    import pandas as pd

    from railsusp.vehicle.track_geometry import write_track_geometry
    from railsusp.vehicle.track_grid import section_irregularities
    from railsusp.vehicle.wagon import load_wagon

    base = TINY[0]
    irr = section_irregularities(base, [base.seed], load_wagon())
    geo = write_track_geometry(tmp_path / "track.csv", irr, origin_m=base.lead_in_m)
    cond = base.with_changes(track_geometry=str(geo))
    cfg = make_config([cond], 4, batch_size=4, parameters=("X14",))
    out = tmp_path / "camp"
    run_campaign(cfg, out)
    meta = json.loads((out / "campaign.json").read_text())
    assert list(meta["track_geometry_files"]) == [str(geo)]
    first = pd.read_parquet(out / "features.parquet")
    run_campaign(cfg, out)  # unchanged: resumed, nothing simulated again
    # a campaign made before the record: the digests are written on its next resume
    stripped = {k: v for k, v in meta.items() if k != "track_geometry_files"}
    (out / "campaign.json").write_text(json.dumps(stripped))
    run_campaign(cfg, out)
    assert json.loads((out / "campaign.json").read_text())["track_geometry_files"] == {
        str(geo): meta["track_geometry_files"][str(geo)]
    }
    table = pd.read_csv(geo)
    table[[c for c in table.columns if c != "distance_m"]] *= 3.0
    table.to_csv(geo, index=False)
    with pytest.raises(CampaignError, match=r"other contents of its track geometry file\(s\)"):
        run_campaign(cfg, out)
    run_campaign(cfg, out, force=True)
    again = pd.read_parquet(out / "features.parquet")
    assert not np.allclose(first.value.to_numpy(), again.value.to_numpy())
    # without measured geometry the record and the hash are as before
    plain = tmp_path / "plain"
    run_campaign(make_config([base], 4, batch_size=4, parameters=("X14",)), plain, max_batches=0)
    assert "track_geometry_files" not in json.loads((plain / "campaign.json").read_text())


def _restamp(path, revision: str) -> None:
    """A batch file as another force-law revision would have written it."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    meta = dict(table.schema.metadata or {})
    meta[b"railsusp.model_revision"] = revision.encode()
    pq.write_table(table.replace_schema_metadata(meta), path)


def test_batches_of_other_force_laws_are_never_taken_as_this_campaigns(full_run, tmp_path):
    """With campaign.json lost, batches were kept by their configuration's stamp alone,
    which does not change with the force laws: a new revision relabelled old batches as its
    own (interrupt/resume audit of stop 60). Each batch now records its revision."""
    from railsusp.campaign.batch_files import REVISION_KEY
    from railsusp.vehicle import MODEL_REVISION

    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    for p in (copy / "batches").rglob("*.parquet"):
        assert pq_meta(p)[REVISION_KEY.encode()] == MODEL_REVISION.encode()
    for p in batch_paths(copy, "curve", 1):
        _restamp(p, "2000-01-01.1")
    (copy / "campaign.json").unlink()
    said = "1 of its batches is not stamped as this configuration.s .another campaign.s or other"
    with pytest.raises(CampaignError, match=said):
        run_campaign(cfg, copy)
    calls = []
    run_campaign(cfg, copy, force=True, progress=lambda d, t: calls.append(d))
    assert calls[0] == 16  # the old revision's batch of 4 simulated again
    assert all(
        pq_meta(p)[REVISION_KEY.encode()] == MODEL_REVISION.encode()
        for p in (copy / "batches").rglob("*.parquet")
    )


def pq_meta(path) -> dict:
    import pyarrow.parquet as pq

    return dict(pq.ParquetFile(path).schema_arrow.metadata or {})


def test_results_of_other_force_laws_are_not_trained_or_analysed(full_run, tmp_path):
    """`railsusp train` and the sensitivity read a finished campaign of an older revision
    without a word (interrupt/resume audit of stop 60): refused now; so is a campaign that
    states none (before 2026-11-30: older force laws; it was warned of, the upgrade audit's
    M3)."""
    from railsusp.campaign import require_complete

    _, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    meta = json.loads((copy / "campaign.json").read_text())
    (copy / "campaign.json").write_text(json.dumps({**meta, "model_revision": "2000-01-01.1"}))
    with pytest.raises(CampaignError, match=r"simulated with force-law revision 2000-01-01.1"):
        require_complete(load_campaign(copy))
    del meta["model_revision"]
    (copy / "campaign.json").write_text(json.dumps(meta))
    with pytest.raises(CampaignError, match=r"it records none"):
        require_complete(load_campaign(copy))


def test_a_batch_left_half_written_by_a_kill_leaves_no_temporary_behind(full_run, tmp_path):
    """A kill during a batch's write left ``.batch-*.parquet.*.tmp`` for good (the
    interrupt/resume audit of stop 60): the next run, holding the folder's lock, removes
    them; the lock file itself and the results stay."""
    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    # named as railsusp's atomic writes name their temporaries (mkstemp's eight characters)
    stale = copy / "batches" / "straight" / ".batch-00001.parquet.k2x_9q0z.tmp"
    stale.write_bytes(b"half a batch")
    run_campaign(cfg, copy)
    assert not stale.exists() and (copy / "features.parquet").exists()


@pytest.mark.parametrize(
    ("address", "ok"),
    [
        ("tcp://h:8786", True),
        ("tcp://10.0.0.5:8786", True),
        ("tcp://[::1]:8786", True),
        ("tcp://h:8786/", False),  # failed in distributed: int('8786/')
        ("tcp://h:99999", False),  # waited 10 s for a port that cannot exist
        ("tls://h:8786", False),  # needs security settings railsusp does not take
        ("h:8786", False),
        ("tcp://h", False),
    ],
)
def test_scheduler_addresses_are_checked_before_any_connection(address, ok):
    from railsusp.campaign.dask_cluster import check_scheduler_address

    if ok:
        check_scheduler_address(address, "--scheduler")
    else:
        with pytest.raises(CampaignError, match=r"accepted tcp://host:port \(host a name"):
            check_scheduler_address(address, "--scheduler")


@pytest.mark.parametrize("peer", ["silent", "ssh"])
def test_a_port_that_is_no_dask_scheduler_is_one_line_within_the_timeout(monkeypatch, peer):
    """Stop 61's Dask audit: a port held by a server that never speaks Dask hung for good
    (distributed's timeout does not bound its handshake); one that answers an SSH banner
    raised a 2.8 EiB allocation error with a traceback."""
    import socket
    import threading
    import time

    import railsusp.campaign.dask_cluster as cluster_mod

    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    held = []

    def serve():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            held.append(conn)
            if peer == "ssh":
                conn.sendall(b"SSH-2.0-OpenSSH_9.2p1 Debian-2\r\n" * 4)

    threading.Thread(target=serve, daemon=True).start()
    monkeypatch.setattr(cluster_mod, "CONNECT_TIMEOUT_S", 3.0)
    t0 = time.monotonic()
    try:
        with pytest.raises(CampaignError, match="no Dask scheduler answered"):
            cluster_mod.connect_scheduler(f"tcp://127.0.0.1:{port}")
    finally:
        server.close()
        for c in held:
            c.close()
    assert time.monotonic() - t0 < 15.0


def test_a_batch_of_other_force_laws_is_refused_not_stamped_ours(monkeypatch, tmp_path):
    """Stop 61's Dask audit: a worker with another railsusp simulated a batch that was
    stored with this client's force-law revision (features 10 apart, no warning)."""
    import railsusp.campaign.run as run_mod

    own = run_mod.simulate_task
    monkeypatch.setattr(
        run_mod, "simulate_task", lambda *a: {**own(*a), "model_revision": "another"}
    )
    cfg = make_config(TINY[:1], 4, batch_size=2, seed=3)
    with pytest.raises(CampaignError, match="force laws of revision another where this"):
        run_campaign(cfg, tmp_path / "r")
    assert not list((tmp_path / "r").glob("**/batch-*.parquet"))  # no batch stored


def test_a_batch_with_a_bit_flipped_in_a_page_is_simulated_again(full_run, tmp_path):
    """The run-directory store audit: a batch whose data page had one bit flipped (footer and
    stamp intact, size kept) was taken as done on resume and its changed forces used. The
    batches are written with page checksums now: read, such a file is a one-line error
    naming it and the remedy, and resumed, the batch is simulated again."""
    from railsusp.campaign.batch_files import batch_done

    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    flip_a_bit_in_a_page(batch_paths(copy, "curve", 1)[0])
    assert not batch_done(copy, "curve", 1, cfg.hash())  # not taken as finished work
    assert batch_done(copy, "curve", 1, cfg.hash(), pages=False)  # footers and stamps: as were
    with pytest.raises(CampaignError) as info:
        load_campaign(copy).series("curve")
    text = str(info.value)
    assert "batch-00001.parquet is damaged (" in text and "\n" not in text
    assert text.endswith("run the same `railsusp campaign` command again (it simulates such a "
                         "batch again)")  # fmt: skip
    calls = []
    run_campaign(cfg, copy, progress=lambda d, t: calls.append(d))
    assert calls[0] == 16  # all but the damaged batch of 4
    np.testing.assert_array_equal(
        load_campaign(copy).series("curve")[1], load_campaign(out).series("curve")[1]
    )


def test_a_batch_written_without_page_checksums_is_still_taken_as_done(full_run, tmp_path):
    """Batches written before page checksums were (no checksum in their pages) are read and
    resumed as before: nothing in them to verify, nothing simulated again."""
    import pyarrow.parquet as pq

    from railsusp.campaign.batch_files import batch_done

    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    for path in batch_paths(copy, "straight", 0):
        pq.write_table(pq.read_table(path), path)  # as the writer before did: no checksums
    assert batch_done(copy, "straight", 0, cfg.hash())
    calls = []
    run_campaign(cfg, copy, progress=lambda d, t: calls.append(d))
    assert calls == [20]
    np.testing.assert_array_equal(
        load_campaign(copy).series("straight")[1], load_campaign(out).series("straight")[1]
    )


def test_a_lost_batch_makes_a_finished_campaign_incomplete(full_run, tmp_path):
    """The run-directory store audit: with a batch file gone, a campaign whose campaign.json
    says "completed" was still complete, and a surrogate trained on the series that were
    left without a word. Now every batch of the design is checked (footers and stamps), the
    missing ones are named with the remedy, and resumed, the campaign is whole again."""
    from railsusp.campaign import incomplete, require_complete

    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    batch_paths(copy, "straight", 2)[0].unlink()
    camp = load_campaign(copy)
    assert camp.complete  # campaign.json still says so
    with pytest.raises(CampaignError) as info:
        require_complete(camp)
    assert str(info.value) == (
        f"{copy}: the campaign is incomplete: 1 of its 6 batches is missing or damaged "
        "(batches/straight/batch-00002.parquet); run the same `railsusp campaign` command "
        "again to simulate it again"
    )
    run_campaign(cfg, copy)
    assert incomplete(load_campaign(copy)) is None
    ids, _ = require_complete(load_campaign(copy)).series("straight")
    assert list(ids) == list(range(10))


def test_a_campaign_removes_only_its_own_temporaries(full_run, tmp_path):
    """The run-directory store audit: a campaign resumed removed every ``.*.tmp`` under its
    folder, among them the temporary of a checkpoint that a training on the campaign was
    saving, and a user's file of that pattern. It removes railsusp's temporaries of its own
    files now: its batches' and its top-level files', nothing else."""
    cfg, out = full_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    stale = [
        copy / "batches" / "curve" / ".batch-00002.features.parquet.a1b2c3d4.tmp",
        copy / ".campaign.json.zz_9y8x7.tmp",
    ]
    kept = [
        copy / "surrogates" / "bp" / "curve" / ".checkpoint.pt.q1w2e3r4.tmp",  # being saved
        copy / "batches" / "curve" / ".notes.tmp",  # a user's
        copy / ".my-analysis.csv.k9j8h7g6.tmp",  # not a file of the campaign's
    ]
    for path in stale + kept:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"half written")
    run_campaign(cfg, copy)
    assert [p.exists() for p in stale] == [False, False]
    assert [p.exists() for p in kept] == [True, True, True]
