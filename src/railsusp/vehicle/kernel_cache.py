"""Where the compiled kernels are cached, keyed by their sources.

Numba caches a compiled function (``cache=True``) and invalidates it only when the
function's own file changes, not when a function it calls or a module-level constant it
reads (the state layout) changes in another file: after an update of the model, the
integrator's cache would run the old equations. Every kernel module imports this module
first; unless the user set NUMBA_CACHE_DIR, it points Numba's cache at a folder named after a
hash of the kernel sources, so that any change of them compiles afresh.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path


def _has_option(name: str) -> bool:
    """Whether this Numba's ``njit`` takes the option ``name``."""
    from numba.core.options import DefaultOptions

    return hasattr(DefaultOptions, name)


#: the fast-math flags every kernel compiles with (issue 24): floating-point contraction
#: (a * b + c as one fused multiply-add), division as multiplication by the reciprocal
#: (``arcp``; constant divisors fold to one multiplication) and no signed zeros (``nsz``).
#: Not ``nnan``/``ninf``: with them LLVM may assume no NaN or infinity and fold away what the
#: integrator's finiteness check and the failure codes rely on; here NaN and infinity
#: propagate as in IEEE arithmetic. Not ``reassoc`` (the sums reordered moved the forces by
#: 3e-4 of the largest, and gained 1 %) nor ``afn`` (no gain). Measured: one right-hand-side
#: evaluation 1.14 times as fast, forces within 3.2e-13 of the largest of the bit-exact
#: kernels' over 10 s (bench/README.md, "Fast-math flags"; tests/vehicle/test_force_reference.py
#: asserts 1e-9). Numba takes a ``set``: never modify this one.
FASTMATH = {"contract", "arcp", "nsz"}

#: the right-hand side's kernels (the modules of :data:`NO_RUNTIME_SOURCES`) compile without
#: Numba's runtime (``_nrt=False``, an option of numba.core.options that Numba's own
#: kernels use): they allocate nothing, and with the runtime every array they passed to a
#: kernel not inlined, or sliced, was reference counted (NRT_incref / NRT_decref, a locked
#: add each, 31 call sites in ``rhs`` alone). Without it: the same forces bit for bit, one
#: evaluation 1.2-1.3 times as fast (bench/README.md, "Without Numba's runtime"; stop 76).
#: A kernel here that allocated fails to compile, not misbehave. The integrator's steps
#: (``integrate._steps``, ``_rk4_finish``: row views of the stage derivatives, a call of
#: the right-hand side per stage) compile with it too; what allocates keeps the runtime.
#: None of them returns an array, nor may one: without the runtime an array handed back
#: (even in a tuple) has no reference of its own, a double free where the caller counts
#: (read through at stop 76's review; they return codes, scalars and tuples of scalars).
#: Splatted into the decorators, and empty on a Numba without the option (the kernels then
#: compile with the runtime, slower but alike, instead of failing to compile).
NO_RUNTIME: dict[str, bool] = {"_nrt": False} if _has_option("_nrt") else {}

#: the modules whose kernels compile with :data:`NO_RUNTIME` (allocating nothing)
NO_RUNTIME_SOURCES = (
    "model.py", "body_bolster.py", "contact_batch.py", "wedge_batch.py", "suspension.py",
    "track_lookup.py", "wheel_rail.py", "normal_contact.py", "vector_math.py",
)  # fmt: skip

#: the modules with compiled kernels, the layout they read, and this one (the flags above)
KERNEL_SOURCES = (
    "kernel_cache.py", "layout.py", "suspension.py", "track_lookup.py", "wheel_rail.py", "model.py",
    "integrate.py", "decay_runs.py", "wheelset.py", "settle.py", "vector_math.py",
    "contact_batch.py", "wedge_batch.py", "body_bolster.py", "normal_contact.py",
)  # fmt: skip


def kernel_cache_dir(sources: Path | None = None) -> Path:
    """The cache folder of this version of the kernels (under XDG_CACHE_HOME or ~/.cache);
    ``sources``: the folder of the kernel modules (this package's by default)."""
    here = Path(__file__).resolve().parent if sources is None else Path(sources)
    digest = hashlib.sha256()
    for name in KERNEL_SOURCES:
        digest.update(name.encode())
        digest.update((here / name).read_bytes())
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "railsusp" / f"numba-{digest.hexdigest()[:16]}"


if "NUMBA_CACHE_DIR" not in os.environ:
    import numba

    numba.config.CACHE_DIR = str(kernel_cache_dir())
