"""The cells of a recording's table file (CSV or Parquet), with the problems of the file
itself said in the project's words: a line that is not UTF-8 (its line number), a
separator other than a comma, a line with more cells than the header, a last line cut
short; and, for the reader to refuse where it uses the column and note where it does not,
a column named twice and cells that are not numbers (each column with its first row).
Shared by the field-format reader (:mod:`railsusp.measured.field_table`) and the long run's
(:mod:`railsusp.measured.raw`), so that a table reads alike whichever command reads it: a
long run's CSV separated by ``;`` said "no time column" before, and its non-UTF-8 lines no
line number.
"""

from __future__ import annotations

import csv
import io
import warnings
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.errors import cut_repr
from railsusp.integrity import csv_last_line_cut
from railsusp.measured.recording import RecordingError

#: lines of a table named in one message (the others counted)
LINES_NAMED = 3


def read_frame(path: Path) -> tuple[pd.DataFrame, list[str], dict[str, list[int]]]:
    """The table's cells (text for CSV), the notes of its header, and its columns named
    more than once: name -> their column numbers (from 1; :func:`twice_said`), the first
    copy kept, the later ones left out (pandas renamed them ``X.1``). Whether that is a
    problem is the reader's to say: a logger repeats an unused name across its groups (a
    second ``status``), which refused a whole long run.
    A column with no name (a trailing comma on each line) is left out, without a word where
    all its cells are empty, with a note where not. A file that does not read as a table
    at all raises :class:`RecordingError` with its problem."""
    if path.suffix.lower() == ".parquet":
        try:
            return pd.read_parquet(path), [], {}
        except Exception as exc:  # pyarrow raises many types on a damaged file
            raise RecordingError(path, [f"cannot read the table ({_first_line(exc)})"]) from None
    data = path.read_bytes()
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise RecordingError(path, [_not_utf8(data)]) from None
    header = next(_csv_rows(path, text), [])
    if len(header) == 1 and any(sep in header[0] for sep in ";\t"):
        sep = "';'" if ";" in header[0] else "a tab"
        raise RecordingError(
            path,
            [
                f"the header {cut_repr(header[0], 80)} is one column: its cells are separated "
                f"by {sep}; "
                "accepted a comma-separated table with '.' as decimal mark"
            ],
        )
    try:  # (index_col=False: lines of one cell more than the header took its first
        # column for the row labels, every column shifted by one)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", pd.errors.ParserWarning)
            df = pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False, index_col=False)
    except Exception as exc:  # pandas raises many types on a damaged file
        longer = _longer_lines(path, text, len(header))
        raise RecordingError(
            path, [longer or f"cannot read the table ({_first_line(exc)})"]
        ) from None
    if caught and (longer := _longer_lines(path, text, len(header))):  # cut off, were they read
        raise RecordingError(path, [longer])
    if csv_last_line_cut(path, len(df.columns)):
        raise RecordingError(
            path,
            [
                f"the last line is cut short (fewer cells than the header's {len(df.columns)}, "
                "no line end): a file truncated in copying? Its last value would be read "
                "wrong; remove the line or copy the file again"
            ],
        )
    twice: dict[str, list[int]] = {}
    notes: list[str] = []
    drop = []
    for name, n in Counter(header).items():
        at = [i for i, h in enumerate(header) if h == name]
        if not name.strip():
            for i in at:
                drop.append(df.columns[i])
                cells = df.iloc[:, i].str.strip()
                if (cells != "").any():
                    notes.append(
                        f"column {i + 1} has no name in the header (its cells are not "
                        "empty): not used"
                    )
        elif n > 1:
            twice[name] = [i + 1 for i in at]
            drop += [df.columns[i] for i in at[1:]]
    return df.drop(columns=drop), notes, twice


def twice_said(columns: list[int]) -> str:
    """A column named more than once, at ``columns`` (from 1), to follow ``column 'X'``."""
    return (
        f" appears {len(columns)} times in the header (columns "
        f"{', '.join(str(i) for i in columns)})"
    )


#: what follows :func:`twice_said` where the reader uses the column
TWICE_REFUSED = "; accepted each column once (which copy is meant cannot be told)"


