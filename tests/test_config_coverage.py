"""A condition's measured track geometry is checked to cover its record under every axle by
the configuration check, before any stage runs: the campaign stage found it after the check
had passed (the rerun audit of stop 65)."""

from __future__ import annotations

import pandas as pd
import pytest

from railsusp.conditions import get_condition
from railsusp.config import ConfigError
from railsusp.pipeline import load_config
from railsusp.vehicle.track_geometry import write_track_geometry
from railsusp.vehicle.track_grid import section_irregularities
from railsusp.vehicle.wagon import load_wagon


def _config(tmp_path, keep_to_m: float | None = None, lead_in_m: float = 20.0):
    base = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    irr = section_irregularities(base, [base.seed], load_wagon())
    geo = write_track_geometry(tmp_path / "track.csv", irr, origin_m=base.lead_in_m)
    if keep_to_m is not None:  # the file cut short of the record's end
        table = pd.read_csv(geo)
        table[table.distance_m <= keep_to_m].to_csv(geo, index=False)
    cfg = tmp_path / "c.toml"
    cfg.write_text(
        f'conditions = [{{base = "straight", name = "short", duration_s = 1.0, n_steps = 50, '
        f'lead_in_m = {lead_in_m}, track_geometry = "{geo}"}}]\n'
        "[field]\ntruth = { X13 = 16.1 }\nwith_track = true\n"
    )
    return cfg


def test_a_covering_file_passes(tmp_path):
    assert load_config(_config(tmp_path)).conditions


def test_a_file_short_of_the_record_is_refused_before_any_stage(tmp_path):
    # the record is 1 s at 60 km/h: 16.7 m; the file ends at 10 m
    with pytest.raises(ConfigError, match=r"conditions: track geometry file .* covers "):
        load_config(_config(tmp_path, keep_to_m=10.0))


def test_a_lead_in_shorter_than_the_axle_spread_is_refused_before_any_stage(tmp_path):
    with pytest.raises(ConfigError, match="lead_in_m = 5 m with measured track geometry"):
        load_config(_config(tmp_path, lead_in_m=5.0))
