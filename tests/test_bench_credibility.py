"""bench/credibility.py: the irregularity components left out of the gap decomposition, and
the labels of its summary table."""

import numpy as np
import pytest

from conftest import bench_script
from railsusp.conditions import STANDARD_CONDITIONS
from railsusp.vehicle.track import COMPONENTS
from railsusp.vehicle.track_geometry import read_track_geometry
from railsusp.vehicle.track_grid import section_irregularities
from railsusp.vehicle.wagon import load_wagon


@pytest.fixture(scope="module")
def bench():
    return bench_script("credibility")


def test_components_are_parsed_in_the_track_order_and_bad_names_refused(bench):
    assert bench.parse_components("gauge, vertical") == ("vertical", "gauge")
    with pytest.raises(SystemExit, match="accepted a comma-separated subset of vertical"):
        bench.parse_components("vertical,twist")
    with pytest.raises(SystemExit, match="--irregularities"):
        bench.parse_components(" , ")


def test_component_tracks_keep_the_named_components_and_zero_the_others(bench, tmp_path):
    wagon = load_wagon()
    cond = STANDARD_CONDITIONS["straight"].with_changes(irregularity_class=5, duration_s=4.0)
    conds = bench.component_tracks(cond, [3, 4], ("alignment", "gauge"), wagon, tmp_path)
    assert [c.seed for c in conds] == [3, 4]
    for c in conds:
        written = read_track_geometry(c.track_geometry)
        synth = section_irregularities(c.with_changes(track_geometry=None), [c.seed], wagon)
        for name in COMPONENTS:
            got = written.component(name)[0]
            if name in ("alignment", "gauge"):
                assert np.abs(got).max() > 1e-4  # Class 5: millimetres
                np.testing.assert_allclose(got, synth.component(name)[0], atol=1e-9)
            else:
                assert not got.any()
    # the two seeds are two tracks
    a, b = (read_track_geometry(c.track_geometry).alignment for c in conds)
    assert not np.allclose(a, b)


def test_variant_labels_name_what_was_changed(bench):
    assert bench.variant_label({"track_class": 5}) == "as the study (Class 5)"
    label = bench.variant_label(
        {"track_class": 6, "irregularities": ["vertical", "crosslevel"], "friction": 0.2}
    )
    assert label == "class 6, only vertical+crosslevel, mu 0.2"
    assert bench.variant_label({"track_class": 0, "cant_mm": 140.0}) == "perfect, cant 140 mm"
