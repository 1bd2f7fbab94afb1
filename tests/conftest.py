"""Test-suite settings: tests marked ``slow`` are left out of the default run, as the marker
says (pyproject.toml); ``pytest -m slow`` (or any ``-m`` naming it) runs them. Tests of a
bench script load it with :func:`bench_script` (bench/ is not a package); the fixture
``integrator_calls`` counts the simulator's parallel calls."""

import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

import pytest


def _a_share_of_the_cores() -> None:
    """In a pytest-xdist worker, the thread pools of BLAS, OpenMP (torch) and Numba get the
    worker's share of the cores, unless the environment says otherwise. Each worker's pools
    took every core: on the 2-core CI machine two workers ran four threads, whose spinning
    waits made the suite 1.4 times slower (534 s against 382 s, one sitting). Set before
    numpy, torch or numba is imported, as they read it then."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0") or 0)
    if workers < 2:
        return
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    share = str(max(1, (cores or 1) // workers))
    for pool in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ.setdefault(pool, share)


_a_share_of_the_cores()


def _ctrl_c_as_a_terminal_gives_it() -> None:
    """Ctrl-C as a terminal's foreground job gets it, even where the suite runs as a
    background job: a non-interactive shell starts those with SIGINT ignored, which their
    children inherit and Python then leaves ignored. The tests of what a Ctrl-C does (the
    console script, a local Dask cluster, the command's handler) then saw none arrive, five
    failures of a suite started with ``nohup ... &`` at stop 76. Python's own handler here;
    a child exec'd from this process starts with the default action again."""
    import signal

    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


_ctrl_c_as_a_terminal_gives_it()

BENCH = Path(__file__).resolve().parents[1] / "bench"


def bench_script(name: str) -> ModuleType:
    """The script bench/NAME.py as a module (its ``main`` not run). bench/ is on the import
    path while it loads, so that its imports of sibling scripts (``from estimate_tracks
    import ...``, as the scripts run from bench/ do) resolve; the path is restored after."""
    # registered under a name no library module has, so that a script's dataclasses (which
    # look their module up in sys.modules) can be built
    spec = importlib.util.spec_from_file_location(f"_bench_{name}", BENCH / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    sys.path.insert(0, str(BENCH))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCH))
    return module


@pytest.fixture
def integrator_calls(monkeypatch) -> list[int]:
    """The parameter sets of each call of the compiled integrator while the test runs
    (``railsusp.vehicle.integrate.integrate_batch``, which every simulation goes through):
    how a test sees which simulations share a parallel call."""
    import railsusp.vehicle.integrate as integrate

    sizes: list[int] = []
    inner = integrate.integrate_batch

    def counted(P, *args):
        sizes.append(P.shape[0])
        return inner(P, *args)

    monkeypatch.setattr(integrate, "integrate_batch", counted)
    return sizes


def pytest_collection_modifyitems(config, items):
    if "slow" in (config.getoption("-m") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


def harmonic_drive(amplitude: float, n: int = 4000, cycles: int = 2):
    """Steps of a harmonic drive x = A sin(2 pi t) at 1 Hz over ``cycles`` periods in ``n``
    explicit-Euler steps: yields (dt, x, dx/dt, in the last cycle) for hysteresis loops."""
    import math

    omega = 2.0 * math.pi
    dt = cycles / n
    for i in range(n):
        t = i * dt
        yield (
            dt,
            amplitude * math.sin(omega * t),
            amplitude * omega * math.cos(omega * t),
            i >= n - n // cycles,
        )


def family_campaign(
    out: Path,
    keys: tuple[str, ...],
    condition,
    samples: int = 12,
    seed: int = 3,
    cant_mm: tuple[float, float] | None = (0, 100),
) -> Path:
    """A tiny many-track campaign into ``out``: ``samples`` samples of ``keys`` by LHS, each
    on its own track of the FRA 4-6, R250-400 m, cant 0-100 mm family, the other
    main-suspension parameters varied over their ranges (what twins are made of); another
    ``seed``: other tracks and parameter sets; ``cant_mm`` None: the cant not varied (no
    cant channel in the networks' features)."""
    from railsusp.campaign import make_config, run_campaign
    from railsusp.variation import full_ranges

    family = {"irregularity_classes": (4, 6), "curve_radius_m": (250.0, 400.0)}
    if cant_mm is not None:
        family["cant_mm"] = cant_mm
    cfg = make_config(
        [condition],
        samples,
        parameters=keys,
        seed=seed,
        batch_size=samples // 2,
        independent_seeds=True,
        track_family=family,
        other_parameters=full_ranges(keys),
    )
    run_campaign(cfg, out)
    return out


@pytest.fixture
def trained_epochs(monkeypatch):
    """The epochs each training actually runs (a resumed one: those after its checkpoint),
    counted: a fresh training gives the same numbers as a resumed one (training is bitwise
    deterministic), so only this tells that a resume resumed."""
    import railsusp.surrogate.train as train_mod

    count = [0]
    real = train_mod._train_epoch

    def epoch(*args):
        count[0] += 1
        return real(*args)

    monkeypatch.setattr(train_mod, "_train_epoch", epoch)

    def take() -> int:
        n, count[0] = count[0], 0
        return n

    return take
