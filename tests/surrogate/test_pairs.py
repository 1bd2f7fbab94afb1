"""Gradient-enhanced training on pairs of runs (railsusp.surrogate.pairs): the campaign's
perturbed twins (railsusp.campaign.perturbed), how they are read and paired, the pair loss,
the pair-shared dropout, and training on them from a warm start."""

import shutil

import numpy as np
import pytest
import torch

from conftest import family_campaign
from railsusp.campaign import CampaignError, load_campaign
from railsusp.campaign.perturbed import (
    perturbation_table,
    perturbed_complete,
    perturbed_folder,
    perturbed_parameters,
    run_perturbed_twins,
)
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.params import bounds
from railsusp.surrogate import TrainConfig, feature_spec, train_surrogate
from railsusp.surrogate.data import Normaliser, load_series
from railsusp.surrogate.models import NetConfig, build_network
from railsusp.surrogate.pairs import PairSampler, load_twins
from railsusp.surrogate.train import sampler_for
from railsusp.variation import sample_condition
from railsusp.vehicle.simulate import simulate_batch
from railsusp.vehicle.simulation_result import measured_wheel_index

KEYS = ("X13", "X14")
CURVE = get_condition("curve", duration_s=2.0, n_steps=100)
STEP = 0.05


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = family_campaign(tmp_path_factory.mktemp("pairs") / "run", KEYS, CURVE)
    seen = []
    run_perturbed_twins(out, step=STEP, per_sample=2, progress=lambda d, t: seen.append(d))
    assert perturbed_complete(out) and perturbed_complete(out, "curve")
    return out


def test_each_twin_moves_one_key_by_the_step_inside_its_range(run):
    """Twin j of sample i moves the keys in turn by ±5 % of the range (down where up would
    leave it), every other parameter as the sample has it; reproducible."""
    camp = load_campaign(run)
    cfg, design = camp.config, camp.design()
    table = perturbation_table(cfg, design, STEP, 2)
    assert table.equals(perturbation_table(cfg, design, STEP, 2))
    assert len(table) == 24 and set(table.twin) == {0, 1}
    assert np.allclose(np.abs(table.delta_unit), STEP)
    assert (table.groupby("parameter").size() == 12).all()  # every key as many pairs
    assert (table.groupby("sample_id").parameter.nunique() == 2).all()  # both keys per sample
    lo, hi = bounds(cfg.simulated_parameters)
    base = design.set_index("sample_id")[list(cfg.simulated_parameters)].to_numpy()
    for j in (0, 1):
        x = perturbed_parameters(cfg, design, table, j)
        assert ((x >= lo) & (x <= hi)).all()
        moved = (x != base).sum(axis=1)
        assert (moved == 1).all()
        rows = table[table.twin == j].set_index("sample_id")
        for i in range(12):
            c = list(cfg.simulated_parameters).index(rows.parameter[i])
            assert x[i, c] - base[i, c] == pytest.approx(rows.delta_unit[i] * (hi[c] - lo[c]))


