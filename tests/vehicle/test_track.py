"""Track input: FRA PSDs, synthesis accuracy, determinism, class ordering, layout geometry."""

import itertools

import numpy as np
import pytest
from scipy.signal import welch

from railsusp.conditions import get_condition
from railsusp.vehicle.track import COMPONENTS, TrackLayout, band_rms, fra_psd, synthesise
from railsusp.vehicle.track_geometry import irregularities_for


@pytest.mark.parametrize(
    ("component", "lam_max", "expected_mm"),
    [  # physics notes: Class 5 over 1-50 m: 5.71 / 3.45 / 4.03 mm; 1-100 m vertical 8.59 mm
        ("vertical", 50, 5.71),
        ("alignment", 50, 3.45),
        ("crosslevel", 50, 4.03),
        ("vertical", 100, 8.59),
    ],
)
def test_class5_band_rms_matches_published_integrals(component, lam_max, expected_mm):
    assert band_rms(component, 5, 1.0, lam_max) * 1e3 == pytest.approx(expected_mm, abs=0.01)


def test_class6_band_rms():
    # physics notes: Class 6 over 1-50 m: 2.30 / 2.30 / 2.41 mm
    got = [band_rms(c, 6, 1.0, 50.0) * 1e3 for c in ("vertical", "alignment", "crosslevel")]
    np.testing.assert_allclose(got, [2.30, 2.30, 2.41], atol=0.01)


def test_psd_rejects_bad_input():
    with pytest.raises(ValueError, match="class 7"):
        fra_psd("vertical", np.array([1.0]), 7)
    with pytest.raises(ValueError, match="unknown irregularity component"):
        fra_psd("twist", np.array([1.0]), 5)


@pytest.fixture(scope="module")
def long_class5():
    return synthesise(40_000.0, 5, 11, wavelength_min=1.0, wavelength_max=120.0)


@pytest.mark.parametrize("component", COMPONENTS)
def test_welch_psd_matches_analytic_in_third_octaves(long_class5, component):
    """Welch PSD of a 40 km realisation vs the FRA PSD, averaged in 1/3-octave bands.

    Tolerance 15 % per band over 1.5-80 m wavelengths (the band edges are excluded because
    the Hann window leaks power across the steep band limits).
    """
    x = long_class5.component(component)[0]
    dx = long_class5.s[1] - long_class5.s[0]
    f, p = welch(x, fs=1 / dx, nperseg=8192)
    omega, s = 2 * np.pi * f, p / (2 * np.pi)
    edges = 2 * np.pi / 80.0 * 2 ** (np.arange(0, 20) / 3)
    edges = edges[edges <= 2 * np.pi / 1.5]
    ratios = []
    for lo, hi in itertools.pairwise(edges):
        sel = (omega >= lo) & (omega < hi)
        ratios.append(s[sel].mean() / fra_psd(component, omega[sel], 5).mean())
    ratios = np.array(ratios)
    assert len(ratios) >= 15
    assert np.all(np.abs(ratios - 1) < 0.15), ratios


def test_variance_equals_band_integral(long_class5):
    for comp in COMPONENTS:
        rms = long_class5.component(comp)[0].std()
        assert rms == pytest.approx(band_rms(comp, 5, 1.0, 120.0), rel=0.08)


def test_class_ordering_class6_smoother_than_class4():
    smooth = synthesise(5000.0, 6, 3)
    rough = synthesise(5000.0, 4, 3)
    for comp in COMPONENTS:
        assert smooth.component(comp).std() < 0.6 * rough.component(comp).std(), comp


def test_determinism_and_independence_of_seeds():
    a = synthesise(500.0, 5, [1, 2])
    b = synthesise(500.0, 5, [2])
    c = synthesise(500.0, 5, [1, 2])
    np.testing.assert_array_equal(a.vertical, c.vertical)
    # a seed gives the same track whatever other seeds are in the call
    np.testing.assert_array_equal(a.vertical[1], b.vertical[0])
    assert not np.allclose(a.vertical[0], a.vertical[1])
    # the four components are independent streams
    assert abs(np.corrcoef(a.vertical[0], a.alignment[0])[0, 1]) < 0.3


def test_rail_combination_convention():
    irr = synthesise(300.0, 5, 0)
    np.testing.assert_allclose(irr.left_vertical - irr.right_vertical, irr.crosslevel)
    np.testing.assert_allclose(irr.left_lateral - irr.right_lateral, irr.gauge)
    np.testing.assert_allclose(0.5 * (irr.left_vertical + irr.right_vertical), irr.vertical)
    at = irr.at(np.array([10.0, 20.0]))
    assert at["zL"].shape == (1, 2)
    assert at["zL"][0, 0] == pytest.approx(np.interp(10.0, irr.s, irr.left_vertical[0]))


def test_synthesis_rejects_bad_arguments():
    with pytest.raises(ValueError, match="wavelength band"):
        synthesise(100.0, 5, 0, wavelength_min=10.0, wavelength_max=5.0)
    with pytest.raises(ValueError, match="length must be positive"):
        synthesise(-1.0, 5, 0)
    with pytest.raises(ValueError, match="non-negative"):
        synthesise(10.0, 5, [-1])


