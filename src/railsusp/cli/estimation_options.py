"""The ``estimate`` command's options beyond their ranges: the estimator's settings named as
the options in its errors and warnings, ``--held-prior`` read and checked against the
estimated parameters, an input's error led by the option that gave it, and the campaign a
``--surrogate`` folder belongs to (held while the estimate reads it), and the line an
interrupted estimate ends with.

Apart from :mod:`railsusp.cli.estimation`, which holds the ``estimate`` command itself (its
options, their defaults and the run of the route), so that the command module is the
command; these helpers call one another and :mod:`railsusp.cli.common`, never back into it."""

from __future__ import annotations

import re
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from railsusp.cli.common import err_console, option_names
from railsusp.errors import RailsuspInputError

#: the estimator's settings -> the options of ``estimate``, for its error messages and
#: warnings (:func:`option_text`)
_ESTIMATE_OPTIONS = {
    "weighting": "--weighting",
    "statistic": "--statistic",
    "parameters": "--parameters",
    "channel_gains": "--channel-gains",
    "expected_draws": "--expected-draws",
    "expected_generations": "--expected-generations",
    "preview_generations": "--preview-generations",
    "preview_s": "--preview-s",
    "n_gen": "--n-gen",
    "held_prior": "--held-prior",
    "geometry_draws": "--geometry-draws",
    "simulator_corrections": "--simulator-corrections",
    "correction_slopes": "--correction-slopes",
}


def option_text(message: str) -> str:
    """``message`` with the estimator's settings named as the options of ``estimate``:
    ``setting = value`` anywhere and ``setting`` at its start
    (:func:`~railsusp.cli.common.option_names`), and a setting spelt with an underscore
    (``expected_draws``, which is no English word) anywhere else too, where ``--expected-draws``
    is what the user typed."""
    message = option_names(message, _ESTIMATE_OPTIONS)
    for setting, option in _ESTIMATE_OPTIONS.items():
        if "_" in setting:
            message = re.sub(rf"(?<![\w./-]){setting}(?![\w/])", option, message)
    return message


@contextmanager
def warnings_as_options() -> Iterator[None]:
    """The library's warnings while the command runs said with the options' names
    (``--expected-draws 3: ...``, not ``expected_draws 3: ...``)."""
    shown = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        shown(option_text(str(message)), category, filename, lineno, file, line)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = shown


def option_naming(option: str, value: object, message: str) -> str:
    """``message`` (an error about ``value``) starting with the option that gave it:
    ``nope: no index.json`` -> ``--measured nope: no index.json``."""
    if message.startswith(option):
        return message
    if message.startswith(f"{value}:") or message.startswith(f"{value} "):
        return f"{option} {message}"
    return f"{option} {value}: {message}"


def campaign_of_surrogate(surrogate: Path | None) -> Path | None:
    """The campaign whose ``surrogates/<model>`` folder ``surrogate`` is (trained there by
    ``railsusp train``), or None (a shipped network set, a folder elsewhere)."""
    if surrogate is None or surrogate.absolute().parent.name != "surrogates":
        return None
    campaign = surrogate.absolute().parent.parent
    return campaign if (campaign / "campaign.json").is_file() else None


def check_held_prior_unused(prior, params, given: str | None, surrogates: bool) -> None:
    """Refuse, in one line naming ``--held-prior`` and where the estimated parameters come
    from, a prior on a parameter the estimate estimates: the refined intervals take priors
    of the held parameters only, and the estimated ones are known before NSGA-II runs (it
    was recorded as ``held_prior_unused`` after the whole estimate)."""
    unused = prior.unused(params) if prior is not None else []
    if not unused:
        return
    source = (
        f"--parameters {given}"
        if given
        else ("the surrogates' key parameters" if surrogates else "the study's key parameters")
    )
    raise RailsuspInputError(
        f"--held-prior {', '.join(unused)}: estimated ({source}: {', '.join(params)}), not "
        "held; accepted ranges of the held parameters only (the refined intervals take them)"
    )


def parse_held_prior(text: str | None, refine: bool, statistic: str):
    """``--held-prior X15=100:200,X19=20000:40000`` as a checked
    :class:`~railsusp.estimate.config.HeldPrior` (None without the option); refused without
    ``--refine`` and with ``--statistic aligned``, where no refined interval takes it."""
    from railsusp.estimate.config import HeldPrior

    if not text:
        return None
    if not refine or "aligned" in statistic.split("+"):
        raise RailsuspInputError(
            "--held-prior: only with --refine and a statistic other than aligned (the "
            "refined intervals take it)"
        )
    ranges: dict[str, list[str]] = {}
    for item in text.split(","):
        key, eq, pair = item.partition("=")
        low, colon, high = pair.partition(":")
        if not (eq and colon and key.strip()):
            raise RailsuspInputError(
                f"--held-prior: {item.strip()!r}: accepted SYMBOL=LOW:HIGH in display units, "
                "comma-separated (e.g. X15=100:200,X19=20000:40000)"
            )
        ranges[key.strip()] = [low.strip(), high.strip()]
    return HeldPrior.from_display(ranges, where="--held-prior")


#: the line an interrupted estimate ends with, in place of the common one ("what was
#: finished is kept ...; run the same command again to resume"): an estimate writes its
#: folder whole when it finishes and keeps nothing on the way, so there is nothing to resume
INTERRUPTED = (
    "interrupted: an estimate is written whole when it finishes, so nothing of this run was "
    "kept (an estimate already in --out is left as it was); the same command starts it "
    "again from the beginning"
)


def interrupted() -> SystemExit:
    """Say :data:`INTERRUPTED` and return the exit (status 130, as a Ctrl-C's) that
    :func:`railsusp.cli.main` lets through without its own line (``said``)."""
    err_console.print(INTERRUPTED, markup=False, highlight=False)
    stop = SystemExit(130)
    stop.said = True  # type: ignore[attr-defined]
    return stop
