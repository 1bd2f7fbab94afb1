"""Model inputs for the kernels: solver settings and the constants of one parameter set.

Everything the compiled equations (:mod:`railsusp.vehicle.model`) need of one parameter set in
one condition is prepared here as a plain NumPy array: the constants vector (with the static
preloads that make the start an equilibrium), with the solver's numerical settings. The
contact table of the wagon's wheel/rail pair with Hertz and Kalker coefficients, the same for
every set and condition, is :mod:`railsusp.vehicle.kernel_contact_table`'s (its names are
importable from here too); the track channels on their grid are
:mod:`railsusp.vehicle.track_grid`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from railsusp.conditions import GRAVITY, WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_real, is_whole
from railsusp.params import spec
from railsusp.vehicle import layout as L

# the contact table, imported from here by many modules
from railsusp.vehicle.kernel_contact_table import ContactArrays as ContactArrays
from railsusp.vehicle.kernel_contact_table import contact_arrays as contact_arrays
from railsusp.vehicle.kernel_contact_table import static_wheel_load as static_wheel_load
from railsusp.vehicle.track import TrackLayout
from railsusp.vehicle.wagon import WagonData

#: how a run starts (:class:`SolverSettings` ``start``)
START_MODES = ("settled", "lead-in")


#: accepted ranges of the solver's real-valued settings (low, high, unit in messages): a
#: zero step or grid divided by zero, a negative step ran one unstable step per sample and
#: reported it as wheel-rail penetration, an ``anti_alias`` above 1 (of the output Nyquist
#: rate) is no anti-alias filter at all (the physics audit of stop 59)
SOLVER_RANGES: dict[str, tuple[float, float, str]] = {
    "max_step": (1e-6, 0.01, " s"),
    "track_step": (0.005, 1.0, " m"),
    "anti_alias": (0.05, 1.0, ""),
    "penetration_max": (1e-5, 0.01, " m"),
    "lift_max": (1e-3, 0.1, " m"),
}


@dataclass(frozen=True)
class SolverSettings:
    """Numerical settings of the simulator.

    ``max_step``: largest internal RK4 step (s); the step is the output interval divided by
    an integer, and no longer than RK4's stability bound at the condition's speed
    (:func:`railsusp.vehicle.step_bound.stable_step`: shorter than 1 ms below about 58 km/h).
    Steps that start with a wheel within ``flange_margin`` (m) of flange contact
    and closing on it faster than ``flange_split_speed`` (m/s) are split into
    ``flange_substeps`` (1: no split, the default). The split is for the single-point contact
    model, whose jump to the 70 deg flank is its stiffest event: with the plain 1 ms step two
    of three of its derailments examined on a long campaign were numerical, and it needs
    ``flange_substeps = 2``. Two-point contact needs no split: its force statistics with the
    plain 1 ms step are those of 0.5 ms within 0.3 %, and none of 768 runs of 200 s
    derails. A negative ``flange_split_speed`` splits every step near the flange.
    ``anti_alias``: filter cut-off as a fraction of the output Nyquist rate.
    ``penetration_max``: Hertz approach of the steel bodies (m) beyond which a contact is
    non-physical (1 mm: a normal force of several MN); ``lift_max``: wheel lift (m) beyond
    which the flange no longer guides (derailment).
    ``start``: ``"lead-in"`` (default) starts at rest at the section start and runs the
    condition's whole ``lead_in_m``; ``"settled"`` starts ``run_in_m`` ahead of the record
    from the vehicle's steady state on the record's design track, the irregularities faded
    in during the run-in (:mod:`railsusp.vehicle.settle`). Both record the same stretch of
    track; conditions where the settled start does not apply (lead-in shorter than the
    run-in, design geometry changing under the wagon at the record start) run the lead-in.
    The settled start is not the default: the tare wagon's lateral forces on tangent
    remember the run before the record longer than the run-in (docs/model.md, Numerics).
    """

    max_step: float = 1.0e-3
    flange_substeps: int = 1
    flange_margin: float = 3.0e-3
    flange_split_speed: float = 0.02
    anti_alias: float = 0.8
    filter_order: int = 4
    penetration_max: float = 1.0e-3
    lift_max: float = 0.025
    track_step: float = 0.125
    start: str = "lead-in"
    run_in_m: float = 60.0

    def __post_init__(self):
        for f in fields(self):  # text or None would fail the range checks below (TypeError)
            if f.type != "float":  # annotations are text (from __future__ import annotations)
                continue
            name, value = f.name, getattr(self, f.name)
            if not is_real(value) or not math.isfinite(value):
                raise RailsuspInputError(f"{name} = {value!r}: accepted a finite number (SI)")
        for name in ("flange_substeps", "filter_order"):  # counts stored as floats in configs
            value = getattr(self, name)
            if isinstance(value, float) and value.is_integer():
                object.__setattr__(self, name, int(value))
        for name, (low, high, unit) in SOLVER_RANGES.items():  # 0 divided, < 0 ran unstable
            value = getattr(self, name)
            if not low <= value <= high:
                raise RailsuspInputError(
                    f"{name} = {value!r}{unit}: accepted {low:g} to {high:g}{unit}"
                )
        if not (is_whole(self.filter_order) and 1 <= self.filter_order <= 12):
            raise RailsuspInputError(
                f"filter_order = {self.filter_order!r}: accepted an integer 1 to 12"
            )
        if not (is_whole(self.flange_substeps) and 1 <= self.flange_substeps <= 16):
            raise RailsuspInputError(
                f"flange_substeps = {self.flange_substeps!r}: accepted an integer 1 to 16"
            )
        if not 0.0 <= self.flange_margin <= 0.02:
            raise RailsuspInputError(
                f"flange_margin = {self.flange_margin:g} m: accepted 0 to 0.02 m"
            )
        if self.start not in START_MODES:
            raise RailsuspInputError(
                f"start = {self.start!r}: accepted {', '.join(map(repr, START_MODES))}"
            )
        if not 15.0 <= self.run_in_m <= 1000.0:
            raise RailsuspInputError(f"run_in_m = {self.run_in_m:g} m: accepted 15 to 1000 m")
        if not -1.0 <= self.flange_split_speed <= 1.0:
            raise RailsuspInputError(
                f"flange_split_speed = {self.flange_split_speed:g} m/s: accepted -1 to 1 m/s"
            )


# ---------------------------------------------------------------- constants per set
def constants(
    wagon: WagonData,
    condition: WorkingCondition,
    p: np.ndarray,
    ca: ContactArrays,
    settings: SolverSettings,
) -> np.ndarray:
    """Constants vector K (layout.K) for one parameter set ``p`` (X1..X20, SI)."""
    k = np.zeros(L.N_K)
    cb, bo, sf, bg = wagon.car_body, wagon.bolster, wagon.side_frame, wagon.bogie
    grade = condition.grade
    gn = GRAVITY / np.sqrt(1.0 + grade * grade)  # g cos(alpha)
    m_w = p[0]
    vals = {
        "m_c": cb.mass, "Ix_c": cb.roll_inertia, "Iy_c": cb.pitch_inertia,
        "Iz_c": cb.yaw_inertia, "m_b": bo.mass, "Ix_b": bo.roll_inertia, "Iz_b": bo.yaw_inertia,
        "m_f": sf.mass, "Iy_f": sf.pitch_inertia, "Iz_f": sf.yaw_inertia,
        "m_w": m_w, "Ix_w": p[1], "Iy_w": p[2], "Iz_w": p[3],
        "l_c": cb.bogie_half_spacing, "a": bg.half_wheelbase, "b1": bg.axle_box_half_span,
        "b2": bg.spring_nest_half_span, "r0": wagon.wheelset.rolling_radius,
        "h_cg_c": cb.cg_height, "h_cp": bg.centre_plate_height, "h_cg_b": bo.cg_height,
        "h_k": cb.coupler_height, "x_k": cb.coupler_half_spacing, "R_cp": bg.centre_plate_radius,
        # the side frame rolls with its wheelsets: its nest's lateral force acts this far
        # above its CG, its axle boxes' this far (negative: below)
        "sf_arm_nest": (bo.cg_height - sf.cg_height) if sf.roll_held_by_axle_boxes else 0.0,
        "sf_arm_axle": (
            (wagon.wheelset.rolling_radius - sf.cg_height) if sf.roll_held_by_axle_boxes else 0.0
        ),
        "sf_yaw_levers": 1.0 if sf.yaw_levers else 0.0,
        "x_coupler_line": (
            cb.coupler_half_spacing
            if cb.length_over_couplers is None
            else 0.5 * cb.length_over_couplers
        ),
        "c_px": wagon.primary.longitudinal_damping, "c_py": wagon.primary.lateral_damping,
        "c_pz": wagon.primary.vertical_damping, "k_sz": wagon.secondary.vertical_stiffness,
        "c_sx": wagon.secondary.longitudinal_damping, "k_gib": wagon.secondary.gib_stiffness,
        "k_cpy": wagon.centre_plate.lateral_stiffness,
        "mu_cp": wagon.centre_plate.friction_coefficient,
        "k_yaw": wagon.centre_plate.yaw_stick_stiffness,
        "c_yaw": wagon.centre_plate.yaw_stick_damping,
        "k_roll": wagon.centre_plate.roll_stick_stiffness,
        "c_roll": wagon.centre_plate.roll_stick_damping,
        "k_sb": wagon.side_bearer.vertical_stiffness, "c_sb": wagon.side_bearer.damping,
        "P_sb": wagon.side_bearer.preload,
        "mu_sb": wagon.side_bearer.friction_coefficient,
        "sb_travel": wagon.side_bearer.travel, "k_sb_stop": wagon.side_bearer.stop_stiffness,
        "k_rz": wagon.track.rail_vertical_stiffness, "k_ry": wagon.track.rail_lateral_stiffness,
        "c_rz": wagon.track.rail_vertical_damping, "c_ry": wagon.track.rail_lateral_damping,
        "rail_damping_cap": 1.0 if wagon.track.rail_damping_capped else 0.0,
        # (the design track of a condition without a curve neither turns nor twists: its
        # terms are zero and skipped)
        "frame_rotation": 1.0 if wagon.track.frame_rotation and condition.curvature else 0.0,
        "design_twist": 1.0 if wagon.track.design_twist and condition.curvature else 0.0,
        "h_cg_f": sf.cg_height,
        # an RK4 step longer than the roll impulse's passage integrates it wrongly (x1.54 of
        # the frame's roll-rate step on a 5 mm grid at 40 km/h and 1 ms): at least a step
        "turn_half_window": condition.speed * settings.max_step,
        "V": condition.speed, "g_n": gn, "mu": condition.wheel_rail_friction,
        "F_coupler": condition.coupler_force, "creep_factor": wagon.contact.creep_factor,
        "pen_max": settings.penetration_max, "lift_max": settings.lift_max,
        "flange_watch": ca.flange_shift - settings.flange_margin,
        "flange_split_speed": settings.flange_split_speed,
        "contact_points": ca.contact_points,
        "yaw_geometry": 1.0 if ca.yaw_geometry else 0.0,
        "N_ref": ca.n_ref,
        "inv_V": 1.0 / condition.speed, "inv_r0": 1.0 / wagon.wheelset.rolling_radius,
        "inv_k_ry": 1.0 / wagon.track.rail_lateral_stiffness,
        "inv_k_rz": 1.0 / wagon.track.rail_vertical_stiffness,
    }  # fmt: skip
    # static preloads (level of each interface), N
    w_body = cb.mass * gn
    f_cp = w_body / 2.0 - 2.0 * wagon.side_bearer.preload
    if f_cp <= 0:
        raise RailsuspInputError(
            "side_bearer.preload: two side bearers carry more than half the car body weight"
        )
    f_nest = (w_body / 2.0 + bo.mass * gn) / 2.0
    f_prim = (f_nest + sf.mass * gn) / 2.0
    for name in L.INERTIAS:
        vals["inv_" + name] = 1.0 / vals[name]
    # where the frame may turn: the transitions, widened by two grid cells, the roll
    # acceleration's window and a metre (outside them it is exactly zero, and skipped)
    pad = 2.0 * settings.track_step + condition.speed * settings.max_step + 1.0
    spans = TrackLayout.from_condition(condition).transitions(pad)
    for name, value in zip(L.TURN_SPANS, spans, strict=True):
        vals[name] = value
    vals.update(_wedge_constants(wagon, f_nest))
    vals.update(_bowl_constants(wagon))
    q0 = f_prim + m_w * gn / 2.0
    vals.update(F0_cp=f_cp, F0_nest=f_nest, F0_prim=f_prim, Q0=q0)
    # the support loads W act at the centre plates, h below the car body's CG: rolled by
    # theta, the body has them h theta off its centreline, a roll moment W h theta that
    # lowers its roll stiffness (docs/model.md, "Roll moments")
    h_cg_cp = cb.cg_height - bg.centre_plate_height
    vals["k_roll_gravity"] = w_body * h_cg_cp if cb.gravity_roll_moment else 0.0
    # static approach: Q0 = N0 cos(delta0) + f23(N0) sin(delta0)^2 / r0 (normal force plus the
    # vertical part of the spin creep force of a coned tread, f23 ~ N); approach along the
    # normal = G N^(2/3) + N / k_rn
    for side, col0 in (("L", 0), ("R", L.CT_RIGHT)):
        i0 = round(-ca.y0 / ca.dy)
        delta0 = ca.table[col0 + L.CT_DELTA, i0]
        g0 = ca.table[col0 + L.CT_G, i0]
        f23 = ca.table[col0 + L.CT_F23, i0] * wagon.contact.creep_factor / ca.n_ref
        cd, sd = np.cos(delta0), np.sin(delta0)
        krn = 1.0 / (cd * cd / vals["k_rz"] + sd * sd / vals["k_ry"])
        n0 = q0 / (cd + f23 * sd * sd / wagon.wheelset.rolling_radius)
        dn = g0 * n0 ** (2.0 / 3.0) + n0 / krn
        vals[f"Z0_{side}"] = dn / cd
    # grade: net coupler force = whole car's grade component at coupler height; the bogies'
    # share is passed on at centre-plate height (pitch moment on the car body about its CG)
    m_total = cb.mass + 2 * bo.mass + 4 * sf.mass + 4 * m_w
    sin_a = grade / np.sqrt(1.0 + grade * grade)
    f_net = m_total * GRAVITY * sin_a
    f_bogies = (m_total - cb.mass) * GRAVITY * sin_a
    vals["M_pitch_grade"] = (
        -(cb.cg_height - cb.coupler_height) * f_net
        + (cb.cg_height - bg.centre_plate_height) * f_bogies
    )
    # the bogie's own moment on the grade (positive: the front lowered, the leading axle
    # loaded), about any point since the forces on it balance: the car body's pull
    # f_bogies / 2 at the centre plate and its parts' grade components at their centres of
    # gravity; each side frame carries half of it to its two axle boxes
    h_cp = bg.centre_plate_height
    m_bogie_lever = (
        bo.mass * (h_cp - bo.cg_height)
        + 2.0 * sf.mass * (h_cp - sf.cg_height)
        + 2.0 * m_w * (h_cp - wagon.wheelset.rolling_radius)
    )
    vals["M_pitch_grade_frame"] = (
        0.5 * m_bogie_lever * GRAVITY * sin_a if bg.grade_pitch_moment else 0.0
    )
    vals["bowl_pitch_on_frames"] = 1.0 if wagon.centre_plate.pitch_reaction_on_side_frames else 0.0
    for name, value in vals.items():
        k[L.K[name]] = value
    return k


#: stiffness standing for a rigid bolster under the bowl (N/m) or in pitch (N m/rad): the
#: quasi-static bending and pitch it leaves are below the round-off of the ring's compression
RIGID = 1.0e30


def _bowl_constants(wagon: WagonData) -> dict[str, float]:
    """Centre-bowl ring (suspension.bowl_ring_forces): its stiffness in all from the rocking
    stiffness, k_ring = 2 k_rock / R^2, and the bolster's bending under the bowl in series
    with it, so that the two give the bowl's vertical stiffness. A rocking stiffness equal to
    vertical_stiffness R^2 / 2 is a ring on a rigid bolster (the bowl before 2026-11-24)."""
    cp = wagon.centre_plate
    radius = wagon.bogie.centre_plate_radius
    k_ring = 2.0 * cp.rocking_stiffness / (radius * radius)
    compliance = 1.0 / cp.vertical_stiffness - 1.0 / k_ring  # of the bolster's bending
    if compliance < -1e-12 / cp.vertical_stiffness:
        raise RailsuspInputError(
            f"centre_plate.rocking_stiffness = {cp.rocking_stiffness:.4g} N m/rad: accepted "
            f"from vertical_stiffness x R^2 / 2 = "
            f"{cp.vertical_stiffness * radius * radius / 2.0:.4g} up (the bowl cannot rock "
            "more easily than its ring compresses)"
        )
    k_bend = RIGID if compliance <= 1e-12 / cp.vertical_stiffness else 1.0 / compliance
    return {"k_cpz": k_ring, "k_cpb": k_bend, "k_cpp": min(cp.bolster_pitch_stiffness, RIGID)}


def _wedge_constants(wagon: WagonData, f_nest: float) -> dict[str, float]:
    """Constants of the friction wedges of one spring nest: the control springs (all
    wedges of the nest) are compressed with the nest, so their static force is their share
    k_ctrl / k_nest of the static nest force."""
    sec = wagon.secondary
    alpha = math.radians(sec.wedge_angle_deg)
    k_ctrl = sec.wedges_per_nest * sec.control_spring_stiffness  # checked by WagonData
    return {
        "tan_wedge": math.tan(alpha),
        "cos_wedge": math.cos(alpha),
        "mu_column": sec.column_friction_coefficient,
        "mu_slope": sec.slope_friction_coefficient,
        "k_ctrl": k_ctrl,
        "F0_ctrl": f_nest * k_ctrl / sec.vertical_stiffness,
        "k_wedge": sec.wedge_stick_stiffness,
        "c_wedge": sec.wedge_stick_damping,
        "x18_ref": spec("X18").nominal,
        "l_wedge": sec.wedge_half_spacing,
    }


# ---------------------------------------------------------------- track arrays
def axle_spread(wagon: WagonData) -> float:
    """Distance from the leading to the trailing wheelset, m."""
    return wagon.car_body.bogie_half_spacing * 2 + wagon.bogie.half_wheelbase * 2
