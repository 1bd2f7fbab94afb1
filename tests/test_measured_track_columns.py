"""A field table's speed and track columns (measured.track_columns): never checked nor
used before, so a 30 km/h run filed as the 60 km/h condition, or a curve's cant in a
tangent's recording, was read without a word. Each is now held against the condition."""

import json

import numpy as np
import pandas as pd
import pytest

from railsusp.conditions import get_condition
from railsusp.measured import Recording, read_recording
from railsusp.vehicle.track import TrackLayout
from test_measured_checks import problems

RATE = 50.0


def write(tmp_path, condition, extra: dict, name="rec", keep_condition=True):
    """A recording of ``condition`` (its record) with the ``extra`` columns, per sample."""
    n = condition.n_steps
    t = np.arange(n) / RATE
    rec = Recording(
        t,
        {"w1R": 5 + 3 * np.sin(2 * np.pi * 1.5 * t)},
        {"w1R": 122 + 10 * np.cos(2 * np.pi * 2.0 * t)},
        condition,
    )
    path = rec.write(tmp_path / name)
    frame = pd.read_csv(path)
    for col, values in extra.items():
        frame[col] = values(t) if callable(values) else values
    frame.to_csv(path, index=False)
    if not keep_condition:
        side = path.with_suffix(".json")
        meta = json.loads(side.read_text())
        meta["condition"]["speed_kmh"] = "sixty"  # no valid condition: the ranges alone
        side.write_text(json.dumps(meta))
    return path


STRAIGHT = get_condition("straight", duration_s=2.0, n_steps=100)
CURVE = get_condition("curve", duration_s=4.0, n_steps=200, lead_in_m=20.0)


def test_a_speed_column_that_contradicts_the_condition_is_refused(tmp_path):
    msg = problems(write(tmp_path, STRAIGHT, {"speed_kmh": 30.0}))
    assert (
        "column 'speed_kmh', rows 2-101: speed 30 km/h (100 row(s)); accepted 54 to 66 km/h "
        "(the condition's 60 km/h within 10 %, the default speed tolerance of railsusp sections)"
    ) in msg
    assert "column 'speed_kmh', rows 2-101: speed -60 km/h" in problems(
        write(tmp_path, STRAIGHT, {"speed_kmh": -60.0})
    )
    # a speed within the tolerance reads (and is not used: the condition is simulated)
    rec = read_recording(write(tmp_path, STRAIGHT, {"speed_kmh": lambda t: 60 + 4 * np.sin(t)}))
    assert rec.condition.speed_kmh == 60.0


def test_cant_and_grade_beyond_the_condition_are_refused(tmp_path):
    msg = problems(write(tmp_path, STRAIGHT, {"cant_mm": 1100.0, "grade_permille": 200.0}))
    assert "column 'cant_mm', rows 2-101: cant 1100 mm (100 row(s)); accepted -20 to 20 mm" in msg
    assert "column 'grade_permille', rows 2-101: grade 200 ‰ (100 row(s)); accepted -5 to 5 ‰" in (
        msg
    )


def test_a_curves_measured_track_reads_and_the_other_hand_is_refused(tmp_path):
    """The design track of the curve at each sample's place (lead-in 20 m: the record
    starts on the approach, 0-20 m short of the spiral), registered 3 m off, noisy."""
    layout = TrackLayout.from_condition(CURVE)
    rng = np.random.default_rng(1)

    def place(t):
        return CURVE.lead_in_m + CURVE.speed * t

    good = {
        "curvature_1_per_km": lambda t: (
            layout.curvature_at(place(t) + 3.0) * 1e3 + 0.05 * rng.standard_normal(t.size)
        ),
        "cant_mm": lambda t: (
            np.abs(layout.cant_at(place(t) - 3.0)) * 1e3 + 2.0 * rng.standard_normal(t.size)
        ),
        "grade_permille": 0.5,
    }
    read_recording(write(tmp_path, CURVE, good))
    good["curvature_1_per_km"] = lambda t: -layout.curvature_at(place(t)) * 1e3
    msg = problems(write(tmp_path, CURVE, good))
    assert "column 'curvature_1_per_km', rows " in msg
    assert "1/km at the first such row (the condition's" in msg
    assert "+ left-hand" in msg


def test_without_a_condition_the_ranges_of_a_condition_hold(tmp_path):
    msg = problems(
        write(tmp_path, STRAIGHT, {"speed_kmh": 0.0, "cant_mm": 250.0}, keep_condition=False)
    )
    assert (
        "column 'speed_kmh', rows 2-101: speed 0 km/h (100 row(s)); accepted above 0 and up to "
        "200 km/h"
    ) in msg
    assert "column 'cant_mm', rows 2-101: cant 250 mm (100 row(s)); accepted -200 to 200 mm" in msg


#: a curve whose spirals lie inside the 20 s record: lead-in 10 m, the curve from 100 m
SPIRALS = get_condition(
    "curve",
    duration_s=20.0,
    n_steps=1000,
    lead_in_m=10.0,
    curve_start_m=100.0,
    entry_spiral_m=60.0,
    arc_length_m=100.0,
    exit_spiral_m=60.0,
)


@pytest.mark.parametrize("axis", ["time_s", "distance_m"])
def test_a_run_slower_than_its_condition_is_placed_by_its_own_speed(tmp_path, axis):
    """The reviewer of the QA pass: each row was placed at the condition's speed, so a run
    at 56 km/h filed as the 60 km/h condition (within the speed tolerance) drifted 1.1 m
    each second from its spirals and was refused with exactly the design track. Placed by
    its distance_m, or by its speed_kmh integrated over time, it reads."""
    layout = TrackLayout.from_condition(SPIRALS)
    v = 0.93 * SPIRALS.speed  # m/s, 55.8 km/h
    t = np.arange(SPIRALS.n_steps) / RATE
    d = v * t  # from the first row
    track = {
        "speed_kmh": np.full(t.size, v * 3.6),
        "curvature_1_per_km": layout.curvature_at(SPIRALS.lead_in_m + d) * 1e3,
        "cant_mm": np.abs(layout.cant_at(SPIRALS.lead_in_m + d)) * 1e3,
    }
    path = write(tmp_path, SPIRALS, track)
    if axis == "distance_m":  # the same rows along distance
        frame = pd.read_csv(path)
        frame.insert(0, "distance_m", d)
        frame.drop(columns="time_s").to_csv(path, index=False)
    rec = read_recording(path)
    assert rec.time.size == SPIRALS.n_steps
    # without its speed column the rows are placed at the condition's speed, as all were
    # before: the same track is then refused (the spirals 15-20 m off by their end)
    del track["speed_kmh"]
    msg = problems(write(tmp_path, SPIRALS, track))
    assert "column 'cant_mm', rows " in msg and "at the first such row" in msg
