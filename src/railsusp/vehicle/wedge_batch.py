"""The four spring nests' eight friction wedges of one evaluation, together, as SIMD loops.

The same force laws as :func:`railsusp.vehicle.suspension.friction_wedges` (one nest, scalar,
with :func:`~railsusp.vehicle.suspension.damped_slider_2d` on each wedge's column face and
:func:`~railsusp.vehicle.suspension.damped_slider` on the slope faces), written branch-free
(both sides of each case computed, one selected) in loops that LLVM vectorises: one loop over
the eight wedges (lane n + 4 r: nest n = 2 bogie + side, r = 0 the front wedge, 1 the rear
one), one over the four nests' slope sliders. The scalar functions were about a tenth of the
right-hand side (their branches on stick and slip, two square roots and six divisions in a
chain per wedge; bench/README.md, stop 22). The arithmetic of every lane is the scalar
functions', operation for operation, so the forces and the friction states' rates are the
same numbers bit for bit (tests/vehicle/test_wedge_batch.py; no fastmath, and
``error_model="numpy"`` only makes the divisions whose results are selected away harmless).

The right-hand side writes the inputs into rows of eight (``R_*``) of a scratch that is the
contact work vector's point blocks (:mod:`railsusp.vehicle.contact_batch`: written there only
once the contact runs, after the suspension), calls :func:`wedge_forces`, and reads the
results back: nothing is allocated.
"""

from __future__ import annotations

import math

import numba as nb

from railsusp.vehicle import contact_batch as CB
from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)
from railsusp.vehicle.suspension import SLIDER_RELAXATION

NL = 8  # wedge lanes: nest n (0-3) front, then the four rear wedges
NN = 4  # nests

# rows of eight in the scratch: per wedge lane, the nest's compression and rates (the same
# in both of its lanes), the wedge's lateral slip, its two friction states; then the results
(R_COMP, R_VV, R_VY, R_SZ, R_SY, R_FZ, R_FY, R_DZ, R_DY, R_N) = range(10)  # fmt: skip
# per nest (lanes 0-3): the slope slider's state and longitudinal slip, its force and rate
R_SX, R_VX, R_FX, R_DX = range(10, 14)
N_ROWS = 14
#: offset of the scratch in the contact work vector (its point blocks)
BASE = CB._P * CB.NW
assert BASE + N_ROWS * NL <= CB.N_WORK


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, inline="always", error_model="numpy")
def _lanes(wk):
    """Eight, as a value LLVM cannot see at compile time (a loop of a known eight iterations
    is unrolled before the loop vectoriser sees it): the contact work vector's lanes."""
    return CB._lanes(wk)


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, error_model="numpy")
def _column_faces(wk, f_ctrl0, k_ctrl, tan_a, mu_c, scale, k_stick, c_stick):
    """Vectorised over the eight wedges: column normal force (rebound limit, loading branch)
    and the column face's friction circle (damped_slider_2d), into R_FZ, R_FY, R_DZ, R_DY
    and the wedge's normal force R_N."""
    k_one = 0.5 * k_stick
    c_one = 0.5 * c_stick
    for c in range(_lanes(wk)):
        f_ctrl = f_ctrl0 + k_ctrl * wk[BASE + R_COMP * NL + c]
        n_reb = 0.5 * (f_ctrl / (tan_a + mu_c) * scale)
        lim_reb = mu_c * n_reb
        sx = wk[BASE + R_SZ * NL + c]
        sy = wk[BASE + R_SY * NL + c]
        vx = wk[BASE + R_VV * NL + c]
        vy = wk[BASE + R_VY * NL + c]
        # suspension.wedge_column_normal_force
        loading = sx / lim_reb if n_reb > 0.0 and mu_c > 0.0 else 0.0
        lo = 1.0 if loading > 1.0 else (-1.0 if loading < -1.0 else loading)
        n_col = 0.0 if f_ctrl <= 0.0 else f_ctrl / (tan_a - mu_c * lo)
        n_w = 0.5 * (scale * n_col)
        limit = mu_c * n_w
        # suspension.damped_slider_2d
        mag = math.sqrt(sx * sx + sy * sy)
        over = mag > limit
        s_over = limit / mag if mag > 0.0 else 0.0
        fx = sx * s_over if over else sx
        fy = sy * s_over if over else sy
        mag = limit if over else mag
        outward = fx * vx + fy * vy
        sliding = mag >= limit and limit > 0.0 and outward > 0.0
        nx = fx / mag
        ny = fy / mag
        vn = vx * nx + vy * ny
        dz_slide = k_one * (vx - vn * nx) + (fx - sx) / SLIDER_RELAXATION
        dy_slide = k_one * (vy - vn * ny) + (fy - sy) / SLIDER_RELAXATION
        dz_stick = k_one * vx + (fx - sx) / SLIDER_RELAXATION
        dy_stick = k_one * vy + (fy - sy) / SLIDER_RELAXATION
        gx = fx + c_one * vx
        gy = fy + c_one * vy
        m2 = math.sqrt(gx * gx + gy * gy)
        s2 = limit / m2 if m2 > 0.0 else 0.0
        over2 = m2 > limit
        gx = gx * s2 if over2 else gx
        gy = gy * s2 if over2 else gy
        wk[BASE + R_FZ * NL + c] = fx if sliding else gx
        wk[BASE + R_FY * NL + c] = fy if sliding else gy
        wk[BASE + R_DZ * NL + c] = dz_slide if sliding else dz_stick
        wk[BASE + R_DY * NL + c] = dy_slide if sliding else dy_stick
        wk[BASE + R_N * NL + c] = n_w


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME, error_model="numpy")
def _slope_faces(wk, cos_a, mu_s, k_stick, c_stick):
    """Per nest (lanes 0-3): the slope faces' slider (damped_slider) with the normal force of
    both wedges, into R_FX and R_DX."""
    for c in range(_lanes(wk) // 2):
        limit = mu_s * (wk[BASE + R_N * NL + c] + wk[BASE + R_N * NL + NN + c]) / cos_a
        state = wk[BASE + R_SX * NL + c]
        v = wk[BASE + R_VX * NL + c]
        f = limit if state > limit else (-limit if state < -limit else state)
        sliding = (f >= limit and v > 0.0) or (f <= -limit and v < 0.0)
        d_slide = (f - state) / SLIDER_RELAXATION
        d_stick = k_stick * v + (f - state) / SLIDER_RELAXATION
        g = f + c_stick * v
        g = limit if g > limit else (-limit if g < -limit else g)
        wk[BASE + R_FX * NL + c] = f if sliding else g
        wk[BASE + R_DX * NL + c] = d_slide if sliding else d_stick


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME)
def wedge_forces(wk, f_ctrl0, k_ctrl, tan_a, cos_a, mu_c, mu_s, scale, k_stick, c_stick):
    """The eight wedges' friction forces and friction-state rates from the inputs in the
    scratch (module docstring); arguments as :func:`~railsusp.vehicle.suspension.
    friction_wedges`'s (k_stick, c_stick: a nest's)."""
    _column_faces(wk, f_ctrl0, k_ctrl, tan_a, mu_c, scale, k_stick, c_stick)
    _slope_faces(wk, cos_a, mu_s, k_stick, c_stick)
