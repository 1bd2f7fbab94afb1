"""Wagon data: masses, inertias, geometry and fixed stiffnesses, read from a TOML file.

The wagon is data, not code: ``data/c80_k6.toml`` describes the C80 gondola on K6 bogies, and
another wagon or bogie type (C70/K5, C64/K2) is another file of the same form. The sampled
suspension parameters (X11-X20) and the wheelset/adapter data (X1-X10) come from the parameter
catalogue (:mod:`railsusp.params`), so that a campaign can vary them.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from railsusp.errors import RailsuspInputError

_POS = {"gt": 0.0, "allow_inf_nan": False}


def _within(hi: float, lo: float = 0.0, unit: str = "m", **kw: Any) -> Any:
    """A positive quantity of a standard-gauge freight wagon, at most ``hi`` (SI): the
    bounds catch a value typed in another unit (a CG height of 2050 "m" in millimetres, a
    car body of 91.6 "kg" in tonnes), which the model would otherwise run into a flange
    climb or a side bearer carrying the car body, far from the field that was wrong."""
    return Field(gt=lo, le=hi, allow_inf_nan=False, json_schema_extra={"unit": unit}, **kw)


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class WagonInfo(_Section):
    name: str
    description: str = ""


class CarBody(_Section):
    mass: float = _within(250_000.0, 1000.0, "kg", description="loaded car body mass, kg")
    roll_inertia: float = Field(**_POS, description="kg m^2")
    pitch_inertia: float = Field(**_POS, description="kg m^2")
    yaw_inertia: float = Field(**_POS, description="kg m^2")
    cg_height: float = _within(5.0, description="centre of gravity above rail top, m")
    bogie_half_spacing: float = _within(15.0, description="half bogie centre distance, m")
    coupler_height: float = _within(2.0, description="coupler height above rail top, m")
    coupler_half_spacing: float = _within(20.0, description="car centre to coupler pivot, m")
    #: the car centre distance of two like cars coupled (= their length over coupler faces):
    #: the coupler line between them is parallel to the track's tangent halfway, so its
    #: angle to the car is kappa times half this length. Left out: kappa times the pivot's
    #: distance ``coupler_half_spacing`` (the model before 2026-11-30.2, 8 % small for the
    #: C80's 12 m over couplers; docs/model.md)
    length_over_couplers: float | None = _within(
        60.0, description="car centre distance of two like cars coupled, m", default=None
    )
    #: the car body's support loads act below its centre of gravity, so a rolled body has
    #: them off its centreline: the gravity (P-delta) roll moment W h theta (false: the
    #: model before 2026-11-30.2, which left it out)
    gravity_roll_moment: bool = True

    @model_validator(mode="after")
    def _couplers_beyond_their_pivots(self) -> CarBody:
        length = self.length_over_couplers
        if length is not None and length <= 2.0 * self.coupler_half_spacing:
            raise ValueError(
                f"car_body.length_over_couplers = {length:g} m: accepted above twice "
                f"coupler_half_spacing ({2.0 * self.coupler_half_spacing:g} m; the coupler "
                "faces lie beyond the pivots)"
            )
        return self


class Bolster(_Section):
    mass: float = _within(5000.0, 10.0, "kg")
    roll_inertia: float = Field(**_POS)
    yaw_inertia: float = Field(**_POS)
    cg_height: float = _within(2.0, description="m above rail top")


class SideFrame(_Section):
    """A side frame has no roll freedom of its own: it sits on its two axle boxes' adapters,
    which hold it in roll. ``roll_held_by_axle_boxes`` (default true) makes it roll with
    its wheelsets (the mean of their roll), so that the couple of the lateral forces that
    enter it at the bolster's height and leave it at the axles' reaches the wheelsets as a
    moment (their wheel loads); false leaves that couple out (the model before
    2026-11-30.2, whose outer-inner load transfer in a curve was 8-12 % small)."""

    mass: float = _within(5000.0, 10.0, "kg")
    pitch_inertia: float = Field(**_POS)
    yaw_inertia: float = Field(**_POS)
    cg_height: float = _within(2.0, description="m above rail top")
    roll_held_by_axle_boxes: bool = True


class Bogie(_Section):
    half_wheelbase: float = _within(2.0)
    axle_box_half_span: float = _within(2.0)
    spring_nest_half_span: float = _within(2.0)
    centre_plate_height: float = _within(2.0, description="m above rail top")
    centre_plate_radius: float = _within(1.0)


class Wheelset(_Section):
    rolling_radius: float = _within(0.7, 0.2, description="wheel diameter / 2, m")
    contact_half_distance: float = _within(1.5, 0.5)


class Primary(_Section):
    longitudinal_damping: float = Field(ge=0.0)
    lateral_damping: float = Field(ge=0.0)
    vertical_damping: float = Field(ge=0.0)


class Secondary(_Section):
    """Spring nest with its friction wedges (per bogie side). ``vertical_stiffness`` is the
    whole nest's, control springs included; the wedges' control springs carry their share
    of the static load. The wedge's column normal force is F_s / (tan a -+ mu_column).
    ``wedge_half_spacing``: the wedges sit this far ahead of and behind the nest centre
    (half of them each way), so that a bolster yawing in the side-frame window slides them on
    their columns in opposite directions (the wedges' warp friction moment); 0 puts them all
    at the nest centre, where they resist no warp."""

    vertical_stiffness: float = Field(**_POS)
    longitudinal_damping: float = Field(ge=0.0)
    wedges_per_nest: int = Field(ge=1, le=4)
    wedge_angle_deg: float = Field(gt=10.0, lt=80.0, description="slope face from vertical")
    control_spring_stiffness: float = Field(**_POS, description="per wedge, N/m")
    column_friction_coefficient: float = Field(ge=0.0, le=1.0)
    slope_friction_coefficient: float = Field(ge=0.0, le=1.0)
    wedge_stick_stiffness: float = Field(**_POS)
    wedge_stick_damping: float = Field(ge=0.0)
    wedge_half_spacing: float = Field(
        ge=0.0, le=0.5, allow_inf_nan=False, description="wedges ahead of/behind the nest, m"
    )
    gib_stiffness: float = Field(**_POS)

    @model_validator(mode="after")
    def _wedges_fit_the_nest(self) -> Secondary:
        """Checked when the file is read, not at the first simulation."""
        k_ctrl = self.wedges_per_nest * self.control_spring_stiffness
        if k_ctrl >= self.vertical_stiffness:
            raise ValueError(
                f"the wedges' control springs ({k_ctrl:.3g} N/m) must be part of the nest's "
                f"vertical_stiffness ({self.vertical_stiffness:.3g} N/m)"
            )
        tan_a = math.tan(math.radians(self.wedge_angle_deg))
        if self.column_friction_coefficient >= tan_a:
            raise ValueError(
                f"column_friction_coefficient = {self.column_friction_coefficient:g}: accepted "
                f"below tan(wedge_angle_deg) = {tan_a:.3g} (else the wedge locks)"
            )
        if self.wedge_half_spacing > 0.0 and self.wedges_per_nest % 2:
            raise ValueError(
                f"wedge_half_spacing = {self.wedge_half_spacing:g} m with wedges_per_nest = "
                f"{self.wedges_per_nest}: accepted an even number of wedges (as many ahead of "
                f"the bolster end as behind it), or wedge_half_spacing = 0"
            )
        return self


class CentrePlate(_Section):
    vertical_stiffness: float = Field(**_POS)
    rocking_stiffness: float = Field(
        **_POS, description="relative roll of body and bolster before lift-off, N m/rad"
    )
    bolster_pitch_stiffness: float = Field(
        **_POS, description="the bolster's pitch restraint in the side-frame windows, N m/rad"
    )
    lateral_stiffness: float = Field(**_POS)
    friction_coefficient: float = Field(ge=0.0, le=1.0)
    yaw_stick_stiffness: float = Field(**_POS)
    yaw_stick_damping: float = Field(ge=0.0)
    roll_stick_stiffness: float = Field(**_POS)
    roll_stick_damping: float = Field(ge=0.0)


class SideBearer(_Section):
    vertical_stiffness: float = Field(**_POS)
    damping: float = Field(ge=0.0, description="elastomer loss as a viscous damper, N s/m")
    preload: float = Field(ge=0.0)
    friction_coefficient: float = Field(ge=0.0, le=1.0)
    travel: float = Field(**_POS, description="compression from static to the solid stop, m")
    stop_stiffness: float = Field(**_POS)


class TrackData(_Section):
    """The rail support under one wheel. ``rail_damping_capped`` (default true): the support's
    damping, in series with the Hertz contact, pushes at most as hard as the contact's
    spring (no step in the normal force when a wheel or flange touches); false keeps the
    damper in parallel with it, the model before revision 2026-11-30.2."""

    rail_vertical_stiffness: float = Field(**_POS)
    rail_lateral_stiffness: float = Field(**_POS)
    rail_vertical_damping: float = Field(ge=0.0)
    rail_lateral_damping: float = Field(ge=0.0)
    gauge: float = Field(gt=1.0, lt=2.0)
    rail_inclination: float = Field(ge=0.0, lt=0.1)
    rail_damping_capped: bool = True


class ContactData(_Section):
    """Wheel-rail contact: ``creep_factor`` scales Kalker's coefficients; ``model`` is
    ``two-point`` (tread and flange contacts act together, the default) or ``single-point``
    (the contact jumps from tread to flange, the model before 2026-11-23, kept for
    comparison); ``yaw_geometry`` (default true) moves the contact point with the wheelset
    yaw (docs/model.md), false keeps the zero-yaw contact of the model before 2026-11-24."""

    creep_factor: float = Field(gt=0.0, le=2.0)
    model: Literal["two-point", "single-point"] = "two-point"
    yaw_geometry: bool = True  # contact lead of the yawed wheelset (false: zero-yaw tables)


#: built-in profile names; anything else is a profile file (two columns y, z in mm)
BUILTIN_WHEELS = ("lm-like",)
BUILTIN_RAILS = ("chn60",)


class Profiles(_Section):
    """Wheel and rail profiles: a built-in name or a profile file path (relative paths are
    taken from the wagon file's folder)."""

    wheel: str = "lm-like"
    rail: str = "chn60"


class WagonData(_Section):
    """Validated wagon description (one TOML file)."""

    wagon: WagonInfo
    car_body: CarBody
    bolster: Bolster
    side_frame: SideFrame
    bogie: Bogie
    wheelset: Wheelset
    primary: Primary
    secondary: Secondary
    centre_plate: CentrePlate
    side_bearer: SideBearer
    track: TrackData
    contact: ContactData
    profiles: Profiles = Profiles()

    @model_validator(mode="after")
    def _bogies_fit_the_car(self) -> WagonData:
        """Bogies that overlap (their centres closer than a wheelbase: the inner wheelsets
        would run past each other) or couplers inside the bogie centres were simulated
        without a word (the command-line audit of stop 60); refused when the file is read."""
        spacing, wheelbase = self.car_body.bogie_half_spacing, self.bogie.half_wheelbase
        if spacing <= wheelbase:
            raise ValueError(
                f"car_body.bogie_half_spacing = {spacing:g} m with bogie.half_wheelbase = "
                f"{wheelbase:g} m: the two bogies' inner wheelsets would overlap; accepted a "
                f"bogie_half_spacing above the half wheelbase"
            )
        if self.car_body.coupler_half_spacing <= spacing:
            raise ValueError(
                f"car_body.coupler_half_spacing = {self.car_body.coupler_half_spacing:g} m "
                f"inside the bogie centres (bogie_half_spacing = {spacing:g} m); accepted a "
                "coupler pivot beyond the bogie centre"
            )
        return self

    @property
    def name(self) -> str:
        return self.wagon.name

    def with_values(self, changes: Mapping[str, Any]) -> WagonData:
        """The same wagon with some fields changed, given as ``{"section.field": value}``
        (e.g. ``{"contact.creep_factor": 0.6}``), validated as a wagon file is."""
        data = self.model_dump()
        for key, value in changes.items():
            section, _, name = key.partition(".")
            if not isinstance(data.get(section), dict) or name not in data[section]:
                raise KeyError(f"wagon field {key!r} does not exist")
            data[section][name] = value
        try:
            return WagonData(**data)
        except ValidationError as exc:
            raise RailsuspInputError(f"wagon: {wagon_error_text(exc)}") from None

    def with_contact_model(self, model: str) -> WagonData:
        """The same wagon with another wheel-rail contact model (``two-point`` or
        ``single-point``), validated."""
        if model not in ("two-point", "single-point"):
            raise RailsuspInputError(
                f"contact.model = {model!r}: accepted two-point or single-point"
            )
        return self.with_values({"contact.model": model})

    def with_physics_before_2026_11_24(self) -> WagonData:
        """The same wagon with the force laws of the model before 2026-11-24's fidelity
        changes (and of revision 2026-11-30.1's: :data:`FORCE_LAWS_BEFORE_2026_11_30_2`):
        the zero-yaw contact (``yaw_geometry = false``), a centre bowl whose ring
        has the bowl's vertical stiffness on a bolster rigid in bending and pitch (no
        rocking stiffness of its own) and the wedge pair at the nest centre (no warp
        friction). It reproduces that model's forces (commit 328b8dd: to 3e-14 of the
        largest; tests/data/force_reference_zero_yaw.npz), so speed can be compared with an
        older commit on the same model (bench/simulator.py ``--physics-before-2026-11-24``)."""
        radius = self.bogie.centre_plate_radius
        return self.with_values(
            {
                **FORCE_LAWS_BEFORE_2026_11_30_2,
                "contact.yaw_geometry": False,
                "centre_plate.rocking_stiffness": (
                    self.centre_plate.vertical_stiffness * radius * radius / 2.0
                ),
                "centre_plate.bolster_pitch_stiffness": 1.0e30,
                "secondary.wedge_half_spacing": 0.0,
            }
        )


#: the wagon fields that give the force laws of revision 2026-11-30.1 and before: the side
#: frames' roll couple and the car body's gravity roll moment left out, the coupler angle
#: taken at the pivot (docs/model.md, "Physical invariants checked by hand"), the rail
#: damping's push not capped at the Hertz force
FORCE_LAWS_BEFORE_2026_11_30_2 = {
    "side_frame.roll_held_by_axle_boxes": False,
    "car_body.gravity_roll_moment": False,
    "car_body.length_over_couplers": None,
    "track.rail_damping_capped": False,
}

#: wagon files shipped with the package, by name (``--wagon tare``); a file path wins
PACKAGED_WAGONS = {
    "loaded": "c80_k6.toml",
    "c80_k6": "c80_k6.toml",
    "tare": "c80_k6_tare.toml",
    "c80_k6_tare": "c80_k6_tare.toml",
}


def packaged_wagon_text(source: str | Path | None) -> str | None:
    """The text of the packaged wagon data ``source`` names (None: the loaded C80/K6; a
    name of :data:`PACKAGED_WAGONS` that no file of that name shadows), or None where
    ``source`` is a file's name."""
    name = None if source is None else str(source)
    if name is not None and (name not in PACKAGED_WAGONS or Path(name).is_file()):
        return None
    where = PACKAGED_WAGONS.get(name or "loaded", "c80_k6.toml")
    return resources.files("railsusp").joinpath(f"data/{where}").read_text("utf-8")


def wagon_error_text(exc: ValidationError) -> str:
    """A wagon's validation errors on one line: each as ``section.field = value: why``
    (the range the field accepts, or the type it needs), joined by "; "."""
    from railsusp.input_checks import BOUND_ERRORS, error_detail, type_error_text

    msgs = []
    for err in exc.errors():
        loc = ".".join(str(p) for p in err["loc"])
        value = err.get("input")
        where_value = loc if isinstance(value, dict) else f"{loc} = {value!r}"
        text = type_error_text(err) or err["msg"].removeprefix("Value error, ")
        detail = error_detail(WagonData, err)  # the accepted range of a value out of it
        if detail and err["type"] in BOUND_ERRORS:
            text = f"{detail} ({text})"
        msgs.append(f"{where_value}: {text}" if loc else text)  # a check across sections
    return "; ".join(msgs)


def load_wagon(source: str | Path | WagonData | None = None) -> WagonData:
    """Read and validate a wagon file; None gives the embedded C80/K6 data (loaded), a
    name of :data:`PACKAGED_WAGONS` (``"tare"``) another embedded file, and a WagonData
    itself (so that a function taking any of them reads it with one call)."""
    from railsusp.input_checks import validate_document
    from railsusp.store import read_toml

    if isinstance(source, WagonData):
        return source
    if source is not None and not isinstance(source, str | os.PathLike):
        raise RailsuspInputError(
            f"wagon = {source!r}: a wagon file (str or Path), a packaged wagon's name "
            f"({', '.join(PACKAGED_WAGONS)}), WagonData or None is needed"
        )

    text = packaged_wagon_text(source)
    if text is not None:
        where = PACKAGED_WAGONS[str(source or "loaded")]
        source = None
    else:
        path = Path(source)
        if not path.exists():
            raise RailsuspInputError(
                f"wagon file {path} does not exist (packaged wagons: {', '.join(PACKAGED_WAGONS)})"
            )
        text, where = None, str(path)
    try:
        # a folder, an unreadable or binary file, bad syntax: one line naming the file
        doc = tomllib.loads(text) if text is not None else read_toml(path, "wagon file")
        prof = doc.get("profiles")
        if source is not None and isinstance(prof, dict):
            base = Path(source).resolve().parent
            for key, builtin in (("wheel", BUILTIN_WHEELS), ("rail", BUILTIN_RAILS)):
                value = prof.get(key)
                if isinstance(value, str) and value not in builtin:
                    path = (base / value).resolve()
                    if not path.is_file():
                        raise RailsuspInputError(
                            f"{where}: profiles.{key} = {value!r} is neither a built-in profile "
                            f"({', '.join(builtin)}) nor an existing file"
                        )
                    prof[key] = str(path)
        doc.pop(
            "tolerances", None
        )  # the report's verdicts (railsusp.suspension_tolerances), not the model
        return validate_document(WagonData, doc)  # strict: mass = "91600" is refused
    except tomllib.TOMLDecodeError as exc:
        raise RailsuspInputError(f"{where}: not valid TOML ({exc})") from None
    except ValidationError as exc:
        raise RailsuspInputError(f"{where}: {wagon_error_text(exc)}") from None


def wagon_reference(wagon: str | Path | None) -> str | None:
    """How a result records the wagon it simulated, for a later step to load it again: a
    packaged name or None as given, a file by its absolute path (a relative one would be
    read from another working folder)."""
    if wagon is None or not Path(wagon).is_file():
        return None if wagon is None else str(wagon)
    return str(Path(wagon).resolve())
