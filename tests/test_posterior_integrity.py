"""Findings of the second posterior audit, each against the behaviour it fixed: a recording
whose own condition puts it in a curve's entry spiral, or whose instrument bandwidth is
narrower than the training's, is refused; statistics outside the training cases' range
flag the result not calibrated; recordings of untrained conditions are named; ``estimate``
writes nothing into the estimator's folder; a calibration record edited, cut short or of
another content is refused by ``load`` and made again by ``train``; the result JSON holds
no bare NaN. The flows learn from a stand-in statistic written by a patched
``cached_cases`` (as tests/test_posterior_audit.py), so no wagon is simulated here."""

from __future__ import annotations

import json
import logging
import shutil
import stat
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import (
    posterior,
    posterior_check,
    posterior_data,
    posterior_fusion,
    posterior_recordings,
)
from railsusp.estimate.calibration import ParameterCalibration
from railsusp.estimate.posterior_result import PosteriorResult
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.posterior_support import OUTSIDE_MARGIN_SD, TrainingSupport
from railsusp.measured.recording import Recording
from railsusp.store import read_json

STRAIGHT = get_condition("straight").with_changes(lead_in_m=30.0)
CURVE = get_condition("curve")  # lead-in 100 m: the record starts in the steady arc


def _recording(cond, seconds: float, wheel: str = "w1L", meta=None) -> Recording:
    """``seconds`` of noise forces (Y about 10 kN, Q about 100 kN) of one wheel."""
    c = cond.with_duration(seconds)
    rng = np.random.default_rng(0)
    t = np.arange(c.n_steps) * c.sample_interval
    return Recording(
        t,
        {wheel: 10 + 3 * rng.standard_normal(t.size)},
        {wheel: 100 + 8 * rng.standard_normal(t.size)},
        c,
        dict(meta or {}),
    )


# ---------------------------------------------------------------- H1. the steady arc
def test_a_recording_from_the_entry_spiral_is_refused_naming_lead_in_m():
    """A curve recording whose condition starts 30 m in (the entry spiral runs 20-80 m) was
    matched to the trained curve (lead-in 100 m) with its lead-in ignored and reported
    calibrated: its Y_p50 was 6 kN where every training case's was about 39. Now its own
    condition is held to the training conditions' steady-arc rule."""
    s = PosteriorSettings((CURVE,), section_s=3.0)
    posterior_recordings.recording_summaries(s, [_recording(CURVE, 3.0, "w1R")])  # read
    late = CURVE.with_changes(lead_in_m=150.0)  # later in the same arc: read too
    posterior_recordings.recording_summaries(s, [_recording(late, 3.0, "w1R")])
    with pytest.raises(
        RailsuspInputError,
        match=r"^recording 'curve': lead_in_m = 30 m \(condition 'curve'\): the recorded "
        r"sections would hold the entry to the curve .* accepted at least 9\d",
    ):
        posterior_recordings.recording_summaries(
            s, [_recording(CURVE.with_changes(lead_in_m=30.0), 3.0, "w1R")]
        )


def test_a_recording_whose_sections_outrun_the_arc_is_refused_naming_arc_length_m():
    short = CURVE.with_changes(arc_length_m=500.0)  # 30 s at 60 km/h from the arc's start
    s = PosteriorSettings((short,), section_s=10.0)
    x, _ = posterior_recordings.recording_summaries(s, [_recording(short, 20.0, "w1R")])
    assert len(x) == 2
    with pytest.raises(
        RailsuspInputError,
        match=r"^recording 'curve': arc_length_m = 500 m \(condition 'curve'\): the curve "
        r"ends within its 40 s of sections; accepted a recording whose sections lie in the arc",
    ):
        posterior_recordings.recording_summaries(s, [_recording(short, 40.0, "w1R")])


