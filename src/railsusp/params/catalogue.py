"""Parameter catalogue of the C80 wagon / K6 bogie model (Tables 1 and 2 of the reference study).

Twenty parameters X1..X20 with their nominal values; the ten *main suspension parameters*
X11..X20 carry the sampling ranges of Table 2 (nominal -50 % .. +50 %). Values are held in SI
inside the code; the study's units (MN/m, mm, ...) are used only for display and user input.

Units the study got wrong, and what railsusp uses instead (values typed by users stay the
study's numbers, only the unit label changes):

* X18, "secondary suspension lateral shock absorber damping", 50 MN·s/m. A K6 bogie has no
  hydraulic lateral damper; its lateral damping comes from the friction wedges. 50 MN·s/m would
  lock the bolster to the side frames (critical damping of the bolster on 1.8 MN/m is about
  60 kN·s/m). We read the value as **50 kN·s/m**, an equivalent viscous lateral damping per
  spring nest, which is physically the right order. Since the friction-wedge element the
  model takes X18 / 50 kN·s/m as the wedges' friction level (their normal forces), see
  docs/parameters.md.
* X19, "swing arm node longitudinal/vertical stiffness", 30 000 MN/m. The K6 has no swing
  arm; the elastic nodes it has are those of the cross-bracing bars whose pin-hole spans are
  X9 and X10. 30 GN/m is stiffer than the steel bar itself (EA/L about 70 MN/m), so we read the
  value as **30 000 kN/m = 30 MN/m**, the axial stiffness of one cross-bracing bar with its
  rubber nodes.
* X20, "primary spring longitudinal/lateral stiffness", 1000 MN/m. Taken at face value
  (**1 GN/m**): the contact stiffness of the bearing-adapter seat, acting in series with the
  primary shear pad (X13, X14). Being stiff, its influence is weak, in line with the study
  not finding it a key parameter.
* X12, "stop clearance", 12 mm: the lateral gib clearance between bolster and side frame.
* X11, "lateral span of resilient side bearing", 1.52 m: the distance between the two
  constant-contact side bearers on one bolster.

Table 1 lists X16/X17 as the secondary longitudinal/lateral stiffness per bogie side (spring
nest shear stiffness) and X13-X15 per axle box (primary rubber pad); see docs/parameters.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from railsusp.errors import ParameterError
from railsusp.numbers import is_real


@dataclass(frozen=True)
class ParameterSpec:
    """One catalogue entry: symbol, engineering name, units and nominal value (display units).

    ``scale`` converts a display-unit value to SI (``si = display * scale``). ``bounds`` is the
    sampling range of Table 2 in display units, or None for fixed (non-sampled) parameters.
    """

    symbol: str
    name: str
    description: str
    display_unit: str
    si_unit: str
    scale: float
    nominal_display: float
    bounds_display: tuple[float, float] | None = None
    table_unit: str | None = None
    note: str = ""

    @property
    def nominal(self) -> float:
        """Nominal value in SI units."""
        return self.nominal_display * self.scale

    @property
    def bounds(self) -> tuple[float, float] | None:
        """Sampling range in SI units, or None for a fixed parameter."""
        if self.bounds_display is None:
            return None
        lo, hi = self.bounds_display
        return lo * self.scale, hi * self.scale

    @property
    def is_sampled(self) -> bool:
        """True for the main suspension parameters that carry a Table 2 range."""
        return self.bounds_display is not None

    def to_display(self, value_si: float) -> float:
        """Convert an SI value to this parameter's display unit."""
        return value_si / self.scale

    @property
    def plausible_display(self) -> tuple[float, float]:
        """Accepted values in display units: the sampling range of a sampled parameter; for
        a fixed one (a mass, an inertia) a tenth to ten times its nominal value, which covers
        any freight wagon and refuses typing slips such as ``X1=1e15``."""
        if self.bounds_display is not None:
            return self.bounds_display
        return self.nominal_display / FIXED_FACTOR, self.nominal_display * FIXED_FACTOR

    def range_text(self) -> str:
        """Human-readable accepted range in display units, for error messages."""
        lo, hi = self.plausible_display
        return f"[{lo:g}, {hi:g}] {self.display_unit}"

    def check(self, value_si: float) -> float:
        """Return ``value_si`` as float after validation; raise ParameterError otherwise."""
        try:
            if not is_real(value_si):  # a boolean, text ("16.1", converted by float) or bytes
                raise TypeError("not a real number")
            value = float(value_si)
        except (TypeError, ValueError):
            raise ParameterError(
                f"{self.symbol} ({self.description}) = {value_si!r} is not a number; "
                f"accepted range {self.range_text()}"
            ) from None
        shown = self.to_display(value) if math.isfinite(value) else value
        if not math.isfinite(value):
            raise ParameterError(
                f"{self.symbol} ({self.description}) = {shown} is not finite; "
                f"accepted range {self.range_text()}"
            )
        bounds = self.bounds
        if bounds is None:
            if value <= 0.0:
                raise ParameterError(
                    f"{self.symbol} ({self.description}) = {shown:g} {self.display_unit} "
                    f"must be positive; accepted range {self.range_text()}"
                )
            lo, hi = (v * self.scale for v in self.plausible_display)
            if not lo <= value <= hi:
                raise ParameterError(
                    f"{self.symbol} ({self.description}) = {shown:g} {self.display_unit} is "
                    f"outside the accepted range {self.range_text()} (a tenth to ten times "
                    f"the nominal value of this fixed parameter)"
                )
        else:
            lo, hi = bounds
            # Tolerate round-off from unit conversion at the range ends.
            tol = 1e-9 * max(abs(lo), abs(hi))
            if not lo - tol <= value <= hi + tol:
                raise ParameterError(
                    f"{self.symbol} ({self.description}) = {shown:g} {self.display_unit} is "
                    f"outside the accepted range {self.range_text()}"
                )
        return value


