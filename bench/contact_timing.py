"""The wheel-rail contact of the eight wheels alone, on the right-hand side's states
(bench/rhs_profile.py --contact): the scalar kernel wheel by wheel against the SIMD kernel.

The rails under each wheel (irregularity and its rate, curvature) are read from the track as
the right-hand side reads them; both kernels then see the same inputs. Figures are the
minimum CPU time over repeats, single-threaded, nanoseconds per evaluation of all eight
wheels; the largest force difference is relative to the largest force.
"""

from __future__ import annotations

import time

import numba as nb
import numpy as np

from railsusp.vehicle import contact_batch as CB
from railsusp.vehicle import layout as L
from railsusp.vehicle.track_lookup import track_point, track_rate, track_value
from railsusp.vehicle.wheel_rail import wheel_rail_forces

_K = L.K
I_ZL, I_ZR = _K["Z0_L"], _K["Z0_R"]
RAIL_ROWS = (CB.W_KAPPA, CB.W_RY, CB.W_RZ, CB.W_RVY, CB.W_RVZ)


def rail_inputs(args, s_front: np.ndarray) -> np.ndarray:
    """(states, 5, 8): curvature, rail lateral and vertical irregularity and their rates
    under each wheel (rows as RAIL_ROWS), at the leading wheelset's position ``s_front``."""
    states, _, K, trk, s0, ds = args[:6]
    lc, a, V = K[_K["l_c"]], K[_K["a"]], K[_K["V"]]
    rails = np.zeros((len(states), 5, 8))
    for j, sf in enumerate(s_front):
        for w in range(4):
            s_w = sf - 2.0 * lc * (w // 2) - 2.0 * a * (w % 2)  # front, then the bogie's rear
            i, f, inside = track_point(s_w, s0, 1.0 / ds, trk.shape[1])
            for side in range(2):
                c = 2 * w + side
                ch_y, ch_z = (L.TR_YL, L.TR_ZL) if side == 0 else (L.TR_YR, L.TR_ZR)
                rails[j, :, c] = (
                    track_value(trk, L.TR_KAPPA, i, f), track_value(trk, ch_y, i, f),
                    track_value(trk, ch_z, i, f), track_rate(trk, ch_y, i, inside, V / ds),
                    track_rate(trk, ch_z, i, inside, V / ds),
                )  # fmt: skip
    return rails


@nb.njit
def _scalar(states, rails, K, ctab, y0, dy, H0L, H0R, res, reps):
    for _ in range(reps):
        for j in range(states.shape[0]):
            x = states[j]
            for c in range(8):
                iw = L.WS0 + 4 * (c >> 1)
                left = (c & 1) == 0
                v = x[L.N_DOF + iw : L.N_DOF + iw + 4]
                _, fy, fz, _, _, _, _, _, _ = wheel_rail_forces(
                    x[iw], x[iw + 1], x[iw + 2], x[iw + 3], v[0], v[1], v[2], v[3],
                    rails[j, 0, c], 1.0 if left else -1.0, rails[j, 1, c], rails[j, 2, c],
                    rails[j, 3, c], rails[j, 4, c], ctab, y0, dy, H0L if left else H0R,
                    K[I_ZL] if left else K[I_ZR], K,
                )  # fmt: skip
                res[j, 0, c] = fy
                res[j, 1, c] = fz


@nb.njit
def _simd(states, rails, K, ctab, y0, dy, H0L, H0R, res, reps, wks):
    """States 2 i and 2 i + 1 (rhs_profile's pairs one step apart) share work vector i, so
    that each shared-rail solve starts warm from a state one step away, as in a run."""
    for _ in range(reps):
        for j in range(states.shape[0]):
            wk = wks[j // 2]
            for r in range(5):
                for c in range(8):
                    wk[RAIL_ROWS[r] * 8 + c] = rails[j, r, c]
            CB.contact_forces_8(states[j], ctab, y0, dy, H0L, H0R, K, wk)
            for c in range(8):
                res[j, 0, c] = wk[CB.W_FY * 8 + c]
                res[j, 1, c] = wk[CB.W_FZ * 8 + c]


def time_contact(states_and_front, reps: int, repeats: int) -> dict:
    """{scalar_ns, simd_ns, max_rel_diff} on the states of rhs_profile._states."""
    args, s_front = states_and_front
    states, _, K, _, _, _, ctab, y0, dy, H0L, H0R = args
    rails = rail_inputs(args, s_front)
    common = (states, rails, K, ctab, y0, dy, H0L, H0R)
    res = {"scalar": np.zeros((len(states), 2, 8)), "simd": np.zeros((len(states), 2, 8))}
    extra = {"scalar": (), "simd": (np.zeros(((len(states) + 1) // 2, CB.N_WORK)),)}
    fns = {"scalar": _scalar, "simd": _simd}
    row = {}
    for name, fn in fns.items():
        fn(*common, res[name], 1, *extra[name])
        best = np.inf
        for _ in range(repeats):
            t0 = time.process_time()
            fn(*common, res[name], reps, *extra[name])
            best = min(best, time.process_time() - t0)
        row[f"{name}_ns"] = best / (reps * len(states)) * 1e9
    scale = np.abs(res["scalar"]).max()
    row["max_rel_diff"] = float(np.abs(res["simd"] - res["scalar"]).max() / scale)
    return row
