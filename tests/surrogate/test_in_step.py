"""Several conditions' sequence surrogates predicted in step
(:func:`railsusp.surrogate.in_step.predict_in_step`): each condition's force series are those
its surrogate predicts alone (scaling, nominal forces, record correction and washout
included) to float32 rounding; :meth:`SurrogateForces.series_conditions
<railsusp.estimate.forces.SurrogateForces.series_conditions>` runs the conditions that can
go in step together and the others alone, and the calibration's objectives keep their
numbers. The surrogates are random-weight bundles and the measured tracks synthesised
geometry files: no campaign, no simulation."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from railsusp.conditions import get_condition
from railsusp.estimate import CalibrationProblem, SurrogateForces
from railsusp.estimate.comparison import AlignedComparison
from railsusp.estimate.statistics import (
    ALIGNED,
    measured_statistics,
    parse_statistics,
    series_statistics,
)
from railsusp.measured import Recording
from railsusp.params import bounds
from railsusp.surrogate import in_step
from railsusp.surrogate.bundle import Surrogate
from railsusp.surrogate.data import Normaliser
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.in_step import in_step_key, predict_in_step
from railsusp.surrogate.models import NetConfig, build_network
from railsusp.vehicle import MODEL_REVISION
from railsusp.vehicle.track_geometry import write_track_geometry
from railsusp.vehicle.track_grid import section_irregularities
from railsusp.vehicle.wagon import load_wagon

KEYS = ("X13", "X14", "X15", "X16", "X17", "X18")
NAMES = ("straight", "curve", "uphill")
T_STEPS, WASHOUT, SEGMENT = 100, 10, 40


def _surrogate(
    name: str,
    seed: int,
    *,
    kind: str = "cnn-gru-seq",
    keys: tuple[str, ...] = KEYS,
    nominal: bool = False,
    segment: int | None = SEGMENT,
) -> Surrogate:
    """A random-weight surrogate of condition ``name`` (2 s in 100 steps) with its own
    normalisation (``seed``); a sequence CNN-GRU of washout 10 predicting in segments of 40
    steps, or a window network (``kind``) of window 20."""
    window = WASHOUT if kind == "cnn-gru-seq" else 20
    spec = FeatureSpec(parameters=keys, window=window, nominal_response=nominal)
    cfg = NetConfig(
        kind=kind,
        n_features=spec.n_features,
        window=window,
        conv_channels=(spec.n_features, 12),
        rnn_hidden=(8, 6, 4),
        dense=(8, 5),
    )
    torch.manual_seed(seed)
    net = build_network(cfg)
    with torch.no_grad():  # biases of a trained network's size
        for p in net.parameters():
            p.mul_(2.0)
    rng = np.random.default_rng(seed)
    n_track = spec.n_features - len(keys)
    norm = Normaliser(
        rng.normal(size=n_track).tolist(),
        (0.5 + rng.random(n_track)).tolist(),
        [5.0 + seed, 110.0 + 5 * seed],
        [3.0 + seed, 15.0 + seed],
    )
    cond = get_condition(name, duration_s=2.0, n_steps=T_STEPS)
    meta = {"segment_steps": segment, "track_realisations": 24, "model_revision": MODEL_REVISION}
    return Surrogate(net, cfg, spec, norm, cond, load_wagon(), 0, meta)


class _Factors:
    """A record correction of known factors: 1 + 0.1 g + 0.2 x (x the first parameter's unit
    value), for the ``g``-th surrogate."""

    def __init__(self, g: int):
        self.g = g

    def apply(self, series: np.ndarray, params_unit: np.ndarray) -> np.ndarray:
        return series * (1.0 + 0.1 * self.g + 0.2 * params_unit[:, :1])[:, :, None]


def _sets(n: int = 5, seed: int = 0) -> np.ndarray:
    lo, hi = bounds(KEYS)
    return lo + (hi - lo) * np.random.default_rng(seed).random((n, len(KEYS)))


def _raw_track(n_cols: int, seed: int, nominal: bool) -> np.ndarray:
    """A raw track input (T, n_cols); with ``nominal`` its last two columns are the nominal
    wagon's Y and Q, kN."""
    rng = np.random.default_rng(100 + seed)
    track = rng.normal(size=(T_STEPS, n_cols)) * (1.0 + seed)
    if nominal:
        track[:, -2:] = [4.0, 120.0] + rng.normal(size=(T_STEPS, 2)) * [2.0, 8.0]
    return track


