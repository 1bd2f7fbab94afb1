"""Measured recordings: format round trip, one broken file per validation rule, resampling,
synthetic field recordings with hidden truth."""

import json

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.measured import (
    Recording,
    RecordingError,
    SimulationFailedError,
    add_sensor_noise,
    bandwidth_filter,
    read_field,
    read_recording,
    recording_from_simulation,
    synthesise_field,
)
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.simulate import simulate

COND = get_condition("straight", duration_s=2.0, n_steps=100)


def make_recording(n=100, rate=50.0) -> Recording:
    t = np.arange(n) / rate
    return Recording(
        t,
        {"w1L": 5 + 3 * np.sin(2 * np.pi * 1.5 * t)},
        {"w1L": 122 + 10 * np.cos(2 * np.pi * 2.0 * t)},
        COND,
        {"wagon": "C80"},
    )


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_round_trip(tmp_path, fmt):
    rec = make_recording()
    path = rec.write(tmp_path / "run1", fmt)
    back = read_recording(path)
    np.testing.assert_allclose(back.time, rec.time, atol=1e-9)
    np.testing.assert_allclose(back.Y["w1L"], rec.Y["w1L"], rtol=1e-5)
    np.testing.assert_allclose(back.Q["w1L"], rec.Q["w1L"], rtol=1e-5)
    assert back.condition == COND and back.meta["wagon"] == "C80"
    assert back.sampling_rate == pytest.approx(50.0)


def broken(tmp_path, edit_table=None, edit_meta=None):
    path = make_recording().write(tmp_path / "rec")
    if edit_table:
        lines = path.read_text().splitlines()
        path.write_text("\n".join(edit_table(lines)) + "\n")
    if edit_meta:
        side = path.with_suffix(".json")
        side.write_text(edit_meta(side.read_text()))
    return path


def problems_of(path) -> str:
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    return str(info.value)


def test_misnamed_column_is_pointed_out(tmp_path):
    p = broken(tmp_path, lambda ls: [ls[0].replace("Y_w1L_kN", "Y_w1l_kN"), *ls[1:]])
    msg = problems_of(p)
    assert "'Y_w1l_kN' not recognised (did you mean 'Y_w1L_kN'?)" in msg
    assert "wheel w1L: column 'Y_w1L_kN' missing" in msg


def test_non_numeric_cell_names_row(tmp_path):
    def edit(ls):
        cells = ls[5].split(",")
        cells[1] = "abc"
        return [*ls[:5], ",".join(cells), *ls[6:]]

    assert "column 'Y_w1L_kN', row 6: 'abc' is not a number" in problems_of(broken(tmp_path, edit))


def test_non_monotonic_time(tmp_path):
    def edit(ls):
        a, b = ls[10], ls[11]
        return [*ls[:10], b, a, *ls[12:]]

    assert "rows 11-12: time not strictly increasing" in problems_of(broken(tmp_path, edit))


def test_short_gap_interpolated_long_gap_rejected(tmp_path):
    def blank(rows):
        def edit(ls):
            out = list(ls)
            for r in rows:
                cells = out[r].split(",")
                cells[2] = ""
                out[r] = ",".join(cells)
            return out

        return edit

    p = broken(tmp_path / "a", blank([20, 21]))
    with pytest.warns(UserWarning, match="2 missing sample"):
        rec = read_recording(p)
    assert np.isfinite(rec.Q["w1L"]).all()
    p = broken(tmp_path / "b", blank(range(30, 40)))
    assert "rows 31-40: gap of 10 missing samples" in problems_of(p)  # file lines, header = 1


def test_implausible_magnitudes(tmp_path):
    def newtons(ls):
        head, rows = ls[0], ls[1:]
        out = [head]
        for r in rows:
            c = r.split(",")
            c[2] = str(float(c[2]) * 1000)
            out.append(",".join(c))
        return out

    assert "the values look like N, not kN" in problems_of(broken(tmp_path / "n", newtons))

    def negative(ls):
        c = ls[3].split(",")
        c[2] = "-5"
        return [*ls[:3], ",".join(c), *ls[4:]]

    assert "row 4: negative wheel load -5 kN" in problems_of(broken(tmp_path / "q", negative))

    def huge(ls):
        c = ls[7].split(",")
        c[1] = "450"
        return [*ls[:7], ",".join(c), *ls[8:]]

    assert "row 8: |force| 450 kN beyond the physical bound 300 kN" in problems_of(
        broken(tmp_path / "y", huge)
    )


