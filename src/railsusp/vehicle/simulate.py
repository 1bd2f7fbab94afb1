"""Simulation: parameter sets + working condition + wagon data -> wheel-rail force time series.

``simulate(params, condition)`` runs one set; ``simulate_batch(matrix, condition)`` runs many
at once in compiled, parallel code (one thread per core). Both return a
:class:`SimulationResult` with, per wheel, the lateral force Y and vertical force Q on the
rail, and derived wheelset lateral force H, derailment quotient Y/Q, wheel-unloading ratio
dQ/Q and car-body accelerations, sampled at the condition's output rate after a causal
anti-alias filter. Sets that diverge or reach a non-physical state are flagged with the
reason and carry NaN series; they never disturb the other sets of the batch.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.signal import butter

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.params import SYMBOLS, ParameterSet, check_matrix, spec
from railsusp.vehicle import layout as L
from railsusp.vehicle.contact import contact_table
from railsusp.vehicle.contact_forces import hertz_contact, kalker_creep_coefficients
from railsusp.vehicle.profiles import chn60_rail, lm_worn_wheel, read_profile
from railsusp.vehicle.track import TrackLayout, irregularities_for
from railsusp.vehicle.wagon import WagonData, load_wagon

GRAVITY = 9.81
WHEEL_NAMES = tuple(f"w{w + 1}{side}" for w in range(4) for side in ("L", "R"))


@dataclass(frozen=True)
class SolverSettings:
    """Numerical settings of the simulator.

    ``max_step``: largest internal RK4 step (s); the step is the output interval divided by
    an integer. ``anti_alias``: filter cut-off as a fraction of the output Nyquist rate.
    ``penetration_max``: Hertz approach of the steel bodies (m) beyond which a contact is
    non-physical (1 mm: a normal force of several MN); ``lift_max``: wheel lift (m) beyond
    which the flange no longer guides (derailment).
    """

    max_step: float = 1.0e-3
    anti_alias: float = 0.8
    filter_order: int = 4
    penetration_max: float = 1.0e-3
    lift_max: float = 0.025
    track_step: float = 0.125


# ---------------------------------------------------------------- contact arrays
@dataclass(frozen=True)
class ContactArrays:
    """Contact table in the kernel's layout: (N_CT, n_y) over a uniform shift grid."""

    table: np.ndarray
    y0: float
    dy: float
    H0L: float
    H0R: float
    delta0: float
    n_ref: float


#: lateral shift range of the contact table (m): the field side of the tread must stay in
#: range under wide gauge; beyond the flange the table shows climbing, flagged as failure
CONTACT_TABLE_HALF_RANGE = 0.035

#: smallest relative curvature given to Hertz at near-conformal (flange-root) points, 1/m
MIN_RELATIVE_CURVATURE = 0.5


