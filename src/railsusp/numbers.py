"""The one number format of tables, reports and interval texts."""

from __future__ import annotations

import math
import numbers


def is_real(value: object) -> bool:
    """A real number, NumPy's scalars included, and not a boolean (``True`` is an ``int``
    to Python, a slip in an input); NumPy's ``bool_`` is not a real to :mod:`numbers`."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_whole(value: object) -> bool:
    """A whole number (Python's or NumPy's integers), not a boolean and not a float that
    happens to be whole (a count given as 4.0 is a slip to refuse, not to round)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def sig3(v: float) -> str:
    """Three significant figures, without an exponent from 0.0001 to 1e6 (the report's and
    the summary's one number format)."""
    if v == 0:
        return "0"
    if not math.isfinite(v):
        return "" if v != v else ("∞" if v > 0 else "-∞")
    if not 1e-4 <= abs(v) < 1e6:
        return f"{v:.2e}"
    digits = max(0, 2 - math.floor(math.log10(abs(v))))
    rounded = round(v, digits)
    if rounded != 0 and math.floor(math.log10(abs(rounded))) > math.floor(math.log10(abs(v))):
        digits = max(0, digits - 1)  # 9.9994 rounds to 10.0, not "10.00"
        rounded = round(v, digits)
    return f"{rounded:.{digits}f}"
