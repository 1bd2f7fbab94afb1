"""Suspension force elements of the three-piece bogie, as compiled pure functions.

The equations of motion (:mod:`railsusp.vehicle.model`) call these per element; tests drive
them directly (hysteresis loops, lift-off, analytic limits). Forces in N, moments in N m,
displacements in m, rates per second. Friction elements keep their friction force as a
first-order state (elasto-plastic, "stiffness in series with a Coulomb slider": the usual
form for explicit integration, physics notes): while sticking the force follows the relative
displacement through a stick stiffness, with a stick damping that stands for the
pre-sliding micro-slip losses of real contacts; at the limit the element slides and the
force stays on the limit. The state derivative is written into ``dxdt[idx]``.
"""

from __future__ import annotations

import math

import numba as nb

from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)
from railsusp.vehicle.layout import W_FRONT_Z, W_LONG, W_REAR_Z

#: relaxation time of a friction state pushed beyond its (shrinking) limit, s
SLIDER_RELAXATION = 2.0e-3

#: contact points of the centre-bowl ring (equally spaced on the bowl radius) and their
#: direction cosines (constants of the compiled code)
BOWL_POINTS = 8
BOWL_COS = tuple(math.cos(2.0 * math.pi * j / BOWL_POINTS) for j in range(BOWL_POINTS))
BOWL_SIN = tuple(math.sin(2.0 * math.pi * j / BOWL_POINTS) for j in range(BOWL_POINTS))
#: Newton steps of the bowl's quasi-static bolster bending and pitch at most (the active set
#: of a ring of 8 changes a few times at most), and the balance asked of them, relative to
#: the static load: forces to 1e-10 of it
BOWL_ITERATIONS = 12
BOWL_TOLERANCE = 1.0e-10


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def series_stiffness(k1, k2):
    """Stiffness of two springs in series, N/m."""
    return k1 * k2 / (k1 + k2)


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def gap_spring(d, clearance, k):
    """Force of a symmetric stop with free play: zero inside +-clearance, k beyond (N)."""
    if d > clearance:
        return k * (d - clearance)
    if d < -clearance:
        return k * (d + clearance)
    return 0.0


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def disc_friction_moment(mu, normal, radius):
    """Limit of the friction moment (N m) of a flat disc of ``radius`` pressed with
    ``normal`` (N), uniform pressure: mu N (2/3) R. The centre bowl's liner in yaw and roll."""
    return mu * normal * (2.0 / 3.0) * radius


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def damped_slider(state, limit, k_stick, c_stick, v, dxdt, idx):
    """Friction force (on the element's first body, opposing v) of an elasto-plastic slider
    with stick damping: a Kelvin element (k_stick, c_stick) in series with a Coulomb slider.

    ``v``: relative velocity (second body minus first, so that a positive v gives a
    positive force on the first body). Sticking: force = state + c_stick v, state rate
    k_stick v, the sum clamped to +-limit; sliding (state on the limit and moving outwards):
    force = +-limit. Dissipates the stick damper's c v^2 while sticking and limit |v| while
    sliding; a static, loaded element holds its force (Coulomb stiction).
    """
    f = state
    if f > limit:
        f = limit
    elif f < -limit:
        f = -limit
    if (f >= limit and v > 0.0) or (f <= -limit and v < 0.0):
        dxdt[idx] = (f - state) / SLIDER_RELAXATION
        return f
    dxdt[idx] = k_stick * v + (f - state) / SLIDER_RELAXATION
    f += c_stick * v
    if f > limit:
        return limit
    if f < -limit:
        return -limit
    return f


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def damped_slider_2d(sx, sy, limit, k_stick, c_stick, vx, vy, dxdt, ix, iy):
    """Two-component version of :func:`damped_slider` for friction on a plane (isotropic
    Coulomb friction circle of radius ``limit``): the state (sx, sy) is the elastic friction
    force; sliding when its magnitude is at the limit and the relative velocity has an
    outward component, in which case only the tangential part of the velocity loads the
    state (it turns towards the slip direction). Returns the force (fx, fy).
    """
    mag = math.sqrt(sx * sx + sy * sy)
    fx = sx
    fy = sy
    if mag > limit:
        scale = limit / mag if mag > 0.0 else 0.0
        fx = sx * scale
        fy = sy * scale
        mag = limit
    outward = fx * vx + fy * vy
    if mag >= limit and limit > 0.0 and outward > 0.0:
        nx = fx / mag
        ny = fy / mag
        vn = vx * nx + vy * ny
        dxdt[ix] = k_stick * (vx - vn * nx) + (fx - sx) / SLIDER_RELAXATION
        dxdt[iy] = k_stick * (vy - vn * ny) + (fy - sy) / SLIDER_RELAXATION
        return fx, fy
    dxdt[ix] = k_stick * vx + (fx - sx) / SLIDER_RELAXATION
    dxdt[iy] = k_stick * vy + (fy - sy) / SLIDER_RELAXATION
    fx += c_stick * vx
    fy += c_stick * vy
    m2 = math.sqrt(fx * fx + fy * fy)
    if m2 > limit:
        scale = limit / m2 if m2 > 0.0 else 0.0
        return fx * scale, fy * scale
    return fx, fy


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def wedge_column_normal_force(spring_force, tan_alpha, mu_column, loading):
    """Normal force (N) of a massless friction wedge on its side-frame column face.

    Equilibrium of the wedge between the bolster's slope face (angle alpha from the vertical)
    and the vertical column face, pushed up by its control spring with ``spring_force`` F_s:
    N = F_s / (tan alpha - mu) while the bolster moves down (compression: column friction
    on the wedge points up, against the spring's push on the slope) and
    N = F_s / (tan alpha + mu) on rebound (physics notes; e.g. the variable-damping wedge of
    Kaiser & Cole). ``loading`` blends the two: +1 (or more) compression, -1 (or less)
    rebound, linear in between. Callers pass the column friction force over its rebound
    limit, so that a sliding wedge sits exactly on its branch and a sticking one moves
    between them without a jump.
    """
    if spring_force <= 0.0:
        return 0.0
    lo = loading
    if lo > 1.0:
        lo = 1.0
    elif lo < -1.0:
        lo = -1.0
    return spring_force / (tan_alpha - mu_column * lo)


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def friction_wedges(
    comp, v_vert, v_lat, v_warp, v_long, f_ctrl0, k_ctrl, tan_a, cos_a, mu_column, mu_slope,
    scale, k_stick, c_stick, x, dxdt, ia,
):  # fmt: skip
    """Friction forces (N) of the two wedges of one spring nest on the bolster, the front one
    ahead of the bolster end and the rear one behind it: vertical (+ up), lateral, the front
    wedge's lateral force less the rear one's, and longitudinal, each opposing the side
    frame's motion relative to the bolster (v_* = side frame minus bolster; comp = nest
    compression from static, m).

    The control springs (f_ctrl0 + k_ctrl comp, all wedges of the nest) set the column
    normal force (:func:`wedge_column_normal_force`), times ``scale`` (wedge rise and wear:
    X18 / X18 nominal); each wedge carries half of it, with half the nest's stick stiffness
    and stick damping (``k_stick``, ``c_stick``: the nest's). Each wedge's column face
    carries Coulomb friction mu_column N / 2 against its vertical and lateral slip together
    (:func:`damped_slider_2d`; states x[ia + W_FRONT_Z], x[ia + W_FRONT_Y] and
    x[ia + W_REAR_Z], x[ia + W_REAR_Y], layout.py), its compression/rebound branch set by its
    own vertical friction force. Both wedges slip vertically with the nest (``v_vert``);
    laterally the front wedge slips ``v_lat + v_warp`` and the rear one ``v_lat - v_warp``,
    where v_warp = l_w (yaw rate of the side frame - yaw rate of the bolster) at the wedges'
    longitudinal offsets +-l_w: a bolster yawing in its window (warp, lozenging) slides the
    two wedges on their columns in opposite directions, and l_w times the third returned
    force is their friction moment on the bolster's yaw (on the side frame's, minus that).
    The slope faces, with normal force N / cos a (both wedges), carry mu_slope N / cos a
    against the bolster end's longitudinal slip (one slider, state x[ia + W_LONG]).

    With v_warp = 0 the two wedges are the same and the sums are the forces of one wedge pair
    acting at the nest centre bit for bit (halving is exact in binary floating point).

    The right-hand side runs the eight wedges of the four nests together as SIMD loops
    (:func:`railsusp.vehicle.wedge_batch.wedge_forces`, the same arithmetic operation for
    operation); this scalar form is the readable reference that is tested bit for bit
    against them (tests/vehicle/test_wedge_batch.py) and that the hysteresis tests call.
    """
    f_ctrl = f_ctrl0 + k_ctrl * comp
    n_reb = 0.5 * (f_ctrl / (tan_a + mu_column) * scale)  # one wedge's normal force, rebound
    lim_reb = mu_column * n_reb
    k_one = 0.5 * k_stick
    c_one = 0.5 * c_stick
    i_f = ia + W_FRONT_Z
    i_r = ia + W_REAR_Z
    # the two wedges written out: a helper for one wedge, called twice from this inlined
    # function, was not inlined by Numba and made the whole rhs 5-7 % slower (measured
    # when the rhs still called this function)
    loading = x[i_f] / lim_reb if n_reb > 0.0 and mu_column > 0.0 else 0.0
    n_f = 0.5 * (scale * wedge_column_normal_force(f_ctrl, tan_a, mu_column, loading))
    fz_f, fy_f = damped_slider_2d(
        x[i_f], x[i_f + 1], mu_column * n_f, k_one, c_one, v_vert, v_lat + v_warp, dxdt, i_f,
        i_f + 1,
    )  # fmt: skip
    loading = x[i_r] / lim_reb if n_reb > 0.0 and mu_column > 0.0 else 0.0
    n_r = 0.5 * (scale * wedge_column_normal_force(f_ctrl, tan_a, mu_column, loading))
    fz_r, fy_r = damped_slider_2d(
        x[i_r], x[i_r + 1], mu_column * n_r, k_one, c_one, v_vert, v_lat - v_warp, dxdt, i_r,
        i_r + 1,
    )  # fmt: skip
    i_x = ia + W_LONG
    fx = damped_slider(x[i_x], mu_slope * (n_f + n_r) / cos_a, k_stick, c_stick, v_long, dxdt, i_x)
    return fz_f + fz_r, fy_f + fy_r, fy_f - fy_r, fx


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always")
def bowl_ring_forces(
    dz, droll, dpitch, droll_rate, radius, k_ring, k_bend, k_pitch, preload_total, mu,
    k_stick, c_stick, state_roll, dxdt, idx,
):  # fmt: skip
    """Centre bowl (flat annulus) as a ring of BOWL_POINTS compression-only springs on the
    bolster, which bends under it and pitches in the side-frame windows, with friction
    against relative roll.

    dz: compression at the bowl centre (bolster up minus car body down, m); droll, dpitch:
    relative roll and pitch of the car body seen from the bolster (rad, right-handed about
    x forward and y left: roll + lifts the left side, pitch + lowers the front; the text
    said "lifts" before stop 74, the formula always lowered it). The point at (x, y) =
    radius (cos t, sin t) is compressed by (dz - u) + x (dpitch - th) - y droll and carries
    preload/n + (k_ring/n) x compression, never a pull (edge lift-off). The ring
    (``k_ring``, N/m in all: the liner and the bowl's rim) sits on the bolster's bending
    under the bowl (``k_bend``, N/m: u)
    and on the bolster's pitch restraint in the side-frame windows (``k_pitch``, N m/rad:
    th; the bolster has no pitch freedom of its own). Both are massless and quasi-static: u
    and th make the ring's vertical force and pitch moment equal to the bending force
    k_bend u (over the static load) and the restraint k_pitch th, i.e. they minimise the
    ring's and the bolster's elastic energy, so the bowl stays conservative with lift-off
    (the forces are the gradient of that minimum). Before lift-off: vertical stiffness
    k_ring k_bend / (k_ring + k_bend), roll k_ring R^2 / 2 (rocking bends no bolster span),
    pitch k_ring R^2 / 2 in series with k_pitch; the bowl carries roll and pitch moments
    elastically up to lift-off at N R / 2 and about N R when it rocks on its rim. Solved by
    Newton on the active points from the all-in-contact solution, which is exact (one pass)
    while no point lifts. ``droll_rate`` is the time rate of droll. Friction moment against
    relative roll: elasto-plastic (:func:`damped_slider`), limit mu N (2/3) R, the friction
    moment of a flat disc: rocking before lift-off shears the bowl liner like yaw does.

    Returns (normal force, roll moment on the car body, pitch moment on the car body about
    the bowl centre, friction roll moment on the car body), N and N m; the roll moment is
    sum(y f), the pitch moment sum(-x f).
    """
    n = BOWL_POINTS
    kp = k_ring / n
    fp = preload_total / n
    k_ring_pitch = 0.5 * k_ring * radius * radius
    u = k_ring * dz / (k_ring + k_bend)  # all points in contact
    th = k_ring_pitch * dpitch / (k_ring_pitch + k_pitch)
    tol = BOWL_TOLERANCE * preload_total
    n_tot = 0.0
    m_roll = 0.0
    m_pitch = 0.0
    for _ in range(BOWL_ITERATIONS):
        n_tot = 0.0
        m_roll = 0.0
        m_pitch = 0.0
        s0 = 0.0  # active points: count, sum of x, sum of x^2
        s1 = 0.0
        s2 = 0.0
        for j in range(n):
            x = radius * BOWL_COS[j]
            y = radius * BOWL_SIN[j]
            f = fp + kp * ((dz - u) - y * droll + x * (dpitch - th))
            if f > 0.0:
                n_tot += f
                m_roll += y * f
                m_pitch += -x * f
                s0 += 1.0
                s1 += x
                s2 += x * x
        g1 = n_tot - preload_total - k_bend * u  # bending out of balance, N
        g2 = -m_pitch - k_pitch * th  # pitch restraint out of balance, N m
        if abs(g1) <= tol and abs(g2) <= tol * radius:
            break
        # Newton step on the active set: J (du, dth) = -g
        j11 = -kp * s0 - k_bend
        j12 = -kp * s1
        j22 = -kp * s2 - k_pitch
        det = j11 * j22 - j12 * j12
        u -= (j22 * g1 - j12 * g2) / det
        th -= (j11 * g2 - j12 * g1) / det
    lim = disc_friction_moment(mu, n_tot, radius)
    m_fr = damped_slider(state_roll, lim, k_stick, c_stick, -droll_rate, dxdt, idx)
    return n_tot, m_roll, m_pitch, m_fr
