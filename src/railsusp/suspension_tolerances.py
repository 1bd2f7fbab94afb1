"""The wagon's tolerances on its suspension elements: how far (% of the nominal value) each
element may have moved from nominal and still be judged "within tolerance", from the wagon
data file's ``[tolerances]`` table (docs/wagon-data.md) or railsusp's default.

A module of its own because the tolerances are the wagon's data, read and checked before any
stage runs (the pipeline records them in ``pipeline.json``, the configuration check refuses a
bad table), while :mod:`railsusp.summary` reads a finished run directory and judges its
estimate against them.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_real
from railsusp.params import MAIN_SUSPENSION, spec

#: change from nominal (% of the nominal value) that an element may show and still be
#: "within tolerance", where the wagon data give no ``[tolerances]`` (docs/wagon-data.md)
DEFAULT_TOLERANCE_PCT = 15.0


@dataclass(frozen=True)
class Tolerances:
    """Accepted change of each suspension element from its nominal value, % of nominal."""

    default_pct: float = DEFAULT_TOLERANCE_PCT
    parameters: Mapping[str, float] = field(default_factory=dict)
    #: whether a wagon data file's ``[tolerances]`` table gave them (what the report names
    #: as their source; not part of the comparison)
    from_wagon: bool = field(default=False, compare=False)

    def __post_init__(self) -> None:
        """Each tolerance in (0, 100] % and keyed by a main suspension parameter (symbol or
        name, kept as its symbol): a negative or NaN tolerance would judge every element
        degraded, a misspelt key would fall back to the default unseen."""
        default, per = _checked("Tolerances", self.default_pct, self.parameters)
        object.__setattr__(self, "default_pct", default)
        object.__setattr__(self, "parameters", per)

    def __hash__(self) -> int:  # the dataclass's hash of its fields fails on the dict
        return hash((self.default_pct, tuple(sorted(self.parameters.items()))))

    def of(self, parameter: str) -> float:
        """The tolerance of one main suspension parameter (symbol or name), % of its nominal
        value; anything else is refused, as in the table."""
        _, per = _checked("Tolerances.of", self.default_pct, {parameter: self.default_pct})
        return float(self.parameters.get(next(iter(per)), self.default_pct))

    def to_dict(self) -> dict:
        """``{"default_pct": ..., "parameters": {symbol: %}}``, as a run's pipeline.json
        records them (:meth:`from_dict` reads it back)."""
        return {
            "default_pct": self.default_pct,
            "parameters": dict(self.parameters),
            "from_wagon": self.from_wagon,
        }

    @classmethod
    def from_dict(cls, doc: object, where: str = "tolerances") -> Tolerances:
        """The tolerances :meth:`to_dict` wrote, checked as the constructor checks them."""
        keys = {"default_pct", "parameters"}
        if not isinstance(doc, Mapping) or not keys <= set(doc) <= keys | {"from_wagon"}:
            raise RailsuspInputError(
                f"{where}: accepted a table of default_pct and parameters, not {doc!r}"
            )
        # a run recorded before the source was: tolerances other than the defaults were
        # the wagon data's
        default, per = _checked(where, doc["default_pct"], doc["parameters"])
        wagon = doc.get("from_wagon", (default, per) != (DEFAULT_TOLERANCE_PCT, {}))
        return cls(default, per, bool(wagon))


def _check_pct(where: str, key: str, value: object) -> float:
    if not is_real(value) or not 0.0 < float(value) <= 100.0:  # type: ignore[arg-type]
        raise RailsuspInputError(
            f"{where}: tolerances.{key} = {value!r}: accepted a number in (0, 100] "
            "(% of the nominal value)"
        )
    return float(value)  # type: ignore[arg-type]


def read_tolerances(wagon: str | Path | None = None) -> Tolerances:
    """The ``[tolerances]`` table of a wagon data file, or of a packaged wagon named as
    :func:`~railsusp.vehicle.wagon.load_wagon` takes it (``"tare"``): ``default_pct`` and one
    entry per main suspension parameter (``X13 = 10.0``), % of the nominal value; the
    defaults (:data:`DEFAULT_TOLERANCE_PCT` for every element) where the table is absent
    (None: the embedded C80/K6 data, which have none)."""
    from railsusp.vehicle.wagon import packaged_wagon_text

    if wagon is None:
        return Tolerances()
    path = Path(wagon)
    packaged = packaged_wagon_text(wagon)
    if packaged is not None:
        text, where = packaged, f"packaged wagon {wagon}"
    elif not path.is_file():
        raise RailsuspInputError(f"wagon file {path} does not exist")
    else:
        text, where = path.read_text("utf-8-sig"), str(path)
    try:
        doc = tomllib.loads(text).get("tolerances", {})
    except tomllib.TOMLDecodeError as exc:
        raise RailsuspInputError(f"{where}: not valid TOML ({exc})") from None
    if not isinstance(doc, dict):
        raise RailsuspInputError(f"{where}: tolerances must be a table ([tolerances])")
    per = {k: v for k, v in doc.items() if k != "default_pct"}
    default = doc.get("default_pct", DEFAULT_TOLERANCE_PCT)
    return Tolerances(*_checked(where, default, per, "default_pct or "), from_wagon=bool(doc))


def _checked(
    where: str, default: object, per: object, also: str = ""
) -> tuple[float, dict[str, float]]:
    """``default`` and ``per`` (a mapping of main suspension parameter to tolerance) checked
    (one line naming ``where`` and the key otherwise), keys as symbols."""
    if not isinstance(per, Mapping):
        raise RailsuspInputError(
            f"{where}: tolerances per parameter: a mapping {{symbol: %}} is needed, not "
            f"{type(per).__name__}"
        )
    out = {}
    for key, value in per.items():
        try:
            symbol = spec(str(key)).symbol
        except RailsuspInputError:
            symbol = None
        if symbol not in MAIN_SUSPENSION:
            raise RailsuspInputError(
                f"{where}: tolerances.{key}: accepted {also}a main suspension "
                f"parameter ({', '.join(MAIN_SUSPENSION)})"
            )
        if symbol in out:
            raise RailsuspInputError(f"{where}: tolerances.{key}: {symbol} is given twice")
        out[symbol] = _check_pct(where, str(key), value)
    return _check_pct(where, "default_pct", default), out
