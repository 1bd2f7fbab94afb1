"""The joint posterior of synthetic-likelihood estimators of different conditions
(railsusp.estimate.posterior_joint) and the ``condition_offset`` that gives an estimator
of further conditions its own tracks and noise (railsusp.estimate.posterior_data).

- seeds: offset 0 keeps every earlier estimator's tracks; another offset never meets them;
- the product: with one part it is that part's sampler, draw for draw; with two parts of a
  linear-Gaussian stand-in its log-likelihood is that of one estimator holding both parts'
  statistics with a block-diagonal covariance (the conditions independent), and its draws
  learn what each part alone cannot;
- in run directories: two estimators trained apart on the same draws, checked jointly on
  their held-out records, stored and read back the same; a part trained again makes the
  joint check stale; estimators that cannot be joined are refused in one line.
The stand-in statistics are written into the simulation caches as in
tests/estimate/test_posterior_synthetic_run.py: no wagon is simulated here."""

from __future__ import annotations

import io

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import posterior_data
from railsusp.estimate import posterior_joint as joint
from railsusp.estimate import posterior_synthetic_run as synthetic
from railsusp.estimate.posterior_data import (
    SEED_BASE,
    cached_cases,
    noise_rng,
    prior_draws,
    track_seeds,
)
from railsusp.estimate.posterior_emulator import StatisticsEmulator
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.posterior_synthetic import SyntheticLikelihood

STRAIGHT = get_condition("straight").with_changes(lead_in_m=30.0)
UPHILL = get_condition("uphill").with_changes(lead_in_m=30.0)


def _common() -> dict:
    return dict(section_s=5.0, n_train=300, n_check=30, samples=100, product_sections=(4,),
                n_product=30)  # fmt: skip


def _settings(cond=STRAIGHT, offset=0, **kw) -> PosteriorSettings:
    return PosteriorSettings((cond,), **{**_common(), "condition_offset": offset, **kw})


# -- seeds --------------------------------------------------------------------------------


def test_offset_zero_keeps_the_tracks_and_the_hash_of_every_estimator_before_it():
    two = PosteriorSettings((STRAIGHT, UPHILL))
    idx = np.arange(5)
    for kind in SEED_BASE:
        for c in (0, 1):
            assert np.array_equal(track_seeds(two, kind, idx, c), SEED_BASE[kind] + idx * 2 + c)
    assert "condition_offset" not in two.to_dict()
    assert PosteriorSettings.from_dict(two.to_dict()) == two
    moved = PosteriorSettings((UPHILL,), condition_offset=2)
    assert moved.to_dict()["condition_offset"] == 2
    assert PosteriorSettings.from_dict(moved.to_dict()) == moved


def test_an_offset_estimator_never_shares_a_track_with_the_first():
    first = PosteriorSettings((STRAIGHT, UPHILL))
    second = PosteriorSettings((UPHILL,), condition_offset=2)
    n = 32_000
    idx = np.arange(n)
    seen = np.concatenate([track_seeds(first, k, idx, c) for k in SEED_BASE for c in (0, 1)])
    mine = np.concatenate([track_seeds(second, k, idx, 0) for k in SEED_BASE])
    assert np.unique(mine).size == mine.size
    assert not np.intersect1d(seen, mine).size


def test_the_instrument_noise_of_an_offset_estimator_is_its_own():
    """The gain error and noise of case i in condition c are keyed by the condition's index
    in the joint design: at offset 0 the key of every estimator before the offset (its
    records keep their noise); an estimator at offset 1 does not repeat offset 0's."""
    zero, one = _settings(), _settings(UPHILL, offset=1)
    for kind in ("train", "long"):
        old = np.random.default_rng([zero.seed, SEED_BASE[kind], 7, 0]).random(5)
        assert np.array_equal(noise_rng(zero, kind, 7, 0).random(5), old)
        assert not np.array_equal(noise_rng(one, kind, 7, 0).random(5), old)
    two = PosteriorSettings((STRAIGHT, UPHILL))  # its second condition is offset 1's slot
    assert np.array_equal(noise_rng(two, "train", 7, 1).random(5),
                          noise_rng(one, "train", 7, 0).random(5))  # fmt: skip


