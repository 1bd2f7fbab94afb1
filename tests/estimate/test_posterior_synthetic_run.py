"""The synthetic-likelihood posterior in a run directory (railsusp.estimate.
posterior_synthetic_run): fitted from the cached training cases, checked on the cached
held-out sets, stored, read back the same by ``load``; its verdict per number of sections.
The cases' statistics come from a linear-Gaussian stand-in for the simulator written into
the simulation cache (the cache is read when its parameter draws match), so no wagon is
simulated here; the simulator's own statistics are measured in bench/posterior_synthetic.py."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import posterior_synthetic_run as synthetic
from railsusp.estimate.posterior_data import prior_draws
from railsusp.estimate.posterior_settings import PosteriorSettings

D = 17  # the summary statistics of one condition without the sum of Y


def _settings() -> PosteriorSettings:
    cond = get_condition("straight").with_changes(lead_in_m=30.0)
    return PosteriorSettings((cond,), section_s=5.0, n_train=300, n_check=30, samples=200,
                             product_sections=(4,), n_product=30)  # fmt: skip


def _statistics(u: np.ndarray, rng, sections: int, d: int = D) -> np.ndarray:
    """Summaries (n, sections, d) of a linear stand-in: X18 and X13 move them."""
    a = np.zeros((10, d))
    a[7, :6] = 3.0  # X18
    a[2, 6:12] = 2.0  # X13
    mean = 40.0 + u @ a
    return mean[:, None, :] + rng.standard_normal((len(u), sections, d))


def _cache(run, settings, kind, n, sections=1):
    folder = run / "posterior" / "simulations"
    folder.mkdir(parents=True, exist_ok=True)
    u = prior_draws(settings, kind, n)
    d = len(settings.summary_names)
    x = _statistics(u, np.random.default_rng(len(kind) + sections), sections, d)
    x = x[:, 0] if sections == 1 else x
    name = kind if sections == 1 else f"{kind}-x{sections}"
    if settings.statistics != ("en14363",):
        name += "+" + "+".join(settings.statistics[1:])
    for k, lo in enumerate(range(0, n, 50)):
        hi = min(n, lo + 50)
        buf = io.BytesIO()
        np.savez(buf, u=u[lo:hi], x=x[lo:hi])
        (folder / f"{name}_{k:04d}_{hi - lo}.npz").write_bytes(buf.getvalue())


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    run = tmp_path_factory.mktemp("synthetic_run")
    s = _settings()
    _cache(run, s, "train", s.n_train)
    _cache(run, s, "check", s.n_check)
    _cache(run, s, "long", s.n_product, 4)
    _cache(run, s, "long-calibration", s.n_product, 4)
    return run


def test_fitted_checked_stored_and_read_back_the_same(run):
    s = _settings()
    post = synthetic.train(s, run)
    folder = run / "posterior" / "synthetic"
    names = {"settings.json", "emulator.npz", "scales.json", "check.json"}
    assert {p.name for p in folder.iterdir()} >= names
    assert [c.sections for c in post.checks] == [1, 4]
    assert all(c.checks[0].n == 30 for c in post.checks)
    x18 = s.parameters.index("X18")
    w1, w4 = (c.width_pct_range["X18"] for c in post.checks)
    # X18 moves six statistics: learnt (the prior's width is 90 %), better from four sections
    assert w4 < w1 < 70.0
    back = synthetic.load(run)
    assert [c.to_dict() for c in back.checks] == [c.to_dict() for c in post.checks]
    d = len(s.summary_names)  # the emulator's error per direction, fitted and read back
    assert post.likelihood.model_error_matrix.shape == (d, d)
    assert np.array_equal(back.likelihood.model_error_matrix, post.likelihood.model_error_matrix)
    x = _statistics(np.full((1, 10), 0.5), np.random.default_rng(9), 4)[0]
    a, b = post.sample(x, 200, seed=1), back.sample(x, 200, seed=1)
    assert np.array_equal(a, b)
    assert abs(np.median(a[:, x18]) - 0.5) < 0.1
    mtime = (folder / "emulator.npz").stat().st_mtime_ns
    synthetic.train(s, run)  # a re-run reads what is there
    assert (folder / "emulator.npz").stat().st_mtime_ns == mtime


@pytest.mark.parametrize("damage", ["cut", "empty"])
def test_a_damaged_emulator_is_refused_in_one_line_and_fitted_again(run, tmp_path, damage):
    """numpy's BadZipFile ended `posterior estimate` and `posterior join` in a traceback, and
    an empty file in typer's "Aborted." (an EOFError taken for an interrupted prompt)."""
    import shutil

    s = _settings()
    synthetic.train(s, run)
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    path = copy / "posterior" / "synthetic" / "emulator.npz"
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2] if damage == "cut" else b"")
    with pytest.raises(RailsuspInputError) as info:
        synthetic.load(copy)
    assert f"the statistics emulator {path} is damaged (" in str(info.value)
    assert "\n" not in str(info.value)
    again = synthetic.train(s, copy)  # training fits it anew
    assert path.stat().st_size == len(data)
    assert [c.to_dict() for c in again.checks] == [c.to_dict() for c in synthetic.load(run).checks]


