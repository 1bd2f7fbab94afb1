"""Wagon data: masses, inertias, geometry and fixed stiffnesses, read from a TOML file.

The wagon is data, not code: ``data/c80_k6.toml`` describes the C80 gondola on K6 bogies, and
another wagon or bogie type (C70/K5, C64/K2) is another file of the same form. The sampled
suspension parameters (X11-X20) and the wheelset/adapter data (X1-X10) come from the parameter
catalogue (:mod:`railsusp.params`), so that a campaign can vary them.

This module is the wagon as a whole (``WagonData``: its checks across sections, its variants
with changed fields) and the reading of wagon files, packaged or given; the sections it joins
(car body, bolster, side frame, bogie, suspension, track, contact, profiles), each with its
fields' bounds, are :mod:`railsusp.vehicle.wagon_sections`.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import ValidationError, model_validator

from railsusp.errors import RailsuspInputError
from railsusp.vehicle.wagon_sections import (
    BUILTIN_RAILS,
    BUILTIN_WHEELS,
    Bogie,
    Bolster,
    CarBody,
    CentrePlate,
    ContactData,
    Primary,
    Profiles,
    Secondary,
    SideBearer,
    SideFrame,
    TrackData,
    WagonInfo,
    WagonSection,
    Wheelset,
)


class WagonData(WagonSection):
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

    def profile_digests(self) -> dict[str, str]:
        """The content hash (SHA-256) of each profile file the wagon reads, by path
        ("missing" for a file not there): what the hashes of its campaigns and runs hold
        beside the path, so that a profile edited in place is simulated again instead of its
        old results being reused (the wagon hunt of stop 79: every stage was skipped). Empty
        with the built-in profiles (the hashes of such wagons are as before)."""
        from railsusp.store import file_hash_cached

        out = {}
        for name, builtin in (
            (self.profiles.wheel, BUILTIN_WHEELS),
            (self.profiles.rail, BUILTIN_RAILS),
        ):
            if name not in builtin and name not in out:
                out[name] = file_hash_cached(name) if Path(name).is_file() else "missing"
        return out

    def with_profile_digests(self, data: dict) -> dict:
        """``data`` (a content hash's input that holds this wagon's dump) with the contents
        of its profile files beside their paths (:meth:`profile_digests`), as the wagon's
        and its campaigns' hashes take them; ``data`` itself with the built-in profiles."""
        files = self.profile_digests()
        return {**data, "profile_files": files} if files else data

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


#: the wagon fields that give the force laws of revision 2026-12-03.1: the side frames' yaw
#: blind to the cross-bracing pins' and the axle boxes' lateral offsets from their
#: centrelines (docs/model.md, "Spring nests and friction wedges")
FORCE_LAWS_BEFORE_2026_12_03_2 = {
    "side_frame.yaw_levers": False,
}

#: the wagon fields that give the force laws of revision 2026-12-02.1 and before: those of
#: :data:`FORCE_LAWS_BEFORE_2026_12_03_2`, and the track-following frames' rotation left out
#: of the bodies' equations (their yaw and roll accelerations in transitions, the frame's
#: rates in the wheelsets' gyroscopic moments), and the primary's deflections and the centre
#: plate's lateral one blind to the design twist between bodies at different positions
#: (docs/model.md, "Transitions")
FORCE_LAWS_BEFORE_2026_12_03_1 = {
    **FORCE_LAWS_BEFORE_2026_12_03_2,
    "track.frame_rotation": False,
    "track.design_twist": False,
}

#: the wagon fields that give the force laws of revision 2026-11-30.2 and before: those of
#: :data:`FORCE_LAWS_BEFORE_2026_12_03_1`, and the centre bowl's pitch moment against the
#: track, with no reaction on the bogie, the side frames free to pitch against the bolster
#: (on level track too), and every wheel of a bogie loaded alike on a grade (docs/model.md,
#: "Centre bowl and side bearers")
FORCE_LAWS_BEFORE_2026_12_02_1 = {
    **FORCE_LAWS_BEFORE_2026_12_03_1,
    "centre_plate.pitch_reaction_on_side_frames": False,
    "bogie.grade_pitch_moment": False,
}

#: the wagon fields that give the force laws of revision 2026-11-30.1 and before: those of
#: :data:`FORCE_LAWS_BEFORE_2026_12_02_1`, and the side frames' roll couple and the car
#: body's gravity roll moment left out, the coupler angle taken at the pivot (docs/model.md,
#: "Physical invariants checked by hand"), the rail damping's push not capped at the Hertz
#: force
FORCE_LAWS_BEFORE_2026_11_30_2 = {
    **FORCE_LAWS_BEFORE_2026_12_02_1,
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