def test_the_emulator_hash_at_offset_zero_leaves_the_offset_out():
    """At offset 0 the hash is that of the settings without the offset (7b2f92d's rule,
    before the offset existed); pinned to its value since stop 32 put the emulators'
    training into it (before: b2b9d5c673b120c0). A folder of before still loads (``load``
    reads its stored hash and checks); training it again fits its emulators anew."""
    from railsusp.estimate.posterior_synthetic_fit import emulator_key

    assert emulator_key(_settings()) == "48984690e8893b1c"
    assert emulator_key(_settings(offset=1)) != emulator_key(_settings())


def test_an_offset_out_of_range_is_refused_in_one_line():
    with pytest.raises(RailsuspInputError, match=r"^condition_offset = 10: accepted 0 to 9$"):
        PosteriorSettings((UPHILL,), condition_offset=10)


def test_an_offset_estimator_does_not_read_the_cache_of_offset_zero(tmp_path, monkeypatch):
    """The same conditions and draws at another offset are other tracks: a chunk cached
    at offset 0 must be simulated again, under its own name."""
    calls = []

    def fake(settings, u, first, kind, sections):
        calls.append(settings.condition_offset)
        return np.full((len(u), sections, len(settings.summary_names)), float(len(calls)))

    monkeypatch.setattr(posterior_data, "simulate_long_cases", fake)
    zero, two = _settings(), _settings(offset=2)
    _, a = cached_cases(zero, tmp_path, "check", 30)
    _, b = cached_cases(two, tmp_path, "check", 30)
    assert calls == [0, 2] and a[0, 0] == 1.0 and b[0, 0] == 2.0
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "check@2_0000_30.npz",
        "check_0000_30.npz",
    ]
    _, again = cached_cases(two, tmp_path, "check", 30)  # read back, not simulated
    assert calls == [0, 2] and np.array_equal(again, b)


def test_a_swallowed_ctrl_c_stops_the_simulations_after_the_chunk_they_cached(
    tmp_path, monkeypatch
):
    """A Ctrl-C that Python swallowed (recorded by the command line's handler,
    railsusp.interrupts) let the posterior's simulations run to their end: they stop after
    the chunk being cached, which the next call reads back."""
    from railsusp.interrupts import catch_interrupts, record_interrupt

    calls = []

    def fake(settings, u, first, kind, sections):
        calls.append(first)
        if len(calls) == 1:
            record_interrupt()  # as the handler does, its KeyboardInterrupt then lost
        return np.zeros((len(u), sections, len(settings.summary_names)))

    monkeypatch.setattr(posterior_data, "simulate_long_cases", fake)
    n = 2 * posterior_data.CHUNK
    restore = catch_interrupts()
    try:
        with pytest.raises(KeyboardInterrupt):
            cached_cases(_settings(), tmp_path, "check", n)
    finally:
        restore()
    assert calls == [0] and len(list(tmp_path.iterdir())) == 1
    cached_cases(_settings(), tmp_path, "check", n)
    assert calls == [0, posterior_data.CHUNK]  # the first chunk read back


# -- the product of likelihoods -------------------------------------------------------------

A = np.array([[2.0, 0.5], [0.3, 1.5], [1.0, -1.0]])  # three statistics of two parameters
B = np.array([1.0, -2.0, 0.5])
S = np.diag([0.25, 0.2, 0.09])  # one section's covariance: the statistics independent


class _Linear(StatisticsEmulator):
    """Exact moments of x = A[rows] u + B[rows] + e, e ~ N(0, S[rows, rows])."""

    def __init__(self, rows):
        self.rows = list(rows)
        d = len(self.rows)
        super().__init__([[(np.zeros((2, 1)), np.zeros(1))]], np.zeros(d), np.ones(d),
                         np.zeros((1, d)), np.eye(d))  # fmt: skip

    def moments(self, u):
        u = np.atleast_2d(u)
        n, r = len(u), self.rows
        cov = np.repeat(S[np.ix_(r, r)][None], n, 0)
        return u @ A[r].T + B[r], cov, np.zeros_like(cov)

    def mean(self, u):
        return self.moments(u)[0]