def test_the_verdict_follows_the_check_of_the_number_of_sections(run):
    post = synthetic.load(run)
    assert post.product_for(1).sections == 1
    assert post.product_for(2).sections == 4  # the smallest checked number >= 2
    assert post.product_for(5) is None  # longer than any check: not calibrated


def test_a_run_without_the_fitted_likelihood_is_refused_in_one_line(tmp_path):
    with pytest.raises(RailsuspInputError, match=r"synthetic.settings\.json does not exist: fit"):
        synthetic.load(tmp_path)


def test_statistics_beyond_the_en14363_summary_are_read_through_their_projection(tmp_path):
    """With the coherence family (68 statistics) the likelihood reads 15 combinations of
    them (the default rank, 15 of 68), fitted on training cases once per emulator and read back by
    ``load``: the same draws; the stand-in's two informative parameters keep nearly all
    their information, and X18's interval holds its truth."""
    s = PosteriorSettings(_settings().conditions, section_s=5.0, n_train=300, n_check=30,
                          samples=200, product_sections=(4,), n_product=30,
                          statistics=("coherence",))  # fmt: skip
    for kind, n, k in (("train", 300, 1), ("check", 30, 1), ("long", 30, 4),
                       ("long-calibration", 30, 4)):  # fmt: skip
        _cache(tmp_path, s, kind, n, k)
    post = synthetic.train(s, tmp_path)
    p = post.likelihood.projection
    assert p.shape == (s.projection_rank, 68) and post.likelihood.dim == s.projection_rank == 15
    assert post.likelihood.model_error_matrix.shape == (15, 15)
    with np.load(tmp_path / "posterior" / "synthetic" / "projection.npz") as z:
        assert float(z["kept"]) > 0.9
    back = synthetic.load(tmp_path)
    assert np.array_equal(back.likelihood.projection, p)
    x = _statistics(np.full((1, 10), 0.5), np.random.default_rng(9), 4, 68)[0]
    a = post.sample(x, 200, seed=1)
    assert np.array_equal(a, back.sample(x, 200, seed=1))
    lo, hi = np.quantile(a[:, s.parameters.index("X18")], [0.05, 0.95])
    assert lo < 0.5 < hi and hi - lo < 0.8  # 30 calibration records for 15 combinations
    # another rank in the same folder: its own projection, scales and check; load follows
    from dataclasses import replace

    check = tmp_path / "posterior" / "synthetic" / "check.json"
    before = check.read_bytes()
    five = synthetic.train(replace(s, projection_rank=5), tmp_path)
    assert five.likelihood.projection.shape == (5, 68) and check.read_bytes() != before
    back = synthetic.load(tmp_path)
    assert back.settings.projection_rank == 5 and back.likelihood.projection.shape == (5, 68)
    # a rank above the number of statistics is said, and all of them are kept
    with pytest.warns(UserWarning, match=r"projection_rank \(--projection-rank\) 100 is more "
                      r"than the 68 statistics"):  # fmt: skip
        every = synthetic.train(replace(s, projection_rank=100), tmp_path)
    assert every.likelihood.projection.shape == (68, 68)
    # a projection that is not the checked one (an interrupted training) is refused
    path = tmp_path / "posterior" / "synthetic" / "projection.npz"
    with np.load(path) as z:
        stale = dict(z)
    stale["stamp"] = np.array("another")
    buf = io.BytesIO()
    np.savez(buf, **stale)
    path.write_bytes(buf.getvalue())
    with pytest.raises(RailsuspInputError, match="projection.npz does not belong to the check"):
        synthetic.load(tmp_path)


