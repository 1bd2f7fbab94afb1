"""Running stability after a lateral kink on ideal straight track (critical speed).

bench/critical_speed.py finds the nonlinear critical speeds (2026-11-24: tare 112 km/h,
bogie hunting at 1.9-2.0 Hz; loaded none up to 200 km/h); these checks pin the two sides of
it with a margin, so that a model change that destabilises the loaded wagon at its running
speed, or that makes the empty wagon stable far above the published empty-car hunting
speeds of three-piece bogies, fails here.
"""

import numpy as np
import pytest

from railsusp.vehicle.stability import (
    DECAY_RATIO,
    kink_response,
    write_kink_geometry,
)
from railsusp.vehicle.track import read_track_geometry
from railsusp.vehicle.wagon import load_wagon


def test_kink_geometry_is_one_alignment_wave_on_ideal_track(tmp_path):
    irr = read_track_geometry(write_kink_geometry(tmp_path / "k.csv", 300.0, 10.0, 0.010))
    assert irr.alignment.max() == pytest.approx(0.010, abs=1e-6)
    bump = irr.alignment[0] > 1e-9
    assert irr.s[bump].min() == pytest.approx(5.0, abs=0.3)
    assert irr.s[bump].max() == pytest.approx(15.0, abs=0.3)
    for other in (irr.vertical, irr.crosslevel, irr.gauge):
        assert not np.any(other)
    # covers every axle over the record, with the 10 m fade-in behind the trailing one
    assert irr.s[0] <= -(10.0 + 10.0) and irr.s[-1] > 300.0


def test_loaded_wagon_kink_response_decays_at_60_kmh():
    r = kink_response(load_wagon(), 60.0)
    assert r.ok and r.decays
    assert r.ratio < DECAY_RATIO


def test_tare_wagon_kink_response_dies_out_at_80_kmh():
    r = kink_response(load_wagon("tare"), 80.0)
    assert r.ok and r.decays
    assert r.rms_last < 20.0  # N: friction has stopped it


def test_loaded_wagon_hunts_well_above_its_critical_speed():
    """185 km/h, about 1.2 x the loaded wagon's critical speed after a 10 mm kink (157 km/h,
    bench/critical_speed.py, 2026-11-24): a sustained limit cycle of the leading wheelset
    (ΣY of kilonewtons at the bogie's hunting frequency), not a decay. (The tare wagon no
    longer hunts below 200 km/h since the friction wedges and the bowl's yaw friction.)"""
    r = kink_response(load_wagon(), 185.0)
    assert r.ok and not r.decays
    assert r.amplitude_last > 1000.0
    assert 1.0 < r.frequency_hz < 6.0


def test_kink_response_needs_two_windows():
    with pytest.raises(ValueError, match="duration_s = 10: at least 15 s"):
        kink_response(load_wagon(), 60.0, duration_s=10.0)
