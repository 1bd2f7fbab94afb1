"""The working-condition model (speed, track layout: curve, cant, spirals, grade;
irregularities, synthesised or measured; coupler load), validated on construction, and its
strict construction from a dict with one-line errors.

A :class:`WorkingCondition` is kept apart from the wagon (``params``) and from the equations
(``vehicle``), PyBaMM-style. Fields carry engineering units in their names (km/h, mm, per
mille, kN) because they are user input; its properties (``speed``, ``cant``, ``grade``, ...)
give SI values for the simulator. The model, :func:`make_condition` (through which
:meth:`~WorkingCondition.with_changes` builds a copy) and the error messages that read the
fields' ranges (:func:`field_range`) call one another, so they are one module, apart from the
study's three conditions built from it (:mod:`railsusp.conditions`, which re-exports the names
of this module that other modules import)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    ValidationError,
    model_serializer,
    model_validator,
)

from railsusp.errors import ConditionError
from railsusp.numbers import is_real

GRAVITY = 9.81  # m/s^2
#: A condition name becomes a folder of run directories: a safe slug (no '/', no '..' alone,
#: no absolute path), so that no condition can make a campaign write outside its run.
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$"
#: Lateral distance over which cant is measured (rail-head centres, Chinese practice), m.
CANT_BASE_M = 1.5


def _f(default: Any, lo: float | None, hi: float | None, unit: str, doc: str, **kw: Any):
    """A bounded float field whose range and unit are reported in error messages."""
    extra = {"unit": unit}
    ge = {} if lo is None else {"ge": lo}
    le = {} if hi is None else {"le": hi}
    return Field(default, description=f"{doc} [{unit}]", json_schema_extra=extra, **ge, **le, **kw)


class WorkingCondition(BaseModel):
    """One working condition of the wagon on a track section (validated on construction)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    name: str = Field(
        "custom",
        min_length=1,
        max_length=64,
        pattern=NAME_PATTERN,
        description="label; also a folder name in run directories, so letters, digits, "
        "'_', '-' and '.', starting with a letter or digit",
    )
    speed_kmh: float = _f(60.0, 1.0, 200.0, "km/h", "running speed")
    duration_s: float = _f(20.0, 1.0, 600.0, "s", "recorded duration")
    n_steps: int = Field(1000, ge=10, le=1_000_000, description="output samples in the record")
    lead_in_m: float = _f(
        100.0,
        0.0,
        5000.0,
        "m",
        "track before the record (transients, entry spiral); a settled start runs only the "
        "last SolverSettings.run_in_m of it",
    )
    curve_radius_m: float | None = _f(
        None, 50.0, 100_000.0, "m", "circular-curve radius; None for tangent track"
    )
    curve_direction: Literal["left", "right"] = Field(
        "left", description="direction of the curve seen in the running direction"
    )
    cant_mm: float = _f(0.0, 0.0, 200.0, "mm", "superelevation of the outer rail in the arc")
    curve_start_m: float = _f(20.0, 0.0, 10_000.0, "m", "start of the entry spiral")
    entry_spiral_m: float = _f(0.0, 0.0, 1000.0, "m", "entry transition (clothoid) length")
    arc_length_m: float | None = _f(
        None, 0.0, 100_000.0, "m", "circular arc length; None: until the section end"
    )
    exit_spiral_m: float = _f(0.0, 0.0, 1000.0, "m", "exit transition (clothoid) length")
    grade_permille: float = _f(0.0, -40.0, 40.0, "‰", "longitudinal grade, + is up-grade")
    coupler_force_kN: float = _f(
        0.0, -3000.0, 3000.0, "kN", "longitudinal coupler force (+ tension) from the train"
    )
    irregularity_class: int | None = Field(
        5,
        ge=1,
        le=6,
        description='FRA/AAR track class of the irregularity PSD; None ("none" in a file): '
        "perfect track",
    )
    wavelength_min_m: float = _f(1.0, 0.1, 50.0, "m", "shortest irregularity wavelength")
    wavelength_max_m: float = _f(120.0, 2.0, 1000.0, "m", "longest irregularity wavelength")
    seed: int = Field(0, ge=0, le=2**63 - 1, description="irregularity random seed")
    track_geometry: str | None = Field(
        None,
        min_length=1,
        max_length=4096,
        pattern=r"(?i).*\.(csv|parquet)$",
        description=(
            "measured rail irregularities (a .csv or .parquet file, docs/data-format.md) "
            "replacing the synthesised ones; irregularity_class and seed are then unused"
        ),
    )
    track_offset_m: float = _f(
        0.0,
        -1000.0,
        1000.0,
        "m",
        "added to the track-geometry file's distances to align it with the recording",
    )
    track_accuracy_mm: float = _f(
        0.0,
        0.0,
        10.0,
        "mm",
        "RMS measurement error of each component of the track-geometry file, within its "
        "measured wavelengths (wavelength_min_m up); 0: exact. Limits the time-aligned "
        "comparison to the wavelengths the geometry resolves",
    )
    wheel_rail_friction: float = _f(0.3, 0.05, 0.8, "-", "wheel-rail friction coefficient")

    @model_serializer(mode="wrap")
    def _without_unset_track(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """Leave ``track_geometry`` out when it is None, ``track_offset_m`` and
        ``track_accuracy_mm`` when they are 0, so that the dump (and the content hashes of
        run directories made before these fields existed) stays as it was."""
        data = handler(self)
        if data.get("track_geometry", "") is None:
            del data["track_geometry"]
        if data.get("track_offset_m", 1.0) == 0.0:
            del data["track_offset_m"]
        if data.get("track_accuracy_mm", 1.0) == 0.0:
            del data["track_accuracy_mm"]
        return data

    @model_validator(mode="before")
    @classmethod
    def _no_booleans(cls, data: Any) -> Any:
        """``speed_kmh = true`` is a slip, not 1 km/h: no field takes a boolean."""
        if isinstance(data, dict):
            for key, value in data.items():  # unknown keys are extra_forbidden's to name
                if key in cls.model_fields and isinstance(value, bool):
                    raise ValueError(
                        f"{key} = {str(value).lower()}: a boolean is not accepted here"
                    )
        return data

    @model_validator(mode="before")
    @classmethod
    def _perfect_track(cls, data: Any) -> Any:
        """``irregularity_class = "none"``: perfect track, as None is in Python (TOML and
        JSON files have no null that a table can hold)."""
        if isinstance(data, dict):
            value = data.get("irregularity_class")
            if isinstance(value, str) and value.strip().lower() == "none":
                data = {**data, "irregularity_class": None}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> WorkingCondition:
        if self.wavelength_min_m >= self.wavelength_max_m:
            raise ValueError(
                f"wavelength_min_m = {self.wavelength_min_m:g} must be below "
                f"wavelength_max_m = {self.wavelength_max_m:g}"
            )
        if self.curve_radius_m is None and (
            self.cant_mm or self.entry_spiral_m or self.exit_spiral_m
        ):
            raise ValueError("cant_mm and spirals need a curve_radius_m")
        if self.track_accuracy_mm and self.track_geometry is None:
            raise ValueError(
                f"track_accuracy_mm = {self.track_accuracy_mm:g} needs a track_geometry file"
            )
        if self.track_offset_m and self.track_geometry is None:  # was taken and ignored
            raise ValueError(
                f"track_offset_m = {self.track_offset_m:g} needs a track_geometry file (it "
                "places the record on it)"
            )
        if self.curve_radius_m is not None and self.arc_length_m is not None:
            if self.arc_length_m <= 0 and not (self.entry_spiral_m or self.exit_spiral_m):
                raise ValueError("arc_length_m = 0 with no spirals leaves no curve")
        return self

    # ----- SI views -----
    @property
    def speed(self) -> float:
        """Running speed, m/s."""
        return self.speed_kmh / 3.6

    @property
    def cant(self) -> float:
        """Cant (superelevation) of the arc, m."""
        return self.cant_mm * 1e-3

    @property
    def cant_angle(self) -> float:
        """Cant angle of the arc, rad (over the 1.5 m rail-head base)."""
        return math.asin(self.cant / CANT_BASE_M)

    @property
    def grade(self) -> float:
        """Grade as a ratio (rise over run), + up."""
        return self.grade_permille * 1e-3

    @property
    def coupler_force(self) -> float:
        """Longitudinal coupler force, N (+ tension)."""
        return self.coupler_force_kN * 1e3

    @property
    def sample_interval(self) -> float:
        """Output sample interval, s."""
        return self.duration_s / self.n_steps

    @property
    def record_length_m(self) -> float:
        """Distance run while recording, m."""
        return self.speed * self.duration_s

    @property
    def section_length_m(self) -> float:
        """Distance run by the leading wheelset: lead-in plus recording, m."""
        return self.lead_in_m + self.record_length_m

    @property
    def curvature(self) -> float:
        """Signed curvature of the arc, 1/m (+ for a left-hand curve, y to the left)."""
        if self.curve_radius_m is None:
            return 0.0
        sign = 1.0 if self.curve_direction == "left" else -1.0
        return sign / self.curve_radius_m

    @property
    def balance_cant_mm(self) -> float:
        """Cant that balances the centripetal acceleration at this speed, mm (0 on tangent)."""
        if self.curve_radius_m is None:
            return 0.0
        return CANT_BASE_M * 1e3 * self.speed**2 / (GRAVITY * self.curve_radius_m)

    @property
    def cant_deficiency_mm(self) -> float:
        """Balance cant minus actual cant, mm."""
        return self.balance_cant_mm - self.cant_mm if self.curve_radius_m else 0.0

    @property
    def kind(self) -> str:
        """'curve', 'grade' or 'tangent', for display."""
        if self.curve_radius_m is not None:
            return "curve"
        return "grade" if self.grade_permille else "tangent"

    def describe(self) -> str:
        """One-line summary in engineering units."""
        parts = [f"{self.speed_kmh:g} km/h"]
        if self.curve_radius_m is not None:
            parts.append(
                f"R {self.curve_radius_m:g} m {self.curve_direction}, cant {self.cant_mm:g} mm "
                f"(deficiency {self.cant_deficiency_mm:.1f} mm), spirals "
                f"{self.entry_spiral_m:g}/{self.exit_spiral_m:g} m"
            )
        else:
            parts.append("tangent")
        if self.grade_permille:
            parts.append(f"grade {self.grade_permille:+g} ‰")
        if self.coupler_force_kN:
            parts.append(f"coupler {self.coupler_force_kN:g} kN")
        irr = (
            f"measured track {Path(self.track_geometry).name}"
            + (f" (offset {self.track_offset_m:+g} m)" if self.track_offset_m else "")
            + (f" (±{self.track_accuracy_mm:g} mm RMS)" if self.track_accuracy_mm else "")
            if self.track_geometry is not None
            else "perfect track"
            if self.irregularity_class is None
            else f"FRA class {self.irregularity_class} ({self.wavelength_min_m:g}-"
            f"{self.wavelength_max_m:g} m), seed {self.seed}"
        )
        parts.append(irr)
        parts.append(f"{self.duration_s:g} s / {self.n_steps} steps")
        return ", ".join(parts)

    def with_changes(self, **changes: Any) -> WorkingCondition:
        """A validated copy with some fields changed."""
        return make_condition({**self.model_dump(), **changes})

    def with_duration(self, duration_s: float) -> WorkingCondition:
        """A validated copy recording ``duration_s`` seconds at the same sampling interval."""
        lo, hi = 1.0, 600.0
        if is_real(duration_s):
            duration_s = float(duration_s)  # NumPy scalars too
        if not (isinstance(duration_s, float) and lo <= duration_s <= hi):
            raise ConditionError(
                f"condition {self.name!r}: duration_s = {duration_s!r}: accepted range "
                f"[{lo:g}, {hi:g}] s"
            )
        n_steps = max(10, round(duration_s / self.sample_interval))
        return self.with_changes(duration_s=duration_s, n_steps=n_steps)

    def differences(self, other: WorkingCondition, ignore: Iterable[str] = ("seed",)) -> list[str]:
        """Names of the fields (other than ``ignore``) in which ``other`` differs."""
        skip = set(ignore)
        mine, theirs = self.model_dump(exclude=skip), other.model_dump(exclude=skip)
        return sorted(k for k in mine.keys() | theirs.keys() if mine.get(k) != theirs.get(k))


def make_condition(fields: Mapping[str, Any]) -> WorkingCondition:
    """Build a condition from a dict, turning validation failures into one-line errors.

    Values are validated strictly, as a file's are
    (:func:`railsusp.input_checks.validate_document`): a value of the wrong type
    (``speed_kmh="80"``, ``n_steps=500.5``) is refused, not converted, whether the dict was
    read from a TOML or JSON file or built in Python (an integer still stands for a real
    number, NumPy's scalars for Python's)."""
    from railsusp.input_checks import validate_document

    if not isinstance(fields, Mapping):
        raise ConditionError(
            f"condition fields: a mapping {{field: value}} is needed, not "
            f"{type(fields).__name__} (e.g. {{'name': 'fast', 'speed_kmh': 80}})"
        )
    name = fields.get("name", "custom")
    try:
        return validate_document(WorkingCondition, dict(fields))
    except ValidationError as exc:
        raise ConditionError(_format_errors(name, exc)) from None
    except (TypeError, ValueError) as exc:  # a value or a key JSON cannot hold
        raise ConditionError(f"condition {name!r}: {exc}") from None


def field_range(field: str) -> tuple[float | None, float | None]:
    """(lowest, highest) a working condition's ``field`` accepts (its ``ge``/``le``; None
    where unbounded): the one source of the ranges that readers of recordings and line
    descriptions check against too."""
    lo = hi = None
    for m in WorkingCondition.model_fields[field].metadata:
        lo = getattr(m, "ge", lo)
        hi = getattr(m, "le", hi)
    return lo, hi


def _format_errors(name: str, exc: ValidationError) -> str:
    """One line per pydantic error, naming field, value and accepted range with unit."""
    from railsusp.input_checks import bound_text, type_error_text

    msgs = []
    for err in exc.errors():
        field = ".".join(str(p) for p in err["loc"]) or "condition"
        info = WorkingCondition.model_fields.get(field)
        unit = ""
        lo = hi = None
        if info is not None:
            extra = info.json_schema_extra
            unit = extra.get("unit", "") if isinstance(extra, dict) else ""
            lo, hi = field_range(field)
        if err["type"] == "extra_forbidden":
            known = ", ".join(WorkingCondition.model_fields)
            msgs.append(f"unknown field {field!r} (accepted: {known})")
            continue
        value = err.get("input")
        shown = "" if field == "condition" else f"{field} = {value!r}: "
        wrong_type = type_error_text(err)
        text = wrong_type or err["msg"].removeprefix("Value error, ")
        if err["type"] == "string_pattern_mismatch" and field == "name":
            text = (
                "a condition name becomes a folder name: letters, digits, '_', '-' and '.', "
                "starting with a letter or digit (no '/', no '..', no absolute path)"
            )
        if lo is not None or hi is not None:
            low = "-inf" if lo is None else bound_text(lo)
            rng = f"[{low}, {'inf' if hi is None else bound_text(hi)}]"
            accepted = f"accepted range {rng} {unit}".rstrip()
            if field == "irregularity_class":
                accepted += ' or "none" (perfect track)'
            if wrong_type:
                msgs.append(f"{shown}{wrong_type}; {accepted}")
            else:
                msgs.append(f"{shown}{accepted} ({text})")
        else:
            msgs.append(f"{shown}{text}")
    return f"condition {name!r}: " + "; ".join(msgs)
