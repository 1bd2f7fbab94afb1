"""The test suite's own setting (tests/conftest.py): each pytest-xdist worker's thread pools
get its share of the cores, so that two workers on two cores do not run four threads."""

import os

import numba
import pytest

from conftest import _a_share_of_the_cores

POOLS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


@pytest.mark.parametrize(("cores", "workers", "share"), [(2, 2, "1"), (8, 2, "4"), (3, 4, "1")])
def test_a_worker_gets_its_share_of_the_cores(monkeypatch, cores, workers, share):
    for pool in POOLS:
        monkeypatch.delenv(pool, raising=False)
    monkeypatch.setenv("PYTEST_XDIST_WORKER_COUNT", str(workers))
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(cores)), raising=False)
    _a_share_of_the_cores()
    assert [os.environ[p] for p in POOLS] == [share] * 4


def test_a_stated_pool_size_and_a_single_process_are_left_alone(monkeypatch):
    for pool in POOLS:
        monkeypatch.delenv(pool, raising=False)
    monkeypatch.setenv("NUMBA_NUM_THREADS", "3")
    monkeypatch.setenv("PYTEST_XDIST_WORKER_COUNT", "2")
    _a_share_of_the_cores()
    assert os.environ["NUMBA_NUM_THREADS"] == "3"
    monkeypatch.delenv("PYTEST_XDIST_WORKER_COUNT")
    monkeypatch.delenv("OMP_NUM_THREADS")
    _a_share_of_the_cores()
    assert "OMP_NUM_THREADS" not in os.environ


def test_this_worker_runs_numba_on_its_share():
    """In the suite run as `make test` runs it (two workers on the 2-core machine), Numba's
    pool here is the share the setting gave, read at Numba's import."""
    if "PYTEST_XDIST_WORKER_COUNT" not in os.environ:
        pytest.skip("not a pytest-xdist worker")
    assert numba.config.NUMBA_NUM_THREADS == int(os.environ["NUMBA_NUM_THREADS"])
