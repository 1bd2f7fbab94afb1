"""Where a run's track comes from when not from its own channels: a line description (km
posts with radius, cant and grade) or a table of sections the user gives."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.conditions import field_range
from railsusp.errors import RailsuspInputError, cut_repr

#: a section name, which becomes a file name: no path separators, no leading dot
_NAME = r"[A-Za-z0-9][A-Za-z0-9._-]"
#: a name a table may give (at most 60 characters)
SAFE_NAME = re.compile(_NAME + "{0,59}")
#: a section's name as written: a split row's number may add to a table's name
FILE_NAME = re.compile(_NAME + "*")
#: names a section cannot take: its recording (NAME.csv, NAME.json) would be written over by
#: the field folder's own files (index.json, sections.csv, en14363.csv), or write over them;
#: a ``truth.json`` beside the recordings reads as a synthetic folder's truth sidecar
RESERVED_NAMES = ("index", "sections", "en14363", "truth")


def geometry_from_line(position_m: np.ndarray, line: pd.DataFrame) -> dict[str, np.ndarray]:
    """Curvature (1/m, + left), cant (m) and grade (1) under each position from a line
    description with columns ``km_start, km_end, radius_m, cant_mm, grade_permille`` and
    ``direction`` (left/right, on each curve row); radius 0 or empty is tangent. Positions outside
    every row are NaN. A line description states direction and grade as seen running
    towards increasing km posts; a run towards decreasing ones (its position falling) sees
    a left-hand curve as right-hand and an up-grade as down-grade, so both are mirrored
    for it (the cant, on the curve's outer rail, is the same either way)."""
    return _geometry_of_rows(position_m, line.km_start * 1e3, line.km_end * 1e3, line)


def geometry_from_table(position_m: np.ndarray, table: pd.DataFrame) -> dict[str, np.ndarray]:
    """The track a section table states for its rows (``start_m, end_m`` in metres along
    the run), as :func:`geometry_from_line` reads a line description's, of only the
    quantities whose columns the table has: ``curvature`` from ``radius_m`` (with
    ``direction``), ``cant`` from ``cant_mm``, ``grade`` from ``grade_permille``; NaN
    outside the rows. None of them: an empty dict (the run's channels give the track)."""
    return _geometry_of_rows(position_m, table.start_m, table.end_m, table)


def running_sense(position_m: np.ndarray) -> float:
    """+1 for a run towards increasing positions, -1 towards falling ones (its finite steps
    summed): a line description's or section table's hand and grade, written as seen
    towards increasing positions, are mirrored for a run whose position falls."""
    steps = np.diff(position_m)
    steps = steps[np.isfinite(steps)]
    return -1.0 if steps.size and np.sum(steps) < 0.0 else 1.0


def _geometry_of_rows(
    position_m: np.ndarray, start_m: pd.Series, end_m: pd.Series, rows: pd.DataFrame
) -> dict[str, np.ndarray]:
    """Per position, the curvature, cant and grade of the row ``start_m <= position <
    end_m`` it lies in (NaN in none), for each of them whose column ``rows`` has."""
    sense = running_sense(position_m)
    columns = {"curvature": "radius_m", "cant": "cant_mm", "grade": "grade_permille"}
    out = {key: np.full(position_m.shape, np.nan) for key, c in columns.items() if c in rows}
    for k, r in enumerate(rows.itertuples(index=False) if out else ()):
        inside = (position_m >= start_m.iloc[k]) & (position_m < end_m.iloc[k])
        if "curvature" in out:
            radius = float(r.radius_m) if np.isfinite(r.radius_m) else 0.0
            side = str(getattr(r, "direction", "")).strip().lower()
            if radius > 0 and side not in ("left", "right"):  # a table given as a DataFrame,
                # not read: a curve's unstated hand was taken as left (the review of stop 72)
                raise RailsuspInputError(
                    f"track row {k + 1}: radius_m = {radius:g} with direction = "
                    f"{cut_repr(getattr(r, 'direction', None))}: accepted left or right"
                )
            sign = -1.0 if side == "right" else 1.0
            out["curvature"][inside] = sense * sign / radius if radius > 0 else 0.0
        if "cant" in out:
            out["cant"][inside] = (r.cant_mm if np.isfinite(r.cant_mm) else 0.0) * 1e-3
        if "grade" in out:
            grade = r.grade_permille if np.isfinite(r.grade_permille) else 0.0
            out["grade"][inside] = sense * grade * 1e-3
    return out


def read_line(path: str | Path) -> pd.DataFrame:
    """A line description CSV (see :func:`geometry_from_line`), checked."""
    need = ["km_start", "km_end", "radius_m", "cant_mm", "grade_permille"]
    what = f"line description {path}"
    df = _read_csv(path, need, what)
    _need_values(df, ["km_start", "km_end"], what)
    _check_track(df, what)
    _check_ranges(
        df, ("km_start", "km_end"), what, "km {:g} to {:g}", "a stretch the line does not describe"
    )
    return df


#: the optional columns of a section table that state its rows' track as a line
#: description's columns do (radius_m with direction, cant_mm, grade_permille)
TABLE_TRACK = ("radius_m", "direction", "cant_mm", "grade_permille")


def read_section_table(path: str | Path) -> pd.DataFrame:
    """A user section table CSV: ``start_m, end_m`` and optional ``name``, checked. Names
    become file names, so they must be plain: letters, digits, ``.``, ``_``, ``-``. The
    optional columns :data:`TABLE_TRACK` state the rows' track, checked as a line
    description's (:func:`geometry_from_table`): a run without geometry channels has no
    other source of it. Rows may not overlap (a sample would be in two sections). The
    table's name for messages is kept in ``attrs["what"]``."""
    what = f"section table {path}"
    df = _read_csv(
        path, ["start_m", "end_m"], what, optional=["radius_m", "cant_mm", "grade_permille"]
    )
    _need_values(df, ["start_m", "end_m"], what)
    if "name" in df:
        seen: dict[str, int] = {}
        for i, name in enumerate(text_cells(df["name"])):
            if not name:  # pandas 3 kept NaN through astype(str): a TypeError's traceback
                raise RailsuspInputError(
                    f"{what}, row {i + 2}: name is empty: accepted 1-60 letters, digits, '.', "
                    "'_', '-', starting with a letter or digit (or no name column: numbered "
                    "names)"
                )
            if not SAFE_NAME.fullmatch(name):
                raise RailsuspInputError(
                    f"{what}, row {i + 2}: name {cut_repr(name)}: accepted 1-60 "
                    "letters, digits, '.', '_', '-', starting with a letter or digit"
                )
            if name.casefold() in RESERVED_NAMES:
                raise RailsuspInputError(
                    f"{what}, row {i + 2}: name {name!r} is the field folder's "
                    f"own file ({', '.join(RESERVED_NAMES)}); accepted another name"
                )
            if name.casefold() in seen:  # the second recording would replace the first
                raise RailsuspInputError(
                    f"{what}, row {i + 2}: name {name!r} is row "
                    f"{seen[name.casefold()]}'s too; accepted a name per section"
                )
            seen[name.casefold()] = i + 2
    if "direction" in df and "radius_m" not in df:
        raise RailsuspInputError(
            f"{what}: a direction column without radius_m; accepted radius_m (empty or 0: "
            "tangent) with direction, or neither"
        )
    _check_track(df, what)
    _check_ranges(df, ("start_m", "end_m"), what, "{:g} to {:g} m", "a stretch in no section")
    df.attrs["what"] = what
    return df


def text_cells(column: pd.Series) -> list[str]:
    """A user column's cells as text, an empty cell as ``""``: ``astype(str)`` made it
    "nan" under pandas 2 (a section named "nan") and kept it NaN under pandas 3."""
    return ["" if pd.isna(v) else str(v) for v in column]


def _check_track(df: pd.DataFrame, what: str) -> None:
    """Refuse, row by row, track columns outside what a working condition takes (those of
    ``radius_m, cant_mm, grade_permille, direction`` that ``df`` has): a negative radius
    was taken for tangent, a direction "up" for left, a grade in per cent written into a
    condition; a curve row whose hand is not stated (it was taken as left); and cant on a
    tangent row (shown, then written as 0)."""
    # empty radius, cant, grade: tangent, level; radius 0: tangent
    for column, field in (("radius_m", "curve_radius_m"), ("cant_mm", "cant_mm"),
                          ("grade_permille", "grade_permille")):  # fmt: skip
        if column not in df:
            continue
        lo, hi = field_range(field)
        vals = df[column].to_numpy(dtype=float)
        out = np.isfinite(vals) & ((vals < lo) | (vals > hi))
        if column == "radius_m":
            out &= vals != 0.0
        if out.any():
            i = int(np.flatnonzero(out)[0])
            raise RailsuspInputError(
                f"{what}, row {i + 2}: {column} = {vals[i]:g}: accepted {lo:g} to {hi:g}, or "
                "empty" + (" (0 or empty: tangent)" if column == "radius_m" else "")
            )
    given = pd.Series(text_cells(df["direction"]) if "direction" in df else [""] * len(df))
    given = given.str.strip().str.lower()
    wrong = ~given.isin(["", "left", "right"])
    if wrong.any():
        i = int(np.flatnonzero(wrong.to_numpy())[0])
        raise RailsuspInputError(
            f"{what}, row {i + 2}: direction = {cut_repr(df['direction'].iloc[i])}: accepted "
            "left or right (empty on a tangent row)"
        )
    if "radius_m" in df:  # an unstated hand was taken as left: a right-hand curve's inner
        # wheel was then compared as its outer one, without a word (the docs audit, stop 72)
        curve = np.nan_to_num(df.radius_m.to_numpy(dtype=float)) > 0.0
        unstated = curve & (given == "").to_numpy()
        if unstated.any():
            i = int(np.flatnonzero(unstated)[0])
            lack = "it has no direction column" if "direction" not in df else "direction empty"
            towards = "km posts" if "km_start" in df else "positions"
            raise RailsuspInputError(
                f"{what}, row {i + 2}: radius_m = {df.radius_m.iloc[i]:g} with no hand "
                f"({lack}): accepted direction = left or right on each curve row (as seen "
                f"running towards increasing {towards}; it decides which wheel is outer)"
            )
    if "radius_m" in df and "cant_mm" in df:
        tangent = ~(df.radius_m.to_numpy(dtype=float) > 0.0)
        canted = tangent & (np.nan_to_num(df.cant_mm.to_numpy(dtype=float)) != 0.0)
        if canted.any():  # written as 0 into the section's condition, shown as given
            i = int(np.flatnonzero(canted)[0])
            raise RailsuspInputError(
                f"{what}, row {i + 2}: cant_mm = {df.cant_mm.iloc[i]:g} on a tangent row "
                "(radius 0 or empty): accepted 0 or empty there (a working condition has "
                "cant in a curve only)"
            )


def _check_ranges(df: pd.DataFrame, ends: tuple[str, str], what: str, shown: str, gap: str) -> None:
    """Refuse a row that ends where or before it starts, and rows that overlap (a line
    description's later row won where two overlapped; a section table's samples were in
    two sections); ``shown`` formats a stretch of the overlap, ``gap`` says what a gap
    between rows is."""
    first, last = ends
    starts_all, ends_all = df[first].to_numpy(), df[last].to_numpy()
    if (ends_all <= starts_all).any():
        i = int(np.flatnonzero(ends_all <= starts_all)[0])
        raise RailsuspInputError(
            f"{what}, row {i + 2}: {last} = {ends_all[i]:g} is not above {first} = "
            f"{starts_all[i]:g}: accepted {last} > {first} (a row from its lower position to "
            "its higher one, also for a run towards falling ones)"
        )
    order = np.argsort(starts_all, kind="stable")
    starts, stops = starts_all[order], ends_all[order]
    overlap = np.flatnonzero(starts[1:] < np.maximum.accumulate(stops)[:-1])
    if overlap.size:
        k = int(overlap[0]) + 1  # row order[k] starts inside the row before it that ends last
        prev = int(np.argmax(stops[:k]))
        a, b = sorted((int(order[prev]) + 2, int(order[k]) + 2))
        span = shown.format(starts[k], min(stops[prev], stops[k]))
        raise RailsuspInputError(
            f"{what}, rows {a} and {b} overlap ({span}): accepted rows that do not overlap "
            f"(a gap is {gap})"
        )


def _read_csv(
    path: str | Path, need: list[str], what: str = "", optional: list[str] | None = None
) -> pd.DataFrame:
    """The table's columns ``need`` (and those of ``optional`` it has) as numbers (an empty
    cell is NaN); ``what`` names the table in the messages (default: its path)."""
    what = what or str(path)
    try:  # only an empty cell is missing: "nan" or "inf" is a value, refused below
        df = pd.read_csv(  # names as written: "01" is no number 1
            path,
            skipinitialspace=True,
            keep_default_na=False,
            na_values=[""],
            dtype={"name": str, "direction": str},
        )
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise RailsuspInputError(f"{path}: cannot read the table ({exc})") from None
    missing = [c for c in need if c not in df.columns]
    if missing or df.empty:
        lack = f"no column {', '.join(missing)}" if missing else "no rows"
        raise RailsuspInputError(
            f"{what}: {lack}; accepted a table with the columns {', '.join(need)} and at "
            "least one row"
        )
    for c in [*need, *(c for c in optional or [] if c in df.columns)]:
        vals = pd.to_numeric(df[c], errors="coerce")
        accepted = "a finite number" + ("" if c in ENDS else ", or an empty cell")
        bad = vals.isna() & df[c].notna()
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            raise RailsuspInputError(
                f"{what}, row {i + 2}: {c} = {cut_repr(df[c].iloc[i])} not a number: "
                f"accepted {accepted}"
            )
        infinite = df[c].notna() & ~np.isfinite(vals.astype(float))
        if infinite.any():  # "nan", "inf": read as an empty cell (a tangent, level track)
            i = int(np.flatnonzero(infinite.to_numpy())[0])
            raise RailsuspInputError(
                f"{what}, row {i + 2}: {c} = {df[c].iloc[i]}: accepted {accepted}"
            )
        df[c] = vals.astype(float)
    return df


#: the columns of a row's ends, which every row must give (an empty cell is refused)
ENDS = ("km_start", "km_end", "start_m", "end_m")


def _need_values(df: pd.DataFrame, columns: list[str], what: str) -> None:
    """Refuse an empty or non-finite cell (``nan``, ``inf``) in columns that must hold a
    number in every row: a section from NaN to 500 m kept nothing, with only numpy's
    "Mean of empty slice" to say so."""
    for c in columns:
        vals = df[c].to_numpy(dtype=float)
        bad = ~np.isfinite(vals)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            shown = "nan (or empty)" if np.isnan(vals[i]) else f"{vals[i]:g}"
            raise RailsuspInputError(
                f"{what}, row {i + 2}: {c} = {shown}: accepted a finite number in every row "
                "(a row's two ends)"
            )
