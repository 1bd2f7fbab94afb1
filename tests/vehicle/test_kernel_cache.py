"""The compiled kernels' cache is keyed by their sources (Numba alone would keep running an
integrator compiled against an older model or state layout)."""

import os
import shutil
from pathlib import Path

import numba
import pytest

import railsusp.vehicle.model
from railsusp.vehicle.kernel_cache import KERNEL_SOURCES, kernel_cache_dir


def test_cache_folder_changes_with_any_kernel_source(tmp_path):
    here = Path(railsusp.vehicle.model.__file__).parent
    copy = tmp_path / "vehicle"
    copy.mkdir()
    for name in KERNEL_SOURCES:
        shutil.copy(here / name, copy / name)
    assert kernel_cache_dir(copy) == kernel_cache_dir()
    for name in ("layout.py", "model.py"):
        changed = tmp_path / f"changed-{name}"
        shutil.copytree(copy, changed)
        (changed / name).write_text((copy / name).read_text() + "\n# changed\n")
        assert kernel_cache_dir(changed) != kernel_cache_dir()


@pytest.mark.skipif("NUMBA_CACHE_DIR" in os.environ, reason="the user chose the folder")
def test_numba_caches_the_kernels_in_that_folder():
    assert numba.config.CACHE_DIR == str(kernel_cache_dir())
