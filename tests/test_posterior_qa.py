"""The QA pass of the simulation-based posterior (railsusp posterior train/estimate/join):

1. sections shorter than about 2.8 s at 50 Hz put the band RMS in the wrong band or made it
   constant: the spectrum's segment now follows the band edges, the statistics of longer
   sections (the 20 s default) are as before, and a folder of such short sections trained
   before is refused, not mixed;
2. the calibration set's coverage after the correction is counted in the coordinates the
   factor was fitted in (it read one case short);
3. the Python API refuses a path where recordings go, a seed out of range and a run folder
   that is no path in one line naming the argument;
4. a damaged cached chunk during an estimate is refused naming the command that makes it
   again (not "simulated again"), and the archive is closed;
5. a recording of another wagon names posterior train --wagon, not a --wagon estimate lacks;
6. a joint estimator names all its conditions where a recording is missing;
7. train's closing warning names the failed fused checks whatever failed in one section;
8. --parameters, --lead-in and --wagon are named in their refusals.
"""

from __future__ import annotations

import gc
import io
import logging
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.signal import welch
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import (
    posterior,
    posterior_check,
    posterior_data,
    posterior_joint,
    posterior_synthetic_run,
)
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.summaries import BAND_FLOOR_KN, band_rms, section_summary
from railsusp.integrity import read_npz
from railsusp.measured import Recording, synthesise_field
from railsusp.params import ParameterSet
from railsusp.store import content_hash, read_json, write_json

runner = CliRunner()
FS = 50.0
STRAIGHT = get_condition("straight").with_changes(lead_in_m=30.0)
TINY = dict(parameters=("X14",), n_train=20, n_check=10, n_calibration=0, samples=100)


def _one_line(output: str) -> str:
    """The command's output as one line (rich wraps long lines at the runner's width)."""
    return " ".join(output.split())


def _recording(cond, seconds: float, wheel: str = "w1L") -> Recording:
    """``seconds`` of noise forces (Y about 10 kN, Q about 100 kN) of one wheel."""
    c = cond.with_duration(seconds)
    rng = np.random.default_rng(0)
    t = np.arange(c.n_steps) * c.sample_interval
    Y = {wheel: 10 + 3 * rng.standard_normal(t.size)}
    return Recording(t, Y, {wheel: 100 + 8 * rng.standard_normal(t.size)}, c, {})


# ---------------------------------------------------------------- 1. band resolution
@pytest.mark.parametrize("seconds", [1.0, 2.0, 2.7])
def test_a_short_sections_tone_lies_in_its_own_band(seconds):
    """At 2.7 s and 50 Hz the segment of a quarter of the section (33 samples) had a
    frequency step of 1.52 Hz: 0.3-1.5 Hz held no line (0), and a 1 Hz tone was read in
    1.5-4 Hz; at 1 and 2 s the 32-sample floor did the same."""
    t = np.arange(round(seconds * FS)) / FS
    low = band_rms(np.sin(2 * np.pi * 1.0 * t), FS)
    assert low[0] > 0.4 and low[0] > 2 * low[1], low
    mid = band_rms(np.sin(2 * np.pi * 2.5 * t), FS)
    assert mid[1] > 0.4 and mid[1] > 2 * mid[0], mid