def test_the_projected_combinations_get_an_emulator_of_their_own_on_every_case(tmp_path):
    """``statistics_emulator_cases``: the emulator of all 68 statistics learns from the
    first 100 cases only (it chooses the projection), the emulator of the 15 combinations
    from all 300. The likelihood's mean, section scatter and emulator spread are the second
    one's, and its spread is narrower than the first one's read through the projection
    (three times the cases). Stored, read back by ``load`` with the same draws; a
    projected emulator that is not the checked one is refused."""
    s = PosteriorSettings(_settings().conditions, section_s=5.0, n_train=300, n_check=30,
                          samples=200, product_sections=(4,), n_product=30,
                          statistics=("coherence",), statistics_emulator_cases=100)  # fmt: skip
    for kind, n, k in (("train", 300, 1), ("check", 30, 1), ("long", 30, 4),
                       ("long-calibration", 30, 4)):  # fmt: skip
        _cache(tmp_path, s, kind, n, k)
    post = synthetic.train(s, tmp_path)
    folder = tmp_path / "posterior" / "synthetic"
    sl = post.likelihood
    assert sl.emulator.cases == 100 and sl.emulator.dim == 68
    assert sl.projected.cases == 300 and sl.projected.dim == sl.dim == 15
    u = np.full((1, 10), 0.5)
    mean, shared, section, spread = sl.parts(u)
    assert np.array_equal(mean, sl.projected.mean(u))
    assert np.array_equal(section, sl.projected.moments(u)[1])
    full_spread = sl.projection @ sl.emulator.moments(u)[2][0] @ sl.projection.T
    assert np.trace(spread[0]) < np.trace(full_spread)
    gain = sl.projection @ sl.shared(sl.emulator.mean(u))[0] @ sl.projection.T
    assert np.trace(gain) > 0 and np.allclose(shared[0], gain)  # the gain model's levels
    back = synthetic.load(tmp_path)
    x = _statistics(u, np.random.default_rng(9), 4, 68)[0]
    a = post.sample(x, 200, seed=1)
    assert np.array_equal(a, back.sample(x, 200, seed=1))
    lo, hi = np.quantile(a[:, s.parameters.index("X18")], [0.05, 0.95])
    assert lo < 0.5 < hi
    from railsusp.estimate.posterior_synthetic import SyntheticLikelihood

    with pytest.raises(RailsuspInputError, match="only with a projection of as many"):
        SyntheticLikelihood(sl.emulator, projected=sl.projected)  # no projection to read
    # the emulator of all statistics is the one an old training of 100 cases would have had
    from dataclasses import replace

    from railsusp.estimate.posterior_synthetic_fit import emulator_key
    from railsusp.store import read_json

    old = replace(s, n_train=100, statistics_emulator_cases=0)
    assert read_json(folder / "settings.json")["hash"] == emulator_key(old) == emulator_key(s)
    assert emulator_key(replace(s, statistics_emulator_cases=150)) != emulator_key(s)
    # scales of another training (an interrupted one) are refused
    scales = folder / "scales.json"
    kept = scales.read_text()
    scales.write_text(json.dumps({**json.loads(kept), "within_scale": 2.0}))
    with pytest.raises(RailsuspInputError, match="scales.json does not belong to the check"):
        synthetic.load(tmp_path)
    scales.write_text(kept)
    # so is a projected emulator that is not the checked one
    path = folder / "projected_emulator.npz"
    stale = synthetic.StatisticsEmulator.load(path)
    stale.stamp = "another"
    stale.save(path)
    with pytest.raises(RailsuspInputError, match="projected_emulator.npz does not belong"):
        synthetic.load(tmp_path)
    # and a re-run of the training fits it again (its stamp no longer matches)
    synthetic.train(s, tmp_path)
    assert synthetic.StatisticsEmulator.load(path).stamp != "another"
    synthetic.load(tmp_path)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"statistics_emulator_cases": 100}, "conflicts with statistics = en14363"),
        ({"statistics": ("coherence",), "statistics_emulator_cases": 301},
         r"statistics_emulator_cases = 301: accepted 0 .* training cases, n_train = 300"),
    ],
)  # fmt: skip
def test_statistics_emulator_cases_that_cannot_work_are_refused(changes, message):
    from dataclasses import replace

    with pytest.raises(RailsuspInputError, match=message):
        replace(_settings(), **changes)


