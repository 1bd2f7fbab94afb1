"""Surrogate data windows, networks, training loop, save/load, evaluation."""

import shutil
import warnings

import numpy as np
import pytest
import torch

from railsusp.campaign import load_campaign, make_config, run_campaign
from railsusp.conditions import get_condition
from railsusp.surrogate import TrainConfig, load, train_surrogate
from railsusp.surrogate.bundle import OneTrackWarning
from railsusp.surrogate.data import (
    Normaliser,
    gather_windows,
    load_series,
    split_samples,
    window_index,
)
from railsusp.surrogate.evaluate import accuracy, evaluate
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.models import NetConfig, build_network
from railsusp.surrogate.train import WindowSampler, train_network

KEYS = ("X13", "X14", "X15", "X16", "X17", "X18")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sur") / "run"
    cond = get_condition("straight", duration_s=2.0, n_steps=100, lead_in_m=30.0)
    run_campaign(make_config([cond], 12, batch_size=6, seed=5, parameters=KEYS), out)
    return out


def test_study_window_count_and_feature_layout():
    """1000-step series, 20-step windows: 980 windows per series (the study's figure);
    6 parameters + 5 track channels x 3 axles = 21 features."""
    spec = FeatureSpec(parameters=KEYS)
    assert spec.n_features == 21 and len(spec.names()) == 21
    idx = window_index(3, 1000, 20)
    assert idx.shape == (3 * 980, 2)
    assert idx[:, 1].min() == 20 and idx[:, 1].max() == 999
    params = np.arange(3 * 6, dtype=np.float32).reshape(3, 6)
    track = np.arange(1000 * 15, dtype=np.float32).reshape(1, 1000, 15)
    w = gather_windows(params, track, idx[[0, 981]], 20)
    assert w.shape == (2, 20, 21)
    np.testing.assert_array_equal(w[1, :, :6], np.tile(params[1], (20, 1)))
    np.testing.assert_array_equal(w[0, -1, 6:], track[0, 20])  # window ends at its step
    np.testing.assert_array_equal(w[0, 0, 6:], track[0, 1])


def test_split_is_by_sample_without_leakage():
    ids = np.arange(40) * 3
    tr, va, te = split_samples(ids, seed=2)
    assert len(tr) + len(va) + len(te) == 40
    assert not set(tr) & set(va) and not set(tr) & set(te) and not set(va) & set(te)
    # windows of a split only come from its samples
    idx = window_index(len(te), 50, 20)
    assert set(np.unique(idx[:, 0])) == set(range(len(te)))
    with pytest.raises(ValueError, match="at least 3 samples"):
        split_samples(np.arange(2))


def test_series_from_campaign_and_train_only_normalisation(run):
    camp = load_campaign(run)
    spec = FeatureSpec(parameters=KEYS)
    data = load_series(camp, "straight", spec)
    assert data.targets.shape == (12, 100, 2) and data.track.shape == (1, 100, 15)
    assert np.all((data.params_unit >= 0) & (data.params_unit <= 1))
    assert 110 < data.targets[:, :, 1].mean() < 135  # Q in kN
    tr, _, _ = split_samples(data.sample_ids)
    norm = Normaliser.fit(data.subset(tr))
    z = norm.target(data.subset(tr).targets)
    np.testing.assert_allclose(z.reshape(-1, 2).mean(axis=0), 0, atol=1e-4)
    with pytest.raises(ValueError, match="not sampled"):
        load_series(camp, "straight", FeatureSpec(parameters=("X11",)))


@pytest.mark.parametrize("kind", ["cnn-gru", "cnn-lstm", "cnn-bilstm", "bp"])
def test_networks_map_windows_to_targets(kind):
    net = build_network(NetConfig(kind=kind))
    out = net(torch.zeros(5, 20, 21))
    assert out.shape == (5, 2)
    with pytest.raises(ValueError, match="unknown surrogate kind"):
        build_network(NetConfig(kind="transformer"))


def test_cnn_gru_follows_the_study_architecture():
    net = build_network(NetConfig())
    convs = [m for m in net.conv if isinstance(m, torch.nn.Conv1d)]
    assert [(c.in_channels, c.out_channels, c.kernel_size) for c in convs] == [
        (21, 21, (1,)),
        (21, 128, (1,)),
    ]
    assert [g.hidden_size for g in net.rnn] == [64, 32, 16]
    lin = [m for m in net.head if isinstance(m, torch.nn.Linear)]
    assert [m.out_features for m in lin] == [64, 8, 8, 2]