@functools.lru_cache(maxsize=8)
def contact_arrays(wagon: WagonData) -> ContactArrays:
    """Contact functions of the wagon's wheel/rail pair, with Hertz and Kalker coefficients.

    Per shift: rolling radius, contact angle, lateral arm of the contact point from the
    wheelset centre, axle-point rise H (rise + arm x roll) at which the wheel just touches,
    Hertz constant G (approach = G N^(2/3), from the local curvatures at the static load),
    and Kalker's f11, f22, f23 at the static load (scaled with N inside the kernel).
    """
    tr = wagon.track
    # Decoupled wheels (no wheelset roll in the table): each wheel's touching height is a
    # function of its own lateral shift at contact level, y_w + r0 roll - y_rail. The
    # wheelset roll then enters the contact through that shift and the lever of the contact
    # point, so normal forces stay the gradient of one contact potential (conservative).
    prof = wagon.profiles
    wheel = lm_worn_wheel() if prof.wheel == "lm-like" else read_profile(prof.wheel, kind="wheel")
    rail = chn60_rail() if prof.rail == "chn60" else read_profile(prof.rail, kind="rail")
    tab = contact_table(
        wheel,
        rail,
        track_gauge=tr.gauge,
        rail_inclination=tr.rail_inclination,
        nominal_radius=wagon.wheelset.rolling_radius,
        wheelset_roll=False,
        y_min=-CONTACT_TABLE_HALF_RANGE,
        y_max=CONTACT_TABLE_HALF_RANGE,
    )
    n_ref = _static_wheel_load(wagon)
    y = tab.y
    arrays = np.empty((L.N_CT, y.size))
    for col0, wheel in ((0, 0), (L.CT_RIGHT, 1)):
        arm = (tab.contact_y[:, wheel] - y) * (1.0 if wheel == 0 else -1.0)
        rise = tab.contact_z[:, wheel] + tab.rolling_radius[:, wheel]  # axle height at touch
        wl = np.maximum(tab.wheel_curvature_long[:, wheel], 2 * MIN_RELATIVE_CURVATURE)
        lat = tab.wheel_curvature_lat[:, wheel] + tab.rail_curvature_lat[:, wheel]
        lat = np.maximum(lat, 2 * MIN_RELATIVE_CURVATURE)
        patch = hertz_contact(n_ref, wl, lat, 0.0)
        g = patch.approach / n_ref ** (2.0 / 3.0)
        f11, f22, f23, _ = kalker_creep_coefficients(patch.a, patch.b)
        arrays[col0 + L.CT_R] = tab.rolling_radius[:, wheel]
        # contact angle consistent with the rigid-contact rise (normal force = gradient of the
        # contact potential, so the table forces are conservative): tan(delta) = +-dH/dy
        slope = np.gradient(rise, y) * (1.0 if wheel == 0 else -1.0)
        arrays[col0 + L.CT_DELTA] = np.arctan(slope)
        arrays[col0 + L.CT_L] = arm
        arrays[col0 + L.CT_H] = rise
        arrays[col0 + L.CT_G] = g
        arrays[col0 + L.CT_F11] = f11
        arrays[col0 + L.CT_F22] = f22
        arrays[col0 + L.CT_F23] = f23
    i0 = int(np.argmin(np.abs(y)))
    arrays[L.CT_H] -= arrays[L.CT_H, i0]
    arrays[L.CT_RIGHT + L.CT_H] -= arrays[L.CT_RIGHT + L.CT_H, i0]
    return ContactArrays(
        table=np.ascontiguousarray(arrays),
        y0=float(y[0]),
        dy=float(y[1] - y[0]),
        H0L=float(arrays[L.CT_H, i0]),
        H0R=float(arrays[L.CT_RIGHT + L.CT_H, i0]),
        delta0=float(arrays[L.CT_DELTA, i0]),
        n_ref=n_ref,
    )


def _static_wheel_load(wagon: WagonData, wheelset_mass: float | None = None) -> float:
    """Static vertical wheel load (N) on level track: total wagon weight / 8."""
    m_w = spec("X1").nominal if wheelset_mass is None else wheelset_mass
    total = wagon.car_body.mass + 2 * wagon.bolster.mass + 4 * wagon.side_frame.mass + 4 * m_w
    return total * GRAVITY / 8.0


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
        "c_px": wagon.primary.longitudinal_damping, "c_py": wagon.primary.lateral_damping,
        "c_pz": wagon.primary.vertical_damping, "k_sz": wagon.secondary.vertical_stiffness,
        "c_sx": wagon.secondary.longitudinal_damping,
        "mu_wedge": wagon.secondary.wedge_friction_ratio,
        "k_wedge": wagon.secondary.wedge_stick_stiffness, "k_gib": wagon.secondary.gib_stiffness,
        "k_cpz": wagon.centre_plate.vertical_stiffness,
        "k_cpy": wagon.centre_plate.lateral_stiffness,
        "mu_cp": wagon.centre_plate.friction_coefficient,
        "k_yaw": wagon.centre_plate.yaw_stick_stiffness,
        "k_sb": wagon.side_bearer.vertical_stiffness, "P_sb": wagon.side_bearer.preload,
        "mu_sb": wagon.side_bearer.friction_coefficient,
        "k_rz": wagon.track.rail_vertical_stiffness, "k_ry": wagon.track.rail_lateral_stiffness,
        "c_rz": wagon.track.rail_vertical_damping, "c_ry": wagon.track.rail_lateral_damping,
        "V": condition.speed, "g_n": gn, "mu": condition.wheel_rail_friction,
        "F_coupler": condition.coupler_force, "creep_factor": wagon.contact.creep_factor,
        "pen_max": settings.penetration_max, "lift_max": settings.lift_max,
        "N_ref": ca.n_ref,
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
    q0 = f_prim + m_w * gn / 2.0
    vals.update(F0_cp=f_cp, F0_nest=f_nest, F0_prim=f_prim, Q0=q0)
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
    for name, value in vals.items():
        k[L.K[name]] = value
    return k


