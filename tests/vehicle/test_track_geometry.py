"""Measured track geometry: file round trip, one broken file per validation rule, coverage,
and the simulator running on a measured track exactly as on the synthesised one."""

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.errors import ConditionError, RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle.setup import axle_spread, section_irregularities
from railsusp.vehicle.simulate import simulate
from railsusp.vehicle.track import (
    COMPONENTS,
    TRACK_TAPER_M,
    read_track_geometry,
    synthesise,
    write_track_geometry,
)
from railsusp.vehicle.wagon import load_wagon

COND = get_condition("straight", duration_s=2.0, n_steps=100, lead_in_m=20.0)


def exported(tmp_path, cond=COND, name="t.csv"):
    """The track a condition's seed gives, written as a measured-geometry file."""
    irr = section_irregularities(cond, [cond.seed], load_wagon())
    return write_track_geometry(tmp_path / name, irr, origin_m=cond.lead_in_m)


@pytest.mark.parametrize("suffix", ["csv", "parquet"])
def test_round_trip(tmp_path, suffix):
    irr = synthesise(60.0, 5, 3, start=-20.0)
    path = write_track_geometry(tmp_path / f"g.{suffix}", irr, origin_m=10.0)
    back = read_track_geometry(path)
    np.testing.assert_allclose(back.s, irr.s - 10.0, atol=1e-9)
    for c in COMPONENTS:
        np.testing.assert_allclose(back.component(c)[0], irr.component(c)[0], atol=1e-9)
    assert back.source == str(path.resolve()) and back.track_class is None


def write_table(tmp_path, text: str):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    return path


HEADER = "distance_m,vertical_mm,alignment_mm,crosslevel_mm,gauge_mm\n"


def good_rows(n=50, dx=0.25, scale=2.0):
    rng = np.random.default_rng(0)
    return [[i * dx - 5.0, *(scale * rng.standard_normal(4))] for i in range(n)]


def as_csv(rows, header=HEADER):
    return (
        header
        + "\n".join(
            ",".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in r) for r in rows
        )
        + "\n"
    )


def problems(path) -> str:
    with pytest.raises(RailsuspInputError) as info:
        read_track_geometry(path)
    return str(info.value)


def test_missing_column_is_pointed_out(tmp_path):
    msg = problems(
        write_table(tmp_path, as_csv(good_rows(), HEADER.replace("gauge_mm", "Gauge_MM")))
    )
    assert "missing column 'gauge_mm'" in msg and "did you mean 'Gauge_MM'" in msg


def test_non_numeric_cell_and_bad_distances_reported_together(tmp_path):
    rows = good_rows()
    rows[4][1] = "x"
    rows[10][0] = rows[9][0]  # not strictly increasing
    msg = problems(write_table(tmp_path, as_csv(rows)))
    assert "column 'vertical_mm'" in msg and "row 6" in msg
    assert "not strictly increasing (row 12)" in msg


def test_coarse_spacing_rejected(tmp_path):
    msg = problems(write_table(tmp_path, as_csv(good_rows(dx=1.0))))
    assert "spacing 1 m" in msg and "exceeds 0.5 m" in msg


def test_implausible_magnitudes(tmp_path):
    rows = good_rows()
    rows[7][3] = 250.0
    msg = problems(write_table(tmp_path, as_csv(rows)))
    assert "'crosslevel_mm'" in msg and "250 mm at row 9" in msg
    metres = problems(write_table(tmp_path, as_csv(good_rows(scale=0.002))))
    assert "look like metres" in metres


def test_missing_file_and_bad_suffix():
    with pytest.raises(RailsuspInputError, match="not found"):
        read_track_geometry("/nonexistent/track.csv")
    with pytest.raises(ConditionError, match="track_geometry"):
        COND.with_changes(track_geometry="track.xlsx")


def test_coverage_must_span_the_record_under_every_axle(tmp_path):
    path = write_table(tmp_path, as_csv(good_rows(n=100)))  # -5 .. 19.75 m
    cond = COND.with_changes(track_geometry=str(path))
    spread = axle_spread(load_wagon())
    with pytest.raises(RailsuspInputError) as info:
        section_irregularities(cond, [0], load_wagon())
    msg = str(info.value)
    assert "covers distance_m -5 to 19.75 m" in msg
    assert f"{-(spread + TRACK_TAPER_M):g} to {cond.record_length_m:g} m" in msg


def test_simulation_on_exported_track_equals_the_synthesised_track(tmp_path):
    """The synthetic field's track file reproduces the seed's track: same forces."""
    path = exported(tmp_path)
    cond = COND.with_changes(track_geometry=str(path), seed=99)  # the seed is unused now
    a = simulate(ParameterSet.nominal(), COND)
    b = simulate(ParameterSet.nominal(), cond)
    np.testing.assert_allclose(b.Y, a.Y, atol=0.05)  # N, from the file's 9 digits
    np.testing.assert_allclose(b.Q, a.Q, atol=0.05)
    other = simulate(ParameterSet.nominal(), COND.with_changes(seed=99))
    assert np.abs(other.Y - a.Y).max() > 1e3  # another seed is another track
    assert "measured track t.csv" in cond.describe()