def test_tiny_training_lowers_the_loss_and_resumes(run, tmp_path):
    camp = load_campaign(run)
    spec = FeatureSpec(parameters=KEYS)
    data = load_series(camp, "straight", spec)
    tr, va, _ = split_samples(data.sample_ids)
    norm = Normaliser.fit(data.subset(tr))
    cfg = TrainConfig(epochs=4, batches_per_epoch=15, batch_size=64, val_windows=500)

    def fresh():
        torch.manual_seed(0)
        return build_network(NetConfig(kind="bp", mlp_hidden=(64, 32)))

    samplers = (WindowSampler(data.subset(tr), norm, 20), WindowSampler(data.subset(va), norm, 20))
    hist = train_network(fresh(), *samplers, cfg)
    assert hist[-1]["train_loss"] < hist[0]["train_loss"]
    # interrupted after 2 epochs, resumed to 4: the same history as one go
    ck = tmp_path / "ck.pt"
    part = train_network(
        fresh(), *samplers, TrainConfig(**{**cfg.to_dict(), "epochs": 2}), checkpoint=ck
    )
    assert len(part) == 2
    shutil.copy(ck, tmp_path / "ck-other.pt")
    net = fresh()
    resumed = train_network(net, *samplers, cfg, checkpoint=ck)
    assert resumed[:2] == part  # restored from the checkpoint (timings included), not re-run
    assert [h["val_loss"] for h in resumed] == pytest.approx([h["val_loss"] for h in hist])
    # other training data (here train and validation swapped) never resume this checkpoint
    other = (WindowSampler(data.subset(va), norm, 20), WindowSampler(data.subset(tr), norm, 20))
    two = TrainConfig(**{**cfg.to_dict(), "epochs": 2})
    afresh = train_network(fresh(), *other, two, checkpoint=tmp_path / "ck-other.pt")
    assert [h["val_loss"] for h in afresh] != [h["val_loss"] for h in part]


def test_a_swallowed_ctrl_c_stops_training_after_the_epochs_checkpoint(run, tmp_path):
    """A Ctrl-C that Python swallowed (recorded by the command line's handler,
    railsusp.interrupts) stopped a training only at the pipeline's next stage boundary, after
    every epoch. It stops after the epoch's checkpoint, from which the resume goes on."""
    from railsusp.interrupts import catch_interrupts, record_interrupt

    camp = load_campaign(run)
    data = load_series(camp, "straight", FeatureSpec(parameters=KEYS))
    tr, va, _ = split_samples(data.sample_ids)
    norm = Normaliser.fit(data.subset(tr))
    cfg = TrainConfig(epochs=3, batches_per_epoch=5, batch_size=64, val_windows=200)
    samplers = (WindowSampler(data.subset(tr), norm, 20), WindowSampler(data.subset(va), norm, 20))
    torch.manual_seed(0)
    net = build_network(NetConfig(kind="bp", mlp_hidden=(16,)))
    epochs = []

    def swallowed(epoch: int, train_loss: float, val_loss: float) -> None:
        epochs.append(epoch)
        record_interrupt()  # as the handler does, its KeyboardInterrupt then lost

    ck = tmp_path / "ck.pt"
    restore = catch_interrupts()
    try:
        with pytest.raises(KeyboardInterrupt):
            train_network(net, *samplers, cfg, checkpoint=ck, progress=swallowed)
    finally:
        restore()
    assert epochs == [1]
    resumed = train_network(
        net, *samplers, cfg, checkpoint=ck, progress=lambda e, *losses: epochs.append(e)
    )
    assert len(resumed) == 3 and epochs == [1, 2, 3]  # the first epoch not run again


def test_fine_tuning_restarts_from_the_best_state_at_a_tenth_of_the_rate(run, tmp_path):
    """The second phase runs at learning_rate x 0.1; a finished main phase, and a phase
    interrupted half way, resume into the same history as one go."""
    camp = load_campaign(run)
    data = load_series(camp, "straight", FeatureSpec(parameters=KEYS))
    tr, va, _ = split_samples(data.sample_ids)
    norm = Normaliser.fit(data.subset(tr))
    samplers = (WindowSampler(data.subset(tr), norm, 20), WindowSampler(data.subset(va), norm, 20))
    cfg = TrainConfig(
        epochs=2, fine_tune_epochs=2, batches_per_epoch=10, batch_size=64, val_windows=500
    )

    def fresh():
        torch.manual_seed(0)
        return build_network(NetConfig(kind="bp", mlp_hidden=(64, 32)))

    hist = train_network(fresh(), *samplers, cfg)
    assert [h["phase"] for h in hist] == ["main", "main", "fine-tune", "fine-tune"]
    assert [h["learning_rate"] for h in hist] == pytest.approx([1e-3, 1e-3, 1e-4, 1e-4])
    assert [h["epoch"] for h in hist] == [1, 2, 3, 4]
    for n_ft in (0, 1):  # stopped after the main phase, and one epoch into fine-tuning
        ck = tmp_path / f"ck{n_ft}.pt"
        part = train_network(
            fresh(), *samplers, TrainConfig(**{**cfg.to_dict(), "fine_tune_epochs": n_ft}), ck
        )
        assert len(part) == 2 + n_ft
        resumed = train_network(fresh(), *samplers, cfg, checkpoint=ck)
        assert resumed[: len(part)] == part
        assert [h["val_loss"] for h in resumed] == pytest.approx([h["val_loss"] for h in hist])
    # another fine-tune factor is other training: it never resumes this checkpoint
    other = TrainConfig(**{**cfg.to_dict(), "fine_tune_lr_factor": 0.5})
    afresh = train_network(fresh(), *samplers, other, checkpoint=tmp_path / "ck0.pt")
    assert afresh[2]["learning_rate"] == pytest.approx(5e-4)