def test_one_part_is_the_parts_own_sampler_draw_for_draw():
    sl = SyntheticLikelihood(_Linear([0, 1, 2]))
    x = (A @ [0.4, 0.6] + B)[None] + 0.1
    assert np.array_equal(joint.sample_product([sl], [x], 300, seed=4), sl.sample(x, 300, 4))


def test_the_product_is_one_estimator_of_both_parts_statistics():
    """Parts of statistics {0, 1} and {2}: their summed log-likelihoods equal the one of
    all three with the block-diagonal covariance (independent conditions), in both SMC
    runs, so the draws agree with that estimator's; and the product knows the parameter
    the second part alone does not pin (its one statistic moves both)."""
    whole = SyntheticLikelihood(_Linear([0, 1, 2]))
    parts = [SyntheticLikelihood(_Linear([0, 1])), SyntheticLikelihood(_Linear([2]))]
    truth = np.array([0.45, 0.55])
    x = np.stack([A @ truth + B + d for d in (0.05, -0.05, 0.02)])  # three sections
    u = np.random.default_rng(0).random((50, 2))
    u0 = np.array([0.4, 0.6])
    for name in ("first", "second"):
        total = 0.0
        for sl, xs in zip(parts, (x[:, :2], x[:, 2:]), strict=True):
            s, k = sl.reading(xs)
            f = sl.first_log_likelihood(s, k) if name == "first" else sl.second_log_likelihood(
                u0, s, k)  # fmt: skip
            total = total + f(u)
        s, k = whole.reading(x)
        f = whole.first_log_likelihood(s, k) if name == "first" else whole.second_log_likelihood(
            u0, s, k)  # fmt: skip
        diff = total - f(u)  # equal up to a constant (the normalisation)
        assert np.ptp(diff) < 1e-9 * np.ptp(f(u))
    a = joint.sample_product(parts, [x[:, :2], x[:, 2:]], 4000, seed=2)
    b = whole.sample(x, 4000, seed=2)
    assert np.allclose(a.mean(axis=0), b.mean(axis=0), atol=0.01)
    assert np.allclose(a.std(axis=0), b.std(axis=0), rtol=0.08)
    alone = parts[1].sample(x[:, 2:], 4000, seed=2)
    assert np.all(a.std(axis=0) < 0.7 * alone.std(axis=0))


# -- in run directories ---------------------------------------------------------------------


def _statistics(u, rng, sections, d, column):
    """A linear stand-in in which only one parameter (``column``) moves the statistics."""
    mean = 40.0 + 3.0 * u[:, [column]] * np.ones(d)
    return mean[:, None, :] + rng.standard_normal((len(u), sections, d))


def _cache(run, settings, kind, n, sections, column, seed, draws=None):
    folder = run / "posterior" / "simulations"
    folder.mkdir(parents=True, exist_ok=True)
    u = prior_draws(settings, kind, n) if draws is None else draws
    d = len(settings.summary_names)
    x = _statistics(u, np.random.default_rng([seed, len(kind), sections]), sections, d, column)
    x = x[:, 0] if sections == 1 else x
    name = kind if sections == 1 else f"{kind}-x{sections}"
    if settings.condition_offset:
        name += f"@{settings.condition_offset}"
    for k, lo in enumerate(range(0, n, 50)):
        hi = min(n, lo + 50)
        buf = io.BytesIO()
        np.savez(buf, u=u[lo:hi], x=x[lo:hi])
        (folder / f"{name}_{k:04d}_{hi - lo}.npz").write_bytes(buf.getvalue())


def _trained(root, name, settings, column, seed):
    run = root / name
    for kind, n, k in (("train", 300, 1), ("check", 30, 1), ("long", 30, 4),
                       ("long-calibration", 30, 4)):  # fmt: skip
        _cache(run, settings, kind, n, k, column, seed)
    sets = 0.1 + 0.8 * prior_draws(settings, "identification", SETS)  # bench/posterior.py's
    _cache(run, settings, "identification", SETS, 4, column, seed, draws=sets)
    synthetic.train(settings, run)
    return run