def column_numbers(raw: pd.Series) -> tuple[np.ndarray, str | None, str]:
    """A column as floats, or why it is not numbers: in full (to follow ``column 'X'``),
    with its first row (file lines: the header is line 1) and the count, and in short, for
    a note. Empty and ``nan`` cells are NaN. A boolean column (Parquet) is not numbers, as
    CSV's ``True`` is not: its values were read as 0 and 1 kN (the command-line audit of
    stop 60)."""
    if raw.dtype.kind == "b" or (raw.dtype == object and raw.map(type).eq(bool).any()):
        return (
            np.zeros(0),
            " holds booleans (true/false), not numbers; accepted numeric values",
            "booleans",
        )
    if raw.dtype.kind in "fiu":
        return raw.to_numpy(dtype=float), None, ""
    text = raw.where(raw.notna(), "").astype(str).str.strip()  # a Parquet null: empty
    vals = pd.to_numeric(text.replace("", "nan"), errors="coerce")
    bad = vals.isna() & ~text.str.lower().isin(["", "nan"])
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        comma = " (',' as decimal mark? accepted '.')" if "," in str(raw.iloc[i]) else ""
        return (
            np.zeros(0),
            f", row {i + 2}: {cut_repr(raw.iloc[i])} is not a number{comma} ({int(bad.sum())} such "
            "cell(s))",
            f"text, {cut_repr(raw.iloc[i])} in row {i + 2}",
        )
    return vals.to_numpy(dtype=float), None, ""


def _csv_rows(path: Path, text: str) -> Iterator[list[str]]:
    """The rows of a CSV text, its lines ended as pandas ends them (``\\r\\n``, ``\\n`` or a
    bare ``\\r``, old Mac Excel's: without ``newline=""`` the ``csv`` module raised on a bare
    ``\\r`` inside a line); a row it cannot parse (a cell beyond its field size limit) is the
    file's problem, said as :class:`RecordingError`, not a traceback."""
    try:
        yield from csv.reader(io.StringIO(text, newline=""))
    except csv.Error as exc:
        raise RecordingError(path, [f"cannot read the table ({_first_line(exc)})"]) from None


def _longer_lines(path: Path, text: str, n_header: int) -> str | None:
    """The lines with values in more cells than the header's (empty cells after the last
    are a comma at a line's end, no value), as a problem; None where there are none."""
    longer = [
        i for i, cells in enumerate(_csv_rows(path, text), start=1)
        if len(cells) > n_header and any(c.strip() for c in cells[n_header:])
    ]  # fmt: skip
    if not longer:
        return None
    return (
        f"{'line' if len(longer) == 1 else 'lines'} {_listed(longer)}: more cells than the "
        f"header's {n_header}; accepted a value under each header"
    )


def _listed(numbers: list[int]) -> str:
    """The first :data:`LINES_NAMED` of ``numbers``, and how many in all."""
    more = f" ({len(numbers)} in all)" if len(numbers) > LINES_NAMED else ""
    return ", ".join(str(n) for n in numbers[:LINES_NAMED]) + more


def _first_line(exc: Exception) -> str:
    return (str(exc).splitlines() or [type(exc).__name__])[0]


def _not_utf8(data: bytes) -> str:
    """The lines of ``data`` that are not UTF-8, named by their numbers (the header is line
    1), with the first offending byte."""
    bad = []
    for number, line in enumerate(data.removeprefix(b"\xef\xbb\xbf").split(b"\n"), start=1):
        try:
            line.decode("utf-8")
        except UnicodeDecodeError as exc:
            bad.append((number, line[exc.start]))
    if not bad:  # (a sequence split across a line end cannot be: "\n" is never inside one)
        return "not UTF-8 text; accepted a UTF-8 table"
    numbers = [n for n, _ in bad]
    where = f"{'line' if len(bad) == 1 else 'lines'} {_listed(numbers)}"
    header = " (the header)" if numbers[0] == 1 else ""
    return (
        f"{where}{header}: not UTF-8 text (byte 0x{bad[0][1]:02x}); accepted a UTF-8 table "
        "(save it as UTF-8, not in a national code page)"
    )
