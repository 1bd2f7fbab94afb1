"""Independent solvers run in step, so that their simulations reach the simulator together.

The simulator runs the parameter sets of one call in parallel, one per core
(:func:`~railsusp.vehicle.simulate.simulate_batch`), so a solver that asks for one set at a
time (a least-squares trial point) leaves the other cores idle. :class:`Lockstep` runs several
independent solvers (the refinement's starts), each in its own thread; a solver's request
waits until every solver still running has made one, and then one call serves them all.
Where the simulations are independent per set, every solver gets the numbers it would get
alone: only the grouping of the simulations changes, not the method.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

Item = TypeVar("Item")
Out = TypeVar("Out")


class Lockstep(Generic[Item]):
    """Gathers the requests of the solvers that :meth:`run` runs into one call of ``serve``.

    ``serve(items)`` does the work of every item (a batch of parameter sets to simulate) and
    keeps the results where the solvers find them (a cache); :meth:`request` returns once
    its item is served, raising what ``serve`` raised. Outside :meth:`run` a request is
    served at once, alone. ``batches`` records how many items each call of ``serve`` got."""

    def __init__(self, serve: Callable[[list[Item]], None]):
        self._serve = serve
        self._cv = threading.Condition()
        self._live = 0  # solvers of the current run still running
        self._pending: list[Item] = []  # requests of the round being gathered
        self._round = 0
        self._errors: dict[int, BaseException] = {}
        self.batches: list[int] = []

    def request(self, item: Item) -> None:
        """Have ``item`` served, together with the requests of the other running solvers."""
        with self._cv:
            if self._live == 0:  # no solvers in step: serve at once
                self._serve_now([item])
                return
            ticket = self._round
            self._pending.append(item)
            self._serve_if_gathered()
            while self._round == ticket:
                self._cv.wait()
            error = self._errors.get(ticket)
        if error is not None:
            raise error

    def run(self, solvers: Sequence[Callable[[], Out]]) -> list[Out]:
        """Run the ``solvers`` in step, one thread each, and return their results in order;
        the first solver error is raised once all have stopped. A solver that finishes
        early leaves the others to go on in step without it."""
        with self._cv:
            if self._live:
                raise RuntimeError("Lockstep.run is already running")
            self._live = len(solvers)
            self._errors.clear()
        results: list = [None] * len(solvers)
        errors: list[BaseException | None] = [None] * len(solvers)
        threads_of_caller = _numba_threads()

        def work(i: int) -> None:
            _set_numba_threads(threads_of_caller)  # the setting is per thread in Numba
            try:
                results[i] = solvers[i]()
            except BaseException as exc:  # handed to the caller below
                errors[i] = exc
            finally:
                with self._cv:
                    self._live -= 1
                    self._serve_if_gathered()

        threads = [
            threading.Thread(target=work, args=(i,), name=f"railsusp-solver-{i}", daemon=True)
            for i in range(len(solvers))
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        for exc in errors:
            if exc is not None:
                raise exc
        return results

    def _serve_if_gathered(self) -> None:
        """Serve the pending requests once every running solver has made one (lock held)."""
        if not self._pending or len(self._pending) < self._live:
            return
        items, self._pending = self._pending, []
        try:
            self._serve_now(items)
        except BaseException as exc:  # every solver of the round sees it
            self._errors[self._round] = exc
        finally:
            self._round += 1
            self._cv.notify_all()

    def _serve_now(self, items: list[Item]) -> None:
        self.batches.append(len(items))
        self._serve(items)


def _numba_threads() -> int | None:
    """The caller's Numba thread count, where Numba is loaded (None otherwise)."""
    numba = sys.modules.get("numba")
    return None if numba is None else int(numba.get_num_threads())


def _set_numba_threads(n: int | None) -> None:
    if n is not None:
        sys.modules["numba"].set_num_threads(n)
