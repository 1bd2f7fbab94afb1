"""Checks of the ``railsusp posterior`` commands' options beyond their types: the
long-record method, the counts of sections and of their cases, the options that only the
synthetic likelihood reads, and a result file that would replace an input.

Apart from :mod:`railsusp.cli.posterior`, the commands, and
:mod:`railsusp.cli.posterior_tables`, what they print: each check here refuses in one line
naming the option, and calls nothing of the commands."""

from __future__ import annotations

import json
from pathlib import Path

from railsusp.errors import RailsuspInputError


def check_long_record_option(method: str) -> str:
    """``--long-record``: a known method, or a one-line error naming the accepted ones."""
    from railsusp.estimate.posterior_synthetic import check_long_record

    try:
        return check_long_record(method)
    except RailsuspInputError as exc:
        raise RailsuspInputError(str(exc).replace("long_record = ", "--long-record ")) from None


def _span(field: str) -> str:
    """The accepted range of a count of the settings, as the options' help and errors say
    it (:data:`~railsusp.estimate.posterior_settings.POSTERIOR_COUNTS`: one source; read
    when a command runs, as importing the estimation package costs a second at start)."""
    from railsusp.estimate.posterior_settings import POSTERIOR_COUNTS

    low, high = POSTERIOR_COUNTS[field]
    return f"{low} to {high}"


def parse_counts(text: str, option: str = "--product-sections", accepted: str = ""):
    accepted = accepted or _span("product_sections")
    try:
        return tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise RailsuspInputError(
            f"{option} {text}: accepted whole numbers from {accepted}, comma-separated"
        ) from None


def parse_product_cases(text: str) -> dict:
    """``--product-cases``: one count for every number of sections (``n_product``), or one
    per entry of ``--product-sections`` (``product_cases``), so the longest records, the
    costliest to simulate, can be checked on fewer cases."""
    counts = parse_counts(text, "--product-cases", _span("product_cases"))
    if len(counts) == 1:
        return {"n_product": counts[0]}
    return {"product_cases": counts}


def refuse_synthetic_only(projection_rank: int, statistics_emulator_cases: int) -> None:
    """Refuse, in one line, the options that only the synthetic likelihood reads when it is
    not fitted (they were ignored silently, and their values still went into the flows'
    hash: a second run with another value was refused as "other settings")."""
    from railsusp.estimate.posterior_settings import DEFAULT_PROJECTION_RANK

    for option, value, default in (
        ("--projection-rank", projection_rank, DEFAULT_PROJECTION_RANK),
        ("--statistics-emulator-cases", statistics_emulator_cases, 0),
    ):
        if value != default:
            raise RailsuspInputError(
                f"{option} {value}: read by the synthetic likelihood only, which is not "
                "fitted here; accepted with --long-record synthetic-likelihood"
            )


def check_result_file(out: Path, inputs: dict[str, Path]) -> None:
    """Refuse an ``--out`` for a result that lies inside an input folder (it replaced a
    field folder's index.json, a recording, or the estimator's calibration record, and
    every later run then failed) or is an existing file other than a posterior result."""
    target = out.resolve()
    for option, folder in inputs.items():
        if folder.resolve() in target.parents:
            raise RailsuspInputError(
                f"--out {out}: inside {option} {folder}, whose files it would replace; "
                "accepted a file elsewhere"
            )
    if out.is_file():
        try:
            doc = json.loads(out.read_text("utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            doc = None
        if not (isinstance(doc, dict) and doc.get("route") == "posterior"):
            raise RailsuspInputError(
                f"--out {out}: an existing file that is not a posterior result; accepted a "
                "new file or an earlier result to replace"
            )


#: the hint of a recording's wheel load against another wagon's, in the words of the
#: commands that take --wagon (:func:`railsusp.measured.checks.check_forces`)
WAGON_HINT = "; another wagon? give its data (--wagon, or wagon = in a pipeline)"


def read_for_estimator(listed, wagon, estimator: Path) -> list:
    """The recordings ``listed`` (a field folder's index), read as recordings of the wagon
    ``wagon`` the estimator in ``estimator`` simulated (its wheel load). A wheel load that
    says another wagon is refused in one line naming the remedy of ``posterior estimate``,
    which has no --wagon: an estimator trained for that wagon (the reading's hint, "give its
    data (--wagon ...)", named an option the command does not take)."""
    from railsusp.measured import read_recording

    try:
        return [read_recording(p, wagon=wagon) for p in listed]
    except RailsuspInputError as exc:
        message = str(exc)
        if WAGON_HINT not in message:
            raise
        hint = (
            f"; a recording of another wagon than the one --estimator {estimator} was trained "
            "for? train an estimator for its wagon (railsusp posterior train --wagon)"
        )
        raise RailsuspInputError(message.replace(WAGON_HINT, hint)) from None
