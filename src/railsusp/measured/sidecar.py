"""The JSON sidecar beside a recording's table: its ``format``, ``wheels`` and
``filter_bandwidth_hz``, and its working condition (``condition`` or ``condition_name``),
whose measured track geometry is resolved inside the recording's folder and checked to cover
the record, and whose record is held against the table it describes.

Kept apart from the table (:mod:`railsusp.measured.recording_reader`) because the sidecar
is a document of its own: the problems found in it are collected into the same list as the
table's, so a file's every problem is reported at once. Every path a data file names (the
sidecar's ``track_geometry``, the recordings an ``index.json`` lists) must lie inside its
folder (:func:`inside`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from railsusp.conditions import WorkingCondition, get_condition, make_condition
from railsusp.errors import RailsuspInputError, cut_repr
from railsusp.input_checks import json_numbers
from railsusp.measured.recording import FORMAT
from railsusp.numbers import is_real
from railsusp.vehicle.layout import WHEEL_NAMES
from railsusp.vehicle.track_geometry import check_coverage, read_track_geometry


def inside(folder: Path, name: Any, what: str) -> Path:
    """``folder / name`` when ``name`` is a relative path that stays inside ``folder``;
    otherwise an error naming ``what`` (a data file must not reach outside its folder)."""
    if not isinstance(name, str) or not name:
        raise RailsuspInputError(f"{what}: {name!r} is not a file name")
    root = folder.resolve()
    target = (root / name).resolve()
    if Path(name).is_absolute() or not target.is_relative_to(root):
        raise RailsuspInputError(
            f"{what}: {name!r} lies outside the folder {folder}; name a file inside it"
        )
    return target


def read_sidecar(side: Path, problems: list[str]) -> dict[str, Any]:
    """The sidecar as a dict (empty, with a problem, when missing or not a JSON object)."""
    if not side.is_file():
        problems.append(f"metadata sidecar {side.name} missing")
        return {}
    try:
        meta = json.loads(side.read_text("utf-8-sig"))
    except UnicodeDecodeError:
        problems.append(f"{side.name}: not UTF-8 text")
        return {}
    except json.JSONDecodeError as exc:
        problems.append(f"{side.name}: not valid JSON ({exc.msg}, line {exc.lineno})")
        return {}
    if not isinstance(meta, dict):
        problems.append(
            f"{side.name}: a JSON object {{...}} is needed, not a {type(meta).__name__}"
        )
        return {}
    if meta.get("format") != FORMAT:
        problems.append(f"{side.name}: format {meta.get('format')!r}, expected {FORMAT!r}")
    problems += _sidecar_fields(meta, side.name)
    return meta


def _sidecar_fields(meta: dict[str, Any], side: str) -> list[str]:
    """Problems of the sidecar's ``wheels`` (a list of distinct wheel names) and
    ``filter_bandwidth_hz`` (null, or a positive number of Hz: the comparison low-passes the
    model's forces at it, so a string or a negative value would fail there, naming nothing)."""
    out = []
    wheels = meta.get("wheels")
    if wheels is not None and (
        not isinstance(wheels, list)
        or not all(isinstance(w, str) and w in WHEEL_NAMES for w in wheels)
        or len(set(wheels)) != len(wheels)
    ):
        out.append(
            f"{side}: wheels = {json.dumps(wheels)}: accepted a list of distinct wheel names "
            f'{WHEEL_NAMES[0]} .. {WHEEL_NAMES[-1]} (e.g. ["w1R"])'
        )
    bw = meta.get("filter_bandwidth_hz")
    if bw is not None and not (is_real(bw) and 0.0 < bw < math.inf):
        out.append(
            f"{side}: filter_bandwidth_hz = {json.dumps(bw)}: accepted a number of Hz above 0 "
            "(the instrument's bandwidth; null or left out: none)"
        )
    return out


def sidecar_condition(
    meta: dict[str, Any], table_path: Path, problems: list[str], axle_spread_m: float
) -> WorkingCondition | None:
    """The sidecar's working condition (numbers must be JSON numbers), its track geometry
    resolved inside the recording's folder, read and checked to cover the record under
    every axle, ``axle_spread_m`` (the recorded wagon's;
    :func:`~railsusp.vehicle.track_geometry.check_coverage`; the simulation checks again
    with the run's wagon)."""
    side = table_path.with_suffix(".json").name
    cdoc = meta.get("condition")
    named = meta.get("condition_name")
    if isinstance(cdoc, dict) and named is not None and named != cdoc.get("name"):
        problems.append(  # the name was ignored, silently (command-line audit of stop 60)
            f"{side}: a 'condition' table (name {cdoc.get('name')!r}) and condition_name "
            f"{named!r}: accepted one of them (or the same name in both)"
        )
        return None
    if isinstance(cdoc, dict) and cdoc.get("curve_radius_m") is not None:
        if "curve_direction" not in cdoc:  # taken as left without a word: a right-hand
            # curve's inner wheel compared as its outer one (the review of stop 72)
            problems.append(
                f"{side}: condition.curve_radius_m = {cut_repr(cdoc['curve_radius_m'])} with "
                'no curve_direction: accepted curve_direction = "left" or "right" (seen in '
                "the running direction; it decides which wheel is outer)"
            )
            return None
    try:
        if isinstance(cdoc, dict):
            condition = make_condition(json_numbers(cdoc))
        elif cdoc is not None:  # a list or a number: "no 'condition' table" was said
            problems.append(
                f"{side}: condition = {json.dumps(cdoc)}: accepted a table (a JSON object "
                '{"name": ..., "speed_kmh": ...}) of working-condition fields, or '
                "condition_name naming a standard condition"
            )
            return None
        elif isinstance(named, str):
            condition = get_condition(named)
        else:
            problems.append(f"{side}: no 'condition' table or 'condition_name'")
            return None
    except RailsuspInputError as exc:
        problems.append(f"{side}: {exc}")
        return None
    if condition.track_geometry is None:
        return condition
    try:
        geo = inside(table_path.parent, condition.track_geometry, f"{side}: track_geometry")
        condition = condition.with_changes(track_geometry=str(geo))
        check_coverage(read_track_geometry(geo), condition, axle_spread_m)
    except RailsuspInputError as exc:
        problems.append(str(exc) if str(exc).startswith(side) else f"{side}: track_geometry: {exc}")
        return None
    return condition


def condition_on_the_table(
    condition: WorkingCondition,
    meta: dict,
    rows: int,
    rate: float,
    side: str,
    problems: list[str],
) -> WorkingCondition | None:
    """The sidecar's condition against the table it describes (``rows`` at ``rate`` Hz):
    its ``duration_s`` must be the table's (its ``n_steps`` may sample it at another rate:
    record statistics are each taken at their own rate; what compares the simulation with
    the table sample by sample refuses it before any work,
    :func:`~railsusp.estimate.comparison.check_time_base`), since the estimate simulates the
    condition's record and compares it with the table (a
    4 s condition on a 1 s table compared 4 s of simulation with 1 s of measurement,
    silently). A condition that states neither (the documented sidecar's), or a standard
    one named by ``condition_name``, takes the table's record (before, the default 20 s of
    1000 steps, whatever the table)."""
    duration = rows / rate
    doc = meta.get("condition")
    if not (isinstance(doc, dict) and ("duration_s" in doc or "n_steps" in doc)):
        try:
            return condition.with_changes(duration_s=round(duration, 6), n_steps=rows)
        except RailsuspInputError as exc:
            problems.append(f"{side}: {exc}")
            return None
    slack = 1.5 * max(1.0 / rate, condition.sample_interval)  # its rate may be its own
    if abs(condition.duration_s - duration) > slack:
        problems.append(
            f"{side}: condition duration_s {condition.duration_s:g} s, the table {rows} rows at "
            f"{rate:.6g} Hz ({duration:.6g} s): accepted the table's duration (the estimate "
            "simulates the condition's record and compares it with the table)"
        )
    return condition