@pytest.mark.parametrize("nominal", [False, True])
@pytest.mark.parametrize("n_conditions", [2, 3])
def test_surrogates_in_step_predict_what_each_predicts_alone(n_conditions, nominal):
    surs = [_surrogate(NAMES[g], g, nominal=nominal) for g in range(n_conditions)]
    for g, s in enumerate(surs):
        s.correction = _Factors(g)
    conds = [s.condition.with_changes(track_geometry=f"{s.condition.name}.csv") for s in surs]
    n_cols = surs[0].spec.n_features - len(KEYS)
    tracks = [_raw_track(n_cols, g, nominal) for g in range(n_conditions)]
    x = _sets()
    for corrected in (True, False):
        together = predict_in_step(surs, x, conds, tracks, corrected=corrected)
        assert len(together) == n_conditions
        for s, c, tr, mine in zip(surs, conds, tracks, together, strict=True):
            alone = s.predict(x, c, track=tr, corrected=corrected)
            assert mine.shape == alone.shape == (5, T_STEPS, 2)
            assert np.isnan(mine[:, :WASHOUT]).all() and np.isfinite(mine[:, WASHOUT:]).all()
            np.testing.assert_allclose(mine, alone, rtol=1e-5, atol=1e-4)  # NaN where alone's
        # each condition's own network, normalisation, nominal forces and correction
        assert np.nanmax(np.abs(together[1] - together[0])) > 1.0
    uncorrected = together
    corrected = predict_in_step(surs, x, conds, tracks)
    assert np.nanmax(np.abs(corrected[0] - uncorrected[0])) > 1.0


def test_in_step_key_pairs_sequence_networks_of_one_architecture_segment_and_track_length():
    a, b = _surrogate("straight", 0), _surrogate("curve", 1)
    track = np.zeros((T_STEPS, 15))
    assert in_step_key(a, track) == in_step_key(b, track) is not None
    assert in_step_key(a, track) != in_step_key(b, np.zeros((T_STEPS + 1, 15)))
    assert in_step_key(a, track) != in_step_key(_surrogate("curve", 1, segment=30), track)
    assert in_step_key(a, track) != in_step_key(_surrogate("curve", 1, segment=None), track)
    assert in_step_key(_surrogate("curve", 1, kind="cnn-gru"), track) is None
    assert in_step_key(a, np.zeros((5, T_STEPS, 15))) is None  # one track per set


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"kind": "cnn-gru"}, "these surrogates cannot be predicted in step"),
        ({"segment": 30}, "accepted sequence CNN-GRUs of one architecture and segment"),
        ({"track_steps": T_STEPS + 10}, "of one length"),
        ({"keys": ("X14", "X13", "X15", "X16", "X17", "X18")}, "of different key parameters"),
    ],
)
def test_surrogates_that_cannot_go_in_step_are_refused_in_one_line(change, message):
    first = _surrogate("straight", 0)
    opts = {k: v for k, v in change.items() if k != "track_steps"}
    second = _surrogate("curve", 1, **opts)
    tracks = [np.zeros((T_STEPS, 15)), np.zeros((change.get("track_steps", T_STEPS), 15))]
    conds = [first.condition, second.condition]
    with pytest.raises(ValueError, match=message) as err:
        predict_in_step([first, second], _sets(), conds, tracks)
    assert "\n" not in str(err.value)


def test_lists_of_other_lengths_and_a_window_network_first_are_refused_in_one_line():
    surs = [_surrogate("straight", 0), _surrogate("curve", 1)]
    conds = [s.condition for s in surs]
    track = np.zeros((T_STEPS, 15))
    x = _sets()
    with pytest.raises(ValueError, match="2 surrogates, 1 conditions and 2 tracks: accepted"):
        predict_in_step(surs, x, conds[:1], [track, track])
    with pytest.raises(ValueError, match="2 surrogates, 2 conditions and 3 tracks"):
        predict_in_step(surs, x, conds, [track] * 3)
    with pytest.raises(ValueError, match="0 surrogates, 0 conditions and 0 tracks"):
        predict_in_step([], x, [], [])
    window = _surrogate("straight", 0, kind="cnn-gru")
    with pytest.raises(ValueError, match="cannot be predicted in step"):
        predict_in_step([window, surs[1]], x, conds, [track, track])
    # the surrogate's own checks still apply: a condition it was not trained for
    fast = surs[1].condition.with_changes(speed_kmh=80.0)
    with pytest.raises(ValueError, match="trained for condition 'curve'.*speed_kmh"):
        predict_in_step(surs, x, [conds[0], fast], [track, track])


