"""Files saved by Windows editors start with a UTF-8 byte-order mark. docs/run-directory.md
promises that railsusp reads such JSON wherever it reads JSON; before stop 57 a measured
folder's index and sidecars were refused ("not valid JSON (Unexpected UTF-8 BOM ...)"), and
TOML files (configurations, wagon files, channel maps) were refused as "not valid TOML"."""

from __future__ import annotations

from pathlib import Path

import pytest

from railsusp.conditions import get_condition
from railsusp.measured import read_field, synthesise_field
from railsusp.params import ParameterSet
from railsusp.pipeline import load_config
from railsusp.vehicle.wagon import load_wagon

BOM = b"\xef\xbb\xbf"
TINY = Path(__file__).resolve().parents[1] / "examples" / "tiny.toml"


def with_bom(path: Path) -> None:
    path.write_bytes(BOM + path.read_bytes())


@pytest.fixture
def field(tmp_path) -> Path:
    cond = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    return synthesise_field(ParameterSet({"X13": 16.1}, units="display"), [cond], tmp_path / "f")


def test_a_measured_folder_whose_json_files_start_with_a_bom(field):
    before = read_field(field)
    with_bom(field / "index.json")
    with_bom(field / "straight.json")
    (after,) = read_field(field)
    assert after.condition == before[0].condition
    assert after.meta == before[0].meta


def test_toml_files_that_start_with_a_bom(tmp_path):
    cfg = tmp_path / "tiny.toml"
    cfg.write_bytes(BOM + TINY.read_bytes())
    assert load_config(cfg) == load_config(TINY)
    from importlib import resources

    wagon = tmp_path / "w.toml"
    wagon.write_bytes(BOM + resources.files("railsusp").joinpath("data/c80_k6.toml").read_bytes())
    assert load_wagon(wagon) == load_wagon()
