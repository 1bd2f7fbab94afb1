"""Simulation-based posterior: geometry-free summaries on analytic inputs, the calibration
check on a conjugate Gaussian problem (it passes the exact posterior and fails an
over-confident or biased one), a small train + estimate on the wagon with a hidden truth,
the cache and resume, and the command line's one-line errors."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from typer.testing import CliRunner

from posterior_fakes import ConfidentEstimator, synthetic_cases
from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import (
    calibration,
    posterior,
    posterior_check,
    posterior_data,
    posterior_fusion,
)
from railsusp.estimate.posterior_estimator import PosteriorEstimator
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.summaries import (
    band_rms,
    cut_sections,
    en14363_percentiles,
    section_summary,
    summary_names,
)
from railsusp.measured import read_field, synthesise_field
from railsusp.params import ParameterSet
from railsusp.store import read_json

runner = CliRunner()
FS = 50.0


# ---------------------------------------------------------------- summaries
def test_band_rms_of_a_sine_is_its_amplitude_over_root_two_in_its_band():
    t = np.arange(int(20 * FS)) / FS
    x = 5.0 + 3.0 * np.sin(2 * np.pi * 3.0 * t)  # the mean is removed first
    rms = band_rms(x, FS)
    assert rms[1] == pytest.approx(3.0 / np.sqrt(2), rel=0.02)  # 1.5-4 Hz
    assert max(rms[0], rms[2], rms[3]) < 0.05


def test_en14363_percentiles_of_constant_and_of_a_long_wave():
    n = int(20 * FS)
    assert en14363_percentiles(np.full(n, 42.0), FS, 16.7) == pytest.approx([42.0] * 3)
    t = np.arange(n) / FS
    wave = 10.0 * np.sin(2 * np.pi * 0.5 * t)  # 33 m wavelength at 16.7 m/s: 2 m keeps 99.4 %
    p = en14363_percentiles(wave, FS, 16.7)
    assert p[0] == pytest.approx(-10.0 * 0.994, abs=0.15)
    assert p[1] == pytest.approx(0.0, abs=0.3)
    assert p[2] == pytest.approx(10.0 * 0.994, abs=0.15)


def test_section_summary_quotient_and_wheelset_force():
    """Both wheels pushing towards their own field sides alike (each Y + towards its own
    field side) put no lateral force on the track: sumY = Y - Y_partner = 0."""
    n = int(10 * FS)
    rng = np.random.default_rng(1)
    Q = 100.0 + rng.standard_normal(n)
    Y = 0.3 * Q
    s = section_summary(Y, Q, FS, 16.7, Y_partner=Y)
    names = summary_names(sum_y=True)
    assert len(s) == len(names)
    got = dict(zip(names, s, strict=True))
    for p in ("p0.15", "p50", "p99.85"):
        assert got[f"YQ_{p}"] == pytest.approx(0.3, abs=1e-6)
        assert got[f"sumY_{p}"] == pytest.approx(0.0, abs=1e-9)
    assert len(section_summary(Y, Q, FS, 16.7)) == len(summary_names())


def test_cut_sections_leaves_out_the_short_remainder():
    assert cut_sections(10, 3) == [slice(0, 3), slice(3, 6), slice(6, 9)]
    assert cut_sections(2, 3) == []
    with pytest.raises(ValueError, match="at least 1"):
        cut_sections(10, 0)


# ---------------------------------------------------------------- calibration
def _gaussian_case(n=400, s=500, sigma=0.5, scale=1.0, shift=0.0, seed=3):
    """theta ~ N(0, 1), x ~ N(theta, sigma^2): the posterior is
    N(x / (1 + sigma^2), sigma^2 / (1 + sigma^2)); ``scale`` narrows (< 1) its draws,
    ``shift`` moves them by that many posterior standard deviations."""
    rng = np.random.default_rng(seed)
    theta = rng.standard_normal((n, 1))
    x = theta + sigma * rng.standard_normal((n, 1))
    sd = np.sqrt(sigma**2 / (1 + sigma**2))
    mean = x / (1 + sigma**2) + shift * sd
    draws = mean[:, None, :] + scale * sd * rng.standard_normal((n, s, 1))
    return draws, theta


def test_calibration_passes_the_exact_posterior():
    (c,) = calibration.check(*_gaussian_case(), ["theta"])
    assert c.passed and 0.86 <= c.coverage <= 0.94 and c.sbc_p > 0.01


def test_calibration_fails_an_over_confident_posterior():
    (c,) = calibration.check(*_gaussian_case(scale=0.5), ["theta"])
    # the half-width interval holds the truth with P(|z| < 1.645/2) = 59 %
    assert not c.passed and c.coverage == pytest.approx(0.59, abs=0.06) and c.sbc_p < 1e-6


def test_calibration_sees_a_biased_posterior_in_the_ranks():
    (c,) = calibration.check(*_gaussian_case(shift=1.0), ["theta"])
    assert not c.passed and c.sbc_p < 1e-6


def test_spread_correction_makes_an_over_confident_posterior_pass_on_untouched_cases():
    """Fitted on one set, checked on a third, untouched one: draws at 0.6 of the exact
    posterior's spread fail; the conformal factor is close to 1 / 0.6 and passes."""
    names = ["theta"]
    test = _gaussian_case(scale=0.6, seed=11)
    (before,) = calibration.check(*test, names)
    assert not before.passed and before.coverage < 0.80
    corr = calibration.SpreadCorrection.fit(*_gaussian_case(scale=0.6, seed=7), names)
    assert corr.factors[0] == pytest.approx(1 / 0.6, rel=0.12) and corr.excessive == []
    (after,) = calibration.check(corr.apply(test[0]), test[1], names)
    assert after.passed and 0.85 <= after.coverage <= 0.95
    assert np.allclose(np.median(corr.apply(test[0]), axis=1), np.median(test[0], axis=1))