# ---------------------------------------------------------------- M1. the instrument
def test_a_recording_filtered_below_the_training_bandwidth_is_refused():
    """A recording low-passed at 4 Hz (its sidecar saying so) was read as the training's
    15 Hz instrument: its 8-15 Hz bands lay far below every training case's, and the
    estimate was reported calibrated."""
    s = PosteriorSettings((STRAIGHT,), section_s=3.0)
    for meta in ({}, {"filter_bandwidth_hz": None}, {"filter_bandwidth_hz": 15.0},
                 {"filter_bandwidth_hz": 40}):  # fmt: skip
        posterior_recordings.recording_summaries(s, [_recording(STRAIGHT, 3.0, meta=meta)])
    with pytest.raises(
        RailsuspInputError,
        match=r"^recording 'straight': filter_bandwidth_hz = 4 Hz is below the 15 Hz .* "
        r"accepted 15 Hz or more \(or none stated\)$",
    ):
        posterior_recordings.recording_summaries(
            s, [_recording(STRAIGHT, 3.0, meta={"filter_bandwidth_hz": 4})]
        )


def test_the_training_support_flags_the_sections_mean_beyond_its_range_by_the_margin():
    x = np.array([[0.0, 10.0], [1.0, 12.0], [2.0, 14.0]])
    sup = TrainingSupport.of(["a", "b"], x)
    sd = x.std(axis=0)
    assert sup.n == 3 and sup.outside([[1.0, 11.0]]) == []
    inside = [2.0 + 0.99 * OUTSIDE_MARGIN_SD * sd[0], 10.0 - 0.99 * OUTSIDE_MARGIN_SD * sd[1]]
    assert sup.outside([inside]) == []  # beyond the range, within the margin
    assert sup.outside([[1.0, 14.0 + 1.01 * OUTSIDE_MARGIN_SD * sd[1]]]) == ["b"]
    # the sections' mean is compared: one section of many a little past the margin is not
    # out (each section compared flagged a long recording's in-distribution sections)
    far = 14.0 + 1.5 * OUTSIDE_MARGIN_SD * sd[1]
    assert sup.outside([[1.0, 12.0], [1.0, 12.0], [1.0, far]]) == []
    assert sup.outside([[1.0, far], [1.0, far]]) == ["b"]
    both = TrainingSupport.joined([sup, sup])
    assert both.names == ("a", "b", "a", "b") and both.outside([[9.0, 11, 1, 11]]) == ["a"]
    assert TrainingSupport.joined([sup, None]) is None


def test_too_few_training_cases_compare_nothing_and_say_so():
    """With 20 training cases their extremes flagged 30 % of held-out simulations of one
    section as outside (the review of stop 65): below MIN_SUPPORT_CASES nothing is flagged."""
    from railsusp.estimate.posterior_support import MIN_SUPPORT_CASES, support_notes

    rng = np.random.default_rng(0)
    few = TrainingSupport.of(["a"], rng.standard_normal((MIN_SUPPORT_CASES - 1, 1)))
    outside, said = support_notes(few, np.array([[50.0]]))
    assert (
        outside == []
        and "not compared" in said[0]
        and f"{MIN_SUPPORT_CASES - 1} training" in said[0]
    )
    enough = TrainingSupport.of(["a"], rng.standard_normal((MIN_SUPPORT_CASES, 1)))
    outside, said = support_notes(enough, np.array([[50.0]]))
    assert outside == ["a"] and "NOT calibrated" in said[0]


# ---------------------------------------------------------------- a small trained estimator
def _cases(settings, folder, kind, n, sections=1, draws=None, simulate=True):
    """17 statistics: the first logit(u_X13) + noise, the others noise (sd 0.3)."""
    u = posterior_data.prior_draws(settings, kind, n)
    rng = np.random.default_rng(posterior_data.SEED_BASE[kind])
    x = 0.3 * rng.standard_normal((n, len(settings.summary_names)))
    x[:, 0] += posterior_fusion.to_logit(u[:, 2])
    return u, x