def test_irregularities_cover_the_section_and_trailing_axles():
    cond = get_condition("straight")
    irr = irregularities_for(cond)
    assert irr.s[0] <= -10.1 and irr.s[-1] >= cond.section_length_m
    assert irr.seeds == (cond.seed,)
    assert irregularities_for(cond.with_changes(irregularity_class=None)) is None


def test_layout_spirals_ramp_curvature_and_cant_linearly():
    cond = get_condition("curve")  # spiral 20..80 m, arc after
    lay = TrackLayout.from_condition(cond)
    s = np.array([-5.0, 20.0, 50.0, 80.0, 300.0])
    np.testing.assert_allclose(lay.curvature_at(s), [0, 0, 0.5 / 300, 1 / 300, 1 / 300])
    # left-hand curve: outer (right) rail raised, so left-minus-right cant is negative
    np.testing.assert_allclose(lay.cant_at(s), [0, 0, -0.055, -0.110, -0.110])
    assert lay.cant_angle_at(np.array([300.0]))[0] == pytest.approx(-np.arcsin(0.11 / 1.5))


def test_layout_exit_spiral_and_grade():
    cond = get_condition("curve", arc_length_m=100.0, curve_direction="right")
    lay = TrackLayout.from_condition(cond)
    exit_start = 20 + 60 + 100
    s = np.array([exit_start - 1, exit_start + 30, exit_start + 60, exit_start + 100])
    np.testing.assert_allclose(lay.curvature_at(s), [-1 / 300, -0.5 / 300, 0, 0])
    np.testing.assert_allclose(lay.cant_at(s)[:2], [0.11, 0.055])
    up = TrackLayout.from_condition(get_condition("uphill"))
    np.testing.assert_allclose(up.grade_at(np.array([0.0, 400.0])), 0.012)


def test_synthesised_gauge_stays_within_the_class_safety_limits():
    from railsusp.vehicle.track import GAUGE_KNEE, GAUGE_LIMITS, limit_gauge

    tight, wide = GAUGE_LIMITS[5]
    assert (tight, wide) == (-0.0127, 0.0254)  # 4'8" and 4'9-1/2" against 4'8-1/2"
    g = np.linspace(-0.05, 0.05, 20001)
    lim = limit_gauge(g, 5)
    assert lim.min() > tight and lim.max() < wide
    inside = (g > GAUGE_KNEE * tight) & (g < GAUGE_KNEE * wide)
    np.testing.assert_array_equal(lim[inside], g[inside])  # ordinary gauge untouched
    slope = np.diff(lim) / np.diff(g)
    assert slope.min() > 0.0 and np.abs(np.diff(slope)).max() < 1e-2  # monotonic, smooth
    # a 3.4 km Class 5 realisation: the raw Gaussian synthesis goes beyond -12.7 mm
    irr = synthesise(3400.0, 5, [1, 2, 3, 4])
    assert irr.gauge.min() > tight and irr.gauge.max() < wide
    assert 3.8e-3 < irr.gauge.std() < 4.8e-3  # the spectrum's RMS is barely touched


def test_short_wavelengths_are_not_folded_onto_the_track_grid():
    """With wavelengths down to 0.2 m the grid takes their synthesis spacing (an eighth of
    the shortest): on the solver's 0.125 m grid the power at 0.25-0.33 m came out 39 % high
    (the wavelengths below 0.25 m folded onto it). The default 1 m keeps the 0.125 m grid."""
    from railsusp.conditions import WorkingCondition
    from railsusp.vehicle import layout as L
    from railsusp.vehicle.setup import SolverSettings
    from railsusp.vehicle.track_grid import section_irregularities, track_arrays
    from railsusp.vehicle.wagon import load_wagon

    wagon, settings = load_wagon(), SolverSettings()
    fine = WorkingCondition(speed_kmh=60.0, irregularity_class=5, wavelength_min_m=0.2, seed=1)
    assert track_arrays(WorkingCondition(speed_kmh=60.0), [1], wagon, settings)[2] == 0.125
    trk, s0, ds = track_arrays(fine, [1], wagon, settings)
    assert ds == pytest.approx(0.025)
    irr = section_irregularities(fine, [1], wagon)
    dx = irr.s[1] - irr.s[0]
    s = s0 + ds * np.arange(trk.shape[-1])
    on_grid = trk[0, L.TR_ZL][s > 40.0]
    synth = irr.left_vertical[0][(irr.s > 40.0) & (irr.s < s[-1] - 30.0)]

    def band_power(z, spacing, nperseg):
        f, p = welch(z, fs=1.0 / spacing, nperseg=nperseg)
        band = (f >= 1 / 0.33) & (f < 1 / 0.25)
        return np.trapezoid(p[band], f[band])

    ratio = band_power(on_grid, ds, 4096) / band_power(synth, dx, 4096)
    assert 0.85 < ratio < 1.15
