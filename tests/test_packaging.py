"""What an installed railsusp needs beyond the repository: its data files declared as
package data, dependency bounds that admit no version missing a feature the code uses, the
examples the help and docs name reachable by name (the packaging audit of stop 65)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.version import Version

from railsusp.pipeline_config import EXAMPLE_CONFIGS, load_config

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())

#: the oldest release of each library with a feature railsusp uses, and where it uses it:
#: pip kept an older one in an existing environment, and every campaign crashed
NEEDED = {
    "scipy": ("1.15", "qmc.LatinHypercube(rng=...) (campaign/design.py, variation.py)"),
    "pyarrow": ("15", "Parquet page checksums (store.write_parquet, store.read_parquet)"),
    "typer": ("0.16", "0.12-0.15 with click 8.2 or later: every command fails"),
    "llvmlite": ("0.42", "llvmlite.ir (vehicle/vector_math.py), numba 0.59's"),
}


def _lower_bound(name: str) -> Version | None:
    for text in PYPROJECT["project"]["dependencies"]:
        req = Requirement(text)
        if req.name.lower() == name.lower():
            bounds = [Version(s.version) for s in req.specifier if s.operator in (">=", "==")]
            return max(bounds) if bounds else None
    return None


@pytest.mark.parametrize("name", sorted(NEEDED))
def test_no_declared_version_lacks_a_feature_the_code_uses(name):
    needed, why = NEEDED[name]
    declared = _lower_bound(name)
    assert declared is not None, f"{name} is imported but not declared ({why})"
    assert declared >= Version(needed), f"{name}>={declared} admits releases without {why}"


def _pattern(glob: str) -> re.Pattern:
    """A package-data glob as setuptools matches it: ``*`` within one path part."""
    return re.compile("".join("[^/]*" if c == "*" else re.escape(c) for c in glob) + r"\Z")


def test_every_data_file_of_the_package_is_declared_package_data():
    """A file under src/railsusp/data that no package-data pattern matches is missing from
    the wheel: the code opening it works in the repository only."""
    patterns = [_pattern(g) for g in PYPROJECT["tool"]["setuptools"]["package-data"]["railsusp"]]
    package = ROOT / "src" / "railsusp"
    files = [
        p.relative_to(package).as_posix()
        for p in (package / "data").rglob("*")
        if p.is_file() and "__pycache__" not in p.parts
    ]
    assert files
    undeclared = [f for f in files if not any(p.match(f) for p in patterns)]
    assert not undeclared, f"not in the wheel: {undeclared}"


@pytest.mark.parametrize("name", EXAMPLE_CONFIGS)
def test_the_examples_load_by_name_where_no_file_of_that_name_is(tmp_path, monkeypatch, name):
    """An installed railsusp had none of the examples its help names (`railsusp run
    examples/quick.toml`): they ship in the package, and a name reads them."""
    monkeypatch.chdir(tmp_path)
    cfg = load_config(name)
    assert cfg == load_config(ROOT / "examples" / f"{name}.toml")


def test_a_folder_of_an_examples_name_does_not_hide_the_example(tmp_path, monkeypatch):
    """`railsusp run tiny --out tiny` made a folder `tiny`; run again, the name read that
    folder ("configuration tiny is a folder, not a TOML file") instead of the example,
    though only a file of the name takes its place (docs/configuration.md)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tiny").mkdir()
    assert load_config("tiny") == load_config(ROOT / "examples" / "tiny.toml")