def _spec(symbol, name, description, unit, si_unit, scale, nominal, bounds=None, **kw):
    return ParameterSpec(symbol, name, description, unit, si_unit, scale, nominal, bounds, **kw)


_MN = 1.0e6
_KN = 1.0e3
#: a fixed parameter is accepted from its nominal value / FIXED_FACTOR to times FIXED_FACTOR
FIXED_FACTOR = 10.0


def _stiffness_mn(symbol, name, description, nominal, bounds):
    """A sampled stiffness as the study gives it, in MN/m (held in N/m): the unit, SI unit
    and scale of Table 2's six entries in that unit written once, so they cannot
    disagree."""
    return _spec(symbol, name, description, "MN/m", "N/m", _MN, nominal, bounds)


#: Table 1 and Table 2 of the study, in study order.
CATALOGUE: tuple[ParameterSpec, ...] = (
    _spec("X1", "wheelset_mass", "wheelset mass", "kg", "kg", 1.0, 1200.0),
    _spec(
        "X2",
        "wheelset_roll_inertia",
        "wheelset roll moment of inertia",
        "kg·m²",
        "kg·m²",
        1.0,
        800.0,
    ),
    _spec(
        "X3",
        "wheelset_pitch_inertia",
        "wheelset pitch (spin) moment of inertia",
        "kg·m²",
        "kg·m²",
        1.0,
        110.0,
    ),
    _spec(
        "X4", "wheelset_yaw_inertia", "wheelset yaw moment of inertia", "kg·m²", "kg·m²", 1.0, 800.0
    ),
    _spec(
        "X5", "adapter_mass", "bearing adapter (load-bearing saddle) mass", "kg", "kg", 1.0, 27.0
    ),
    _spec(
        "X6",
        "adapter_roll_inertia",
        "bearing adapter roll moment of inertia",
        "kg·m²",
        "kg·m²",
        1.0,
        0.4,
    ),
    _spec(
        "X7",
        "adapter_pitch_inertia",
        "bearing adapter pitch moment of inertia",
        "kg·m²",
        "kg·m²",
        1.0,
        0.2,
    ),
    _spec(
        "X8",
        "adapter_yaw_inertia",
        "bearing adapter yaw moment of inertia",
        "kg·m²",
        "kg·m²",
        1.0,
        0.4,
    ),
    _spec(
        "X9",
        "cross_brace_longitudinal_span",
        "longitudinal span of cross-bracing pin holes",
        "m",
        "m",
        1.0,
        1.0,
    ),
    _spec(
        "X10",
        "cross_brace_lateral_span",
        "lateral span of cross-bracing pin holes",
        "m",
        "m",
        1.0,
        1.981,
    ),
    _spec(
        "X11",
        "side_bearer_lateral_span",
        "lateral span of the resilient side bearers",
        "m",
        "m",
        1.0,
        1.52,
        (0.76, 2.28),
    ),
    _spec(
        "X12",
        "lateral_stop_clearance",
        "bolster lateral stop (gib) clearance",
        "mm",
        "m",
        1.0e-3,
        12.0,
        (6.0, 18.0),
    ),
    _stiffness_mn(
        "X13",
        "primary_longitudinal_stiffness",
        "primary longitudinal stiffness per axle box",
        14.0,
        (7.0, 21.0),
    ),
    _stiffness_mn(
        "X14",
        "primary_lateral_stiffness",
        "primary lateral stiffness per axle box",
        10.0,
        (5.0, 15.0),
    ),
    _stiffness_mn(
        "X15",
        "primary_vertical_stiffness",
        "primary vertical stiffness per axle box",
        170.0,
        (85.0, 255.0),
    ),
    _stiffness_mn(
        "X16",
        "secondary_longitudinal_stiffness",
        "secondary longitudinal stiffness per spring nest",
        1.8,
        (0.9, 2.7),
    ),
    _stiffness_mn(
        "X17",
        "secondary_lateral_stiffness",
        "secondary lateral stiffness per spring nest",
        1.8,
        (0.9, 2.7),
    ),
    _spec(
        "X18",
        "secondary_lateral_damping",
        "secondary lateral damping per spring nest (friction-wedge equivalent)",
        "kN·s/m",
        "N·s/m",
        _KN,
        50.0,
        (25.0, 75.0),
        table_unit="MN·s/m",
        note="study prints MN·s/m; read as kN·s/m (see module docstring)",
    ),
    _spec(
        "X19",
        "cross_brace_node_stiffness",
        "cross-bracing bar axial (elastic node) stiffness",
        "kN/m",
        "N/m",
        _KN,
        30000.0,
        (15000.0, 45000.0),
        table_unit="MN/m",
        note="study prints MN/m ('swing arm node'); read as kN/m (see module docstring)",
    ),
    _stiffness_mn(
        "X20",
        "adapter_seat_stiffness",
        "primary spring long./lat. stiffness (adapter seat, series with X13/X14)",
        1000.0,
        (500.0, 1500.0),
    ),
)

