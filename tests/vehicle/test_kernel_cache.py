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


def test_every_module_holding_a_compiled_kernel_keys_the_cache():
    """A kernel whose module is not in KERNEL_SOURCES would be read back from Numba's cache
    after its source changed (the cache folder would not move): every vehicle module with
    an ``njit``-decorated function is listed (decay.py's kernel moved to decay_runs.py in
    stop 67, and the list moved with it)."""
    import ast

    here = Path(railsusp.vehicle.model.__file__).parent
    compiled = set()
    for path in here.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and any(
                "jit" in ast.unparse(d) for d in node.decorator_list
            ):
                compiled.add(path.name)
    assert compiled and compiled <= set(KERNEL_SOURCES), sorted(compiled - set(KERNEL_SOURCES))