# ---------------------------------------------------------------- track arrays
def track_arrays(
    condition: WorkingCondition, seeds: Sequence[int], wagon: WagonData, settings: SolverSettings
) -> tuple[np.ndarray, float, float]:
    """Track channels (layout.TR_*) on a uniform grid for each seed: (n_seeds, N_TR, n_s).

    Geometry (curvature, cant angle, heading θ = ∫κ ds, lateral position Y = ∫θ ds) is
    shared; irregularities ramp in smoothly over the first 30 m (zero behind s = 0), so that
    the run starts from static equilibrium.
    """
    behind = wagon.car_body.bogie_half_spacing * 2 + wagon.bogie.half_wheelbase * 2 + 20.0
    ds = settings.track_step
    s = np.arange(-behind, condition.section_length_m + 20.0 + ds, ds)
    lay = TrackLayout.from_condition(condition)
    kappa = lay.curvature_at(s)
    head = np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * ds)])
    offset = np.concatenate([[0.0], np.cumsum(0.5 * (head[1:] + head[:-1]) * ds)])
    out = np.zeros((len(seeds), L.N_TR, s.size))
    out[:, L.TR_KAPPA] = kappa
    out[:, L.TR_CANT] = lay.cant_angle_at(s)
    out[:, L.TR_HEAD] = head
    out[:, L.TR_OFFSET] = offset
    if condition.irregularity_class is not None:
        irr = irregularities_for(condition, list(seeds), behind=behind + 5.0)
        rails = irr.at(s)  # type: ignore[union-attr]
        ramp = np.clip(s / 30.0, 0.0, 1.0)  # zero under every wheel at the start
        window = ramp * ramp * (3.0 - 2.0 * ramp)
        out[:, L.TR_ZL] = rails["zL"] * window
        out[:, L.TR_ZR] = rails["zR"] * window
        out[:, L.TR_YL] = rails["yL"] * window
        out[:, L.TR_YR] = rails["yR"] * window
    return np.ascontiguousarray(out), float(s[0]), ds


def measured_wheel_index(condition: WorkingCondition, which: str | int = "auto") -> int:
    """Index 0..7 of the measured wheel: 'auto' = leading wheelset, outer wheel in a curve
    (left wheel on tangent); or a name like 'w1R' or an index."""
    if isinstance(which, int):
        if not 0 <= which < 8:
            raise RailsuspInputError(f"measured wheel index {which} outside 0..7")
        return which
    if which == "auto":
        if condition.curve_radius_m is None:
            return 0
        return 1 if condition.curve_direction == "left" else 0
    if which not in WHEEL_NAMES:
        raise RailsuspInputError(
            f"measured wheel {which!r} unknown; accepted 'auto' or {', '.join(WHEEL_NAMES)}"
        )
    return WHEEL_NAMES.index(which)