def test_the_statistics_of_the_default_sections_are_as_before():
    """Where a quarter of the section resolves the bands (3.36 s or more at 50 Hz, the 20 s
    default among them) the segment is that quarter, and the summary is the one computed
    with it."""
    from railsusp.estimate.summaries import band_segment

    for n in range(168, 30_001):
        assert band_segment(n, FS) == n // 4
    assert band_segment(150, FS) == 42 and band_segment(100, FS) == 42  # 3 s, 2 s: longer
    rng = np.random.default_rng(3)
    n = 1000  # 20 s
    Y, Q = 10 + 3 * rng.standard_normal(n), 100 + 8 * rng.standard_normal(n)
    s = section_summary(Y, Q, FS, 16.7)

    def old_bands(x):  # band_rms as it was: Welch segments of a quarter of the record
        f, pxx = welch(x - x.mean(), fs=FS, nperseg=n // 4, detrend="constant")
        df = f[1] - f[0]
        out = [np.sqrt(np.sum(pxx[(f >= lo) & (f < hi)]) * df) for lo, hi in
               ((0.3, 1.5), (1.5, 4.0), (4.0, 8.0), (8.0, 15.0))]  # fmt: skip
        return np.log10(np.maximum(out, BAND_FLOOR_KN))

    assert np.array_equal(s[-8:], np.concatenate([old_bands(Y), old_bands(Q)]))


def test_the_training_statistics_of_2_s_sections_are_not_constant(tmp_path):
    """The QA's `--section 2` training: sbi warned "Data has constant values in
    dimension(s) [9, 13]" (Y and Q in 0.3-1.5 Hz at the floor, log10 = -4, in every case)."""
    s = PosteriorSettings((STRAIGHT,), section_s=2.0, **TINY)
    _, x = posterior_data.cached_cases(s, tmp_path, "train", 20)
    x = x[np.all(np.isfinite(x), axis=1)]
    for name in ("straight:Y_band_0.3-1.5Hz", "straight:Q_band_0.3-1.5Hz"):
        column = x[:, s.summary_names.index(name)]
        assert np.all(column > np.log10(BAND_FLOOR_KN)) and np.std(column) > 0, name


def trained_before(s, folder, monkeypatch, said: str) -> dict:
    """``s``'s settings as a folder trained before its band-resolution mark stored them
    (written into ``folder``): ``posterior.train`` there is refused, saying ``said``, and
    nothing is read as this training's. Returns those stored settings."""
    from railsusp.estimate.posterior_stamp import estimator_stamp

    before = {k: v for k, v in s.to_dict().items() if k != "band_resolution"}
    write_json(
        folder / "posterior" / "settings.json",
        {"hash": content_hash(before), **estimator_stamp(), "settings": before},
    )

    def simulated(*args, **kw):
        raise AssertionError("the folder of before was read as this training's")

    monkeypatch.setattr(posterior, "cached_cases", simulated)
    with pytest.raises(RailsuspInputError, match=f"trained with other settings .*{said}"):
        posterior.train(s, folder)
    return before


def test_a_short_section_folder_trained_before_is_refused_not_mixed(tmp_path, monkeypatch):
    """Its cached statistics are of the old segments: the settings' hash now differs, so
    train refuses the folder instead of mixing old and new statistics, and the settings it
    stored are refused where a load reads them (the synthetic likelihood's load read such
    a folder's emulator with a recording's new statistics and reported it calibrated)."""

    s = PosteriorSettings((STRAIGHT,), section_s=2.0, **TINY)
    assert s.to_dict()["band_resolution"]
    assert "band_resolution" not in PosteriorSettings((STRAIGHT,), section_s=5.0).to_dict()
    assert PosteriorSettings.from_dict(s.to_dict()) == s
    before = trained_before(s, tmp_path, monkeypatch, "band statist")
    # the loads (the flows' and the synthetic likelihood's, which read no settings hash)
    with pytest.raises(RailsuspInputError, match=r"^an estimator of 2 s sections \(section_s"):
        PosteriorSettings.from_dict(before)


def test_a_section_or_rate_that_cannot_resolve_the_bands_is_refused(tmp_path):
    slow = STRAIGHT.with_changes(n_steps=380)  # 19 Hz: 8-15 Hz is capped to 8-8.55 Hz
    with pytest.raises(RailsuspInputError, match=r"^section_s = 1: at the 19 Hz .* at least "
                       r"1\.87 s; accepted 1\.87 to 600$"):  # fmt: skip
        PosteriorSettings((slow,), section_s=1.0, **TINY)
    PosteriorSettings((slow,), section_s=1.87, **TINY)  # the shortest it names is accepted
    with pytest.raises(RailsuspInputError, match=r"sampled at 10 Hz, the band RMS from 8 Hz"):
        PosteriorSettings((STRAIGHT.with_changes(n_steps=200),), section_s=5.0, **TINY)
    (tmp_path / "c.toml").write_text(
        '[[condition]]\nname = "straight"\nbase = "straight"\nn_steps = 380\n'
    )
    args = ["posterior", "train", "--out", str(tmp_path / "run"), "--section", "1"]
    result = runner.invoke(app, [*args, "--conditions", str(tmp_path / "c.toml")])
    assert result.exit_code == 2, result.output
    assert _one_line(result.output).startswith("error: --section 1: at the 19 Hz")


# ---------------------------------------------------------------- 2. calibration set coverage
def test_the_calibration_sets_coverage_after_holds_what_the_factor_holds(tmp_path, monkeypatch):
    """/tmp/qa/posterior/conf.py: the factor is the ceil(21 x 0.9) = 19th smallest score of
    20, so the widened intervals hold at least 19 truths; counted on the unit box
    calibration.json's ``calibration_set.after`` read 0.90 (18 of 20)."""
    rng = np.random.default_rng(1)
    n, draws = 20, 100
    u = 1 / (1 + np.exp(-(rng.normal(size=(n, 1, 1)) + 0.5 * rng.normal(size=(n, draws, 1)))))
    truth = 1 / (1 + np.exp(-rng.normal(size=(n, 1))))
    monkeypatch.setattr(posterior_check, "raw_draws", lambda est, folder, kind, k: (u, truth, 0))
    settings = SimpleNamespace(parameters=("X13",), n_calibration=n, n_check=n,
                               product_sections=())  # fmt: skip
    correction, after, _ = posterior_check.calibrate(SimpleNamespace(settings=settings), tmp_path)
    assert correction.factors[0] > 1
    record = read_json(tmp_path / "calibration.json")
    assert record["calibration_set"]["after"][0]["coverage"] >= 19 / 20
    assert after[0].coverage >= 19 / 20  # the same cases here


def test_the_widened_coverage_holds_the_conformal_count_on_many_sets():
    from railsusp.estimate.calibration import SpreadCorrection
    from railsusp.estimate.posterior_fusion import to_logit

    for seed in range(200):
        rng = np.random.default_rng(seed)
        n, draws = int(rng.integers(20, 60)), int(rng.integers(100, 400))
        z = rng.normal(size=(n, 1, 2)) + 0.5 * rng.normal(size=(n, draws, 2))
        u, truth = 1 / (1 + np.exp(-z)), 1 / (1 + np.exp(-rng.normal(size=(n, 2))))
        c = SpreadCorrection.fit(to_logit(u), to_logit(truth), ["a", "b"])
        k = int(np.ceil((n + 1) * 0.9 - 1e-9))
        for raw, check in zip(
            c.raw_factors, posterior_check.check_widened(c, u, truth, ["a", "b"]), strict=True
        ):
            if raw >= 1:  # a floored factor holds more
                assert round(check.coverage * n) >= k, (seed, check)


# ---------------------------------------------------------------- 3. the Python API
@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda est: posterior.estimate(est, "f_s2"), r"recordings = 'f_s2': accepted a list "
         r"of Recording \(railsusp\.measured\.read_field"),
        (lambda est: posterior.estimate(est, ["f_s2/straight.csv"]),
         r"recordings\[0\] = 'f_s2/straight\.csv': accepted a list of Recording"),
        (lambda est: posterior.estimate(est, [], seed=-1), r"seed = -1: accepted 0 to 4294967295"),
        (lambda est: posterior.estimate(est, [], seed=1.5), r"seed = 1\.5: accepted an integer 0"),
        (lambda est: posterior.load(None), r"run = None: accepted the run directory"),
        (lambda est: posterior_joint.load(None), r"out = None: accepted the run directory"),
        (lambda est: posterior_joint.estimate(est, [], seed=-2), r"seed = -2: accepted 0 to"),
        (lambda est: posterior_synthetic_run.estimate(est, [], seed=-3),
         r"seed = -3: accepted 0 to"),
    ],
)  # fmt: skip
def test_bad_api_arguments_are_one_line_naming_the_argument(call, needle):
    """They failed with an AttributeError ('str' object has no attribute 'condition'),
    numpy's ValueError, a TypeError; docs/api.md promises one line naming the argument."""
    est = SimpleNamespace(settings=PosteriorSettings((STRAIGHT,), section_s=5.0, **TINY))
    with pytest.raises(RailsuspInputError, match=needle) as info:
        call(est)
    assert "\n" not in str(info.value)


