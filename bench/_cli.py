"""The bench scripts' command line: bad input as one line on stderr, exit status 2.

A script ends with ``run_main(main)`` instead of ``main()``. The library's input errors
(:class:`railsusp.errors.RailsuspInputError`) and missing files then print
``error: MESSAGE`` (one line) and exit 2, as the railsusp command line
does, instead of a traceback with exit 1; a script's own ``sys.exit("error: ...")`` exits 2
too (Python exits 1 on a message). The argparse types below refuse a bad count or list while
the arguments are parsed, naming the option, so that nothing runs before the input is known
to be good.

Every script builds its parser with :func:`parser`: its refusals (a bad option, a type's
refusal, the script's own ``ap.error``) are the same one line ``error: ...`` with exit 2,
not argparse's usage lines and ``prog: error: ...`` (bench/README.md promises one line), and
its ``--help`` description is the docstring's whole first paragraph (its first line alone
stopped mid-sentence).

It imports nothing of railsusp: reference_run.py runs today's scripts on another
checkout's ``src``, whose package may differ.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import NoReturn


def one_line(text: object) -> str:
    """``text`` with its line breaks and runs of blanks as single spaces."""
    return " ".join(str(text).split())


def fail(message: object) -> NoReturn:
    """Print ``error: MESSAGE`` (one line) on stderr and exit 2."""
    text = one_line(message).removeprefix("error:").strip()
    print(f"error: {text}", file=sys.stderr)
    sys.exit(2)


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser whose refusals are one line, ``error: MESSAGE``, and exit 2."""

    def error(self, message: str) -> NoReturn:
        """Refuse the command line as :func:`fail` does (no usage lines, no prog prefix)."""
        fail(message)


def first_paragraph(doc: str | None) -> str:
    """The first paragraph of a docstring (up to its first blank line), as one line."""
    return one_line((doc or "").strip().split("\n\n")[0])


def parser(doc: str | None, whole: bool = False, **kwargs: object) -> ArgumentParser:
    """A script's parser (:class:`ArgumentParser`), described by its docstring ``doc``: the
    first paragraph, or with ``whole`` all of it (argparse wraps it as one paragraph)."""
    description = doc if whole else first_paragraph(doc)
    return ArgumentParser(description=description, **kwargs)


def _bad_input(exc: BaseException) -> bool:
    """Whether ``exc`` says the input is bad: railsusp's input error (told by its class's
    name, not imported: module docstring) or a missing file. Any other error, a ValueError
    of NumPy's or pandas' among them, is a fault that keeps its traceback (the review of
    stop 65: they read as bad input, exit 2, their place lost)."""
    names = {cls.__name__ for cls in type(exc).__mro__}
    return "RailsuspInputError" in names or isinstance(exc, FileNotFoundError)


def run_main(main: Callable[[], object]) -> None:
    """Run a script's ``main()``; bad input (railsusp's input errors, a missing file, a
    message given to ``sys.exit``) ends it with :func:`fail`, and an int it returns is its
    exit status."""
    try:
        result = main()
    except SystemExit as exc:
        if isinstance(exc.code, str):
            fail(exc.code)
        raise
    except (ValueError, FileNotFoundError) as exc:
        if not _bad_input(exc):
            raise
        fail(exc)
    if isinstance(result, int) and not isinstance(result, bool):
        sys.exit(result)


def _whole(text: str, accepted: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: accepted {accepted}") from None


def positive_int(text: str) -> int:
    """argparse type: a whole number 1 or more (a count of sets, samples, threads...)."""
    value = _whole(text, "a whole number 1 or more")
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value}: accepted a whole number 1 or more")
    return value


def non_negative_int(text: str) -> int:
    """argparse type: a whole number 0 or more (a limit where 0 means none)."""
    value = _whole(text, "a whole number 0 or more")
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value}: accepted a whole number 0 or more")
    return value


def _finite(text: str, accepted: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: accepted {accepted}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text}: accepted {accepted}")
    return value


def non_negative_float(text: str) -> float:
    """argparse type: a finite number 0 or more (a noise level, a tolerance)."""
    value = _finite(text, "a finite number 0 or more")
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value:g}: accepted a finite number 0 or more")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number above 0 (a length, a duration, a step)."""
    value = _finite(text, "a finite number above 0")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{value:g}: accepted a finite number above 0")
    return value


def number_list(kind: Callable[[str], float | int]) -> Callable[[str], list]:
    """argparse type of a comma-separated list, each item of the argparse type ``kind``
    (e.g. :func:`positive_int`); at least one item."""

    def parse(text: str) -> list:
        items = [t.strip() for t in text.split(",") if t.strip()]
        if not items:
            raise argparse.ArgumentTypeError(f"{text!r}: accepted a comma-separated list")
        try:
            return [kind(t) for t in items]
        except argparse.ArgumentTypeError as exc:
            raise argparse.ArgumentTypeError(f"{text!r}: item {exc}") from None

    parse.__name__ = f"list of {getattr(kind, '__name__', 'number')}"
    return parse