X18, X13 = 7, 2  # the columns of X18 and X13 in X11-X20
SETS = 3  # middle-80 % sets in the bench's test


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("joint")
    a = _trained(root, "straight", _settings(), X18, 1)
    b = _trained(root, "uphill", _settings(UPHILL, offset=1), X13, 2)
    return root, a, b


def test_two_estimators_checked_jointly_stored_and_read_back(runs):
    root, a, b = runs
    j = joint.train([a, b], root / "joint")
    assert [c.sections for c in j.checks] == [1, 4]
    assert all(c.checks[0].n == 30 for c in j.checks)
    widths = {c.sections: c.width_pct_range for c in j.checks}
    alone_a = {c.sections: c.width_pct_range for c in synthetic.load(a).checks}
    alone_b = {c.sections: c.width_pct_range for c in synthetic.load(b).checks}
    # each part pins its own parameter, the joint both
    assert widths[4]["X18"] < 0.8 * alone_b[4]["X18"]
    assert widths[4]["X13"] < 0.8 * alone_a[4]["X13"]
    back = joint.load(root / "joint")
    assert [c.to_dict() for c in back.checks] == [c.to_dict() for c in j.checks]
    x = np.full((4, 2 * 17), 41.5)
    assert np.array_equal(j.sample(x, 200, seed=1), back.sample(x, 200, seed=1))
    assert back.product_for(2).sections == 4 and back.product_for(5) is None


def test_a_part_trained_again_makes_the_joint_check_stale(runs, tmp_path):
    root, a, b = runs
    joint.train([a, b], root / "joint")
    check = b / "posterior" / "synthetic" / "check.json"
    saved = check.read_text()
    try:
        check.write_text(saved.replace('"emulator": [', '"emulator": ["other", ', 1))
        with pytest.raises(RailsuspInputError, match=r"trained again after the joint check"):
            joint.load(root / "joint")
    finally:
        check.write_text(saved)


def test_estimators_that_cannot_be_joined_are_refused_in_one_line(runs, tmp_path):
    _, a, b = runs
    part_a, part_b = synthetic.load(a), synthetic.load(b)
    with pytest.raises(RailsuspInputError, match=r"condition 'straight' in estimators 1 and 2"):
        joint.JointPosterior((part_a, part_a))
    with pytest.raises(RailsuspInputError, match=r"accepted two or more"):
        joint.JointPosterior((part_a,))
    same_tracks = synthetic.SyntheticPosterior(_settings(UPHILL), part_b.likelihood)
    with pytest.raises(RailsuspInputError, match=r"both hold condition index 0 .* share tracks"):
        joint.JointPosterior((part_a, same_tracks))
    # a first estimator of two conditions holds slots 0 and 1: offset 1 overlaps it
    two = synthetic.SyntheticPosterior(PosteriorSettings((STRAIGHT, get_condition("curve")),
                                       **_common()), part_a.likelihood)  # fmt: skip
    curve_less = synthetic.SyntheticPosterior(_settings(UPHILL, offset=1), part_b.likelihood)
    with pytest.raises(RailsuspInputError, match=r"both hold condition index 1"):
        joint.JointPosterior((two, curve_less))
    other = synthetic.SyntheticPosterior(_settings(UPHILL, offset=1, section_s=10.0),
                                         part_b.likelihood)  # fmt: skip
    with pytest.raises(RailsuspInputError, match=r"section_s = 10.0 differs from the first's"):
        joint.JointPosterior((part_a, other))
    j = joint.JointPosterior((part_a, part_b))
    with pytest.raises(RailsuspInputError, match=r"accepted summaries \(k, 34\), the parts'"):
        j.sample(np.zeros((2, 33)), 100)
    with pytest.raises(RailsuspInputError, match=r"does not exist: check the joint"):
        joint.load(tmp_path)


