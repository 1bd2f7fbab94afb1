"""The nominal response as a surrogate input (railsusp.surrogate.nominal): the campaign's
nominal twins (railsusp.campaign.twins), the same forces simulated at prediction time, the
target the network learns, and the nominal forces added back when it predicts."""

import numpy as np
import pytest
import torch

from conftest import family_campaign
from railsusp.campaign import CampaignError, load_campaign, make_config, run_campaign
from railsusp.campaign.twins import nominal_folder, run_nominal_twins, twins_complete
from railsusp.conditions import get_condition
from railsusp.params import ParameterSet
from railsusp.surrogate import TrainConfig, feature_spec, train_surrogate
from railsusp.surrogate.data import Normaliser, load_series
from railsusp.surrogate.features import FeatureSpec, track_features
from railsusp.surrogate.nominal import nominal_forces
from railsusp.variation import sample_condition
from railsusp.vehicle.simulate import simulate_batch
from railsusp.vehicle.simulation_result import measured_wheel_index

KEYS = ("X13", "X14")
CURVE = get_condition("curve", duration_s=2.0, n_steps=100)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = family_campaign(tmp_path_factory.mktemp("twins") / "run", KEYS, CURVE)
    return out


@pytest.fixture(scope="module")
def twins(run):
    seen = []
    run_nominal_twins(run, progress=lambda d, t: seen.append((d, t)), max_batches=1)
    assert not twins_complete(run) and seen == [(0, 2), (1, 2)]
    run_nominal_twins(run)
    assert twins_complete(run)
    return run


def test_twins_resume_and_are_the_nominal_wagon_on_each_samples_track(twins):
    """A twin is the nominal wagon on its sample's own class, radius, cant and seed; a
    second call simulates nothing (it resumes from the stored batches)."""
    files = sorted(nominal_folder(twins).rglob("batch-*.parquet"))
    stamps = [f.stat().st_mtime_ns for f in files]
    seen = []
    run_nominal_twins(twins, progress=lambda d, t: seen.append((d, t)))
    assert seen == [(2, 2)] and [f.stat().st_mtime_ns for f in files] == stamps
    only = []  # limited to conditions the campaign lacks: nothing to do
    run_nominal_twins(twins, progress=lambda d, t: only.append((d, t)), conditions=["uphill"])
    assert only == [(0, 0)]
    camp = load_campaign(twins)
    row = camp.tracks("curve").iloc[4]
    r = simulate_batch(
        [ParameterSet.nominal()],
        sample_condition(CURVE, row),
        seeds=[int(row.seed)],
        wagon=camp.config.wagon,
        settings=camp.config.settings(),
    )
    spec = feature_spec(camp, KEYS, nominal_response=True)
    data = load_series(camp, "curve", spec)
    i = list(data.sample_ids).index(4)
    j = measured_wheel_index(CURVE, "auto")
    np.testing.assert_allclose(data.track[i, :, -2], r.Y[0, j] / 1e3, rtol=1e-5, atol=1e-3)
    np.testing.assert_allclose(data.track[i, :, -1], r.Q[0, j] / 1e3, rtol=1e-5, atol=1e-3)
    # what the network learns: the change from the nominal wagon, much smaller in Q
    np.testing.assert_allclose(data.learned, data.targets - data.track[..., -2:])
    assert np.abs(data.learned[..., 1]).mean() < 0.2 * np.abs(data.targets[..., 1]).mean()


def test_prediction_time_nominal_equals_the_twin(twins):
    """The nominal forces simulated when a surrogate predicts on a new track are those its
    training read from the twins (same wheel, settings, lead-in and track)."""
    camp = load_campaign(twins)
    row = camp.tracks("curve").iloc[2]
    cond = sample_condition(CURVE, row)
    spec = feature_spec(camp, KEYS, nominal_response=True)
    live = track_features(cond, int(row.seed), spec, camp.config.wagon)
    data = load_series(camp, "curve", spec)
    i = list(data.sample_ids).index(int(row.sample_id))
    np.testing.assert_allclose(live, data.track[i], rtol=1e-4, atol=1e-3)
    np.testing.assert_allclose(
        live[:, -2:], nominal_forces(cond, int(row.seed), camp.config.wagon), rtol=1e-6
    )