# ---------------------------------------------------------------- 4. a damaged cached chunk
def test_a_damaged_chunk_in_an_estimate_names_the_training_and_closes_the_file(tmp_path, caplog):
    s = PosteriorSettings((STRAIGHT,), section_s=5.0, **TINY)
    buf = io.BytesIO()
    np.savez(buf, u=np.zeros((20, 10)), x=np.zeros((20, 17)))
    chunk = tmp_path / "train_0000_20.npz"
    chunk.write_bytes(buf.getvalue()[:300])  # cut short
    with warnings.catch_warnings(record=True) as seen, caplog.at_level(logging.WARNING):
        warnings.simplefilter("always")
        with pytest.raises(RailsuspInputError) as info:
            posterior_data.cached_cases(s, tmp_path, "train", 20, simulate=False)
        gc.collect()
    said = str(info.value)
    assert said.startswith(f"{chunk} is not cached whole (damaged: File is not a zip file)")
    assert "run railsusp posterior train on this folder again" in said
    assert "simulated again" not in caplog.text  # an estimate simulates nothing
    assert not [w for w in seen if issubclass(w.category, ResourceWarning)], seen


def test_read_npz_closes_a_damaged_archive(tmp_path):
    path = tmp_path / "a.npz"
    path.write_bytes(b"PK\x03\x04" + b"x" * 100)  # a zip's first bytes, nothing after
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with pytest.raises(RailsuspInputError, match="is damaged"):
            read_npz(path, "cached chunk", "simulated again")
        gc.collect()
    assert not [w for w in seen if issubclass(w.category, ResourceWarning)], seen


