"""A Ctrl-C that Python swallowed, remembered until the next checkpoint.

Python raises a Ctrl-C's KeyboardInterrupt wherever the main thread is; raised inside a
garbage-collector or weakref callback it is printed ("Exception ignored in: ...") and lost,
and ``railsusp run`` went on to finish every stage. The command line's SIGINT handler
(:func:`catch_interrupts`) records each Ctrl-C here before raising it as Python's own
handler does, and :func:`stop_if_interrupted` is called where stopping loses nothing: the
pipeline's stage boundaries, and inside the long stages each stored campaign or twin batch,
cached posterior chunk and training epoch (its checkpoint written), and each NSGA-II
generation (an estimate is not resumed, so nothing is kept of it either way). A swallowed
Ctrl-C stops the command there, with the usual "interrupted" line and exit 130.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from types import FrameType

#: a plain flag, not a threading.Event: the signal handler runs between bytecodes of the
#: main thread, and an Event's set() would wait on the lock a clear() there holds
_recorded = [False]


def record_interrupt() -> None:
    """Remember a Ctrl-C (the handler's first step; tests call it to swallow one)."""
    _recorded[0] = True


def forget_interrupt() -> None:
    """Forget a recorded Ctrl-C (a command's start and end)."""
    _recorded[0] = False


def stop_if_interrupted() -> None:
    """Raise KeyboardInterrupt where a Ctrl-C was recorded and not yet forgotten: the one
    raised may have been swallowed."""
    if _recorded[0]:
        raise KeyboardInterrupt


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    """SIGINT: recorded, then raised as KeyboardInterrupt, as Python's own handler does."""
    record_interrupt()
    signal.default_int_handler(signum, frame)


def catch_interrupts() -> Callable[[], None]:
    """Install the recording SIGINT handler for one command; returns the function that puts
    the previous handler back and forgets any record (a command run in-process, by a test
    runner, leaves the process as it found it). Installed only in the main thread and over
    Python's own handler: a process that ignores SIGINT (started in the background by a
    shell) or handles it otherwise keeps that."""
    forget_interrupt()
    in_main = threading.current_thread() is threading.main_thread()
    if not in_main or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        return forget_interrupt
    previous = signal.signal(signal.SIGINT, _on_sigint)

    def restore() -> None:
        signal.signal(signal.SIGINT, previous)
        forget_interrupt()

    return restore