def test_sampling_rate_too_low(tmp_path):
    path = make_recording(n=40, rate=20.0).write(tmp_path / "slow")
    assert "sampling rate 20 Hz below the 50 Hz" in problems_of(path)
    assert read_recording(path, min_rate_hz=20.0).sampling_rate == pytest.approx(20.0)


def test_metadata_problems_reported_together(tmp_path):
    p = broken(
        tmp_path,
        edit_meta=lambda s: s.replace(
            '"format": "railsusp-recording/1"', '"format": "other/9"'
        ).replace('"speed_kmh": 60.0', '"speed_kmh": -60.0'),
    )
    msg = problems_of(p)
    assert "format 'other/9'" in msg and "speed_kmh = -60" in msg
    p.with_suffix(".json").unlink()
    assert "metadata sidecar rec.json missing" in problems_of(p)


def test_resampling_keeps_the_signal():
    rec = make_recording(n=400, rate=200.0)
    low = rec.resampled(50.0)
    assert low.sampling_rate == pytest.approx(50.0) and len(low.time) == 100
    mid = slice(10, 90)  # away from the edges of the polyphase filter
    np.testing.assert_allclose(low.Q["w1L"][mid], rec.Q["w1L"][::4][mid], atol=0.5)


def test_sensor_noise_level():
    rec = make_recording(n=2000, rate=50.0)
    noisy = add_sensor_noise(rec, noise=0.03, seed=1, gain_error=0.0, bandwidth_hz=20.0)
    resid = noisy.Q["w1L"] - rec.Q["w1L"]
    rms = np.sqrt(np.mean(rec.Q["w1L"] ** 2))
    assert np.std(resid) == pytest.approx(0.03 * rms, rel=0.15)


def test_synthetic_field_hides_the_truth(tmp_path):
    truth = ParameterSet({"X13": 16.1, "X14": 8.3}, units="display")
    conds = [
        get_condition("straight", duration_s=2.0, n_steps=100),
        get_condition("curve", duration_s=2.0, n_steps=100),
    ]
    out = synthesise_field(truth, conds, tmp_path / "field", seed=7, noise=0.03)
    index = json.loads((out / "index.json").read_text())
    assert index["recordings"] == ["straight.csv", "curve.csv"]
    assert json.loads((out / "truth.json").read_text())["parameters_display"]["X13"] == 16.1
    (out / "truth.json").write_text("not json: the reader must never open this file")
    recs = read_field(out)
    assert [r.condition.name for r in recs] == ["straight", "curve"]
    assert recs[1].wheels == ("w1R",) and 20 < recs[1].Y["w1R"].mean() < 120
    # the field track is another realisation than the design track (seed + 1000)
    assert recs[0].condition.seed == conds[0].seed


def test_synthetic_field_longer_recording_keeps_the_sampling_rate(tmp_path):
    cond = get_condition("straight", duration_s=2.0, n_steps=100)
    out = synthesise_field(
        ParameterSet.nominal(), [cond], tmp_path / "field", noise=0.0, duration_s=5.0
    )
    (rec,) = read_field(out)
    assert len(rec.time) == 250
    assert rec.time[1] - rec.time[0] == pytest.approx(cond.sample_interval)
    assert rec.condition.duration_s == 5.0 and rec.condition.seed == cond.seed