def test_the_bench_checks_scores_the_sets_and_adds_the_parts_information(runs, monkeypatch):
    """bench/posterior_joint.py on the two stand-in estimators: the joint check per
    length, the sets scored, and a bound from the parts' informations added, so narrower
    for each parameter than the part that does not see it."""
    import json
    import sys

    from conftest import bench_script

    root, a, b = runs
    bench = bench_script("posterior_joint")
    out = root / "bench.json"
    # the joint check of the first test (same sets and calibration records): read, not redone
    argv = ["posterior_joint.py", "--runs", f"{a},{b}", "--joint", str(root / "joint"),
            "--out", str(out), "--lengths", "5,20", "--check", "30", "--long", "30",
            "--long-length", "20", "--calibration-records", "30", "--sets", str(SETS),
            "--set-length", "20"]  # fmt: skip
    monkeypatch.setattr(sys, "argv", argv)
    bench.main()
    got = json.loads(out.read_text())
    assert got["conditions"] == ["straight", "uphill"]
    assert [c["sections"] for c in got["checks"]] == [1, 4]
    assert [r["sections"] for r in got["identification"]] == [1, 4]
    assert got["identification"][-1]["sets"] == SETS
    bound = got["cramer_rao_width_pct"]["statistics_alone"]
    parts = [synthetic.load(r) for r in (a, b)]
    u = 0.1 + 0.8 * prior_draws(parts[0].settings, "identification", SETS)
    from railsusp.estimate.posterior_synthetic_information import (
        cramer_rao_width,
        fisher_information,
    )

    info = [fisher_information(p.likelihood, u, 4, emulator_error=False) for p in parts]
    both = 100 * cramer_rao_width(info[0] + info[1])
    assert np.allclose(bound["X18"], both[:, X18]) and np.allclose(bound["X13"], both[:, X13])
    # each part alone cannot bound the parameter it does not see; together both are pinned
    with np.errstate(invalid="ignore", divide="ignore"):
        alone = [100 * cramer_rao_width(i) for i in info]
    assert not np.all(alone[1][:, X18] < 90) and not np.all(alone[0][:, X13] < 90)
    assert np.all(both[:, [X18, X13]] < 70)  # the prior alone: 90


def test_the_emulators_hash_holds_the_offset_only_where_set():
    """An estimator at another offset learns from other tracks: its emulator is not the
    offset-0 one; at offset 0 the hash is the one of estimators trained before the offset
    existed (their run folders load)."""
    from railsusp.estimate.posterior_synthetic_fit import _trained_on, emulator_key

    assert "condition_offset" not in _trained_on(_settings())
    assert _trained_on(_settings(offset=2))["condition_offset"] == 2
    assert emulator_key(_settings()) != emulator_key(_settings(offset=2))


def test_a_joint_folder_is_its_own_and_reads_only_cached_records(runs, tmp_path):
    """The joint check goes into a folder of its own (an estimator's would read as the
    joint afterwards), and it reads the parts' caches only: held-out cases a part has not
    simulated are a one-line error, never simulated by the join."""
    _, a, b = runs
    with pytest.raises(RailsuspInputError, match=r"an estimator's folder; accepted a folder"):
        joint.train([a, b], a)
    with pytest.raises(RailsuspInputError, match=r"is not cached \(cases 1-40 of 40 check"):
        joint.train([a, b], tmp_path / "j", [("check", 40, 1, (1,))])
    assert not (tmp_path / "j" / "posterior" / "joint.json").exists()


def test_a_recordings_sections_are_the_fewest_of_the_parts(runs, monkeypatch):
    """Each part cuts its own conditions; the part with the fewest sections sets their
    number, and the other's sections beyond it are counted as left out."""
    _, a, b = runs
    j = joint.JointPosterior((synthetic.load(a), synthetic.load(b)))
    counts = {"straight": 5, "uphill": 3}

    def summaries(settings, recordings):
        name = settings.conditions[0].name
        k = counts[name]
        return np.zeros((k, 17)), {name: {"sections": k, "seconds_left_out": 1.5}}

    monkeypatch.setattr(joint, "recording_summaries", summaries)
    x, used = joint.recording_sections(j, [])
    assert x.shape == (3, 34)
    assert used == {"straight": {"sections": 3, "seconds_left_out": 11.5},
                    "uphill": {"sections": 3, "seconds_left_out": 1.5}}  # fmt: skip


