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

#: the modules with compiled kernels, and the layout they read
KERNEL_SOURCES = (
    "layout.py", "suspension.py", "track_lookup.py", "wheel_rail.py", "model.py",
    "integrate.py", "decay.py", "wheelset.py", "settle.py", "vector_math.py", "contact_batch.py",
    "wedge_batch.py",
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