def test_synthetic_field_with_measured_track(tmp_path):
    """--with-track writes the track the truth ran on; the reader resolves it against the
    recording's folder, and the truth simulated on it reproduces the noise-free recording."""
    from railsusp.measured import conditions_from
    from railsusp.vehicle.simulate import simulate

    cond = get_condition("straight", duration_s=2.0, n_steps=100, lead_in_m=20.0)
    truth = ParameterSet({"X13": 16.1}, units="display")
    out = synthesise_field(truth, [cond], tmp_path / "field", noise=0.0, with_track=True)
    sidecar = json.loads((out / "straight.json").read_text())
    assert sidecar["condition"]["track_geometry"] == "straight.track.csv"  # travels along
    moved = out.rename(tmp_path / "moved")
    (rec,) = read_field(moved)
    assert rec.condition.track_geometry == str((moved / "straight.track.csv").resolve())
    sim = simulate(truth, rec.condition)
    clean = bandwidth_filter(sim.Y[0, 0] / 1e3, rec.sampling_rate, 15.0)
    # equal up to the channel's gain error (noise 0): perfectly correlated
    assert np.corrcoef(clean, rec.Y["w1L"])[0, 1] > 0.99999
    other = bandwidth_filter(simulate(truth, cond).Y[0, 0] / 1e3, rec.sampling_rate, 15.0)
    assert np.corrcoef(other, rec.Y["w1L"])[0, 1] < 0.9  # the design track is another track
    # a campaign can take the recordings' conditions, measured track included
    (c,) = conditions_from(str(moved))
    assert c.track_geometry == rec.condition.track_geometry
    # a file too short for the record is reported by the reader (check-recording), not
    # first by the simulation (stop 53's fuzzing: 2 m of geometry passed)
    track = moved / "straight.track.csv"
    full = track.read_text()
    lines = full.splitlines()
    short = [ln for ln in lines[1:] if 0.0 <= float(ln.split(",")[0]) <= 2.0]
    track.write_text("\n".join([lines[0], *short]) + "\n")
    with pytest.raises(RecordingError, match=r"straight.json: track_geometry: .* covers "):
        read_field(moved)
    track.write_text(full)
    # a missing track file is reported as a recording problem
    (moved / "straight.track.csv").unlink()
    with pytest.raises(RecordingError, match="track_geometry.*not found"):
        read_field(moved)


def test_track_noise_is_bounded(tmp_path):
    from railsusp.errors import RailsuspInputError

    with pytest.raises(RailsuspInputError, match="track_noise_mm = 20: accepted 0 to 10 mm"):
        synthesise_field(
            ParameterSet.nominal(), [COND], tmp_path, with_track=True, track_noise_mm=20
        )


def test_track_measurement_error_has_the_asked_rms_within_the_band(tmp_path):
    import pandas as pd

    cond = get_condition("straight", duration_s=2.0, n_steps=100, lead_in_m=20.0)
    kw = {"noise": 0.0, "with_track": True}
    exact = synthesise_field(ParameterSet.nominal(), [cond], tmp_path / "a", **kw)
    noisy = synthesise_field(
        ParameterSet.nominal(), [cond], tmp_path / "b", track_noise_mm=0.5, **kw
    )
    a = pd.read_csv(exact / "straight.track.csv")
    b = pd.read_csv(noisy / "straight.track.csv")
    err = (b - a)[["vertical_mm", "alignment_mm", "crosslevel_mm", "gauge_mm"]].to_numpy()
    assert np.allclose(err.std(axis=0), 0.5, rtol=0.05)
    # band-limited: neighbouring samples (0.125 m apart) are strongly correlated
    assert np.corrcoef(err[1:, 0], err[:-1, 0])[0, 1] > 0.8
    # the recordings state the geometry's accuracy (exact geometry states none)
    stated = [json.loads((f / "straight.json").read_text())["condition"] for f in (exact, noisy)]
    assert "track_accuracy_mm" not in stated[0] and stated[1]["track_accuracy_mm"] == 0.5
    (rec,) = read_field(noisy)
    assert rec.condition.track_accuracy_mm == 0.5


def test_a_failed_simulation_makes_no_recording():
    r = simulate(None, COND)
    assert recording_from_simulation(r).Y["w1L"].size == 100
    r.status[0], r.fail_time[0] = L.FAIL_LIFT, 1.25  # as the integrator flags a derailment
    with pytest.raises(SimulationFailedError, match=r"'straight' failed at 1.25 s: wheel lift"):
        recording_from_simulation(r)


def test_synthetic_field_folder_is_written_as_one(tmp_path, monkeypatch):
    """A failure half-way (the second condition's simulation) leaves the existing folder as
    it was: no new table without its sidecar, no index listing recordings not written."""
    import railsusp.vehicle.simulate as sim

    truth = ParameterSet({"X13": 16.1}, units="display")
    short = dict(duration_s=2.0, n_steps=100)
    conds = [get_condition("straight", **short), get_condition("curve", **short)]
    out = synthesise_field(truth, conds[:1], tmp_path / "field", seed=7, noise=0.03)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    real = sim.simulate

    def second_fails(params, condition, **kw):
        if condition.name == "curve":
            raise RuntimeError("power lost")
        return real(params, condition, **kw)

    monkeypatch.setattr(sim, "simulate", second_fails)
    with pytest.raises(RuntimeError, match="power lost"):
        synthesise_field(truth, conds, out, seed=8, noise=0.03)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".field")]
