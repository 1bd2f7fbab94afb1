"""A saved network's record correction fitted again under today's rule (the runs cap), its
weights untouched; refused for a campaign it was not trained on."""

import shutil

import numpy as np
import pytest

import railsusp.surrogate.correction as correction
from conftest import family_campaign
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.surrogate import TrainConfig, load, train_surrogate
from railsusp.surrogate.refit import refit_record_correction

KEYS = ("X13", "X14")
CURVE = get_condition("curve", duration_s=2.0, n_steps=100)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny campaign of 16 runs and a window network with its record correction."""
    root = tmp_path_factory.mktemp("refit")
    run = family_campaign(root / "run", KEYS, CURVE, samples=16)
    tcfg = TrainConfig(epochs=1, batches_per_epoch=2, batch_size=32, val_windows=100)
    out = run / "surrogates" / "bp" / "curve"
    train_surrogate(run, "curve", kind="bp", parameters=KEYS, window=10, train=tcfg, out=out)
    return run, out


@pytest.fixture
def copy(trained, tmp_path):
    """The trained bundle copied, so that each test refits its own."""
    run, bundle = trained
    shutil.copytree(bundle, tmp_path / "curve")
    return run, tmp_path / "curve"


def test_without_a_cap_the_refit_is_the_training_fit(copy):
    """Under the training's own rule the refit gives back the correction training fitted."""
    run, bundle = copy
    before = load(bundle)
    after = refit_record_correction(bundle, run)
    np.testing.assert_array_equal(after.correction.x_unit, before.correction.x_unit)
    np.testing.assert_allclose(after.correction.log_ratio, before.correction.log_ratio, rtol=1e-6)
    for a, b in zip(after.correction.thetas, before.correction.thetas, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)


def test_the_refit_caps_the_runs_and_keeps_the_weights(copy, monkeypatch):
    run, bundle = copy
    before = load(bundle)
    n_train = before.meta["record_correction"]["n_runs"]
    assert before.correction.x_unit.shape[0] == n_train > correction.MIN_RUNS
    monkeypatch.setattr(correction, "MAX_RUNS", correction.MIN_RUNS)
    refit_record_correction(bundle, run)
    after = load(bundle)
    assert after.correction.x_unit.shape[0] == correction.MIN_RUNS
    rc = after.meta["record_correction"]
    assert rc["n_runs"] == n_train and rc["n_fitted"] == correction.MIN_RUNS
    assert set(rc["validation_error_corrected"]) == {"Y", "Q"}
    for k, v in before.net.state_dict().items():
        np.testing.assert_array_equal(after.net.state_dict()[k].numpy(), v.numpy())
    # the fitted runs are among the training runs the first fit used
    first = {tuple(r) for r in before.correction.x_unit.round(9)}
    assert {tuple(r) for r in after.correction.x_unit.round(9)} <= first


def test_a_network_of_another_campaign_or_without_a_correction_is_refused(copy, tmp_path):
    run, bundle = copy
    other = family_campaign(tmp_path / "other", KEYS, CURVE, seed=5)
    with pytest.raises(RailsuspInputError, match=r"trained on campaign .*, not on .*other"):
        refit_record_correction(bundle, other)
    sur = load(bundle)
    sur.correction = None
    sur.save(bundle)
    with pytest.raises(RailsuspInputError, match="trained without a record correction"):
        refit_record_correction(bundle, run)


def test_the_bench_script_refits_and_refuses_in_one_line(copy, tmp_path, capsys):
    """bench/refit_correction.py: before and after printed per network; a campaign the
    network was not trained on ends in one line and exit 2, the bundle untouched."""
    from conftest import bench_script

    run, bundle = copy
    script = bench_script("refit_correction")
    assert script.main(["--run", str(run), str(bundle)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [ln.split(": fitted on")[0] for ln in out] == [f"{bundle} before", f"{bundle} after"]
    before = (bundle / "surrogate.json").read_bytes()
    other = family_campaign(tmp_path / "other", KEYS, CURVE, seed=7)
    assert script.main(["--run", str(other), str(bundle)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "not on" in err
    assert (bundle / "surrogate.json").read_bytes() == before