# ----- SurrogateForces and the calibration problem -------------------------------------


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """A folder of surrogates (sequence CNN-GRUs of 'straight' and 'curve', a window
    network of 'uphill') and their conditions on synthesised measured tracks: two tracks of
    'straight', one of the others."""
    root = tmp_path_factory.mktemp("in_step")
    folder = root / "surrogates"
    surs = {
        "straight": _surrogate("straight", 0),
        "curve": _surrogate("curve", 1),
        "uphill": _surrogate("uphill", 2, kind="cnn-gru"),
    }
    for name, s in surs.items():
        s.save(folder / name)
    wagon = load_wagon()
    conds = {}
    for key, name, seed in [
        ("straight", "straight", 11),
        ("straight2", "straight", 12),
        ("curve", "curve", 13),
        ("uphill", "uphill", 14),
    ]:
        cond = surs[name].condition.with_changes(seed=seed)
        irr = section_irregularities(cond, [seed], wagon)
        path = write_track_geometry(root / f"{key}.track.csv", irr, origin_m=cond.lead_in_m)
        conds[key] = cond.with_changes(track_geometry=str(path))
    conds["synthesised"] = surs["straight"].condition
    return folder, conds


@pytest.fixture
def in_step_calls(monkeypatch):
    """The conditions of each call of predict_in_step (which it still makes)."""
    calls = []
    real = in_step.predict_in_step

    def spy(surrogates, params, conditions, tracks, **kw):
        calls.append([c.name for c in conditions])
        return real(surrogates, params, conditions, tracks, **kw)

    monkeypatch.setattr(in_step, "predict_in_step", spy)
    return calls


def test_series_conditions_runs_the_pairable_conditions_in_step_and_gives_series(
    measured, in_step_calls
):
    """Two measured tracks of 'straight' and one of 'curve' go in step; the window network
    of 'uphill' and 'straight' on its synthesised training track go alone; each condition
    gets :meth:`series`'s numbers, in the order asked."""
    folder, conds = measured
    model = SurrogateForces(folder)
    order = ["straight", "uphill", "curve", "straight2", "synthesised"]
    x = _sets(4)
    out = model.series_conditions(x, [conds[k] for k in order])
    assert in_step_calls == [["straight", "curve", "straight"]]
    alone = [model.series(x, conds[k]) for k in order]
    for key, mine, theirs in zip(order, out, alone, strict=True):
        assert mine.shape == (4, T_STEPS, 2), key
        np.testing.assert_allclose(mine, theirs, rtol=1e-5, atol=1e-4, err_msg=key)
    # the two tracks of 'straight' give two series, the synthesised track a third
    assert np.nanmax(np.abs(out[0] - out[3])) > 0.1
    assert np.nanmax(np.abs(out[0] - out[4])) > 0.1


def test_series_conditions_of_conditions_that_cannot_pair_are_series_one_by_one(
    measured, in_step_calls
):
    folder, conds = measured
    model = SurrogateForces(folder)
    x = _sets(3)
    for keys in (["curve"], ["uphill", "straight"], ["synthesised", "curve"]):
        out = model.series_conditions(x, [conds[k] for k in keys])
        for key, mine in zip(keys, out, strict=True):
            np.testing.assert_array_equal(mine, model.series(x, conds[key]))
    # another segment: 'curve' no longer pairs with 'straight', the two tracks of which do
    model.surrogate("curve").meta["segment_steps"] = 30
    keys = ["straight", "curve", "straight2"]
    out = model.series_conditions(x, [conds[k] for k in keys])
    assert in_step_calls == [["straight", "straight"]]
    np.testing.assert_array_equal(out[1], model.series(x, conds["curve"]))
    for k in (0, 2):
        np.testing.assert_allclose(out[k], model.series(x, conds[keys[k]]), rtol=1e-5, atol=1e-4)


def _recording(cond, seed: int) -> Recording:
    """A recording of random forces (lateral about 5 kN, vertical about 115 kN) of the
    wheel the models compare in ``cond`` (a curve's outer wheel)."""
    from railsusp.vehicle.simulation_result import WHEEL_NAMES, measured_wheel_index

    rng = np.random.default_rng(seed)
    t = np.arange(cond.n_steps) * cond.sample_interval
    y = 5.0 + 3.0 * np.sin(2 * np.pi * 1.1 * t + seed) + rng.normal(size=t.size)
    q = 115.0 + 8.0 * np.cos(2 * np.pi * 0.6 * t) + 2.0 * rng.normal(size=t.size)
    w = WHEEL_NAMES[measured_wheel_index(cond)]
    return Recording(t, {w: y}, {w: q}, cond, {})