def test_the_nominal_context_is_the_twins_other_channels_read_as_at_prediction(twins):
    """``nominal_context`` inserts the nominal wagon's other channels (every wheel's forces
    in kN, the car body's accelerations in m/s²) before its measured-wheel forces, in the
    same order and units whether read from the twins (training) or simulated when a
    surrogate predicts; the measured wheel's forces stay the last columns."""
    camp = load_campaign(twins)
    row = camp.tracks("curve").iloc[3]
    cond = sample_condition(CURVE, row)
    ctx = ("Y_w2R", "Q_w3L", "car_acc_y", "car_acc_z")
    spec = feature_spec(camp, KEYS, nominal_response=True, nominal_context=ctx)
    plain = feature_spec(camp, KEYS, nominal_response=True)
    assert spec.n_features == plain.n_features + 4 and spec.n_baseline == 2
    assert spec.names()[-6:] == [f"{c}_nominal" for c in ctx] + ["Y_nominal", "Q_nominal"]
    data = load_series(camp, "curve", spec)
    i = list(data.sample_ids).index(int(row.sample_id))
    live = track_features(cond, int(row.seed), spec, camp.config.wagon)
    np.testing.assert_allclose(live, data.track[i], rtol=1e-4, atol=1e-4)
    r = simulate_batch(
        [ParameterSet.nominal()],
        cond,
        seeds=[int(row.seed)],
        wagon=camp.config.wagon,
        settings=camp.config.settings(),
    )
    want = np.stack([r.Y[0, 3] / 1e3, r.Q[0, 4] / 1e3, r.car_acc_y[0], r.car_acc_z[0]], axis=1)
    np.testing.assert_allclose(data.track[i, :, -6:-2], want, rtol=1e-5, atol=1e-5)
    # what the network learns is still the change from the measured wheel's nominal forces
    base = load_series(camp, "curve", plain)
    np.testing.assert_allclose(data.learned, base.learned)
    assert FeatureSpec.from_dict(spec.to_dict()) == spec
    assert "nominal_context" not in plain.to_dict()  # older surrogates read the same
    with pytest.raises(ValueError, match="nominal_context \\['Y_w9L'\\]: accepted channels"):
        FeatureSpec(parameters=KEYS, nominal_response=True, nominal_context=("Y_w9L",))
    with pytest.raises(ValueError, match="only with nominal_response"):
        FeatureSpec(parameters=KEYS, nominal_context=("Y_w2R",))


def test_nominal_surrogate_adds_the_nominal_forces_back(twins, tmp_path):
    """A surrogate with the nominal response predicts the nominal forces plus its network's
    output: with the network's output layer zeroed and the learned targets' mean at zero it
    predicts the nominal wagon exactly. Its inputs are two columns wider and it refuses a
    track input without them."""
    tcfg = TrainConfig(epochs=1, batches_per_epoch=2, batch_size=32, val_windows=200)
    sur = train_surrogate(
        twins,
        "curve",
        parameters=KEYS,
        train=tcfg,
        out=tmp_path / "s",
        record_correction=False,
        nominal_response=True,
    )
    plain = FeatureSpec(parameters=KEYS, track_channels=sur.spec.track_channels)
    assert sur.spec.n_features == plain.n_features + 2
    assert sur.spec.names()[-2:] == ["Y_nominal", "Q_nominal"]
    last = [m for m in sur.net.modules() if isinstance(m, torch.nn.Linear)][-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.zero_()
    camp = load_campaign(twins)
    data = load_series(camp, "curve", sur.spec)
    # the targets' normalisation is fitted on what the network learns (force - nominal)
    fitted = Normaliser.fit(data)
    np.testing.assert_allclose(fitted.target_mean, data.learned.mean(axis=(0, 1)), rtol=1e-4)
    mean, std = [3.0, -5.0], [2.0, 4.0]  # the network's zero output is this change
    sur.normaliser = Normaliser(sur.normaliser.track_mean, sur.normaliser.track_std, mean, std)
    x = np.array([[16e6, 8e6], [12e6, 6e6]])
    pred = sur.predict(x, track=data.track[0])
    w = sur.spec.window
    for k in range(2):
        np.testing.assert_allclose(pred[k, w:], data.track[0, w:, -2:] + mean, rtol=1e-6)
    assert np.isnan(pred[:, :w]).all()
    # the nominal response at prediction is simulated with the campaign's solver settings
    assert sur.solver_settings() == camp.config.settings()
    with pytest.raises(ValueError, match="track input has 18 columns, this surrogate reads 20"):
        sur.predict(x, track=data.track[0, :, :-2])


def test_twins_need_a_track_per_sample(tmp_path):
    cond = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    out = tmp_path / "common"
    run_campaign(make_config([cond], 2, parameters=KEYS, batch_size=2), out)
    with pytest.raises(CampaignError, match="nominal twins need a campaign with a track per"):
        run_nominal_twins(out)
    spec = FeatureSpec(parameters=KEYS, nominal_response=True)
    with pytest.raises(CampaignError, match="nominal twins need a campaign with a track per"):
        load_series(load_campaign(out), "straight", spec)


def test_twins_of_another_configuration_are_not_used(twins, tmp_path):
    """Twins stamped with another configuration's hash count as missing and are not
    completed; a negative batch limit is refused in one line."""
    import shutil

    run = tmp_path / "copy"
    shutil.copytree(twins, run)
    stamp = nominal_folder(run) / "twins.json"
    stamp.write_text('{"config_hash": "0123456789abcdef"}')
    assert not twins_complete(run)
    with pytest.raises(CampaignError, match="nominal twins of another configuration"):
        run_nominal_twins(run)
    spec = feature_spec(load_campaign(run), KEYS, nominal_response=True)
    with pytest.raises(ValueError, match="missing, incomplete or of another configuration"):
        load_series(load_campaign(run), "curve", spec)
    with pytest.raises(CampaignError, match="max_batches = -1: accepted an integer >= 0"):
        run_nominal_twins(run, max_batches=-1)


def test_a_campaign_rerun_with_another_configuration_discards_its_twins(tmp_path):
    cond = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    out = tmp_path / "run"
    kw = {"parameters": KEYS, "batch_size": 2, "independent_seeds": True}
    run_campaign(make_config([cond], 2, seed=1, **kw), out)
    run_nominal_twins(out)
    assert twins_complete(out)
    run_campaign(make_config([cond], 2, seed=2, **kw), out, force=True)
    assert not nominal_folder(out).exists() and not twins_complete(out)