def test_a_missing_chunk_in_an_estimate_names_the_training(tmp_path):
    s = PosteriorSettings((STRAIGHT,), section_s=5.0, **TINY)
    with pytest.raises(RailsuspInputError, match=r"is not cached .*railsusp posterior train"):
        posterior_data.cached_cases(s, tmp_path, "train", 20, simulate=False)


# ---------------------------------------------------------------- 5. another wagon
def test_a_recording_of_another_wagon_names_posterior_train_wagon(tmp_path, monkeypatch):
    """posterior estimate has no --wagon; its refusal said "give its data (--wagon, or
    wagon = in a pipeline)"."""
    cond = get_condition("straight")
    synthesise_field(ParameterSet.nominal(), [cond], tmp_path / "f", duration_s=2.0,
                     wagon="tare")  # fmt: skip
    run = tmp_path / "run"
    run.mkdir()
    est = SimpleNamespace(settings=SimpleNamespace(wagon=None))  # the loaded C80's
    monkeypatch.setattr(posterior, "load", lambda folder: est)
    args = ["posterior", "estimate", "--measured", str(tmp_path / "f"), "--estimator", str(run)]
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    said = _one_line(result.output)
    assert "median wheel load" in said and "railsusp posterior train --wagon" in said, said
    assert "wagon = in a pipeline" not in said and "give its data" not in said


# ---------------------------------------------------------------- 6. a joint's conditions
def test_a_joint_estimator_names_all_its_conditions_for_a_missing_recording():
    parts = tuple(
        SimpleNamespace(settings=PosteriorSettings((c,), section_s=5.0, **TINY))
        for c in (STRAIGHT, get_condition("uphill"))
    )
    with pytest.raises(
        RailsuspInputError,
        match=r"^no recording of condition 'uphill'; the estimator was trained on "
        r"straight, uphill$",
    ):
        posterior_joint.recording_sections(
            SimpleNamespace(parts=parts), [_recording(STRAIGHT, 10.0)]
        )