def test_one_emulator_keeps_the_settings_and_hash_of_before():
    """0 (the default) is left out of the stored settings, so estimators trained before
    the field existed keep their hashes; a value is stored and read back."""
    from dataclasses import replace

    s = replace(_settings(), statistics=("coherence",))
    assert "statistics_emulator_cases" not in s.to_dict()
    two = replace(s, statistics_emulator_cases=100)
    assert PosteriorSettings.from_dict(two.to_dict()) == two


def test_a_degenerate_scatter_scale_is_said(run, tmp_path, monkeypatch):
    """Stop 56's audit: on 2 s sections the sections' scatter came out 8e21 times the
    emulator's, in the log alone. A scale beyond WITHIN_SCALE_WARN is now a warning naming
    the likely cause; the fitted, ordinary one is not."""
    import shutil
    import warnings

    from railsusp.estimate import posterior_synthetic_fit as fit

    s = _settings()
    sl = synthetic.train(s, run).likelihood  # read back where an earlier test trained it
    where = fit.scale_set(s)
    for scale, warned in ((None, False), (1e6, True)):
        copy = tmp_path / f"run{warned}"
        shutil.copytree(run / "posterior", copy / "posterior")
        (copy / "posterior" / "synthetic" / "scales.json").unlink()
        if scale is not None:
            monkeypatch.setattr(fit, "fit_scales", lambda sl, u, x, c=scale: (c, 0.0))
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            record = fit.fit_covariance_scales(s, sl, copy, where)
        said = [w for w in seen if "scatter" in str(w.message)]
        assert bool(said) == warned, [str(w.message) for w in seen]
        assert (record["within_scale"] == scale) if warned else record["within_scale"] < 10
        if warned:
            assert "1e+06 times as much as the emulator expects" in str(said[0].message)
            assert "longer than the 5 s section" in str(said[0].message)


def test_an_emulator_or_a_check_that_is_not_the_trained_one_is_refused(
    run, tmp_path, monkeypatch, caplog
):
    """The second posterior audit: another estimator's emulator.npz of the same settings
    (its stamp is the settings' hash) was accepted with the check of the folder's own, and
    a check.json edited by hand was trusted as it stood. Now the check's stamp holds the
    emulators' SHA-256 and the record is sealed: load refuses either in one line."""
    import logging
    import shutil

    from railsusp.store import read_json

    s = _settings()
    synthetic.train(s, run)
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    folder = copy / "posterior" / "synthetic"
    emulator = folder / "emulator.npz"
    kept = emulator.read_bytes()
    other = synthetic.StatisticsEmulator.load(emulator)
    other.x_mean = other.x_mean + 0.5  # another training's emulator, the same stamp
    other.save(emulator)
    with pytest.raises(RailsuspInputError, match=r"emulator.npz does not belong to the check"):
        synthetic.load(copy)
    emulator.write_bytes(kept)
    check = folder / "check.json"
    good = check.read_text()
    record = json.loads(good)
    record["checks"][0]["parameters"][0]["coverage"] = 0.95
    check.write_text(json.dumps(record))
    with pytest.raises(RailsuspInputError) as info:
        synthetic.load(copy)
    assert str(info.value).startswith(f"{check} was changed after the synthetic likelihood")
    assert "train --long-record synthetic-likelihood again on this folder" in str(info.value)
    # a check written before records were sealed and the files stamped: read as it stands
    # (a warning), sealed by a re-run of the training without checking again
    from railsusp.estimate.posterior_check import SEAL

    old = json.loads(good)
    del old[SEAL]
    del old["emulator"][5]
    check.write_text(json.dumps(old))
    with caplog.at_level(logging.WARNING):
        back = synthetic.load(copy)
    assert "written before check records were sealed" in caplog.text
    assert [c.to_dict() for c in back.checks] == [c.to_dict() for c in synthetic.load(run).checks]

    def no_check(*a, **k):
        raise AssertionError("checked again")

    monkeypatch.setattr(synthetic, "run_checks", no_check)
    synthetic.train(s, copy)
    assert read_json(check) == json.loads(good)