@pytest.fixture(scope="module")
def trained(run):
    cfg = TrainConfig(epochs=1, batches_per_epoch=5, batch_size=64, val_windows=500)
    sur = train_surrogate(run, "straight", parameters=KEYS, train=cfg)
    return sur, run / "surrogates" / "cnn-gru" / "straight"


def test_save_load_round_trip_and_predict(run, trained):
    sur, path = trained
    back = load(path)
    from railsusp.params import bounds

    lo, hi = bounds(KEYS)
    x = np.vstack([lo, (lo + hi) / 2, hi])
    a, b = sur.predict(x), back.predict(x)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (3, 100, 2)
    # 8 training runs: a record correction was fitted, saved and applied
    assert back.correction is not None and back.meta["record_correction"]["n_runs"] == 8
    raw = back.predict(x, corrected=False)
    unit = (x - lo) / (hi - lo)
    np.testing.assert_allclose(a, raw * back.correction.factors(unit)[:, None, :], rtol=1e-6)
    assert not np.allclose(a[:, 20:], raw[:, 20:])
    assert np.isnan(a[:, :20]).all() and np.isfinite(a[:, 20:]).all()
    assert set(back.meta["test_ids"]).isdisjoint(back.meta["train_ids"])
    same = back.predict(x, back.condition)  # its own condition: the training track
    np.testing.assert_array_equal(same, a)
    # trained on one track realisation: another is new input it does not predict, said so
    assert back.one_track and back.reads_training_track(back.condition)
    assert not back.reads_training_track(back.condition.with_changes(seed=77))
    with pytest.warns(OneTrackWarning, match="one track realisation"):
        other_track = back.predict(x, back.condition.with_changes(seed=77))
    assert not np.allclose(other_track[:, 20:], a[:, 20:])
    with pytest.raises(ValueError, match="differs in speed_kmh"):
        back.predict(x, back.condition.with_changes(speed_kmh=80))
    with pytest.raises(ValueError, match="6 columns"):
        back.predict(np.zeros((1, 3)))
    with pytest.raises(FileNotFoundError, match="no surrogate"):
        load(run)


def test_record_correction_can_be_left_out(run, tmp_path):
    cfg = TrainConfig(epochs=1, batches_per_epoch=2, batch_size=32, val_windows=100)
    sur = train_surrogate(
        run, "straight", parameters=KEYS, train=cfg, out=tmp_path, record_correction=False
    )
    assert sur.correction is None and load(tmp_path).correction is None
    assert "record_correction" not in sur.meta


def test_accuracy_metrics_on_known_predictions():
    sim = np.ones((2, 30, 2)) * np.array([10.0, 120.0])
    sim[:, :, 0] += np.sin(np.arange(30))[None]
    pred = sim * np.array([1.1, 1.0])
    rows = {r["target"]: r for r in accuracy(sim, pred, ("Y", "Q"), 5)}
    assert rows["Y"]["relative_error_of_mean"] == pytest.approx(0.1)
    assert rows["Q"]["relative_error_of_mean"] == 0.0 and rows["Q"]["r2"] != rows["Q"]["r2"]
    assert rows["Y"]["r2"] < 1.0
    # per run 10 % off in opposite directions: the per-run average says 10 %, the pooled
    # mean (one simulated and one predicted value, the study's Table 7 form) says 0
    pred = sim * np.array([[[1.1, 1.0]], [[0.9, 1.0]]])
    rows = {r["target"]: r for r in accuracy(sim, pred, ("Y", "Q"), 5)}
    assert rows["Y"]["relative_error_of_mean"] == pytest.approx(0.1)
    assert rows["Y"]["relative_error_of_pooled_mean"] == pytest.approx(0.0, abs=1e-12)


