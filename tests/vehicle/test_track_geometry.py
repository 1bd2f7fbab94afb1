"""Measured track geometry: file round trip, one broken file per validation rule, coverage,
and the simulator running on a measured track exactly as on the synthesised one."""

import numpy as np
import pytest

from railsusp.conditions import get_condition
from railsusp.errors import ConditionError, RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle.setup import axle_spread
from railsusp.vehicle.simulate import simulate
from railsusp.vehicle.track import COMPONENTS, synthesise
from railsusp.vehicle.track_geometry import (
    TRACK_TAPER_M,
    read_track_geometry,
    same_measured_track,
    write_track_geometry,
)
from railsusp.vehicle.track_grid import section_irregularities
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


def test_same_measured_track_is_one_file_or_a_copy_of_it(tmp_path):
    """A synthetic recording carries a copy of its condition's geometry file, rewritten with
    the offset moved into its distances: the surrogate trained on the file must take the
    copy for its own track, and nothing else for it."""
    path = exported(tmp_path)
    on = COND.with_changes(track_geometry=str(path), track_offset_m=1.5)
    irr = read_track_geometry(path)
    moved = irr.__class__(**{**vars(irr), "s": irr.s + 1.5})
    copy = write_track_geometry(tmp_path / "copy.csv", moved)
    as_copy = COND.with_changes(track_geometry=str(copy))
    assert same_measured_track(on, on) and same_measured_track(on, as_copy)
    assert same_measured_track(as_copy, on)
    assert not same_measured_track(on, as_copy.with_changes(track_offset_m=0.5))  # moved
    assert not same_measured_track(on, on.with_changes(track_offset_m=0.0))  # same file
    other = exported(tmp_path, COND.with_changes(seed=COND.seed + 1), "other.csv")
    assert not same_measured_track(on, COND.with_changes(track_geometry=str(other)))
    gone = COND.with_changes(track_geometry=str(tmp_path / "gone.csv"))
    assert not same_measured_track(on, gone) and not same_measured_track(on, COND)


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


def test_one_component_in_metres_is_refused_and_one_not_measured_is_not(tmp_path):
    """Stop 53's fuzzing: a single column left in metres passed the all-columns test."""
    rows = good_rows()
    for r in rows:
        r[4] *= 1e-3  # gauge in metres
    msg = problems(write_table(tmp_path, as_csv(rows)))
    assert "column 'gauge_mm': every value below 0.1 mm" in msg and "looks like metres" in msg
    for r in rows:
        r[4] = 0.0  # gauge not measured
    assert read_track_geometry(write_table(tmp_path, as_csv(rows))).component("gauge").max() == 0


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


def test_accurate_wavelength_follows_the_fra_spectrum():
    """Where the Class 5 PSD (converted to m²/(cycle/m)) falls to (1 + SNR) times the PSD of
    a white error of the stated RMS over the measured band, the geometry stops being
    accurate: the estimate from a 2 km realisation lands within a quarter of the analytic
    wavelength, and a larger error gives a longer shortest-accurate wavelength."""
    from scipy.optimize import brentq

    from railsusp.vehicle.track import fra_psd
    from railsusp.vehicle.track_geometry import GEOMETRY_SNR_MIN, accurate_wavelength_m

    irr = synthesise(2000.0, 5, 3, dx=0.125)
    for sigma in (0.25e-3, 1e-3):
        lam = accurate_wavelength_m(irr, sigma, 1.0)

        def excess(log_lam, component, error_psd=sigma**2 * 1.0):
            omega = np.array([2 * np.pi / np.exp(log_lam)])
            psd = 2 * np.pi * fra_psd(component, omega, 5)[0]  # m²/(cycle/m)
            return psd / error_psd - 1.0 - GEOMETRY_SNR_MIN

        for c in ("vertical", "alignment"):
            expected = np.exp(brentq(excess, np.log(1.0), np.log(100.0), args=(c,)))
            assert lam[c] == pytest.approx(expected, rel=0.25), (c, sigma)
    rough, fine = accurate_wavelength_m(irr, 2e-3, 1.0), accurate_wavelength_m(irr, 0.1e-3, 1.0)
    assert all(rough[c] > fine[c] for c in COMPONENTS)
    assert all(fine[c] >= 1.0 for c in COMPONENTS)
    with pytest.raises(ValueError, match="accuracy_m = 0"):
        accurate_wavelength_m(irr, 0.0, 1.0)


def test_a_track_sampled_at_exactly_half_a_metre_is_accepted(tmp_path):
    """Distances every 0.5 m, written rounded to millimetres, have differences a rounding
    above 0.5 m: refused as "spacing 0.5 m exceeds 0.5 m" (command-line audit, stop 60)."""
    import pandas as pd

    d = np.round(np.arange(-60.3, 30.0, 0.5), 3)
    assert np.diff(d).max() > 0.5  # the float rounding the check must tolerate
    wave = 2.0 * np.sin(d / 7.0)  # mm
    table = {"distance_m": d, **{f"{c}_mm": wave for c in COMPONENTS}}
    pd.DataFrame(table).to_csv(tmp_path / "half.csv", index=False)
    assert read_track_geometry(tmp_path / "half.csv").s.size == d.size
    table["distance_m"] = np.concatenate([d[:10], d[10:] + 0.01])  # one 0.51 m step
    pd.DataFrame(table).to_csv(tmp_path / "wide.csv", index=False)
    with pytest.raises(RailsuspInputError, match="spacing 0.51 m at row 12 exceeds 0.5 m"):
        read_track_geometry(tmp_path / "wide.csv")