def test_spread_correction_leaves_an_honest_posterior_nearly_alone():
    corr = calibration.SpreadCorrection.fit(*_gaussian_case(seed=7), ["theta"])
    assert 1.0 <= corr.factors[0] < 1.15  # never narrows; the raw factor is near 1
    assert corr.raw_factors[0] == pytest.approx(1.0, abs=0.15)
    wide = calibration.SpreadCorrection.fit(*_gaussian_case(scale=2.0, seed=7), ["theta"])
    assert wide.factors == (1.0,) and wide.raw_factors[0] < 0.6  # too wide: left as it is


def test_spread_correction_beyond_its_bound_is_flagged_and_round_trips():
    draws, truth = _gaussian_case(n=400, scale=0.3, seed=7)
    two = np.concatenate([draws, _gaussian_case(n=400, seed=8)[0]], axis=2)
    truths = np.concatenate([truth, _gaussian_case(n=400, seed=8)[1]], axis=1)
    corr = calibration.SpreadCorrection.fit(two, truths, ["a", "b"])
    assert corr.factors[0] > calibration.MAX_INFLATION and corr.excessive == ["a"]
    again = calibration.SpreadCorrection.from_dict(corr.to_dict())
    assert again == corr and again.excessive == ["a"]
    with pytest.raises(ValueError, match="at least 9 are needed"):
        calibration.SpreadCorrection.fit(draws[:5], truth[:5], ["a"])


def test_fusion_adds_the_sections_information_and_clips_what_is_below_the_prior():
    """Gaussian sections in logit coordinates: the fused precision is the prior's plus the
    sum of each section's precision less the prior's; a section wider than the prior (its
    draws' precision below the prior's) adds nothing."""
    rng = np.random.default_rng(5)
    p0 = 1.0 / (np.pi**2 / 3.0)
    sd, means = np.array([0.5, 1.0]), np.array([1.0, -0.5])
    z = means[:, None, None] + sd[:, None, None] * rng.standard_normal((2, 200_000, 1))
    precision, mean = posterior_fusion.fused_precision(z)
    info = 1 / sd**2 - p0
    assert precision[0, 0] == pytest.approx(p0 + info.sum(), rel=0.01)
    assert mean[0] == pytest.approx(np.sum(means / sd**2) / precision[0, 0], abs=0.01)
    wide = np.concatenate([z, 3.0 * rng.standard_normal((1, 200_000, 1))])  # sd 3 > 1.81
    assert posterior_fusion.fused_precision(wide)[0][0, 0] == pytest.approx(
        precision[0, 0], rel=0.01
    )
    u = np.array([1e-9, 0.3, 0.5, 1.0])
    assert np.allclose(
        posterior_fusion.from_logit(posterior_fusion.to_logit(u)), np.clip(u, 1e-6, 1 - 1e-6)
    )


