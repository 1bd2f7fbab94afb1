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


def test_the_right_hand_sides_kernels_compile_without_numbas_runtime():
    """With Numba's runtime every array the right-hand side passed to a kernel not inlined,
    or sliced, was reference counted (a locked add each way; 31 call sites in ``rhs``):
    its kernels allocate nothing and compile without it (1.2-1.3 times as fast an
    evaluation, the same forces bit for bit). Each of their modules' kernels says so, and
    the compiled code of one that passes an array on holds no reference count."""
    import importlib
    import re

    from numba.core.registry import CPUDispatcher

    from railsusp.vehicle.kernel_cache import NO_RUNTIME, NO_RUNTIME_SOURCES

    assert NO_RUNTIME == {"_nrt": False}  # (this Numba takes the option)
    for name in NO_RUNTIME_SOURCES:
        module = importlib.import_module(f"railsusp.vehicle.{name.removesuffix('.py')}")
        kernels = [
            f
            for f in vars(module).values()
            if isinstance(f, CPUDispatcher) and f.py_func.__module__ == module.__name__
        ]
        assert kernels, name
        for f in kernels:
            assert f.targetoptions.get("_nrt") is False, f"{name}: {f.py_func.__name__}"
    from railsusp.vehicle import integrate

    for f in (integrate._steps, integrate._rk4_finish):  # the integrator's steps
        assert f.targetoptions.get("_nrt") is False, f.py_func.__name__
    from railsusp.vehicle.wedge_batch import wedge_forces

    # a fresh copy compiled with the kernel's options (a cached kernel shows no code); with
    # the runtime, its call of _column_faces with the work vector holds an NRT_incref
    skip = ("cache", "nopython")
    options = {k: v for k, v in wedge_forces.targetoptions.items() if k not in skip}
    fresh = numba.njit(**options)(wedge_forces.py_func)
    sig = (numba.float64[::1], *([numba.float64] * 9))
    fresh.compile(sig)
    functions = re.split(r"\ndefine ", fresh.inspect_llvm(sig))[1:]
    own = [f for f in functions if re.match(r"[^\n(]*@_ZN[^\n(]*wedge_forces", f)]
    assert own and not any("NRT_incref" in f for f in own)