def _settings() -> PosteriorSettings:
    return PosteriorSettings(
        (STRAIGHT,), parameters=("X13",), section_s=3.0, n_train=100, n_check=30,
        n_calibration=30, samples=100, hidden_features=5, num_transforms=1,
    )  # fmt: skip


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    run = tmp_path_factory.mktemp("integrity") / "run"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(posterior, "cached_cases", _cases)
        mp.setattr(posterior_check, "cached_cases", _cases)
        est = posterior.train(_settings(), run)
    return est, run


@pytest.fixture
def stand_in(monkeypatch):
    """The stand-in cases for load and train; the recordings' statistics are set by
    ``stand_in["x"]`` (a recording of the patched summaries is that, one section)."""
    monkeypatch.setattr(posterior, "cached_cases", _cases)
    monkeypatch.setattr(posterior_check, "cached_cases", _cases)
    state = {"x": np.zeros((1, 17))}

    def summaries(settings, recordings):
        return state["x"], {"straight": {"sections": len(state["x"]), "seconds_left_out": 0.0}}

    monkeypatch.setattr(posterior, "recording_summaries", summaries)
    return state


def _named(name: str):
    return SimpleNamespace(condition=SimpleNamespace(name=name))


def _files(folder: Path) -> dict:
    """Every file under ``folder``: (inode, modification time, size)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        st = p.stat()
        out[str(p.relative_to(folder))] = (st.st_ino, st.st_mtime_ns, st.st_size)
    return out


# ---------------------------------------------------------------- M1. outside the training
def test_statistics_outside_the_training_range_flag_the_estimate_not_calibrated(
    trained, stand_in, tmp_path
):
    est, _ = trained
    result = posterior.estimate(est, [_named("straight")])
    assert result.outside_training == [] and result.calibrated == est.calibrated
    far = np.zeros((1, 17))
    far[0, 4] = 10.0  # 33 standard deviations of the training cases out
    stand_in["x"] = far
    result = posterior.estimate(est, [_named("straight")])
    assert result.outside_training == ["straight:Q_p50"] and not result.calibrated
    assert any(
        "straight:Q_p50 lie outside the range of the estimator's training cases" in w
        and "NOT calibrated" in w
        for w in result.warnings
    ), result.warnings
    saved = read_json(result.save(tmp_path / "post.json"))
    assert saved["calibrated"] is False and saved["outside_training"] == ["straight:Q_p50"]
    assert [r["calibrated"] for r in saved["estimates"]] == [False]


# ---------------------------------------------------------------- L2. unused recordings
def test_recordings_of_untrained_conditions_are_named_not_dropped(trained, stand_in):
    """A field folder of the straight and uphill, on an estimator of the straight: the
    uphill recording was left out unsaid."""
    est, _ = trained
    result = posterior.estimate(est, [_named("straight"), _named("uphill")])
    assert any(
        "not trained on are not used: uphill (trained on straight)" in w for w in result.warnings
    ), result.warnings
    alone = posterior.estimate(est, [_named("straight")])
    assert not any("not used" in w for w in alone.warnings)


# ---------------------------------------------------------------- M2. estimate only reads
def test_estimate_writes_nothing_into_the_estimator_folder(trained, stand_in, tmp_path):
    """load() rewrote settings.json on every estimate, which failed on a read-only
    estimator folder. Here the folder is made read-only (a root user writes through
    that: every file's inode, time and size are compared as well)."""
    _, run = trained
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    before = _files(copy)
    modes = {p: p.stat().st_mode for p in [copy, *copy.rglob("*")]}
    for p in modes:
        p.chmod(modes[p] & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    try:
        est = posterior.load(copy)
        posterior.estimate(est, [_named("straight")])
    finally:
        for p, mode in modes.items():
            p.chmod(mode)
    assert _files(copy) == before
    posterior.train(est.settings, copy)  # a re-run of the same training rewrites nothing
    assert _files(copy) == before


# ---------------------------------------------------------------- M3 and L3. the record
def test_an_edited_calibration_record_is_refused_and_checked_again(
    trained, stand_in, tmp_path, caplog
):
    """calibration.json was trusted as it stood: every correction factor set to 1 and the
    verdict to passed gave narrower intervals said to be calibrated. Now the record is
    sealed: load refuses it in one line, a re-run of the training checks again."""
    _, run = trained
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    path = copy / "posterior" / "calibration.json"
    good = read_json(path)
    edited = json.loads(json.dumps(good))
    edited["correction"]["factors"] = {"X13": 0.5}  # narrower intervals, said calibrated
    edited["passed"] = True
    for c in edited["parameters"]:
        c["passed"], c["coverage"] = True, 0.9
    assert edited != good
    path.write_text(json.dumps(edited))
    with pytest.raises(RailsuspInputError) as info:
        posterior.load(copy)
    msg = str(info.value)
    assert msg.startswith(f"{path} was changed after its check was written") and "\n" not in msg
    assert "run railsusp posterior train again on this folder" in msg
    with caplog.at_level(logging.WARNING):
        posterior.train(_settings(), copy)
    assert "changed after its check was written" in caplog.text
    assert read_json(path) == good  # made again, as it was
    posterior.load(copy)


@pytest.mark.parametrize("damage", ["cut", "other"])
def test_a_cut_short_calibration_record_is_made_again_by_train(
    trained, stand_in, tmp_path, caplog, damage
):
    """A calibration.json cut to 300 bytes stopped train ("is corrupt: not valid JSON"),
    though the docs say a record of another content is made again with a warning."""
    _, run = trained
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    path = copy / "posterior" / "calibration.json"
    good = path.read_bytes()
    path.write_bytes(good[:300] if damage == "cut" else b'{"other": "tool"}')
    with pytest.raises(RailsuspInputError, match=r"train again on this folder") as info:
        posterior.load(copy)  # which only reads: refused, never checked and written there
    assert "\n" not in str(info.value) and path.read_bytes() != good
    with caplog.at_level(logging.WARNING):
        posterior.train(_settings(), copy)
    assert "the check runs again" in caplog.text
    assert path.read_bytes() == good


def test_a_record_written_before_seals_is_read_and_sealed_by_train(
    trained, stand_in, tmp_path, caplog
):
    """An estimator folder trained before records were sealed stays readable (with a
    warning); a re-run of its training seals the record as it stands."""
    _, run = trained
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    path = copy / "posterior" / "calibration.json"
    good = read_json(path)
    old = {k: v for k, v in good.items() if k != posterior_check.SEAL}
    path.write_text(json.dumps(old))
    with caplog.at_level(logging.WARNING):
        est = posterior.load(copy)
    assert "written before check records were sealed" in caplog.text
    assert [c.coverage for c in est.calibration] == [c["coverage"] for c in good["parameters"]]
    posterior.train(_settings(), copy)
    assert read_json(path) == good


# ---------------------------------------------------------------- L1. strict JSON
def test_the_result_json_has_null_where_a_number_is_undefined(tmp_path):
    """A record longer than any checked number of sections has no held-out coverage: it
    was written as a bare NaN, which strict JSON parsers (JavaScript's) refuse."""
    draws = np.random.default_rng(0).uniform(8e6, 16e6, (200, 1))
    check = ParameterCalibration("X13", 0, float("nan"), float("nan"), float("nan"), False)
    result = PosteriorResult(("X13",), draws, [check], {}, 3, [], None, None)
    path = result.save(tmp_path / "post.json")

    def refuse(name):
        raise ValueError(f"bare {name} in the result")

    doc = json.loads(path.read_text(), parse_constant=refuse)
    assert doc["estimates"][0]["coverage_heldout"] is None
    assert doc["calibrated"] is False and doc["checked_as_sections"] is None