@pytest.mark.parametrize("statistic", ["mean", "mean+p99", "aligned", "aligned+std"])
def test_the_objectives_on_a_series_model_are_those_of_each_conditions_series(
    measured, in_step_calls, statistic
):
    """:meth:`CalibrationProblem.errors` (all conditions' series at once) gives what each
    recording's condition's :meth:`series` gives through the statistics and the time-aligned
    comparison, one recording at a time (the objective before the conditions went in
    step)."""
    folder, conds = measured
    keys = ["curve", "straight", "uphill"]
    recs = [_recording(conds[k], seed) for seed, k in enumerate(keys)]
    problem = CalibrationProblem(SurrogateForces(folder), recs, KEYS, statistic)
    x = _sets(6, seed=7)
    errors = problem.errors(x)
    assert in_step_calls == [["curve", "straight"]]
    combination = parse_statistics(statistic)
    stats = tuple(s for s in combination if s != ALIGNED)
    reference = SurrogateForces(folder)  # a model of its own: nothing shared
    expected = []
    for rec in recs:
        series = reference.series(x, rec.condition)
        parts = []
        if ALIGNED in combination:
            parts.append(AlignedComparison(rec).error(series)[:, :, None])
        if stats:
            meas = measured_statistics(rec, stats)
            pred = series_statistics(series, rec.condition, stats)
            parts.append(np.abs(pred - meas) / np.abs(meas))
        expected.append(np.concatenate(parts, axis=2).mean(axis=2))
    expected = np.stack(expected, axis=1)
    assert errors.shape == expected.shape == (6, 3, 2)
    np.testing.assert_allclose(errors, expected, rtol=1e-5, atol=1e-6)
    # the recordings differ: an objective of another recording's series would show
    assert np.abs(expected[:, 0] - expected[:, 1]).max() > 1e-2


def test_prime_tracks_batches_the_nominal_wagons_and_keeps_each_input_bit_for_bit(
    tmp_path, integrator_calls
):
    """Networks that read the nominal wagon's response on the measured track: priming three
    tracks (two of 'straight', one of 'curve') simulates the nominal wagon in fewer calls
    than tracks, each track input is the one :meth:`track_input` computes alone, and a
    primed track is not simulated again."""
    folder = tmp_path / "surrogates"
    surs = {"straight": _surrogate("straight", 0, nominal=True)}
    surs["curve"] = _surrogate("curve", 1, nominal=True)
    for name, s in surs.items():
        s.save(folder / name)
    wagon = load_wagon()
    conds = []
    for name, seed in [("straight", 21), ("straight", 22), ("curve", 23)]:
        cond = surs[name].condition.with_changes(seed=seed)
        irr = section_irregularities(cond, [seed], wagon)
        path = write_track_geometry(tmp_path / f"{seed}.track.csv", irr, origin_m=cond.lead_in_m)
        conds.append(cond.with_changes(track_geometry=str(path)))
    alone = SurrogateForces(folder)
    expected = [alone.track_input(c) for c in conds]
    sizes = integrator_calls
    sizes.clear()  # the nominal wagons of the inputs computed alone, above
    model = SurrogateForces(folder)
    model.prime_tracks(conds)
    assert sum(sizes) == 3 and len(sizes) < 3, sizes
    for c, want in zip(conds, expected, strict=True):
        assert want.shape[1] == surs[c.name].spec.n_features - len(KEYS)
        np.testing.assert_array_equal(model.track_input(c), want)
    model.prime_tracks(conds)
    model.series_conditions(_sets(2), conds)
    assert sum(sizes) == 3  # kept: no nominal wagon simulated again
    assert np.abs(expected[0][:, -2:] - expected[1][:, -2:]).max() > 0.01  # two tracks


def test_a_track_input_is_kept_by_the_geometrys_content_not_its_path(tmp_path, integrator_calls):
    """The same geometry written again under another name (the drawn true tracks of the
    expected-forces polish, then of a simulator correction, each in its own temporary
    folder) is not simulated again: its input is the kept one, bit for bit. A file of other
    content at the first one's path (rewritten) is a new track and is computed anew."""
    folder = tmp_path / "surrogates"
    sur = _surrogate("straight", 0, nominal=True)
    sur.save(folder / "straight")
    wagon = load_wagon()
    cond = sur.condition.with_changes(seed=31)
    irr = section_irregularities(cond, [31], wagon)
    first = write_track_geometry(tmp_path / "a.track.csv", irr, origin_m=cond.lead_in_m)
    again = write_track_geometry(tmp_path / "b.track.csv", irr, origin_m=cond.lead_in_m)
    model = SurrogateForces(folder)
    sizes = integrator_calls
    sizes.clear()
    kept = model.track_input(cond.with_changes(track_geometry=str(first)))
    assert sum(sizes) == 1
    model.prime_tracks([cond.with_changes(track_geometry=str(again))])
    np.testing.assert_array_equal(
        model.track_input(cond.with_changes(track_geometry=str(again))), kept
    )
    assert sum(sizes) == 1  # the copy: no nominal wagon simulated again
    other = section_irregularities(cond.with_changes(seed=32), [32], wagon)
    write_track_geometry(first, other, origin_m=cond.lead_in_m)  # other content, same path
    new = model.track_input(cond.with_changes(track_geometry=str(first)))
    assert sum(sizes) == 2
    assert np.abs(new[:, -2:] - kept[:, -2:]).max() > 0.01
