"""The run directory's files that the summary reads, each checked as it is read: an
``estimate.json`` (its parameters, point, held values and the fields the estimate table
reads beside them), ``campaign.json``'s configuration and ``validation.csv``. A file edited
or damaged where the stages' hashes do not see it (a run made before they were recorded, a
reader that goes to the files directly) is a one-line input error naming the file, the field
and how to write it again, not a traceback from deep in a table (the run-directory store
audit; stop 79's hunt).

Kept apart from :mod:`railsusp.summary`, which forms the tables from what these return.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_real
from railsusp.store import read_csv, read_json


def damaged(path: Path, what: str) -> RailsuspInputError:
    """The one-line error of an estimate.json edited or damaged (a same-size edit is not
    seen by a run made before its stages recorded hashes), with how to write it again."""
    run = path.parent.parent
    first = what.strip().splitlines()[0] if what.strip() else what
    return RailsuspInputError(
        f"{path}: {first}; the file is damaged or was edited "
        f"(railsusp run CONFIG --out {run} --from estimate writes it again)"
    )


def read_estimate(path: str | Path) -> dict:
    """An ``estimate.json`` with the fields the summary reads checked: ``parameters`` a list
    of parameter symbols and ``estimate_display`` a real number for each of them. An edited
    or damaged file (a key renamed, a number made text) is a one-line input error naming the
    file and the field, not a KeyError's traceback from deep in the table (``railsusp run``
    ended so, exit 1, on a run whose key had been edited: the run-directory store audit)."""
    path = Path(path)
    est = read_json(path)
    if not isinstance(est, dict):
        raise damaged(path, f"a JSON object is needed, not {type(est).__name__}")
    params = est.get("parameters")
    if not isinstance(params, list) or not all(isinstance(p, str) for p in params):
        raise damaged(path, f"parameters = {params!r:.60}: accepted a list of parameter symbols")
    shown = est.get("estimate_display")
    if not isinstance(shown, dict):
        raise damaged(path, f"estimate_display = {shown!r:.60}: accepted a table {{symbol: value}}")
    for p in params:
        if not is_real(shown.get(p)) or not math.isfinite(float(shown[p])):
            raise damaged(
                path,
                f"estimate_display.{p} = {repr(shown[p])[:40] if p in shown else 'missing'}: "
                f"accepted a finite number (the estimate of each of {', '.join(params)})",
            )
    from railsusp.estimate.config import held_at_of

    held_at_of(est, str(path))  # where it held the parameters it did not estimate
    return est


def campaign_config(run: Path) -> dict:
    """``campaign.json``'s configuration, checked to be a table whose ``parameters`` (where
    given) is a list of symbols: a damaged file is one line naming the field."""
    path = run / "campaign" / "campaign.json"
    doc = read_json(path)
    config = doc.get("config") if isinstance(doc, dict) else None
    params = config.get("parameters", []) if isinstance(config, dict) else None
    if not isinstance(params, list) or not all(isinstance(p, str) for p in params):
        shown = f"config.parameters = {params!r:.60}" if params is not None else "config"
        raise RailsuspInputError(
            f"{path}: {shown}: accepted a table whose parameters are a list of symbols; the "
            f"file is damaged or was edited (railsusp run CONFIG --out {run} writes it again)"
        )
    return config


def check_table_fields(est: dict, details: dict, path: Path) -> None:
    """The fields of an ``estimate.json`` (``est``, its intervals' ``details``) that
    :func:`estimate_table` reads beside the point and the intervals, checked: the standard
    errors and the polish, tables of numbers; the held parameters' assumed ranges and the
    parameters not estimated, tables of the fields the verdicts name. A damaged or edited
    file is one line naming the file and the field (each was a TypeError's or KeyError's
    traceback from the table's rows)."""

    def refuse(field: str, value: object, accepted: str) -> None:
        raise damaged(path, f"{field} = {value!r:.60}: accepted {accepted}")

    ref = est.get("refinement")
    if ref is not None and not isinstance(ref, dict):
        refuse("refinement", ref, "a table")
    numbers = (
        ("intervals.details.total_standard_error_pct_range", details),
        ("refinement.standard_error_pct_range", ref or {}),
        ("polished_display", est),
    )
    for field, where in numbers:
        table = where.get(field.rsplit(".", 1)[-1])
        if table is None:
            continue
        if not isinstance(table, dict):
            refuse(field, table, "a table {symbol: number}")
        for p, v in table.items():
            if not is_real(v):
                refuse(f"{field}.{p}", v, "a number")
    held = details.get("held_parameters_assumed") or {}
    if not isinstance(held, dict):
        refuse("intervals.details.held_parameters_assumed", held, "a table {symbol: range}")
    for p, h in held.items():
        ends = ("held_at_display", "low_display", "high_display")
        if not isinstance(h, dict) or not all(is_real(h.get(k)) for k in ends):
            refuse(
                f"intervals.details.held_parameters_assumed.{p}",
                h,
                "a table of held_at_display, low_display, high_display (numbers) and range",
            )
    rows = est.get("not_estimated", [])
    if not isinstance(rows, list) or not all(
        isinstance(r, dict) and isinstance(r.get("symbol"), str) for r in rows
    ):
        refuse("not_estimated", rows, "a list of tables, each naming its parameter's symbol")
    for r in rows:
        if r.get("assumed") == "varied" and not (is_real(r.get("low")) and is_real(r.get("high"))):
            refuse(f"not_estimated.{r['symbol']}", r, "low and high numbers of the varied range")


def read_validation(path: str | Path) -> pd.DataFrame:
    """A ``validation.csv``, its columns checked: condition, force and statistic there, the
    force statistics (``*_kN``) and errors (``*_error``) numbers (blank where a simulation
    stopped). A damaged or edited file is one line naming the file, the column and the row
    (a number made text was a ValueError's or TypeError's traceback in ``agreement`` and
    ``validation``)."""
    path = Path(path)
    df = read_csv(path)
    remedy = f"railsusp run CONFIG --out {path.parents[2]} --from validate writes it again"
    missing = [c for c in ("condition", "force", "statistic") if c not in df.columns]
    if missing:
        raise RailsuspInputError(f"{path}: no column {missing[0]}; the file is damaged ({remedy})")
    for c in [c for c in df.columns if c.endswith(("_kN", "_error"))]:
        values = pd.to_numeric(df[c], errors="coerce")
        bad = values.isna() & df[c].notna()
        if bad.any():
            row = int(bad.to_numpy().argmax())
            raise RailsuspInputError(
                f"{path}: column {c} = {df[c].iloc[row]!r:.40} in row {row + 2}: accepted a "
                f"number; the file is damaged or was edited ({remedy})"
            )
        df[c] = values
    return df
