"""A single free wheelset under axle load on tangent track, built from the wagon's contact kernel.

Used to verify the contact model against Klingel's kinematic wavelength: a free wheelset with
equivalent conicity λ_e, contact half-distance b0 and radius r0 sways with wavelength
L = 2π sqrt(r0 b0 / λ_e) (Klingel, 1883; e.g. Iwnicki, Handbook of Railway Vehicle Dynamics,
ch. 7). It shares :func:`railsusp.vehicle.wheel_rail.wheel_rail_forces` with the wagon model.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH  # (sets the kernel cache before any compiles)
from railsusp.vehicle.wagon import WagonData, load_wagon
from railsusp.vehicle.wheel_rail import wheel_rail_forces

I_Z0L, I_Z0R, I_R0, I_V = L.K["Z0_L"], L.K["Z0_R"], L.K["r0"], L.K["V"]


@nb.njit(cache=True, fastmath=FASTMATH)
def _wheelset_rhs(x, dxdt, m, Ix, Iz, Iy, axle_load, K, ctab, y0, dy, H0L, H0R):
    q = x[:4]
    v = x[4:]
    f = np.zeros(4)
    for sidx in range(2):
        side = 1.0 if sidx == 0 else -1.0
        code, f_y, f_z, _, m_roll, m_yaw, _, _, _ = wheel_rail_forces(
            q[0], q[1], q[2], q[3], v[0], v[1], v[2], v[3], 0.0, side, 0.0, 0.0, 0.0, 0.0,
            ctab, y0, dy, H0L if sidx == 0 else H0R, K[I_Z0L] if sidx == 0 else K[I_Z0R], K,
        )  # fmt: skip
        if code != 0:
            return code
        f[0] += f_y  # lateral
        f[1] += f_z  # vertical
        f[2] += m_roll  # roll moment
        f[3] += m_yaw  # yaw moment
    spin = Iy * K[I_V] / K[I_R0]
    f[1] -= axle_load
    f[2] += spin * v[3]
    f[3] -= spin * v[2]
    for i in range(4):
        dxdt[i] = v[i]
    dxdt[4] = f[0] / m
    dxdt[5] = f[1] / m
    dxdt[6] = f[2] / Ix
    dxdt[7] = f[3] / Iz
    return 0


@nb.njit(cache=True, fastmath=FASTMATH)
def _integrate(x, n, dt, m, Ix, Iz, Iy, axle_load, K, ctab, y0, dy, H0L, H0R, out):
    k1 = np.empty(8)
    k2 = np.empty(8)
    k3 = np.empty(8)
    k4 = np.empty(8)
    for i in range(n):
        out[i, 0] = x[0]
        out[i, 1] = x[3]
        code = _wheelset_rhs(x, k1, m, Ix, Iz, Iy, axle_load, K, ctab, y0, dy, H0L, H0R)
        code += _wheelset_rhs(
            x + 0.5 * dt * k1, k2, m, Ix, Iz, Iy, axle_load, K, ctab, y0, dy, H0L, H0R
        )
        code += _wheelset_rhs(
            x + 0.5 * dt * k2, k3, m, Ix, Iz, Iy, axle_load, K, ctab, y0, dy, H0L, H0R
        )
        code += _wheelset_rhs(x + dt * k3, k4, m, Ix, Iz, Iy, axle_load, K, ctab, y0, dy, H0L, H0R)
        if code != 0:
            return i
        x += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return n


def free_wheelset_sway(
    speed_kmh: float = 20.0,
    y_initial: float = 0.003,
    duration: float = 12.0,
    dt: float = 2.0e-4,
    wagon: WagonData | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Release a free wheelset (C80 axle load) with a lateral offset; return (s, y, yaw).

    ``s`` is the distance run (m), ``y`` the lateral displacement (m) and ``yaw`` (rad).
    """
    from railsusp.vehicle.setup import SolverSettings, constants, contact_arrays

    wagon = load_wagon(wagon)
    cond = WorkingCondition(speed_kmh=speed_kmh, irregularity_class=None)
    p = ParameterSet.nominal().to_array()
    ca = contact_arrays(wagon)
    k = constants(wagon, cond, p, ca, SolverSettings())
    axle_load = 2.0 * k[L.K["Q0"]]
    x = np.zeros(8)
    x[0] = y_initial
    n = int(duration / dt)
    out = np.full((n, 2), np.nan)
    done = _integrate(
        x, n, dt, p[0], p[1], p[3], p[2], axle_load, k, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R, out
    )
    s = cond.speed * dt * np.arange(done)
    return s, out[:done, 0], out[:done, 1]


def sway_wavelength(s: np.ndarray, y: np.ndarray) -> float:
    """Mean wavelength (m) from the upward zero crossings of y(s) (linear interpolation)."""
    yc = y - np.mean(y)
    idx = np.flatnonzero((yc[:-1] < 0.0) & (yc[1:] >= 0.0))
    if idx.size < 3:
        raise ValueError("fewer than three upward zero crossings: run longer")
    crossings = s[idx] - yc[idx] * (s[idx + 1] - s[idx]) / (yc[idx + 1] - yc[idx])
    return float(np.mean(np.diff(crossings)))
