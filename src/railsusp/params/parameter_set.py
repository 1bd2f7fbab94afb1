"""A complete, validated set of the twenty catalogue parameters (:class:`ParameterSet`): SI
inside, the study's display units (MN/m, mm, ...) at the edges, read from a mapping or a TOML
file, every value checked against its Table 2 range or plausible span on construction."""

from __future__ import annotations

import os
import tomllib
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Literal

import numpy as np

from railsusp.errors import ParameterError, RailsuspInputError
from railsusp.numbers import is_real
from railsusp.params.catalogue import CATALOGUE, SYMBOLS, ParameterSpec, spec

Units = Literal["si", "display"]


def _check_units(units: object) -> None:
    if units not in ("si", "display"):
        raise ParameterError(f"units must be 'si' or 'display', got {units!r}")


def _keyed(values: object) -> list[tuple[ParameterSpec, object]]:
    """The (spec, value) pairs of a mapping of symbols or names to values; anything else (a
    list of pairs, a string, a key that is not a string) is a one-line ParameterError."""
    if values is None:
        return []
    if not isinstance(values, Mapping):
        raise ParameterError(
            f"parameter values: a mapping {{symbol: value}} is needed, not "
            f"{type(values).__name__} (e.g. {{'X13': 16.1}}; text: parse_overrides)"
        )
    out: list[tuple[ParameterSpec, object]] = []
    given: dict[str, str] = {}
    for key, value in values.items():
        if not isinstance(key, str):
            raise ParameterError(f"parameter {key!r}: a symbol or name (a string) is needed")
        s = spec(key)
        if s.symbol in given:  # X13 and primary_longitudinal_stiffness: which one holds?
            raise ParameterError(
                f"parameter {key!r}: {s.symbol} is given twice (also as {given[s.symbol]!r}); "
                "give each parameter once"
            )
        given[s.symbol] = key
        out.append((s, value))
    return out


def _to_si(s: ParameterSpec, value: object, units: str) -> object:
    """``value`` in SI for ``units`` = 'display' (left as given when it is not a number, for
    :meth:`ParameterSpec.check` to name it)."""
    if units != "display" or not is_real(value):
        return value
    return float(value) * s.scale  # type: ignore[arg-type]


class ParameterSet(Mapping[str, float]):
    """A complete, validated set of the 20 catalogue parameters, in SI units.

    Keys are symbols (``"X13"``); lookup also accepts names. Parameters not given take their
    nominal value. Construction raises :class:`ParameterError` naming the parameter, value
    and accepted range for unknown names, non-finite values, and sampled parameters outside
    their Table 2 range.

    >>> p = ParameterSet({"X13": 16.1}, units="display")
    >>> p.display("X13"), round(p["X13"])
    (16.1, 16100000)
    """

    __slots__ = ("_values",)

    def __init__(self, values: Mapping[str, float] | None = None, *, units: Units = "si"):
        _check_units(units)
        data = {s.symbol: s.nominal for s in CATALOGUE}
        for s, value in _keyed(values):
            data[s.symbol] = s.check(_to_si(s, value, units))
        self._values = data

    @classmethod
    def nominal(cls) -> ParameterSet:
        """The study's nominal parameter set (Table 1)."""
        return cls()

    def replace(self, values: Mapping[str, float], *, units: Units = "si") -> ParameterSet:
        """A copy with some parameters changed (given in ``units``)."""
        _check_units(units)
        merged: dict[str, float] = dict(self._values)
        for s, value in _keyed(values):
            merged[s.symbol] = _to_si(s, value, units)
        return ParameterSet(merged)  # checks every value

    def __getitem__(self, key: str) -> float:
        return self._values[spec(key).symbol]

    def __contains__(self, key: object) -> bool:
        """A catalogue parameter's symbol or name; anything else is not in the set (the
        Mapping contract: ``"X99" in p`` is False, not an error)."""
        try:
            spec(key)  # type: ignore[arg-type]
        except ParameterError:
            return False
        return True

    def get(self, key: str, default: float | None = None) -> float | None:  # type: ignore[override]
        """The SI value of ``key`` (symbol or name), ``default`` for anything else."""
        return self[key] if key in self else default

    def __iter__(self) -> Iterator[str]:
        return iter(SYMBOLS)

    def __len__(self) -> int:
        return len(SYMBOLS)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ParameterSet):
            return NotImplemented
        return self._values == other._values

    def __hash__(self) -> int:
        return hash(tuple(self._values.items()))

    def __repr__(self) -> str:
        changed = {k: self.display(k) for k in SYMBOLS if self._values[k] != spec(k).nominal}
        return f"ParameterSet(changed from nominal: {changed or 'none'}, display units)"

    def display(self, key: str) -> float:
        """Value of one parameter in its display unit."""
        s = spec(key)
        return s.to_display(self._values[s.symbol])

    def to_display(self) -> dict[str, float]:
        """All values keyed by symbol, in display units."""
        return {k: self.display(k) for k in SYMBOLS}

    def to_array(self, symbols: Iterable[str] = SYMBOLS) -> np.ndarray:
        """SI values of ``symbols`` as a float array (catalogue order by default)."""
        return np.array([self[s] for s in symbols], dtype=float)

    @classmethod
    def from_toml(cls, source: str | Path) -> ParameterSet:
        """Read display-unit values from a TOML file (or TOML text).

        The values may sit at top level or in a ``[parameters]`` table, keyed by symbol or
        name: ``X13 = 16.1`` or ``primary_longitudinal_stiffness = 16.1`` (MN/m).
        """
        text, where = _read_text(source)
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ParameterError(f"{where}: not valid TOML ({exc})") from None
        table = doc.get("parameters", doc)
        if not isinstance(table, dict):
            raise ParameterError(f"{where}: [parameters] must be a table of name = value")
        beside = [k for k in doc if k != "parameters"] if table is not doc else []
        if beside:  # ignored before: a value at the top or in a misspelt table was lost
            raise ParameterError(
                f"{where}: {', '.join(beside)} beside the [parameters] table; accepted the "
                "values at the top level or in [parameters], not both"
            )
        for key, value in table.items():  # as strictly as the other files: "16.1" is a slip
            if isinstance(value, str):
                raise ParameterError(
                    f"{where}: {key} = {value!r}: a number is needed, not a string (write it "
                    "without quotes)"
                )
        try:
            return cls(table, units="display")
        except ParameterError as exc:
            raise ParameterError(f"{where}: {exc}") from None


def _read_text(source: str | Path) -> tuple[str, str]:
    """The TOML text of ``source`` (a file path, or the text itself) and where it is from:
    a string holding no ``=`` cannot be TOML values, so it is taken for a path."""
    if not isinstance(source, str | os.PathLike):
        raise ParameterError(
            f"parameter file {source!r}: a path (str or Path) or TOML text is needed"
        )
    path = Path(source) if not (isinstance(source, str) and "\n" in source) else None
    if path is not None and path.exists():
        from railsusp.store import read_toml

        try:
            read_toml(path, "parameter file")  # one-line errors: folder, unreadable, binary
        except RailsuspInputError as exc:
            raise ParameterError(str(exc)) from None
        return path.read_text(encoding="utf-8-sig"), str(path)
    if not isinstance(source, str) or source.endswith(".toml") or "=" not in source:
        raise ParameterError(f"parameter file {source} does not exist")
    return str(source), "<toml text>"
