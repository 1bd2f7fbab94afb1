"""Parameters as users type them: a list of sampled symbols (``--parameters X13,X14``),
overrides (``X13=16.1,X14=8.3``) and a matrix of sampled values; each refused in one line
naming the option, the parameter and its accepted range."""

from __future__ import annotations

import re
from collections.abc import Iterable

import numpy as np

from railsusp.errors import ParameterError, repeated
from railsusp.params.catalogue import MAIN_SUSPENSION, spec


def parse_sampled(text: str, option: str = "--parameters") -> tuple[str, ...]:
    """Symbols of a comma-separated list of sampled parameters (``"X13,X14"``, names
    accepted), each known, with a range, and given once; else one line naming ``option``."""
    accepted = f"accepted a comma-separated list of {MAIN_SUSPENSION[0]}..{MAIN_SUSPENSION[-1]}"
    out: list[str] = []
    for part in (p.strip() for p in text.split(",")):
        try:
            s = spec(part)
        except ParameterError:
            raise ParameterError(
                f"{option} {text}: unknown parameter {part!r}; {accepted}"
            ) from None
        if s.bounds is None:
            raise ParameterError(f"{option} {text}: {s.symbol} is fixed (no range); {accepted}")
        if s.symbol in out:
            raise ParameterError(f"{option} {text}: {s.symbol} is given twice")
        out.append(s.symbol)
    return tuple(out)


#: a number as an override may give it: plain ASCII decimal, one optional sign, a point
#: and an exponent (16.1, -5, .5, 1.5e3), nothing that Python's float() takes besides
#: (underscores "1_6", other scripts' digits "０", "nan", "inf")
_DECIMAL = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
#: the accepted form, as the refusal says it
DECIMAL_FORM = "a plain decimal number: digits, an optional sign, point and exponent (e.g. 16.1)"


def parse_overrides(items: str | Iterable[str]) -> dict[str, float]:
    """Parse ``"X13=16.1,X14=8.3"`` (or a list of ``"X13=16.1"``) into display-unit values.

    Keys are validated against the catalogue; values must be plain ASCII decimal numbers
    (:data:`DECIMAL_FORM`): Python's ``float()`` also reads ``1_6`` as 16 and a full-width
    ``０`` as 0, which a mistyped override should not become. Range checks happen when the
    values are put into a :class:`ParameterSet`.
    """
    given = [items] if isinstance(items, str) else items
    given = list(given) if isinstance(given, Iterable) else None
    if given is None or not all(isinstance(i, str) for i in given):
        raise ParameterError(
            f"overrides {items!r}: accepted text such as 'X13=16.1,X14=8.3' or a list of "
            "'X13=16.1' items"
        )
    parts: list[str] = []
    for item in given:
        parts.extend(p for p in item.replace(";", ",").split(",") if p.strip())
    out: dict[str, float] = {}
    for part in parts:
        if "=" not in part:
            raise ParameterError(f"override {part.strip()!r} must look like X13=16.1")
        key, _, raw = part.partition("=")
        s = spec(key)
        if s.symbol in out:
            raise ParameterError(
                f"override {part.strip()!r}: {s.symbol} is given twice; give each parameter once"
            )
        text = raw.strip(" \t")
        if _DECIMAL.fullmatch(text) is None:
            raise ParameterError(
                f"override {part.strip()!r}: {raw.strip()!r} is not a number; accepted "
                f"{DECIMAL_FORM}, for {s.symbol} in the range {s.range_text()}"
            )
        out[s.symbol] = float(text)
    return out


def check_matrix(symbols: Iterable[str], matrix: np.ndarray) -> np.ndarray:
    """Validate an (n_sets, n_symbols) matrix of SI values of sampled parameters.

    Returns the matrix as a float array; raises ParameterError naming the first offending
    row, parameter, value and range.
    """
    syms = [spec(s).symbol for s in symbols]
    twice = repeated(syms)
    if twice:
        raise ParameterError(f"symbols: {', '.join(twice)} given twice; give each column once")
    try:
        x = np.asarray(matrix, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(
            f"parameter matrix: numbers in shape (n_sets, {len(syms)}) are needed"
        ) from None
    if x.ndim != 2 or x.shape[1] != len(syms):
        raise ParameterError(
            f"parameter matrix must have shape (n_sets, {len(syms)}) for {syms}, got {x.shape}"
        )
    for j, sym in enumerate(syms):
        col = x[:, j]
        s = spec(sym)
        # a fixed parameter: inside its plausible range, as ParameterSet checks it
        lo, hi = (v * s.scale for v in s.plausible_display) if s.bounds is None else s.bounds
        tol = 1e-9 * max(abs(lo), abs(hi))
        bad = ~np.isfinite(col) | (col < lo - tol) | (col > hi + tol)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            try:
                s.check(col[i])
            except ParameterError as exc:
                raise ParameterError(f"row {i}: {exc}") from None
    return x