def test_the_calibration_step_fits_on_one_set_and_passes_on_the_untouched_one(
    tmp_path, monkeypatch
):
    """The training's calibration step end to end on an over-confident estimator: its
    check fails before the correction and passes after it, on test cases nothing was
    fitted on; the factor is stored and read back."""
    monkeypatch.setattr(posterior_check, "cached_cases", synthetic_cases)
    s = _settings(parameters=("X13",), n_calibration=300, n_check=300, samples=400)
    s = PosteriorSettings.from_dict({**s.to_dict(), "product_sections": []})
    correction, after, products = posterior_check.calibrate(ConfidentEstimator(s), tmp_path)
    record = read_json(tmp_path / "calibration.json")
    (before,) = record["before"]
    assert not before["passed"] and before["coverage"] < 0.8
    assert correction.factors[0] == pytest.approx(1 / 0.6, rel=0.15) and not correction.excessive
    (c,) = after
    assert c.passed and 0.85 <= c.coverage <= 0.95 and record["passed"] and products == []
    again = posterior_check.calibrate(ConfidentEstimator(s), tmp_path)  # read back
    assert again[0] == correction and again[1] == after


def _synthetic_long_cases(calls):
    """Cases of X13 whose sections are x_i = logit(u) + N(0, 0.5^2) each, recording the
    (kind, cases, sections) asked for."""

    def cases(settings, folder, kind, n, sections=1, draws=None):
        calls.append((kind, n, sections))
        u = posterior_data.prior_draws(settings, kind, n)
        rng = np.random.default_rng([posterior_data.SEED_BASE[kind], sections])
        z = posterior_fusion.to_logit(u[:, [2]])
        if sections == 1:
            return u, z + 0.5 * rng.standard_normal((n, 1))
        return u, z[:, None, :] + 0.5 * rng.standard_normal((n, sections, 1))

    return cases


def test_each_number_of_sections_is_checked_on_its_own_count_of_cases(tmp_path, monkeypatch):
    """With ``product_cases``, the numbers of sections of one count share a set simulated
    for the longest of them, the others get their own; the truths stay with their cases
    (the over-confident fused posterior then passes after its correction)."""
    calls = []
    monkeypatch.setattr(posterior_check, "cached_cases", _synthetic_long_cases(calls))
    s = _settings(
        parameters=("X13",), n_calibration=100, n_check=100, samples=300,
        product_sections=(4, 2, 3), product_cases=(60, 150, 150),
    )  # fmt: skip
    assert s.product_sets() == [(150, 3, (2, 3)), (60, 4, (4,))]
    _, _, products = posterior_check.calibrate(ConfidentEstimator(s), tmp_path)
    assert {c for c in calls if c[0] == "long"} == {("long", 150, 3), ("long", 60, 4)}
    record = read_json(tmp_path / "calibration.json")["products"]
    assert [(p["sections"], p["calibration_cases"], p["cases"]) for p in record] == [
        (2, 150, 150), (3, 150, 150), (4, 60, 60)
    ]  # fmt: skip
    for p, prod in zip(record, products, strict=True):
        (before,) = p["before"]
        assert before["coverage"] < 0.8  # k sections of 0.6 times the spread each
        assert prod.correction.factors[0] > 1.3 and prod.passed, p