# ---------------------------------------------------------------- result
@dataclass
class SimulationResult:
    """Wheel-rail forces of a batch of runs in one working condition.

    Arrays (SI): ``Y`` and ``Q`` (n_sets, 8, n_t), wheel order w1L, w1R, ... w4R (w1 the
    leading wheelset); Y is the lateral force of the wheel on the rail, + towards the field
    side (flange force +); Q the vertical force on the rail, + down. ``car_acc_y``/``_z``
    (n_sets, n_t) car-body CG accelerations (lateral uncompensated). ``status`` 0 = ok, else a
    code of ``layout.FAILURE_REASONS``; failed sets hold NaN series.
    """

    condition: WorkingCondition
    params: np.ndarray  # (n_sets, 20) SI, X1..X20
    time: np.ndarray
    Y: np.ndarray
    Q: np.ndarray
    car_acc_y: np.ndarray
    car_acc_z: np.ndarray
    status: np.ndarray
    fail_time: np.ndarray
    static_wheel_load: float
    wall_time: float = 0.0
    settings: SolverSettings = field(default_factory=SolverSettings)
    wagon_name: str = ""

    @property
    def n_sets(self) -> int:
        return self.Y.shape[0]

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask of sets that completed."""
        return self.status == L.OK

    def failures(self) -> list[tuple[int, str, float]]:
        """(set index, reason, time s) of each failed set."""
        return [
            (int(i), L.FAILURE_REASONS[int(self.status[i])], float(self.fail_time[i]))
            for i in np.flatnonzero(self.status != L.OK)
        ]

    @property
    def H(self) -> np.ndarray:
        """Wheelset lateral force on the track (n_sets, 4, n_t), N, + to the left."""
        return self.Y[:, 0::2] - self.Y[:, 1::2]

    @property
    def derailment_quotient(self) -> np.ndarray:
        """Y/Q per wheel (n_sets, 8, n_t); NaN where the wheel is unloaded."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.Q > 1.0, self.Y / self.Q, np.nan)

    @property
    def unloading_ratio(self) -> np.ndarray:
        """Wheel-unloading ratio dQ/Q per wheel (n_sets, 8, n_t): (Q_static - Q)/Q_static."""
        return (self.static_wheel_load - self.Q) / self.static_wheel_load

    def measured_wheel(self, which: str | int = "auto") -> int:
        """Index of the measured wheel (see :func:`measured_wheel_index`)."""
        return measured_wheel_index(self.condition, which)

    def statistics(self, wheel: str | int = "auto") -> dict[str, np.ndarray]:
        """Per-set statistics (kN for forces) of the measured wheel: mean, RMS, p99, max of
        |Y| and Q, max Y/Q, max dQ/Q."""
        j = self.measured_wheel(wheel)
        y = np.abs(self.Y[:, j]) / 1e3
        q = self.Q[:, j] / 1e3
        stats = {}
        for name, arr in (("Y", y), ("Q", q)):
            stats[f"{name}_mean"] = arr.mean(axis=1)
            stats[f"{name}_rms"] = np.sqrt((arr * arr).mean(axis=1))
            stats[f"{name}_p99"] = np.percentile(arr, 99, axis=1)
            stats[f"{name}_max"] = arr.max(axis=1)
        stats["YQ_max"] = np.nanmax(np.abs(self.derailment_quotient[:, j]), axis=1)
        stats["dQQ_max"] = np.max(self.unloading_ratio[:, j], axis=1)
        return stats

    def to_dataframe(self, set_index: int = 0):
        """Time series of one set as a pandas DataFrame (kN, m/s^2), time in s as index."""
        import pandas as pd

        cols = {}
        for j, name in enumerate(WHEEL_NAMES):
            cols[f"Y_{name}_kN"] = self.Y[set_index, j] / 1e3
        for j, name in enumerate(WHEEL_NAMES):
            cols[f"Q_{name}_kN"] = self.Q[set_index, j] / 1e3
        for w in range(4):
            cols[f"H_w{w + 1}_kN"] = self.H[set_index, w] / 1e3
        cols["car_acc_y_m_s2"] = self.car_acc_y[set_index]
        cols["car_acc_z_m_s2"] = self.car_acc_z[set_index]
        return pd.DataFrame(cols, index=pd.Index(self.time, name="time_s"))

    def to_xarray(self):
        """All sets as an xarray Dataset: Y, Q (set, wheel, time) in N; accelerations."""
        import xarray as xr

        coords = {
            "set": np.arange(self.n_sets),
            "wheel": list(WHEEL_NAMES),
            "time": self.time,
            "parameter": [f"X{i}" for i in range(1, 21)],
        }
        ds = xr.Dataset(
            {
                "Y": (
                    ("set", "wheel", "time"),
                    self.Y,
                    {
                        "units": "N",
                        "long_name": "lateral force on the rail, + towards the field side",
                    },
                ),
                "Q": (
                    ("set", "wheel", "time"),
                    self.Q,
                    {"units": "N", "long_name": "vertical force on the rail, + down"},
                ),
                "car_acc_y": (("set", "time"), self.car_acc_y, {"units": "m/s^2"}),
                "car_acc_z": (("set", "time"), self.car_acc_z, {"units": "m/s^2"}),
                "params": (("set", "parameter"), self.params, {"units": "SI"}),
                "status": (("set",), self.status),
            },
            coords=coords,
            attrs={"condition": self.condition.model_dump_json(), "wagon": self.wagon_name},
        )
        return ds

    def to_parquet(self, path: str | Path, set_index: int = 0) -> Path:
        """Write one set's series to Parquet atomically, with the condition in the metadata."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        table = pa.Table.from_pandas(self.to_dataframe(set_index))
        meta = dict(table.schema.metadata or {})
        meta[b"railsusp.condition"] = self.condition.model_dump_json().encode()
        meta[b"railsusp.params"] = ",".join(f"{v:.9g}" for v in self.params[set_index]).encode()
        meta[b"railsusp.status"] = L.FAILURE_REASONS[int(self.status[set_index])].encode()
        tmp = path.with_name(f".{path.name}.tmp")
        pq.write_table(table.replace_schema_metadata(meta), tmp)
        tmp.replace(path)
        return path


# ---------------------------------------------------------------- entry points
def _param_matrix(sets: np.ndarray | Iterable[ParameterSet], symbols: Sequence[str] | None):
    """Full (n, 20) SI matrix from ParameterSets, or from a matrix over ``symbols``."""
    if isinstance(sets, np.ndarray) or (symbols is not None):
        syms = list(symbols) if symbols is not None else list(SYMBOLS)
        x = (
            check_matrix(syms, np.atleast_2d(np.asarray(sets, dtype=float)))
            if syms != list(SYMBOLS)
            else np.atleast_2d(np.asarray(sets, float))
        )
        full = np.tile(ParameterSet.nominal().to_array(), (x.shape[0], 1))
        for j, s in enumerate(syms):
            full[:, SYMBOLS.index(spec(s).symbol)] = x[:, j]
        if syms == list(SYMBOLS):
            for i in range(full.shape[0]):  # validate every row as a full set
                ParameterSet(dict(zip(SYMBOLS, full[i], strict=True)))
        return full
    rows = [p.to_array() for p in sets]
    if not rows:
        raise RailsuspInputError("no parameter sets given")
    return np.array(rows)


def simulate_batch(
    sets: np.ndarray | Iterable[ParameterSet],
    condition: WorkingCondition,
    *,
    symbols: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    wagon: WagonData | None = None,
    settings: SolverSettings | None = None,
    progress: Callable[[int, int], None] | None = None,
    chunk_size: int = 32,
) -> SimulationResult:
    """Simulate N parameter sets in one condition, in parallel.

    ``sets``: ParameterSets, or an (N, len(symbols)) SI matrix of the parameters in
    ``symbols`` (others nominal), or (N, 20) for all. ``seeds``: one irregularity seed per
    set (default: the condition's seed for every set, i.e. common random numbers).
    ``progress(done, total)`` is called after each chunk of ``chunk_size`` sets.
    """
    from railsusp.vehicle.integrate import integrate_batch

    wagon = load_wagon() if wagon is None else wagon
    settings = SolverSettings() if settings is None else settings
    P = np.ascontiguousarray(_param_matrix(sets, symbols))
    n = P.shape[0]
    ca = contact_arrays(wagon)
    K = np.ascontiguousarray(
        np.stack([constants(wagon, condition, P[i], ca, settings) for i in range(n)])
    )
    if seeds is None:
        track_seeds, track_index = [condition.seed], np.zeros(n, dtype=np.int64)
    else:
        if len(seeds) != n:
            raise RailsuspInputError(f"seeds: {len(seeds)} given for {n} parameter sets")
        track_seeds, inverse = np.unique(np.asarray(seeds, dtype=np.int64), return_inverse=True)
        track_seeds, track_index = list(track_seeds), inverse.astype(np.int64)
    tracks, s0, ds = track_arrays(condition, track_seeds, wagon, settings)
    dt_out = condition.sample_interval
    n_sub = max(1, int(np.ceil(dt_out / settings.max_step - 1e-9)))
    dt = dt_out / n_sub
    n_pre = round(condition.lead_in_m / condition.speed / dt)
    n_out = condition.n_steps
    sos = butter(
        settings.filter_order, settings.anti_alias * 0.5 / dt_out, fs=1.0 / dt, output="sos"
    )
    out = np.zeros((n, L.N_OUT, n_out))
    status = np.zeros(n, dtype=np.int64)
    fail_time = np.zeros(n)
    sos = np.ascontiguousarray(sos)
    chunk = n if progress is None else max(1, chunk_size)
    t0 = time.perf_counter()
    for lo in range(0, n, chunk):
        sl = slice(lo, min(n, lo + chunk))
        integrate_batch(
            P[sl],
            K[sl],
            tracks,
            track_index[sl],
            s0,
            ds,
            ca.table,
            ca.y0,
            ca.dy,
            ca.H0L,
            ca.H0R,
            dt,
            n_pre,
            n_sub,
            n_out,
            sos,
            out[sl],
            status[sl],
            fail_time[sl],
        )
        if progress is not None:
            progress(sl.stop, n)
    wall = time.perf_counter() - t0
    return SimulationResult(
        condition=condition,
        params=P,
        time=np.arange(n_out) * dt_out,
        Y=out[:, L.OUT_Y : L.OUT_Y + 8],
        Q=out[:, L.OUT_Q : L.OUT_Q + 8],
        car_acc_y=out[:, L.OUT_ACC_Y],
        car_acc_z=out[:, L.OUT_ACC_Z],
        status=status,
        fail_time=fail_time,
        static_wheel_load=float(K[0, L.K["Q0"]]),
        wall_time=wall,
        settings=settings,
        wagon_name=wagon.name,
    )


def simulate(
    params: ParameterSet | None, condition: WorkingCondition, **kwargs
) -> SimulationResult:
    """Simulate one parameter set (nominal if None) in one condition."""
    return simulate_batch([params or ParameterSet.nominal()], condition, **kwargs)
