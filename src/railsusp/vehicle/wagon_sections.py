"""The sections of a wagon file, one validated model each: the bodies (car body, bolster, side
frame, wheelset) with their masses, inertias and heights, the bogie's geometry, the primary and
secondary suspension (spring nest and friction wedges), centre plate and side bearers, the
track under the wheels, the wheel-rail contact model and the profiles.

Each field's bounds catch a value typed in another unit where the file is read. The sections
are apart from :mod:`railsusp.vehicle.wagon`, which joins them into the whole wagon
(``WagonData``, its checks across sections, its variants) and reads the packaged and user
wagon files: here is what each table of a file holds, there what a wagon is as a whole.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

_POS = {"gt": 0.0, "allow_inf_nan": False}


def _within(hi: float, lo: float = 0.0, unit: str = "m", **kw: Any) -> Any:
    """A positive quantity of a standard-gauge freight wagon, at most ``hi`` (SI): the
    bounds catch a value typed in another unit (a CG height of 2050 "m" in millimetres, a
    car body of 91.6 "kg" in tonnes), which the model would otherwise run into a flange
    climb or a side bearer carrying the car body, far from the field that was wrong."""
    return Field(gt=lo, le=hi, allow_inf_nan=False, json_schema_extra={"unit": unit}, **kw)


def _stiffness(lo: float, unit: str = "N/m", **kw: Any) -> Any:
    """A stiffness of a freight wagon's element (SI), above ``lo``: a value typed in MN/m or
    kN/m (the catalogue's display units: 5.9 for a 5.9e6 N/m nest) is refused where the file
    is read. The model takes its static loads as preloads, so such a spring ran without a
    word and gave plausible forces (a 5.9 N/m nest: car-body bounce at 0.003 Hz, an
    unstable sway, every simulation "ok")."""
    return Field(gt=lo, allow_inf_nan=False, json_schema_extra={"unit": unit}, **kw)


#: the radii of gyration (sqrt(I / m)) a body of a standard-gauge freight wagon can have, m
GYRATION_RADIUS_M = (0.05, 20.0)


def _gyration_radii(section: str, body: BaseModel, inertias: tuple[str, ...]) -> None:
    """Refuse an inertia whose radius of gyration about the body's own mass lies outside
    :data:`GYRATION_RADIUS_M`: typed in t m^2 (a thousand times small) it was simulated
    without a word, the forces plausible."""
    lo, hi = GYRATION_RADIUS_M
    mass = body.mass  # type: ignore[attr-defined]
    for name in inertias:
        inertia = getattr(body, name)
        radius = math.sqrt(inertia / mass)
        if not lo <= radius <= hi:
            raise ValueError(
                f"{section}.{name} = {inertia:g} kg m^2: a radius of gyration sqrt(I / mass) "
                f"of {radius:.3g} m about the {mass:g} kg of {section}; accepted {lo:g} to "
                f"{hi:g} m (an inertia in t m^2 is a thousand times small)"
            )


#: the base of every section: unknown keys refused, frozen
class WagonSection(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class WagonInfo(WagonSection):
    name: str
    description: str = ""


class CarBody(WagonSection):
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
    def _inertias_of_its_mass(self) -> CarBody:
        _gyration_radii("car_body", self, ("roll_inertia", "pitch_inertia", "yaw_inertia"))
        return self

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


class Bolster(WagonSection):
    mass: float = _within(5000.0, 10.0, "kg")
    roll_inertia: float = Field(**_POS)
    yaw_inertia: float = Field(**_POS)
    cg_height: float = _within(2.0, description="m above rail top")

    @model_validator(mode="after")
    def _inertias_of_its_mass(self) -> Bolster:
        _gyration_radii("bolster", self, ("roll_inertia", "yaw_inertia"))
        return self


class SideFrame(WagonSection):
    """A side frame has no roll freedom of its own: it sits on its two axle boxes' adapters,
    which hold it in roll. ``roll_held_by_axle_boxes`` (default true) makes it roll with
    its wheelsets (the mean of their roll), so that the couple of the lateral forces that
    enter it at the bolster's height and leave it at the axles' reaches the wheelsets as a
    moment (their wheel loads); false leaves that couple out (the model before
    2026-11-30.2, whose outer-inner load transfer in a curve was 8-12 % small).

    ``yaw_levers`` (default true): the cross-bracing pins (X10 / 2 from the wagon's
    centreline) and the axle boxes (b1) lie off the side frame's centreline (b2), so that
    its yaw moves them longitudinally too; without it a rigid yaw of the bogie strained the
    bars (1.7 kN each at 5 mrad). False: the model before revision 2026-12-03.2."""

    mass: float = _within(5000.0, 10.0, "kg")
    pitch_inertia: float = Field(**_POS)
    yaw_inertia: float = Field(**_POS)
    cg_height: float = _within(2.0, description="m above rail top")
    roll_held_by_axle_boxes: bool = True
    yaw_levers: bool = True

    @model_validator(mode="after")
    def _inertias_of_its_mass(self) -> SideFrame:
        _gyration_radii("side_frame", self, ("pitch_inertia", "yaw_inertia"))
        return self


class Bogie(WagonSection):
    """``grade_pitch_moment`` (default true): on a grade the car body pulls each bogie up at
    the centre plate against the grade components of its bolster, side frames and
    wheelsets, which act lower, at their centres of gravity; the bogie's pitch moment of
    these forces is shared between its two axles (the leading one loaded). False leaves it
    out, every wheel of a bogie loaded alike (the model before revision 2026-12-02.1)."""

    half_wheelbase: float = _within(2.0)
    axle_box_half_span: float = _within(2.0)
    spring_nest_half_span: float = _within(2.0)
    centre_plate_height: float = _within(2.0, description="m above rail top")
    centre_plate_radius: float = _within(1.0)
    grade_pitch_moment: bool = True


class Wheelset(WagonSection):
    rolling_radius: float = _within(0.7, 0.2, description="wheel diameter / 2, m")
    contact_half_distance: float = _within(1.5, 0.5)


class Primary(WagonSection):
    longitudinal_damping: float = Field(ge=0.0)
    lateral_damping: float = Field(ge=0.0)
    vertical_damping: float = Field(ge=0.0)


class Secondary(WagonSection):
    """Spring nest with its friction wedges (per bogie side). ``vertical_stiffness`` is the
    whole nest's, control springs included; the wedges' control springs carry their share
    of the static load. The wedge's column normal force is F_s / (tan a -+ mu_column).
    ``wedge_half_spacing``: the wedges sit this far ahead of and behind the nest centre
    (half of them each way), so that a bolster yawing in the side-frame window slides them on
    their columns in opposite directions (the wedges' warp friction moment); 0 puts them all
    at the nest centre, where they resist no warp."""

    vertical_stiffness: float = _stiffness(1.0e5)
    longitudinal_damping: float = Field(ge=0.0)
    wedges_per_nest: int = Field(ge=1, le=4)
    wedge_angle_deg: float = Field(gt=10.0, lt=80.0, description="slope face from vertical")
    control_spring_stiffness: float = _stiffness(1.0e4, description="per wedge, N/m")
    column_friction_coefficient: float = Field(ge=0.0, le=1.0)
    slope_friction_coefficient: float = Field(ge=0.0, le=1.0)
    wedge_stick_stiffness: float = _stiffness(1.0e5)
    wedge_stick_damping: float = Field(ge=0.0)
    wedge_half_spacing: float = Field(
        ge=0.0, le=0.5, allow_inf_nan=False, description="wedges ahead of/behind the nest, m"
    )
    gib_stiffness: float = _stiffness(1.0e5)

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


#: the stiffest bolster pitch restraint accepted where it acts on the side frames, N m/rad
MAX_BOLSTER_PITCH_STIFFNESS = 1.0e10


class CentrePlate(WagonSection):
    """``pitch_reaction_on_side_frames`` (default true): the bowl's pitch moment follows the
    car body's pitch against its bogie (the mean pitch of the two side frames, in whose
    windows the bolster pitches) and its reaction reaches the side frames, half each. False
    gives the model before revision 2026-12-02.1: the moment followed the car body's pitch
    against the track and had no reaction on the bogie."""

    vertical_stiffness: float = _stiffness(1.0e6)
    rocking_stiffness: float = _stiffness(
        1.0e4, "N m/rad", description="relative roll of body and bolster before lift-off"
    )
    bolster_pitch_stiffness: float = _stiffness(
        1.0e3, "N m/rad", description="the bolster's pitch restraint in the side-frame windows"
    )
    lateral_stiffness: float = _stiffness(1.0e5)
    friction_coefficient: float = Field(ge=0.0, le=1.0)
    yaw_stick_stiffness: float = _stiffness(1.0e3, "N m/rad")
    yaw_stick_damping: float = Field(ge=0.0)
    roll_stick_stiffness: float = _stiffness(1.0e3, "N m/rad")
    roll_stick_damping: float = Field(ge=0.0)
    pitch_reaction_on_side_frames: bool = True

    @model_validator(mode="after")
    def _pitch_restraint_the_step_can_follow(self) -> CentrePlate:
        """With the restraint acting on the side frames, a bolster rigid in pitch (the 1e30
        that stood for it before revision 2026-12-02.1) locks them into a mode no RK4 step
        can follow (stable step 4e-14 s; 0.96 ms at 1e9, 1.04 at the nominal 2.8e6)."""
        limit = MAX_BOLSTER_PITCH_STIFFNESS
        if self.pitch_reaction_on_side_frames and self.bolster_pitch_stiffness > limit:
            raise ValueError(
                f"centre_plate.bolster_pitch_stiffness = {self.bolster_pitch_stiffness:g} N m/rad "
                f"with pitch_reaction_on_side_frames = true: accepted up to {limit:g} (the "
                "restraint acts on the side frames; a bolster rigid in pitch needs "
                "pitch_reaction_on_side_frames = false, the model before revision 2026-12-02.1)"
            )
        return self


class SideBearer(WagonSection):
    vertical_stiffness: float = _stiffness(1.0e4)
    damping: float = Field(ge=0.0, description="elastomer loss as a viscous damper, N s/m")
    preload: float = Field(ge=0.0)
    friction_coefficient: float = Field(ge=0.0, le=1.0)
    travel: float = Field(**_POS, description="compression from static to the solid stop, m")
    stop_stiffness: float = _stiffness(1.0e5)


class TrackData(WagonSection):
    """The rail support under one wheel. ``rail_damping_capped`` (default true): the support's
    damping, in series with the Hertz contact, pushes at most as hard as the contact's
    spring (no step in the normal force when a wheel or flange touches); false keeps the
    damper in parallel with it, the model before revision 2026-11-30.2.

    ``frame_rotation`` (default true): the track-following frames turn with the design
    track, so every body's equations carry the frame's angular accelerations, yaw V^2 dk/ds
    in a spiral and roll V^2 d^2(cant)/ds^2 at a cant ramp's ends (with the lateral H of it
    at a centre of gravity H above the rail), and the spinning wheelsets' gyroscopic moments
    take the frame's yaw and roll rates (V k, V d(cant)/ds) with their own. False leaves
    them out, the model before revision 2026-12-03.1 (a body's motion relative to its frame
    as if the frame did not turn).

    ``design_twist`` (default true): in a transition each body moves in the frame of the
    design cant at its own position, so a connection between bodies at different positions
    sees the two frames' roll difference: the primary's vertical deflection at an axle box
    b1 off the centreline takes in b1 (cant_w - cant_b), its lateral one r0 (cant_w -
    cant_b) at the axle's height, the centre plate's lateral one -h_cp (cant_c - cant_b),
    with their rates: the spiral's twist loads the wheels as a cross-level twist of the same
    size does. False leaves them out (the model before revision 2026-12-03.1; the centre
    bowl's vertical and roll parts always had the difference)."""

    rail_vertical_stiffness: float = _stiffness(1.0e6)
    rail_lateral_stiffness: float = _stiffness(1.0e6)
    rail_vertical_damping: float = Field(ge=0.0)
    rail_lateral_damping: float = Field(ge=0.0)
    gauge: float = Field(gt=1.0, lt=2.0)
    rail_inclination: float = Field(ge=0.0, lt=0.1)
    rail_damping_capped: bool = True
    frame_rotation: bool = True
    design_twist: bool = True


class ContactData(WagonSection):
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


class Profiles(WagonSection):
    """Wheel and rail profiles: a built-in name or a profile file path (relative paths are
    taken from the wagon file's folder)."""

    wheel: str = "lm-like"
    rail: str = "chn60"