def test_product_cases_are_one_count_per_number_of_sections():
    s = _settings(product_sections=(6, 2, 30), product_cases=(200, 200, 100))
    assert s.product_sections == (2, 6, 30) and s.product_cases == (200, 200, 100)
    assert s.product_sets() == [(200, 6, (2, 6)), (100, 30, (30,))]
    assert PosteriorSettings.from_dict(s.to_dict()) == s
    plain = _settings(product_sections=(2, 6))
    assert plain.product_sets() == [(20, 6, (2, 6))]  # n_product for all: one set
    assert "product_cases" not in plain.to_dict()  # the hash of earlier estimators holds
    with pytest.raises(RailsuspInputError, match="product_cases = 200,100: accepted one count"):
        _settings(product_sections=(2, 6, 30), product_cases=(200, 100))
    with pytest.raises(RailsuspInputError, match=r"product_cases = 5,200: .* 20 to 100000"):
        _settings(product_sections=(2, 6), product_cases=(5, 200))


def test_cached_cases_simulate_given_draws_and_refuse_a_wrong_shape(tmp_path, monkeypatch):
    seen = []

    def fake(settings, u, first, kind, sections):
        seen.append(u.copy())
        return np.tile(u[:, None, :1], (1, sections, len(settings.summary_names)))

    monkeypatch.setattr(posterior_data, "simulate_long_cases", fake)
    s = _settings()
    u = np.full((3, 10), 0.25)
    got_u, x = posterior_data.cached_cases(s, tmp_path, "identification", 3, 2, draws=u)
    assert np.array_equal(got_u, u) and x.shape == (3, 2, 17) and np.all(x == 0.25)
    posterior_data.cached_cases(s, tmp_path, "identification", 3, 2, draws=u)  # cached
    assert len(seen) == 1
    with pytest.raises(ValueError, match=r"draws \(2, 10\): need \(3, 10\)"):
        posterior_data.cached_cases(s, tmp_path, "identification", 3, 2, draws=u[:2])


def test_a_curve_must_be_steady_under_the_wagon_in_every_section():
    """The sections of a long recording of a curve are steady curving; a training section
    that holds the entry (curve from 20 m, 60 m spiral, a wagon of about 10 m) is not
    like them, nor a record that outlasts the arc."""
    curve = get_condition("curve")
    PosteriorSettings((curve,), product_sections=(30,))  # lead-in 100 m: in the arc
    with pytest.raises(RailsuspInputError, match=r"lead_in_m = 30 m .* accepted at least 90"):
        PosteriorSettings((curve.with_changes(lead_in_m=30.0),))
    short = curve.with_changes(arc_length_m=500.0)  # 30 s at 60 km/h
    PosteriorSettings((short,), section_s=20.0)
    with pytest.raises(RailsuspInputError, match=r"arc_length_m = 500 m .* within the 40 s"):
        PosteriorSettings((short,), section_s=20.0, product_sections=(2,))


def test_ranks_and_bad_shapes():
    samples = np.array([[[1.0], [2.0], [3.0]]])
    assert calibration.ranks(samples, np.array([[2.5]])).tolist() == [[2]]
    with pytest.raises(ValueError, match="need"):
        calibration.check(samples, np.zeros((2, 1)), ["a"])


# ---------------------------------------------------------------- train, estimate
CONDITION = get_condition("straight").with_changes(lead_in_m=30.0)


def _settings(**kw) -> PosteriorSettings:
    base = dict(
        parameters=("X13", "X14"),
        section_s=3.0,
        n_train=150,
        n_check=50,
        n_calibration=40,
        product_sections=(2,),
        n_product=20,
        samples=300,
        hidden_features=20,
        num_transforms=2,
    )
    return PosteriorSettings((CONDITION,), **{**base, **kw})


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    run = tmp_path_factory.mktemp("posterior_run")
    return posterior.train(_settings(), run), run


def test_settings_refuse_bad_values():
    with pytest.raises(RailsuspInputError, match="subset of X11"):
        _settings(parameters=("X13", "X3"))
    with pytest.raises(RailsuspInputError, match="section_s = 0.5: accepted 1 to 600"):
        _settings(section_s=0.5)
    s = _settings()
    assert PosteriorSettings.from_dict(s.to_dict()) == s