def test_the_widening_is_fitted_on_calibration_records_stored_and_applied(runs):
    """The join fits a split-conformal widening per checked number of sections on the
    parts' calibration records (never below 1), stores it and reads it back; the draws
    are widened about their median in logit coordinates by its factors; a factor above
    the bound marks the parameter as failed in that check."""
    from railsusp.estimate.calibration import SpreadCorrection
    from railsusp.estimate.posterior_fusion import to_logit

    root, a, b = runs
    j = joint.train([a, b], root / "joint")
    assert sorted(j.corrections) == [1, 4]
    assert all(f >= 1.0 for c in j.corrections.values() for f in c.factors)
    assert all(c.n == 30 for c in j.corrections.values())  # the parts' 30 records
    back = joint.load(root / "joint")
    assert {k: c.to_dict() for k, c in back.corrections.items()} == {
        k: c.to_dict() for k, c in j.corrections.items()
    }
    names = list(j.settings.parameters)
    j.corrections = {4: SpreadCorrection(tuple(names), (2.0,) * 10, 30)}
    assert j.correction_for(2) is j.corrections[4]
    # beyond the longest corrected record, its widening (none was applied: a longer record
    # got narrower intervals than a checked one; stop 78's hunt)
    assert j.correction_for(5) is j.corrections[4]
    saved, j.corrections = j.corrections, {}
    assert j.correction_for(2) is None
    j.corrections = saved
    x = np.full((4, 2 * 17), 41.5)
    raw, wide = (to_logit(f(x, 400, seed=3)) for f in (j.raw_sample, j.sample))
    assert np.allclose(np.median(wide, axis=0), np.median(raw, axis=0), atol=1e-9)
    spread = np.subtract(*np.quantile(wide, [0.95, 0.05], axis=0))
    assert spread == pytest.approx(2.0 * np.subtract(*np.quantile(raw, [0.95, 0.05], axis=0)))
    factors = [2.5 if p == "X18" else 1.0 for p in names]
    j.corrections = {4: SpreadCorrection(tuple(names), tuple(factors), 30)}
    flagged = joint.flag_excessive(j, back.checks)
    x18 = names.index("X18")
    assert not flagged[-1].checks[x18].passed and flagged[-1].sections == 4
    assert [c.passed for c in flagged[-1].checks if c.parameter != "X18"] == [
        c.passed for c in back.checks[-1].checks if c.parameter != "X18"
    ]
    # one section takes the widening of the smallest corrected number above it, here 4's
    assert not flagged[0].checks[x18].passed


def test_a_joint_check_edited_since_it_was_written_is_refused_and_made_again(
    runs, tmp_path, caplog
):
    """joint.json was trusted as it stood (a coverage or a widening edited by hand). Now it
    is sealed: load refuses an edited one in one line, a join run again makes it anew."""
    import json
    import logging
    import shutil

    _, a, b = runs
    # a check of its own, on the one-section cases alone and with no widening (a fraction
    # of the default check's time): the seal is the same
    small = dict(sets=[("check", 30, 1, (1,))], calibration=None)
    joint.train([a, b], tmp_path / "first", **small)
    copy = tmp_path / "joint"
    shutil.copytree(tmp_path / "first", copy)
    path = copy / "posterior" / "joint.json"
    good = path.read_text()
    record = json.loads(good)
    record["checks"][0]["parameters"][0]["passed"] = not record["checks"][0]["parameters"][0][
        "passed"
    ]
    path.write_text(json.dumps(record))
    with pytest.raises(RailsuspInputError) as info:
        joint.load(copy)
    assert str(info.value) == (
        f"{path} was changed after the joint posterior's check was written (its content does "
        "not match its seal): run railsusp posterior join again to make it again"
    )
    with caplog.at_level(logging.WARNING):
        joint.train([a, b], copy, **small)
    assert "the joint check runs again" in caplog.text
    assert json.loads(path.read_text()) == json.loads(good)
