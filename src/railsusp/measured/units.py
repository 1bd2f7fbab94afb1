"""Units of recorded channels: the unit a file states, its conversion to SI, and the check
that a channel's magnitude agrees with its stated unit.

Measurement systems write forces in N or kN, speeds in km/h or m/s, positions in m or km.
A channel is converted from the unit the file states; a unit that is missing, unknown or
contradicted by the magnitude (a wheel load of 0.08 "kN": the data are in MN) is refused
with the channel named, never guessed.
"""

from __future__ import annotations

import re

from railsusp.errors import RailsuspInputError

#: accepted unit spellings per quantity, with the factor to SI (N, m/s, m, 1/m, m, ‰ -> 1)
UNITS: dict[str, dict[str, float]] = {
    "force": {"N": 1.0, "kN": 1e3, "MN": 1e6, "daN": 10.0},
    "speed": {"m/s": 1.0, "km/h": 1 / 3.6, "kmh": 1 / 3.6, "kph": 1 / 3.6},
    "position": {"m": 1.0, "km": 1e3},
    "curvature": {"1/m": 1.0, "1/km": 1e-3},
    "cant": {"m": 1.0, "mm": 1e-3},
    "grade": {"permille": 1e-3, "‰": 1e-3, "%": 1e-2, "1": 1.0, "-": 1.0, "m/m": 1.0},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "min": 60.0, "h": 3600.0},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0, "g": 9.80665},
}

_ALIASES = {
    "kmph": "km/h",
    "km/hr": "km/h",
    "mps": "m/s",
    "per_km": "1/km",
    "per_m": "1/m",
    "sec": "s",
    "secs": "s",
    "second": "s",
    "seconds": "s",
    "msec": "ms",
    "millisecond": "ms",
    "milliseconds": "ms",
    "minute": "min",
    "minutes": "min",
    "usec": "us",
    "μs": "µs",  # the Greek mu, as the micro sign
}


def normalise_unit(unit: str | None) -> str | None:
    """A unit string as written in ``UNITS`` (spaces dropped, ``_per_`` as ``/``); None for
    an empty unit."""
    if unit is None:
        return None
    u = unit.strip().replace(" ", "")
    if not u:
        return None
    u = _ALIASES.get(u, u)
    u = re.sub(r"^1_per_", "1/", u)
    return u


def si_factor(quantity: str, unit: str | None, channel: str) -> float:
    """Factor taking ``channel`` from its stated ``unit`` to SI for ``quantity``; a missing or
    unknown unit is an error naming the channel and the accepted units."""
    accepted = UNITS[quantity]
    u = normalise_unit(unit)
    if u is None:
        raise RailsuspInputError(
            f"channel {channel!r}: no unit stated; a {quantity} channel needs one of "
            f"{', '.join(accepted)} (in the file, or 'unit' in the channel map)"
        )
    for name, factor in accepted.items():
        if u == name or (u.lower() == name.lower() and name not in ("MN", "mm", "m")):
            return factor
    raise RailsuspInputError(
        f"channel {channel!r}: unit {unit!r} is not a {quantity} unit; accepted "
        f"{', '.join(accepted)}"
    )


_HEADER = re.compile(r"^\s*(?P<name>.+?)\s*(?:\[(?P<b>[^\]]*)\]|\((?P<p>[^)]*)\))\s*$")
_SUFFIXES = (
    "1_per_km",
    "1_per_m",
    "permille",
    "kN",
    "MN",
    "daN",
    "N",
    "kmh",
    "kmph",
    "kph",
    "km_h",
    "mps",
    "m_s",
    "km",
    "mm",
    "ms",
    "m",
    "s",
    "g",
)


def split_header(header: str) -> tuple[str, str | None]:
    """A table header as (name, unit): ``Y [kN]`` and ``Y (kN)`` -> (``Y``, ``kN``);
    ``Y_kN`` -> (``Y``, ``kN``) for the usual unit suffixes; otherwise (header, None)."""
    m = _HEADER.match(header)
    if m:
        return m.group("name"), (m.group("b") or m.group("p") or "").strip() or None
    for suf in _SUFFIXES:
        if header.endswith("_" + suf) and len(header) > len(suf) + 1:
            unit = {"km_h": "km/h", "m_s": "m/s", "1_per_km": "1/km", "1_per_m": "1/m"}.get(
                suf, suf
            )
            return header[: -len(suf) - 1], unit
    return header, None


def named(headers, name: str):
    """The first of ``headers`` whose name less its unit (:func:`split_header`) is ``name``
    (``speed_kmh``, ``speed_mps`` and ``speed [m/s]`` are all ``speed``), or None."""
    return next((h for h in headers if split_header(h)[0] == name), None)


#: plausible median magnitude of a channel in SI, per quantity: (low, high). A wheel load
#: (Q) of a loaded or empty freight wagon is 20-250 kN; a lateral force's median |Y| can be
#: small, so only its maximum is bounded above.
PLAUSIBLE_MEDIAN_SI: dict[str, tuple[float, float]] = {
    "Q": (10e3, 300e3),
    "speed": (0.0, 100.0),
}
PLAUSIBLE_MAX_SI: dict[str, float] = {"Y": 400e3, "Q": 800e3, "speed": 100.0}