def test_hidden_truth_inside_the_interval_of_a_long_recording(trained, tmp_path):
    est, _ = trained
    truth = ParameterSet({"X13": 12.6e6, "X14": 11.0e6})
    synthesise_field(truth, [CONDITION], tmp_path / "field", duration_s=10.0)
    result = posterior.estimate(est, read_field(tmp_path / "field"))
    df = result.to_dataframe().set_index("parameter")
    assert result.sections == {"straight": {"sections": 3, "seconds_left_out": 1.0}}
    for p, value in (("X13", 12.6), ("X14", 11.0)):
        assert df.loc[p, "lo90"] <= value <= df.loc[p, "hi90"], df
        assert df.loc[p, "width_pct_range"] < 90.0  # the record told it something
    assert result.n_sections == 3 and result.checked_as is None and not result.calibrated
    assert any("3 sections" in w and "checked up to 2 section(s)" in w for w in result.warnings)
    two = posterior.estimate(est, [_cut(r, 6.0) for r in read_field(tmp_path / "field")])
    (product,) = est.products
    assert two.checked_as == 2 and two.correction == product.correction
    assert two.calibrated == product.passed
    assert any("FAILED" in w for w in two.warnings) == (not all(c.passed for c in product.checks))
    one = posterior.estimate(est, [_cut(r, 3.0) for r in read_field(tmp_path / "field")])
    assert one.n_sections == 1 and one.calibrated == est.calibrated
    w_one = one.to_dataframe()["width_pct_range"].to_numpy()
    assert np.all(df["width_pct_range"].to_numpy() < w_one)  # three sections: narrower


def _cut(rec, seconds):
    n = round(seconds * rec.sampling_rate)
    rec.time = rec.time[:n]
    rec.Y = {w: v[:n] for w, v in rec.Y.items()}
    rec.Q = {w: v[:n] for w, v in rec.Q.items()}
    return rec


def test_calibration_is_stored_with_the_estimator(trained):
    est, run = trained
    data = read_json(run / "posterior" / "calibration.json")
    assert data["cases"] + data["failed_simulations"] == 50
    cal = data["calibration_set"]
    assert cal["cases"] + cal["failed_simulations"] == 40  # a set of its own
    assert [c["parameter"] for c in data["parameters"]] == ["X13", "X14"]
    assert [c["parameter"] for c in data["before"]] == ["X13", "X14"]
    assert data["passed"] == est.calibrated
    corr = data["correction"]
    assert corr["n"] == cal["cases"] and set(corr["factors"]) == {"X13", "X14"}
    assert all(f >= 1.0 for f in corr["factors"].values())
    # split conformal: on its own calibration cases the corrected intervals hold at least
    # ceil(0.9 (n + 1)) of n truths, in the coordinates the correction is applied in
    assert all(c["coverage"] >= 0.9 for c in cal["after"]), cal["after"]
    assert est.correction.factors == tuple(corr["factors"][p] for p in ("X13", "X14"))
    (prod,) = data["products"]  # the fused posterior of two sections, corrected and checked
    assert prod["sections"] == 2 and prod["calibration_cases"] + prod["cases"] <= 40
    assert prod["passed"] == est.products[0].passed
    assert set(prod["correction"]["factors"]) == {"X13", "X14"}
    assert set(prod["width_pct_range"]) == {"X13", "X14"}
    assert all(c["coverage"] >= 0.9 for c in prod["calibration_after"]), prod