def test_evaluate_runs_on_held_out_samples(run, trained):
    sur = load(trained[1])
    data = load_series(load_campaign(run), "straight", sur.spec)
    test = data.subset(np.flatnonzero(np.isin(data.sample_ids, sur.meta["test_ids"])))
    rows = evaluate(sur, test)
    assert [r["target"] for r in rows] == ["Y", "Q"]
    assert all(r["n_samples"] == test.n_samples for r in rows)


def test_predict_on_a_measured_track_and_another_record_length(trained, tmp_path):
    """The network reads the track: on a measured-geometry file equal to its training track
    it predicts what it predicts there; on another seed's geometry, something else; and a
    longer record gives a longer series."""
    from railsusp.params import bounds
    from railsusp.vehicle.track_geometry import write_track_geometry
    from railsusp.vehicle.track_grid import section_irregularities

    _, path = trained
    sur = load(path)
    lo, hi = bounds(KEYS)
    x = np.vstack([lo, hi])
    cond = sur.condition.with_changes(seed=sur.track_seed)
    irr = section_irregularities(cond, [cond.seed], sur.wagon)
    geometry = write_track_geometry(tmp_path / "same.csv", irr, origin_m=cond.lead_in_m)
    with pytest.warns(OneTrackWarning):  # a file: railsusp cannot tell it is the same track
        on_file = sur.predict(x, cond.with_changes(track_geometry=str(geometry), seed=999))
    np.testing.assert_allclose(on_file, sur.predict(x), rtol=1e-4, atol=1e-3)
    longer = sur.predict(x, cond.with_changes(duration_s=3.0, n_steps=150))
    assert longer.shape == (2, 150, 2)
    # estimation: a one-track network does not read a recording's measured track; its
    # statistics come from its own track, and a time-aligned comparison is refused
    from types import SimpleNamespace

    from railsusp.errors import RailsuspInputError
    from railsusp.estimate import SurrogateForces, check_aligned

    forces = SurrogateForces(path.parent)
    measured = cond.with_changes(track_geometry=str(geometry))
    assert not forces.reads_track(measured)
    with pytest.warns(OneTrackWarning, match="cannot read"):
        np.testing.assert_array_equal(forces.series(x, measured), sur.predict(x))
    with warnings.catch_warnings():  # said once per condition, not at every generation
        warnings.simplefilter("error", OneTrackWarning)
        forces.series(x, measured)
    with pytest.raises(RailsuspInputError, match="one track realisation.*campaign over the rec"):
        check_aligned(forces, [SimpleNamespace(condition=measured)])


def test_sampled_parameters_left_out_of_the_inputs_are_named(tmp_path):
    """Without a sensitivity analysis the surrogate inputs are the study's six; the other
    parameters the campaign sampled vary between runs unseen, and are named for a warning."""
    import json

    from railsusp.params import MAIN_SUSPENSION
    from railsusp.surrogate import key_parameters, unexplained_parameters

    (tmp_path / "campaign.json").write_text(
        json.dumps({"config": {"parameters": list(MAIN_SUSPENSION)}})
    )
    assert key_parameters(tmp_path) == ("X13", "X14", "X15", "X16", "X17", "X18")
    assert unexplained_parameters(tmp_path) == ("X11", "X12", "X19", "X20")
    sens = tmp_path / "sensitivity"
    sens.mkdir()
    keys = ["X11", "X12", "X13", "X14", "X17", "X18"]
    (sens / "key_parameters.json").write_text(json.dumps({"key_parameters": {"keys": keys}}))
    assert key_parameters(tmp_path) == tuple(keys)
    assert unexplained_parameters(tmp_path) == ()


def test_a_trained_folder_left_aside_mid_swap_is_put_back_before_training(run, tmp_path):
    """A crash between the save's two renames leaves the trained folder aside as
    ``.NAME.old-*``: `train` started again from epoch 1 and the swap then deleted the trained
    network (the QA of stop 74). It is put back first, and its checkpoint resumes."""
    cfg = TrainConfig(epochs=2, batches_per_epoch=3, batch_size=32, val_windows=100)
    out = tmp_path / "bp" / "straight"
    train_surrogate(run, "straight", kind="bp", parameters=KEYS, train=cfg, out=out)
    weights = (out / "model.pt").read_bytes()
    out.rename(out.parent / ".straight.old-abc12345")
    epochs = []
    train_surrogate(
        run, "straight", kind="bp", parameters=KEYS, train=cfg, out=out,
        progress=lambda epoch, *_: epochs.append(epoch),
    )  # fmt: skip
    assert epochs == []  # resumed from the finished checkpoint: no epoch trained again
    assert (out / "model.pt").read_bytes() == weights
    assert [p.name for p in out.parent.iterdir()] == ["straight"]