# ---------------------------------------------------------------- 7. train's closing line
@pytest.mark.parametrize("excessive", [["X14"], []])
def test_the_closing_warning_names_a_failed_fused_check_whatever_failed_in_one(
    excessive, tmp_path, monkeypatch
):
    """An estimator whose one-section check widened excessively (or failed) and whose
    fused check of 4 sections failed: the warning named the widening alone."""
    from railsusp.cli import posterior as cli_posterior

    correction = SimpleNamespace(excessive=excessive, max_inflation=2.0)
    est = SimpleNamespace(
        calibrated=False,
        correction=correction,
        products=[SimpleNamespace(sections=4, passed=False)],
    )
    monkeypatch.setattr(posterior, "train", lambda settings, out: est)
    monkeypatch.setattr(cli_posterior, "print_calibration_table", lambda est: None)
    args = ["posterior", "train", "--out", str(tmp_path / "run"), "--conditions", "straight"]
    args += ["--section", "5", "--simulations", "20", "--check", "10", "--calibration", "20"]
    result = runner.invoke(app, [*args, "--product-sections", "4", "--product-cases", "20"])
    assert result.exit_code == 0, result.output
    said = _one_line(result.output)
    first = "widened more than 2 times for X14" if excessive else "FAILED its coverage check"
    assert first in said and "FAILED those of 4 sections" in said, said


# ---------------------------------------------------------------- 8. the options named
@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--parameters", "X99"],
         "error: --parameters X99: accepted a subset of X11,X12,X13,X14,X15,X16,X17,X18,X19,"),
        (["--conditions", "curve", "--lead-in", "30"],
         "error: --lead-in 30 m (condition 'curve'): the recorded sections"),
        (["--wagon", "bogus"], "error: --wagon bogus: wagon file bogus does not exist"),
    ],
)  # fmt: skip
def test_train_refusals_name_the_option_typed(args, needle, tmp_path):
    result = runner.invoke(app, ["posterior", "train", "--out", str(tmp_path / "run"), *args])
    assert result.exit_code == 2, result.output
    assert _one_line(result.output).startswith(needle), result.output
    assert not (tmp_path / "run").exists()


def test_the_settings_name_an_unknown_parameter_as_the_field():
    with pytest.raises(RailsuspInputError, match=r"^parameters X99: accepted a subset of X11"):
        PosteriorSettings((STRAIGHT,), parameters=("X99",))
    with pytest.raises(RailsuspInputError, match=r"^wagon = bogus: wagon file bogus"):
        PosteriorSettings((STRAIGHT,), wagon="bogus")


# ---------------------------------------------------------------- 9. third-octave resolution
def _old_third_octave(x: np.ndarray) -> np.ndarray:
    """The third-octave family's log band RMS as it was: Welch segments of half the record."""
    from railsusp.estimate.statistic_families import THIRD_OCTAVE_HZ

    f, pxx = welch(x - x.mean(), fs=FS, nperseg=int(min(x.size, max(32, round(0.5 * x.size)))),
                   detrend="constant")  # fmt: skip
    df = f[1] - f[0]
    out = [np.sqrt(np.sum(pxx[sel]) * df) if (sel := (f >= lo) & (f < min(hi, 0.45 * FS))).any()
           else 0.0 for lo, hi in THIRD_OCTAVE_HZ]  # fmt: skip
    return np.log10(np.maximum(out, BAND_FLOOR_KN))


@pytest.mark.parametrize("seconds", [8.4, 12.0, 16.0, 20.5, 21.0])
def test_every_third_octave_band_of_a_short_section_holds_a_line(seconds):
    """Half of a 20.5 s section (512 samples at 50 Hz, 0.098 Hz lines) put no line in
    0.3-0.378 Hz: Y_3oct_0.3-0.378Hz read the floor (log10 = -4) in every case; at 12 s
    several of the lowest bands did."""
    from railsusp.estimate.statistic_families import family_statistics

    rng = np.random.default_rng(5)
    n = round(seconds * FS)
    Y, Q = 10 + 3 * rng.standard_normal(n), 100 + 8 * rng.standard_normal(n)
    out = family_statistics("third-octave", Y, Q, FS, 16.7)
    assert out.shape == (36,) and np.all(out > np.log10(BAND_FLOOR_KN) + 1), out