def test_draws_stay_in_the_prior_box_and_the_correction_widens_them(trained):
    est, run = trained
    x = np.load(next((run / "posterior" / "simulations").glob("check_*")))["x"][:3]
    raw = est.sample_raw(x, 400, seed=1)
    assert raw.shape == (3, 400, 2) and np.all((raw > 0) & (raw < 1))
    assert np.array_equal(est.sample_raw(x, 400, seed=1), raw)  # reproducible
    u = np.array([[0.5, 0.5], [1.2, 0.5], [0.5, -0.1]])
    lq = est.log_q(u, x[:1])
    assert np.isfinite(lq[0]) and np.all(np.isneginf(lq[1:]))
    wider = PosteriorEstimator(
        est.settings, est.members, est.calibration,
        calibration.SpreadCorrection(("X13", "X14"), (1.5, 1.0), 40),
    )  # fmt: skip
    z, zw = posterior.to_logit(raw), posterior.to_logit(wider.correct(raw))
    iqr = np.subtract(*np.quantile(z, [0.95, 0.05], axis=1))
    iqr_w = np.subtract(*np.quantile(zw, [0.95, 0.05], axis=1))
    assert np.allclose(iqr_w[:, 0], 1.5 * iqr[:, 0], rtol=1e-6)
    assert np.allclose(iqr_w[:, 1], iqr[:, 1]) and np.all((zw > -50) & (zw < 50))


def test_an_excessive_correction_flags_the_estimator_and_its_estimates(trained, tmp_path):
    est, _ = trained
    wide = PosteriorEstimator(
        est.settings, est.members, est.calibration,
        calibration.SpreadCorrection(("X13", "X14"), (1.0, 2.6), 40),
    )  # fmt: skip
    assert not wide.calibrated
    synthesise_field(ParameterSet.nominal(), [CONDITION], tmp_path / "f", duration_s=3.0)
    result = posterior.estimate(wide, read_field(tmp_path / "f"))
    assert not result.calibrated
    assert any("widened by more than 2 times" in w and "X14 (2.6)" in w for w in result.warnings)
    saved = read_json(result.save(tmp_path / "post.json"))
    assert saved["calibrated"] is False and saved["correction"]["excessive"] == ["X14"]
    flags = {r["parameter"]: r["calibrated"] for r in saved["estimates"]}
    assert flags["X14"] is False


def test_resume_reads_the_cache_and_refuses_other_settings(trained, monkeypatch):
    est, run = trained

    def no_simulation(*a, **k):
        raise AssertionError("simulated again")

    monkeypatch.setattr(posterior_data, "simulate_long_cases", no_simulation)
    again = posterior.load(run)
    assert again.correction == est.correction  # stored and reloaded
    assert again.products == est.products
    u = np.array([[0.3, 0.6], [0.5, 0.5]])
    x = np.atleast_2d(np.load(next((run / "posterior" / "simulations").glob("check_*")))["x"][0])
    assert np.allclose(again.log_q(u, x), est.log_q(u, x))
    assert np.array_equal(again.sample(x[0], 200, seed=4), est.sample(x[0], 200, seed=4))
    (run / "posterior" / "calibration.json").unlink()  # recomputed from cached simulations
    assert [c.coverage for c in posterior.train(est.settings, run).calibration] == [
        c.coverage for c in est.calibration
    ]
    with pytest.raises(RailsuspInputError, match="other settings"):
        posterior.train(_settings(seed=1), run)


def test_training_prints_nothing_of_its_own(trained, tmp_path, capfd):
    """sbi's convergence line ("\\r Neural network successfully converged ...", no newline)
    used to reach the terminal and run into the next line; the log says it instead."""
    est, run = trained
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    (copy / "posterior" / "estimator.pt").unlink()  # trained again from the cached cases
    capfd.readouterr()
    again = posterior.train(est.settings, copy)
    out = capfd.readouterr().out
    assert "converged" not in out and out == ""
    assert len(again.members) == len(est.members)


def test_recording_of_another_condition_or_too_short_is_refused(trained, tmp_path):
    est, _ = trained
    synthesise_field(ParameterSet.nominal(), [CONDITION], tmp_path / "f", duration_s=2.0)
    with pytest.raises(RailsuspInputError, match="needs at least one section of 3 s"):
        posterior.estimate(est, read_field(tmp_path / "f"))
    curve = get_condition("curve").with_changes(lead_in_m=30.0)
    synthesise_field(ParameterSet.nominal(), [curve], tmp_path / "g", duration_s=3.0)
    with pytest.raises(RailsuspInputError, match="no recording of condition 'straight'"):
        posterior.estimate(est, read_field(tmp_path / "g"))