def test_a_twin_is_the_perturbed_wagon_on_its_samples_own_track(run):
    camp = load_campaign(run)
    cfg = camp.config
    table = perturbation_table(cfg, camp.design(), STEP, 2)
    row = camp.tracks("curve").iloc[5]
    x = perturbed_parameters(cfg, camp.design(), table, 1)[5]
    r = simulate_batch(
        x[None],
        sample_condition(CURVE, row),
        symbols=cfg.simulated_parameters,
        seeds=[int(row.seed)],
        wagon=cfg.wagon,
        settings=cfg.settings(),
    )
    spec = feature_spec(camp, KEYS)
    data = load_series(camp, "curve", spec)
    twins = load_twins(camp, data, spec)
    i = list(data.sample_ids).index(5)
    w = measured_wheel_index(CURVE, "auto")
    np.testing.assert_allclose(twins.targets[i, 1, :, 0], r.Y[0, w] / 1e3, rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(twins.targets[i, 1, :, 1], r.Q[0, w] / 1e3, rtol=1e-5, atol=1e-4)
    moved = np.flatnonzero(twins.params_unit[i, 1] != data.params_unit[i])
    assert len(moved) == 1
    assert twins.params_unit[i, 1, moved[0]] - data.params_unit[i, moved[0]] == pytest.approx(
        table.set_index(["sample_id", "twin"]).delta_unit[(5, 1)], abs=1e-6
    )
    # the parameter moved changes the force: the pair carries a derivative
    assert np.abs(twins.targets[i, 1] - data.targets[i]).max() > 1e-3


def test_twins_resume_and_refuse_another_step(run, tmp_path):
    files = sorted(perturbed_folder(run).rglob("batch-*.parquet"))
    stamps = [f.stat().st_mtime_ns for f in files]
    seen = []
    run_perturbed_twins(run, step=STEP, per_sample=2, progress=lambda d, t: seen.append((d, t)))
    assert seen == [(2, 2), (2, 2)] and [f.stat().st_mtime_ns for f in files] == stamps
    with pytest.raises(CampaignError, match="perturbed twins of another configuration, step"):
        run_perturbed_twins(run, step=0.1, per_sample=2)
    with pytest.raises(CampaignError, match=r"step = 0.7: accepted a fraction of the range in"):
        run_perturbed_twins(run, step=0.7)
    with pytest.raises(CampaignError, match="per_sample = 0: accepted an integer >= 1"):
        run_perturbed_twins(run, per_sample=0)
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    shutil.rmtree(perturbed_folder(copy, 1))
    assert not perturbed_complete(copy)
    camp = load_campaign(copy)
    spec = feature_spec(camp, KEYS)
    with pytest.raises(ValueError, match="perturbed twins of 'curve' are missing, incomplete"):
        load_twins(camp, load_series(camp, "curve", spec), spec)


def test_a_swallowed_ctrl_c_stops_the_twins_after_the_batch_they_stored(run, tmp_path):
    """A Ctrl-C that Python swallowed (recorded by the command line's handler,
    railsusp.interrupts) stopped the twins only at the pipeline's next stage boundary: it
    stops after the batch being stored, which the resume keeps."""
    from railsusp.interrupts import catch_interrupts, record_interrupt

    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    shutil.rmtree(perturbed_folder(copy, 1))  # the second twin's two batches to make again
    seen = []

    def swallowed(done: int, total: int) -> None:
        seen.append(done)
        if len(seen) > 2:  # during the second twin's first batch, then lost
            record_interrupt()

    restore = catch_interrupts()
    try:
        with pytest.raises(KeyboardInterrupt):
            run_perturbed_twins(copy, step=STEP, per_sample=2, progress=swallowed)
    finally:
        restore()
    assert seen == [2, 0, 1]  # the first twin stored; of the second, one batch and no more
    assert len(list(perturbed_folder(copy, 1).rglob("batch-?????.parquet"))) == 1
    run_perturbed_twins(copy, step=STEP, per_sample=2)
    assert perturbed_complete(copy)


def _sampler(run, chunk_steps=100, weight=1.0):
    camp = load_campaign(run)
    spec = feature_spec(camp, KEYS, window=20)
    data = load_series(camp, "curve", spec)
    twins = load_twins(camp, data, spec)
    norm = Normaliser.fit(data)
    cfg = TrainConfig(pair_weight=weight, chunk_steps=chunk_steps)
    return sampler_for("cnn-gru-seq", data, norm, 20, cfg, twins), data, twins, norm, spec


def test_a_pair_batch_is_the_run_then_its_twin_on_the_same_track_and_steps(run):
    smp, data, twins, norm, spec = _sampler(run, chunk_steps=60)
    assert isinstance(smp, PairSampler)
    rows = np.array([0, 7, len(smp.index) - 1])
    x, y = smp.batch(rows)
    assert x.shape == (6, 60, spec.n_features) and y.shape == (6, 40, 2)
    n_par = len(KEYS)
    np.testing.assert_array_equal(x[3:, :, n_par:], x[:3, :, n_par:])  # same track, steps
    for b, (i, start, j) in enumerate(smp.index[rows]):
        np.testing.assert_allclose(x[3 + b, 0, :n_par], twins.params_unit[i, j], rtol=1e-6)
        want = norm.target(twins.targets[i, j, start + 20 : start + 60])
        np.testing.assert_allclose(y[3 + b], want, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(
            y[b], norm.target(data.targets[i, start + 20 : start + 60]), rtol=1e-5, atol=1e-6
        )


def test_the_pair_term_is_zero_for_the_right_difference_and_one_for_none(run):
    """With one chunk per series, predicting every run exactly gives zero loss; predicting
    each twin as its run (a network the parameter does not move) gives the pair term 1 over
    the whole set, by its normalisation."""
    smp, *_ = _sampler(run, chunk_steps=100, weight=0.5)
    _x, y = smp.batch(np.arange(len(smp.index)))
    total, pair = smp.loss(y.clone(), y)
    assert float(total) == 0.0 and float(pair) == 0.0
    b = len(y) // 2
    still = torch.cat([y[:b], y[:b]])
    total, pair = smp.loss(still, y)
    assert float(pair) == pytest.approx(1.0, rel=1e-5)
    main = float(torch.mean((still - y) ** 2))
    assert float(total) == pytest.approx(main + 0.5, rel=1e-5)


def test_both_members_of_a_pair_get_the_same_dropout_mask():
    cfg = NetConfig(kind="cnn-gru-seq", n_features=7, window=5, n_outputs=2, dropout=0.5)
    net = build_network(cfg).train()
    x = torch.randn(3, 30, 7)
    xx = torch.cat([x, x])
    torch.manual_seed(0)
    out = net(xx, pairs=True)
    np.testing.assert_allclose(out[:3].detach(), out[3:].detach(), atol=1e-6)  # rounding
    torch.manual_seed(0)
    out = net(xx)  # masks drawn per row: the two halves differ
    assert float((out[:3] - out[3:]).detach().abs().max()) > 1e-3


def test_training_on_pairs_from_a_warm_start(run, tmp_path):
    """The sequence network trains on pairs (history with both pair terms; the stopping
    criterion is the training loss's), starting from a saved network's weights; a network
    of other features is refused as a start, and pairs are refused for window networks."""
    tcfg = TrainConfig(
        epochs=1, batches_per_epoch=2, chunk_steps=60, chunks_per_batch=4, val_windows=100
    )
    kw = {"parameters": KEYS, "kind": "cnn-gru-seq", "window": 20, "record_correction": False}
    first = train_surrogate(run, "curve", train=tcfg, out=tmp_path / "a", **kw)
    paired = TrainConfig(**{**tcfg.to_dict(), "pair_weight": 2.0})
    sur = train_surrogate(
        run, "curve", train=paired, out=tmp_path / "b", init_from=tmp_path / "a", **kw
    )
    h = sur.meta["history"][0]
    assert h["val_pair_loss"] > 0 and h["train_pair_loss"] > 0
    assert h["val_criterion"] == pytest.approx(h["val_loss"] + 2.0 * h["val_pair_loss"])
    # the warm start is the first network: with no step taken its weights come back
    still = TrainConfig(**{**paired.to_dict(), "learning_rate": 1e-12})
    same = train_surrogate(
        run, "curve", train=still, out=tmp_path / "c", init_from=tmp_path / "a", **kw
    )
    for k, v in first.net.state_dict().items():
        np.testing.assert_allclose(same.net.state_dict()[k], v, atol=1e-8)
    with pytest.raises(RailsuspInputError, match="init_from .*: its network differs"):
        train_surrogate(
            run,
            "curve",
            train=paired,
            out=tmp_path / "d",
            init_from=tmp_path / "a",
            **{**kw, "window": 30},
        )
    with pytest.raises(RailsuspInputError, match="pair_weight = 2.0: accepted 0 for 'cnn-gru'"):
        train_surrogate(
            run,
            "curve",
            train=paired,
            out=tmp_path / "e",
            **{**kw, "kind": "cnn-gru", "window": 20},
        )
    with pytest.raises(RailsuspInputError, match=r"training pair_weight = -1: accepted \[0, 100\]"):
        TrainConfig(pair_weight=-1)


def test_validation_takes_the_chunks_a_network_on_forces_alone_takes(run):
    """The runs' half of the pair sampler's validation batch is the chunk sampler's
    validation batch from the same seed: the validation losses of both trainings are taken
    on the same chunks."""
    smp, data, _twins, norm, _spec = _sampler(run, chunk_steps=60)
    plain = sampler_for("cnn-gru-seq", data, norm, 20, TrainConfig(chunk_steps=60))
    count = smp.validation_rows(500)
    assert count == plain.validation_rows(500) == 13  # ceil(500 / 40 targets per chunk)
    xp, yp = plain.batch(plain.pick(np.random.default_rng(1), count))
    x, y = smp.batch(smp.pick(np.random.default_rng(1), count))
    np.testing.assert_array_equal(x[:count], xp)
    np.testing.assert_array_equal(y[:count], yp)


def test_a_failed_twin_is_replaced_by_its_samples_other_or_by_the_run(run):
    _smp, data, twins, norm, _spec = _sampler(run, chunk_steps=100)
    broken = twins.subset(np.arange(data.n_samples))
    broken.targets = broken.targets.copy()
    broken.targets[3, 0] = np.nan  # sample 3: twin 0 failed, twin 1 ran
    broken.targets[5] = np.nan  # sample 5: both failed
    fixed = PairSampler(data, broken, norm, 20, 100, 1.0)
    np.testing.assert_array_equal(fixed.twin_params[3, 0], fixed.twin_params[3, 1])
    np.testing.assert_array_equal(fixed.twin_targets[3, 0], fixed.twin_targets[3, 1])
    for j in (0, 1):  # paired with itself: no pair term
        rows = np.flatnonzero((fixed.index[:, 0] == 5) & (fixed.index[:, 2] == j))
        x, y = fixed.batch(rows)
        np.testing.assert_array_equal(x[:1], x[1:])
        assert float(fixed.loss(torch.zeros_like(y), y)[1]) == 0.0
    assert np.isfinite(fixed.twin_targets).all()
    with pytest.raises(ValueError, match="no perturbed twin ran"):
        broken.targets[:] = np.nan
        PairSampler(data, broken, norm, 20, 100, 1.0)


def test_a_warm_start_from_another_campaign_trains_on_its_inputs(run, tmp_path):
    """A network of one campaign starts a training on another campaign of the same family
    (other tracks and parameter sets, the cant not varied) only with ``init_inputs``: its
    features (the cant channel, which this campaign's own features leave out) and its
    normalisation are kept, so that its weights mean what they meant (with no step taken
    they come back). Without it the network of the other campaign's features (one input
    fewer) is refused; the option
    without a network to start from, or from a network of other parameters, is refused."""
    other = family_campaign(tmp_path / "other", KEYS, CURVE, seed=4, cant_mm=None)
    tcfg = TrainConfig(
        epochs=1, batches_per_epoch=2, chunk_steps=60, chunks_per_batch=4, val_windows=100
    )
    kw = {"parameters": KEYS, "kind": "cnn-gru-seq", "window": 20, "record_correction": False}
    first = train_surrogate(run, "curve", train=tcfg, out=tmp_path / "a", **kw)
    assert "cant" in first.spec.track_channels
    with pytest.raises(RailsuspInputError, match="init_from .*: its network differs"):
        train_surrogate(
            other, "curve", train=tcfg, out=tmp_path / "b", init_from=tmp_path / "a", **kw
        )
    still = TrainConfig(**{**tcfg.to_dict(), "learning_rate": 1e-12})

    def onto_other(out: str, **changed):
        return train_surrogate(
            other,
            "curve",
            train=still,
            out=tmp_path / out,
            init_from=tmp_path / "a",
            init_inputs=True,
            **{**kw, **changed},
        )

    moved = onto_other("c")
    assert moved.spec == first.spec
    for field in ("track_mean", "track_std", "target_mean", "target_std"):
        np.testing.assert_array_equal(
            getattr(moved.normaliser, field), getattr(first.normaliser, field)
        )
    for k, v in first.net.state_dict().items():
        np.testing.assert_allclose(moved.net.state_dict()[k], v, atol=1e-8)
    assert moved.meta["campaign"] == str(other)  # trained (and split) on the other campaign
    assert moved.meta["init_inputs"]["campaign"] == str(run)  # on the inputs of the first
    with pytest.raises(RailsuspInputError, match="init_inputs: accepted only with init_from"):
        train_surrogate(tmp_path / "missing", "curve", init_inputs=True, **kw)
    with pytest.raises(
        RailsuspInputError, match=r"its parameters \('X13', 'X14'\); accepted with init_inputs"
    ):
        onto_other("d", parameters=("X14", "X13"))


def test_the_validation_pairs_are_normalised_by_the_training_pairs(run):
    """The pair term of the early-stopping criterion divides by the training pairs' mean
    square difference, as the training loss does (it used the validation pairs' own)."""
    from railsusp.surrogate.train import share_pair_scale

    train, data, twins, norm, _spec = _sampler(run, chunk_steps=100)
    half = np.arange(data.n_samples // 2)
    cfg = TrainConfig(pair_weight=1.0, chunk_steps=100)
    val = sampler_for("cnn-gru-seq", data.subset(half), norm, 20, cfg, twins.subset(half))
    assert not torch.equal(val.diff_scale, train.diff_scale)
    share_pair_scale(train, val)
    assert torch.equal(val.diff_scale, train.diff_scale)