_BY_KEY: dict[str, ParameterSpec] = {}
for _s in CATALOGUE:
    _BY_KEY[_s.symbol] = _s
    _BY_KEY[_s.symbol.lower()] = _s
    _BY_KEY[_s.name] = _s

#: Symbols in catalogue order.
SYMBOLS: tuple[str, ...] = tuple(s.symbol for s in CATALOGUE)
#: The ten main suspension parameters of the study (sampled, X11..X20).
MAIN_SUSPENSION: tuple[str, ...] = tuple(s.symbol for s in CATALOGUE if s.is_sampled)
#: The six key parameters the study selected by Sobol analysis (its Section 2.2).
STUDY_KEY_PARAMETERS: tuple[str, ...] = ("X13", "X14", "X15", "X16", "X17", "X18")


def spec(key: str) -> ParameterSpec:
    """Look up a parameter by symbol (``"X13"``, case-insensitive) or name."""
    if not isinstance(key, str):
        raise ParameterError(
            f"parameter {key!r}: a symbol or name (a string) is needed, e.g. X13 or "
            "primary_longitudinal_stiffness"
        )
    try:
        return _BY_KEY[key.strip()] if key.strip() in _BY_KEY else _BY_KEY[key.strip().lower()]
    except KeyError:
        raise ParameterError(
            f"unknown parameter {key!r}; accepted: X1..X20 or their names "
            f"(e.g. X13 or primary_longitudinal_stiffness)"
        ) from None


def bounds(symbols: Iterable[str]) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper sampling bounds (SI) of the given sampled parameters, as arrays."""
    specs = [spec(s) for s in symbols]
    for s in specs:
        if s.bounds is None:
            raise ParameterError(f"{s.symbol} ({s.description}) is fixed and has no range")
    lo = np.array([s.bounds[0] for s in specs])  # type: ignore[index]
    hi = np.array([s.bounds[1] for s in specs])  # type: ignore[index]
    return lo, hi
