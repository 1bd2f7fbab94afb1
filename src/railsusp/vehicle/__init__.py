"""The vehicle-track dynamics model: track input, contact, equations, simulation.

Compiled kernels are cached on disk by Numba (``cache=True``). Numba invalidates a cached
function only when its own source file changes, not when a function it calls or a
module-level constant it reads (the state layout) changes in another file: after an update of
the model, the integrator's cache would run the old equations. So the kernels of this
package are cached in a folder named after a hash of the package's sources (unless the user
set NUMBA_CACHE_DIR), and any change of the model compiles afresh.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path


def _kernel_cache_dir() -> str:
    here = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for src in sorted(here.glob("*.py")):
        digest.update(src.name.encode())
        digest.update(src.read_bytes())
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return str(Path(base) / "railsusp" / f"numba-{digest.hexdigest()[:16]}")


if "NUMBA_CACHE_DIR" not in os.environ:
    import numba

    numba.config.CACHE_DIR = _kernel_cache_dir()