def test_the_third_octave_statistics_of_the_default_sections_are_as_before():
    """Where half the section puts a line in every third-octave band (16.78-20.02 s and from
    21.18 s on at 50 Hz, the 20 s default among them) the statistics are bit for bit the
    ones computed with that half (a guard: it holds on the code before the fix too)."""
    from railsusp.estimate.statistic_families import family_statistics

    rng = np.random.default_rng(6)
    for seconds in (16.8, 20.0, 21.2, 30.0, 60.0):
        n = round(seconds * FS)
        Y, Q = 10 + 3 * rng.standard_normal(n), 100 + 8 * rng.standard_normal(n)
        old = np.concatenate([_old_third_octave(Y), _old_third_octave(np.maximum(Q, 0.0))])
        assert np.array_equal(family_statistics("third-octave", Y, Q, FS, 16.7), old), seconds


def test_a_section_or_rate_too_coarse_for_the_third_octave_bands_is_refused(tmp_path):
    """5 s sections (a 250-sample segment at most: 0.2 Hz lines) cannot put a line in
    0.3-0.378 Hz, and at 30 Hz the bands above 13.5 Hz lie above 0.45 of the rate: both
    were accepted, their statistics a floor in every case."""
    third = dict(TINY, statistics=("third-octave",))
    with pytest.raises(RailsuspInputError, match=r"^section_s = 5: at the 50 Hz of condition "
                       r"'straight' the statistics family 'third-octave' .* at least 8\.4 s; "
                       r"accepted 8\.4 to 600$"):  # fmt: skip
        PosteriorSettings((STRAIGHT,), section_s=5.0, **third)
    PosteriorSettings((STRAIGHT,), section_s=8.4, **third)  # the shortest it names
    PosteriorSettings((STRAIGHT,), section_s=5.0, **TINY)  # the EN 14363 summary alone
    with pytest.raises(RailsuspInputError, match=r"sampled at 30 Hz, the statistics family "
                       r"'third-octave' has bands from 15\.2 Hz"):  # fmt: skip
        PosteriorSettings((STRAIGHT.with_changes(n_steps=600),), **third)
    args = ["posterior", "train", "--out", str(tmp_path / "run"), "--section", "5"]
    result = runner.invoke(app, [*args, "--statistics", "third-octave"])
    assert result.exit_code == 2, result.output
    said = _one_line(result.output)
    assert said.startswith("error: --section 5: at the 50 Hz") and "8.4 s" in said, said
    assert not (tmp_path / "run").exists()


def test_a_third_octave_folder_whose_statistics_changed_is_refused_not_mixed(tmp_path, monkeypatch):
    """12 s sections now read the third-octave bands with a longer segment than half of
    the section: their settings' hash changes (band_resolution), a folder trained before is
    refused by train and by a load; settings whose statistics did not change (the 20 s
    default, 12 s without the family) and the EN 14363 marking keep their dicts."""

    third = dict(TINY, statistics=("third-octave",))
    s = PosteriorSettings((STRAIGHT,), section_s=12.0, **third)
    assert "third-octave" in s.to_dict()["band_resolution"]
    assert PosteriorSettings.from_dict(s.to_dict()) == s
    for same in (dict(section_s=20.0, **third), dict(section_s=12.0, **TINY)):
        assert "band_resolution" not in PosteriorSettings((STRAIGHT,), **same).to_dict()
    en = PosteriorSettings((STRAIGHT,), section_s=2.0, **TINY).to_dict()["band_resolution"]
    assert en == "frequency step at most the narrowest band"  # folders trained since keep it
    before = trained_before(s, tmp_path, monkeypatch, "third-octave band statist")
    with pytest.raises(
        RailsuspInputError, match=r"^an estimator of 12 s sections \(section_s = 12\) .*"
        r"third-octave band RMS"
    ):  # fmt: skip
        PosteriorSettings.from_dict(before)
