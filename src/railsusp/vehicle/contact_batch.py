"""The eight wheels' wheel-rail contacts of one evaluation, together, as SIMD loops.

The same force laws as :func:`railsusp.vehicle.wheel_rail.wheel_rail_forces` (one wheel,
scalar), evaluated for all eight wheels in loops over the wheels that LLVM vectorises (one
AVX-512 register holds the eight wheels' values): branch-free geometry (both sides of every
case computed, one selected), the Hertz solves of tread and flange as Newton steps of all
sixteen contact points in step until the slowest has converged, Kalker creep and
saturation; cube root, sine and cosine from :mod:`railsusp.vehicle.vector_math` (the C
library's are not vectorised). Two parts run wheel by wheel: the contact table reads (gathers,
which LLVM does not vectorise next to stores whose bounds it cannot check) and the flange's
shared-rail 2 x 2 solve where a flange touches, started from the wheel's solution of the
previous evaluation (rows ``W_U1``, ``W_U2``;
:func:`railsusp.vehicle.normal_contact.shared_rail_newton`). Forces agree with the scalar kernel
to round-off and the failure codes are the same (tests/vehicle/test_contact_batch.py).

Every value lives in the work vector ``wk`` (rows of eight wheels, ``W_*``), which the right-
hand side keeps in its output work array (``layout.OUT_CONTACT``): nothing is allocated.
Wheel c = 2 w + (0 left, 1 right) of wheelset w. The right-hand side fills the rows
``W_KAPPA`` (curvature at the wheelset) and ``W_RY``, ``W_RZ``, ``W_RVY``, ``W_RVZ`` (the
rail's irregularity and its rate); wheelset displacements and velocities are read from the
state. Results: ``W_CODE`` (failure code, 0 ok), ``W_FY``, ``W_FZ`` (forces on the wheel,
track frame), ``W_MX``, ``W_MZ`` (roll and yaw moments about the wheelset centre).

Compiled with ``error_model="numpy"`` (a division by zero gives inf or NaN instead of
raising, which would stop the vectorisation) and the kernels' fast-math flags
(:data:`~railsusp.vehicle.kernel_cache.FASTMATH`: contraction, reciprocals, no signed zeros;
none that assumes finite values): NaN and infinity propagate as in the scalar kernel, and the
integrator's finiteness check of the state sees them.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)
from railsusp.vehicle.normal_contact import HERTZ_ITERATIONS, HERTZ_TOLERANCE, shared_rail_newton
from railsusp.vehicle.vector_math import cbrt_positive, cbrt_rough, sin_cos
from railsusp.vehicle.wheel_rail import table_index

_K = L.K
I_R0, I_MU, I_CREEP = _K["r0"], _K["mu"], _K["creep_factor"]
I_CRZ, I_CRY, I_DCAP = _K["c_rz"], _K["c_ry"], _K["rail_damping_cap"]
I_NREF, I_PENMAX, I_LIFTMAX = _K["N_ref"], _K["pen_max"], _K["lift_max"]
I_NPTS, I_YAWGEO = _K["contact_points"], _K["yaw_geometry"]
I_INVV, I_INVR0, I_INVKRY, I_INVKRZ = _K["inv_V"], _K["inv_r0"], _K["inv_k_ry"], _K["inv_k_rz"]
I_Z0L, I_Z0R = _K["Z0_L"], _K["Z0_R"]
NCTW = L.CT_PER_WHEEL
CT_LEAD, CT_L, CT_H, CT_R = L.CT_LEAD, L.CT_L, L.CT_H, L.CT_R
CT_DELTA, CT_G, CT_F11, CT_F22, CT_F23 = L.CT_DELTA, L.CT_G, L.CT_F11, L.CT_F22, L.CT_F23
NQ = L.N_DOF
WS0 = L.WS0
NW = 8  # wheels

# rows of the work vector: per wheel, the inputs from the right-hand side, the wheelset's
# state, the results and the shared-rail solution (W_U1, W_U2: u of tread and flange, kept to
# the next evaluation as its warm start; 0 where the wheel had none); per contact point
# (tread p = 0, flange p = 1, from row _P + p _NP) the table values read, the geometry and
# the Hertz solve
(W_KAPPA, W_RY, W_RZ, W_RVY, W_RVZ, W_Y, W_Z, W_ROLL, W_YAW, W_VY, W_VZ, W_VROLL, W_VYAW,
 W_SIDE, W_H0, W_Z0, W_CODE, W_FY, W_FZ, W_MX, W_MZ, W_U1, W_U2) = range(23)  # fmt: skip
_P = 23
(P_LEAD, P_LAT, P_H, P_R, P_DELTA, P_G, P_F11, P_F22, P_F23, P_XC, P_XPOS, P_A, P_CD, P_SD,
 P_RD, P_RATE, P_M, P_C, P_D, P_U, P_N) = range(21)  # fmt: skip
_NP = 21
N_ROWS = _P + 2 * _NP
#: the table column of each table row P_LEAD .. P_F23
_COLUMN = (CT_LEAD, CT_L, CT_H, CT_R, CT_DELTA, CT_G, CT_F11, CT_F22, CT_F23)
N_WORK = N_ROWS * NW  # length of the work vector
assert N_WORK == L.N_CONTACT_WORK


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def _lanes(wk):
    """The number of wheels, NW, as a value LLVM cannot see at compile time: a loop of a known
    eight iterations is unrolled before the loop vectoriser sees it, and then not vectorised."""
    return wk.shape[0] // N_ROWS


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def _cell(ctab, c, i, f):
    """Column c of the contact table interpolated at (i, f)."""
    return ctab[c, i] * (1.0 - f) + ctab[c, i + 1] * f


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def _read_tables(x, ctab, y0, inv_dy, H0L, H0R, K, wk, p):
    """Wheel by wheel: the wheelset's state into the W_* rows (tread, p = 0), and the
    contact table of point p read at the wheel's shift, for the yawed wheelset at the contact
    point's rail point (:func:`railsusp.vehicle.wheel_rail.contact_geometry`); a shift beyond
    the table (flange climb) sets W_CODE where none is yet (for the flange only with
    two-point contact). The reads stay scalar: as gathers LLVM does not vectorise them next
    to stores, and AVX-512 gathers (vectorised with a stack buffer) were slower than these
    scalar loads on the bench's AMD Zen 5, as was a table laid out by shift
    (bench/README.md, stop 22). Inlined: the call cost about 1 % of the right-hand side."""
    n = ctab.shape[1]
    r0 = K[I_R0]
    yawed = K[I_YAWGEO] > 0.5
    checked = p == 0 or K[I_NPTS] > 1.5
    b = (_P + p * _NP) * NW
    for c in range(NW):
        right = (c & 1) == 1
        side = -1.0 if right else 1.0
        if p == 0:
            iw = WS0 + 4 * (c >> 1)
            for k in range(4):
                wk[(W_Y + k) * NW + c] = x[iw + k]
                wk[(W_VY + k) * NW + c] = x[NQ + iw + k]
            wk[W_SIDE * NW + c] = side
            wk[W_H0 * NW + c] = H0R if right else H0L
            wk[W_Z0 * NW + c] = K[I_Z0R] if right else K[I_Z0L]
            wk[W_CODE * NW + c] = 0.0
        ws_yaw = wk[W_YAW * NW + c]
        col0 = p * L.CT_FLANGE + (NCTW if right else 0)
        yrel = wk[W_Y * NW + c] + r0 * wk[W_ROLL * NW + c] - wk[W_RY * NW + c]
        i, f = table_index(yrel, y0, inv_dy, n)
        lead = _cell(ctab, col0 + CT_LEAD, i, f) if i >= 0 else 0.0
        x_c = side * lead * ws_yaw
        x_pos = 0.0
        if yawed and i >= 0:  # the yawed contact's rail point
            x_pos = x_c - side * _cell(ctab, col0 + CT_L, i, f) * ws_yaw
            move = 0.5 * (x_c + x_pos) * ws_yaw
            f += move * inv_dy  # mostly within the same table interval: no new index
            if f < 0.0 or f > 1.0:
                i, f = table_index(yrel + move, y0, inv_dy, n)
        if i < 0:
            if checked and wk[W_CODE * NW + c] == 0.0:
                wk[W_CODE * NW + c] = L.FAIL_FLANGE_CLIMB
            i, f = 0, 0.0
        wk[b + P_LEAD * NW + c] = lead
        wk[b + P_XC * NW + c] = x_c
        wk[b + P_XPOS * NW + c] = x_pos
        for k in range(P_LAT, P_F23 + 1):
            wk[b + k * NW + c] = _cell(ctab, col0 + _COLUMN[k], i, f)


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, error_model="numpy")
def _geometry(K, wk, p):
    """Vectorised over the wheels: gap, contact angle, gap rate of point p from the table
    values (:func:`railsusp.vehicle.wheel_rail.contact_geometry`), the rigid approach along
    the normal, the rail's compliance along it and the start of the single-contact Hertz
    solve; the tread's lift beyond the bound sets W_CODE where none is yet."""
    r0 = K[I_R0]
    inv_r0 = K[I_INVR0]
    yawed = K[I_YAWGEO] > 0.5
    c_lat = K[I_INVKRY]
    c_vert = K[I_INVKRZ]
    lift_max = K[I_LIFTMAX] if p == 0 else np.inf
    b = (_P + p * _NP) * NW
    for c in range(_lanes(wk)):
        side = wk[W_SIDE * NW + c]
        ws_roll = wk[W_ROLL * NW + c]
        vroll = wk[W_VROLL * NW + c]
        x_c = wk[b + P_XC * NW + c]
        lat = wk[b + P_LAT * NW + c]
        r = wk[b + P_R * NW + c]
        inv_2r = 0.5 * inv_r0 * (2.0 - r * inv_r0) if yawed else 0.0
        drop = x_c * x_c * inv_2r
        gap = (
            wk[W_Z * NW + c] + side * lat * ws_roll - wk[W_RZ * NW + c]
            - (wk[b + P_H * NW + c] - wk[W_H0 * NW + c]) - wk[W_Z0 * NW + c] + drop
        )  # fmt: skip
        sd, cd = sin_cos(wk[b + P_DELTA * NW + c])
        slope = side * sd / cd
        vyaw = wk[W_VYAW * NW + c]
        rate = (
            wk[W_VZ * NW + c] + side * lat * vroll - wk[W_RVZ * NW + c]
            - slope * (wk[W_VY * NW + c] + r0 * vroll - wk[W_RVY * NW + c]
                       + (x_c + wk[b + P_XPOS * NW + c]) * vyaw)
            + 2.0 * x_c * (side * wk[b + P_LEAD * NW + c] * vyaw) * inv_2r
        )  # fmt: skip
        a = -gap * cd
        m = sd * sd * c_lat + cd * cd * c_vert
        g = wk[b + P_G * NW + c]
        krn = 1.0 / m
        cc = krn * g
        d = krn * a
        touching = a > 0.0
        ur = cbrt_rough(d if touching else 1.0)  # rail alone
        uh = math.sqrt(a / g if touching else 1.0)  # Hertz alone
        u0 = ur - cc / 3.0 + cc * cc / (9.0 * ur) if ur > cc else min(uh, ur)
        if gap > lift_max and wk[W_CODE * NW + c] == 0.0:
            wk[W_CODE * NW + c] = L.FAIL_LIFT
        wk[b + P_A * NW + c] = a
        wk[b + P_CD * NW + c] = cd
        wk[b + P_SD * NW + c] = sd
        wk[b + P_RD * NW + c] = r - drop
        wk[b + P_RATE * NW + c] = rate
        wk[b + P_M * NW + c] = m
        wk[b + P_C * NW + c] = cc
        wk[b + P_D * NW + c] = d
        wk[b + P_U * NW + c] = u0 if touching else 0.0


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, error_model="numpy")
def _hertz_steps(wk):
    """Newton steps of the Hertz-on-elastic-rail cubic u^3 + c u^2 = d of all sixteen points
    together (:func:`railsusp.vehicle.normal_contact.hertz_rail_solve`; u = 0 where a point does
    not touch), until every point's step is below HERTZ_TOLERANCE of its u: a point that
    converged earlier takes steps of round-off size. Stores N = u^3."""
    u0 = (_P + P_U) * NW
    for _ in range(HERTZ_ITERATIONS):
        n_open = 0
        for p in range(2):
            b = p * _NP * NW
            for c in range(_lanes(wk)):
                u = wk[b + u0 + c]
                cc = wk[b + (_P + P_C) * NW + c]
                d = wk[b + (_P + P_D) * NW + c]
                du = ((u + cc) * u * u - d) / ((3.0 * u + 2.0 * cc) * u)
                du = du if u > 0.0 else 0.0
                u -= du
                wk[b + u0 + c] = u
                n_open += abs(du) > HERTZ_TOLERANCE * u  # (a NaN counts as converged)
        if n_open == 0:
            break
    for p in range(2):
        b = p * _NP * NW
        for c in range(NW):
            u = wk[b + u0 + c]
            wk[b + (_P + P_N) * NW + c] = u * u * u


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def _damped_load(N, rate, cd, sd, g, K):
    """(N less the rail support's damping along the normal, the damping's push capped at N,
    whether that leaves a load,
    1.0 where the Hertz approach is beyond the penetration bound) of one point with Hertz
    force N (:func:`railsusp.vehicle.wheel_rail.creep_contact_forces`). An unloaded point
    gets N = 1 (a harmless value for the cube root; its forces are selected away)."""
    pen = K[I_PENMAX]
    deep = 1.0 if N * N * (g * g * g) > pen * pen * pen else 0.0
    damping = -(cd * cd * K[I_CRZ] + sd * sd * K[I_CRY]) * rate * cd
    # at most the Hertz force (no step at a touch-down; K rail_damping_cap)
    n = N + (min(damping, N) if K[I_DCAP] != 0.0 else damping)
    loaded = n > 0.0 if N > 0.0 else False
    return n if loaded else 1.0, loaded, deep


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def _creep(N, u, loaded, cd, sd, lat, r, f11, f22, f23, x_c, x_pos, side, vy, vroll, ws_yaw,
           vyaw, kappa, K, yawed):  # fmt: skip
    """Branch-free :func:`railsusp.vehicle.wheel_rail.creep_contact_forces` of one point
    from its damped load N and u = (N / N_ref)^(1/3): (f_y, f_z, roll moment, yaw moment),
    zeros for a point that carries no load. (The cube root is the caller's: a function
    inlined into one that is inlined is not, and the call stops the vectoriser.)"""
    r0 = K[I_R0]
    inv_r0 = K[I_INVR0]
    inv_v = K[I_INVV]
    scale = u * u * K[I_CREEP]
    c11 = f11 * scale
    c22 = f22 * scale
    c23 = f23 * scale * u
    yaw_rate = vyaw * inv_v + kappa
    xi_x = 1.0 - r * inv_r0 - side * lat * yaw_rate
    if yawed:
        xi_y = (vy + r * vroll) * inv_v - ws_yaw * cd - side * sd * x_c * inv_r0 + yaw_rate * x_pos
    else:
        xi_y = (vy + r * vroll) * inv_v - ws_yaw
    spin = yaw_rate * cd - side * sd * inv_r0
    fx = -c11 * xi_x
    fy = -c22 * xi_y - c23 * spin
    # Shen-Hedrick-Elkins (railsusp.vehicle.wheel_rail.she_saturation)
    mu_n = K[I_MU] * N
    beta = math.sqrt(fx * fx + fy * fy) / mu_n
    eps = 1.0 - beta / 3.0 + beta * beta / 27.0 if beta < 3.0 else 1.0 / beta
    eps = eps if mu_n > 0.0 else 0.0
    fx *= eps
    fy *= eps
    f_y = -side * N * sd + fy * cd
    f_z = N * cd + side * fy * sd
    m_x = side * lat * f_z + r0 * f_y
    m_z = x_pos * f_y - side * lat * fx
    # one return of selects (two returns stop the vectoriser)
    return (
        f_y if loaded else 0.0, f_z if loaded else 0.0, m_x if loaded else 0.0,
        m_z if loaded else 0.0,
    )  # fmt: skip


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, error_model="numpy")
def _forces(K, wk):
    """Vectorised over the wheels: creep forces of both points, summed per wheel (tread
    first) into W_FY, W_FZ, W_MX, W_MZ; a penetration beyond the bound sets W_CODE where
    none is yet."""
    yawed = K[I_YAWGEO] > 0.5
    inv_n_ref = 1.0 / K[I_NREF]  # once, not a division per point
    t = _P * NW
    fl = (_P + _NP) * NW
    for c in range(_lanes(wk)):
        side = wk[W_SIDE * NW + c]
        ws_yaw = wk[W_YAW * NW + c]
        vy = wk[W_VY * NW + c]
        vroll = wk[W_VROLL * NW + c]
        vyaw = wk[W_VYAW * NW + c]
        kappa = wk[W_KAPPA * NW + c]
        cd0 = wk[t + P_CD * NW + c]
        sd0 = wk[t + P_SD * NW + c]
        cd1 = wk[fl + P_CD * NW + c]
        sd1 = wk[fl + P_SD * NW + c]
        n0, loaded0, deep0 = _damped_load(
            wk[t + P_N * NW + c], wk[t + P_RATE * NW + c], cd0, sd0, wk[t + P_G * NW + c], K
        )
        n1, loaded1, deep1 = _damped_load(
            wk[fl + P_N * NW + c], wk[fl + P_RATE * NW + c], cd1, sd1, wk[fl + P_G * NW + c], K
        )
        fy, fz, mx, mz = _creep(
            n0, cbrt_positive(n0 * inv_n_ref), loaded0, cd0, sd0, wk[t + P_LAT * NW + c],
            wk[t + P_RD * NW + c], wk[t + P_F11 * NW + c], wk[t + P_F22 * NW + c],
            wk[t + P_F23 * NW + c], wk[t + P_XC * NW + c], wk[t + P_XPOS * NW + c], side, vy,
            vroll, ws_yaw, vyaw, kappa, K, yawed,
        )  # fmt: skip
        gy, gz, nx, nz = _creep(
            n1, cbrt_positive(n1 * inv_n_ref), loaded1, cd1, sd1, wk[fl + P_LAT * NW + c],
            wk[fl + P_RD * NW + c], wk[fl + P_F11 * NW + c], wk[fl + P_F22 * NW + c],
            wk[fl + P_F23 * NW + c], wk[fl + P_XC * NW + c], wk[fl + P_XPOS * NW + c], side, vy,
            vroll, ws_yaw, vyaw, kappa, K, yawed,
        )  # fmt: skip
        if wk[W_CODE * NW + c] == 0.0 and deep0 + deep1 > 0.0:
            wk[W_CODE * NW + c] = L.FAIL_PENETRATION
        wk[W_FY * NW + c] = fy + gy
        wk[W_FZ * NW + c] = fz + gz
        wk[W_MX * NW + c] = mx + nx
        wk[W_MZ * NW + c] = mz + nz


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME)
def contact_forces_8(x, ctab, y0, dy, H0L, H0R, K, wk):
    """Contact forces of the eight wheels of state x into the work vector ``wk`` (module
    docstring; exactly N_WORK long: its loops take their length from it), given its rows
    W_KAPPA, W_RY, W_RZ, W_RVY, W_RVZ."""
    inv_dy = 1.0 / dy
    _read_tables(x, ctab, y0, inv_dy, H0L, H0R, K, wk, 0)
    _geometry(K, wk, 0)
    _read_tables(x, ctab, y0, inv_dy, H0L, H0R, K, wk, 1)
    _geometry(K, wk, 1)
    _hertz_steps(wk)
    t = _P * NW
    fl = (_P + _NP) * NW
    two = K[I_NPTS] > 1.5
    for c in range(NW):
        if two and wk[fl + P_A * NW + c] > 0.0:  # the flange touches: both on one rail
            n0, n1, v0, v1 = shared_rail_newton(
                wk[t + P_N * NW + c], wk[t + P_U * NW + c], wk[fl + P_N * NW + c],
                wk[fl + P_U * NW + c], wk[t + P_A * NW + c], wk[t + P_G * NW + c],
                wk[fl + P_A * NW + c], wk[fl + P_G * NW + c], wk[t + P_M * NW + c],
                wk[t + P_SD * NW + c] * wk[fl + P_SD * NW + c] * K[I_INVKRY]
                + wk[t + P_CD * NW + c] * wk[fl + P_CD * NW + c] * K[I_INVKRZ],
                wk[fl + P_M * NW + c], wk[W_U1 * NW + c], wk[W_U2 * NW + c],
            )  # fmt: skip
            wk[t + P_N * NW + c] = n0
            wk[fl + P_N * NW + c] = n1
            wk[W_U1 * NW + c] = v0
            wk[W_U2 * NW + c] = v1
        else:
            wk[fl + P_N * NW + c] = 0.0
            wk[W_U1 * NW + c] = 0.0
            wk[W_U2 * NW + c] = 0.0
    _forces(K, wk)