# ---------------------------------------------------------------- command line
def test_cli_estimate_prints_the_table(trained, tmp_path):
    _, run = trained
    synthesise_field(ParameterSet.nominal(), [CONDITION], tmp_path / "f", duration_s=3.0)
    out = tmp_path / "post.json"
    args = ["posterior", "estimate", "--measured", str(tmp_path / "f"), "--estimator", str(run)]
    result = runner.invoke(app, [*args, "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "X14" in result.output and "lo90" in result.output and out.exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["train", "--parameters", "X13,X3"], "subset of X11"),
        (["train", "--section", "0.2"], "--section 0.2: accepted 1 to 600"),
        (["train", "--noise", "0.9"], "--noise 0.9: accepted 0 to 0.5"),
        (["train", "--simulations", "5"], "--simulations 5: accepted 20 to"),
        (["train", "--calibration", "5"], "--calibration 5: accepted 0 (no correction) or 20"),
        (["train", "--ensemble", "0"], "--ensemble 0: accepted 1 to 20"),
        (["train", "--samples", "99"], "--samples 99: accepted 100 to 100000"),
        (["train", "--product-sections", "1,4"], "--product-sections 1,4: accepted distinct"),
        (["train", "--product-sections", "two"], "--product-sections two: accepted whole"),
        (
            ["train", "--product-sections", "2,4", "--product-cases", "50,40,30"],
            "--product-cases 50,40,30: accepted one count from 20 to 100000 per entry",
        ),
        (["train", "--product-sections", "2", "--product-cases", "5"], "--product-cases 5: acc"),
        (["train", "--product-cases", "many"], "--product-cases many: accepted whole numbers"),
        (["train", "--conditions", "nowhere"], "nowhere"),
        (["train", "--statistics", "spectra"], "--statistics spectra: accepted 'all' (en14363"),
        (["train", "--projection-rank", "0"], "--projection-rank 0: accepted 1 to 1000"),
        (["train", "--statistics", "wheelset", "--sum-y"], "--sum-y true conflicts with the st"),
        (["train", "--lead-in", "-5"], "--lead-in -5"),
        (["train", "--conditions", "curve", "--lead-in", "30"], "accepted at least 90.03 m"),
        (
            ["train", "--section", "1", "--statistics", "coherence"],
            "--section 1: the statistics family 'coherence' correlates over lags up to 1 s, "
            "which needs sections of at least 1.5 s",
        ),
        (["estimate", "--measured", "MISSING", "--estimator", "RUN"], "MISSING"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2(args, needle, tmp_path):
    if args[0] == "train":
        args = [*args, "--out", str(tmp_path / "run")]
    result = runner.invoke(app, ["posterior", *args])
    assert result.exit_code == 2, result.output
    assert needle in result.output and len(result.output.strip().splitlines()) == 1


def test_cli_estimate_without_a_trained_estimator(tmp_path):
    synthesise_field(ParameterSet.nominal(), [CONDITION], tmp_path / "f", duration_s=3.0)
    args = ["--measured", str(tmp_path / "f"), "--estimator", str(tmp_path)]
    result = runner.invoke(app, ["posterior", "estimate", *args])
    assert result.exit_code == 2 and "train first" in result.output


def test_cli_train_writes_the_estimator_and_its_check(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may land in the working directory
    run = tmp_path / "run"
    args = ["posterior", "train", "--out", str(run), "--conditions", "straight"]
    args += ["--parameters", "X14", "--section", "2", "--simulations", "40", "--check", "10"]
    args += ["--calibration", "20"]
    result = runner.invoke(app, [*args, "--lead-in", "20"])
    assert result.exit_code == 0, result.output
    assert "coverage_after" in result.output and "widening" in result.output
    for name in ("settings.json", "estimator.pt", "calibration.json"):
        assert (run / "posterior" / name).exists()
    assert len(list((run / "posterior" / "simulations").glob("*.npz"))) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_cli_product_cases_one_count_or_one_per_number_of_sections():
    from railsusp.cli.posterior_options import parse_product_cases
    from railsusp.estimate.posterior_settings import PosteriorSettings

    assert parse_product_cases("80") == {"n_product": 80}
    per = parse_product_cases("100, 40")
    assert per == {"product_cases": (100, 40)}
    s = PosteriorSettings((CONDITION,), product_sections=(8, 2), **parse_product_cases("40,100"))
    assert s.product_sections == (2, 8) and s.product_cases == (100, 40)


@pytest.mark.parametrize("content", ["crafted", "dict", "two flows", "other flows"])
def test_an_estimator_file_that_reads_but_is_not_this_estimator_s_is_refused(
    trained, tmp_path, content
):
    """estimator.pt judged as the surrogates' checkpoints are (stop 56): a pickle that would
    run code ended in torch's UnpicklingError traceback, a dict or another number of flows
    in a TypeError or a silently short ensemble, other layers in load_state_dict's
    RuntimeError; each is now one line naming the file, and nothing is trained over it."""

    import torch

    est, run = trained
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    weights = copy / "posterior" / "estimator.pt"
    states = torch.load(weights, weights_only=True)
    marker = tmp_path / "pwned"

    class Evil:
        def __reduce__(self):
            return (exec, (f"open({str(marker)!r}, 'w').write('ran')",))

    saved = {
        "crafted": [{"w": Evil()}],
        "dict": states[0],
        "two flows": states * (est.settings.ensemble + 1),
        "other flows": [{"layer.weight": torch.ones(2)}] * est.settings.ensemble,
    }[content]
    torch.save(saved, weights)
    before = weights.read_bytes()
    with pytest.raises(RailsuspInputError, match=r"posterior estimator .*estimator\.pt refused"):
        posterior.train(est.settings, copy)
    assert weights.read_bytes() == before and not marker.exists()


def test_loading_an_estimator_cut_short_is_refused_not_trained_again(trained, tmp_path):
    """posterior.load reads a finished estimator and trains nothing (its docstring); an
    estimator.pt cut short was trained again in silence inside it (the review of stop 56)."""

    _, run = trained
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    weights = copy / "posterior" / "estimator.pt"
    weights.write_bytes(weights.read_bytes()[:300])
    with pytest.raises(RailsuspInputError, match=r"estimator\.pt is cut short or damaged: train"):
        posterior.load(copy)
    assert len(weights.read_bytes()) == 300
    weights.write_bytes((run / "posterior" / "estimator.pt").read_bytes())
    chunk = sorted((copy / "posterior" / "simulations").glob("train_*"))[0]
    chunk.write_bytes(chunk.read_bytes()[:300])  # simulated again inside load before
    with pytest.raises(RailsuspInputError, match=f"{chunk.name} is not cached"):
        posterior.load(copy)
    assert len(chunk.read_bytes()) == 300


def test_a_cached_chunk_or_estimator_cut_short_is_made_again(trained, tmp_path, monkeypatch):
    """The kill/resume pass (stop 54): a truncated simulation chunk or estimator.pt stopped
    `posterior train` with numpy's / torch's traceback; each is now made again."""

    est, run = trained
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    chunk = sorted((copy / "posterior" / "simulations").glob("train_*"))[0]
    chunk.write_bytes(chunk.read_bytes()[:300])
    weights = copy / "posterior" / "estimator.pt"
    weights.write_bytes(weights.read_bytes()[:300])
    (copy / "posterior" / "calibration.json").unlink()
    real = posterior_data.simulate_long_cases
    simulated = []

    def counted(settings, u, *a, **k):
        simulated.append(len(u))
        return real(settings, u, *a, **k)

    monkeypatch.setattr(posterior_data, "simulate_long_cases", counted)
    again = posterior.train(est.settings, copy)
    assert simulated == [int(chunk.name.split("_")[-1].split(".")[0])]  # that chunk alone
    assert np.load(chunk)["x"].shape[0] == simulated[0]
    assert [c.coverage for c in again.calibration] == [c.coverage for c in est.calibration]
