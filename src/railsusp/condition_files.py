"""Working conditions from the user: a TOML file of ``[[condition]]`` or
``[condition.NAME]`` tables (:func:`load_conditions`, each table a standard condition
changed or a new one, checked as :func:`~railsusp.conditions.make_condition` checks it),
or a command-line spec of standard names or such a file (:func:`resolve_conditions`);
a condition's measured track file is checked to exist before any work
(:func:`check_track_file`)."""

from __future__ import annotations

from pathlib import Path

from railsusp.conditions import (
    STANDARD_CONDITIONS,
    WorkingCondition,
    get_condition,
    make_condition,
)
from railsusp.errors import ConditionError, RailsuspInputError


def check_track_file(cond: WorkingCondition) -> None:
    """Refuse a condition whose ``track_geometry`` file does not exist: it is read only when
    simulating, so a missing file would stop a run there, after other work."""
    if cond.track_geometry is not None and not Path(cond.track_geometry).is_file():
        raise ConditionError(
            f"condition {cond.name!r}: track_geometry {cond.track_geometry} does not exist "
            "(relative to the working folder); accepted a track geometry file "
            "(docs/data-format.md)"
        )


def load_conditions(source: str | Path) -> list[WorkingCondition]:
    """Read conditions from TOML: ``[[condition]]`` tables, or ``[condition.NAME]`` tables.

    A table may start from a standard condition with ``base = "curve"`` and change fields.
    """
    from railsusp.store import read_toml

    path = Path(source)
    try:
        doc = read_toml(path, "condition file")
    except RailsuspInputError as exc:
        raise ConditionError(str(exc)) from None
    raw = doc.get("condition")
    expected = "expected [[condition]] or [condition.NAME] tables"
    other = sorted(k for k in doc if k != "condition")
    if other:  # a misspelt table ([conditon]) or a key meant for one would be lost
        raise ConditionError(f"{path}: {', '.join(other)} unknown; {expected} only")
    if isinstance(raw, dict) and all(isinstance(v, dict) for v in raw.values()):
        renamed = [k for k, v in raw.items() if "name" in v and v["name"] != k]
        if renamed:  # the table's name was dropped for the key's, silently (audit, stop 60)
            k = renamed[0]
            raise ConditionError(
                f"{path}: [condition.{k}] with name = {raw[k]['name']!r}: accepted the "
                "table's own name (leave name out, or give the same)"
            )
        tables = [{"name": k, **v} for k, v in raw.items()]
    elif isinstance(raw, list) and all(isinstance(v, dict) for v in raw):
        tables = raw
    else:
        raise ConditionError(f"{path}: {expected}")
    if not tables:
        raise ConditionError(f"{path}: no condition; {expected}")
    out = []
    for table in tables:
        fields = dict(table)
        base = fields.pop("base", None)
        if base is not None and not isinstance(base, str):
            raise ConditionError(f"{path}: base = {base!r} must be a standard condition name")
        try:
            if base is not None:
                start = get_condition(base).model_dump()
                start.update(fields)
                fields = start
            cond = make_condition(fields)
        except ConditionError as exc:
            raise ConditionError(f"{path}: {exc}") from None
        try:
            check_track_file(cond)
        except ConditionError as exc:
            raise ConditionError(f"{path}: {exc}") from None
        out.append(cond)
    return out


def resolve_conditions(spec: str) -> list[WorkingCondition]:
    """Comma-separated standard names (``"straight,curve"``) or a TOML file path; refuses
    a spec that names none (an empty string, commas alone)."""
    if spec.endswith(".toml") or Path(spec).is_file():
        return load_conditions(spec)
    try:
        conds = [get_condition(n) for n in spec.split(",") if n.strip()]
    except ConditionError as exc:  # here a file of conditions is accepted too
        raise ConditionError(f"{exc}, or a TOML file of conditions") from None
    if not conds:
        raise RailsuspInputError(
            f"conditions {spec!r}: none named; accepted {', '.join(STANDARD_CONDITIONS)} "
            "(comma-separated) or a TOML file"
        )
    return conds
