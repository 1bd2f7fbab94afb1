"""Test-suite settings: tests marked ``slow`` are left out of the default run, as the marker
says (pyproject.toml); ``pytest -m slow`` (or any ``-m`` naming it) runs them."""

import pytest


def pytest_collection_modifyitems(config, items):
    if "slow" in (config.getoption("-m") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
