"""Compiled batch integrator: fixed-step RK4 over many parameter sets in parallel (Numba).

Each set is integrated independently (``prange`` over sets), so a diverging set is stopped and
flagged without touching the others. Outputs pass through a causal anti-alias filter
(Butterworth second-order sections) at the internal rate and are sampled at the output rate.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH, NO_RUNTIME  # (sets the cache first)
from railsusp.vehicle.model import rhs

NQ = L.N_DOF
NS = L.N_STATE
NOUT = L.N_OUT
I_V = L.K["V"]
I_SPLIT_SPEED = L.K["flange_split_speed"]


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME)
def _rk4_finish(x, ks, xt, h, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s, V, o_dummy):
    """Stages 2-4 of one RK4 step of length h from x at track position s (stage 1 already
    in ks[0]) and the update of x. Returns a failure code (0 ok)."""
    for j in range(1, 4):  # stages 2-4: x + c h k_(j-1), at s + c V h
        c = 1.0 if j == 3 else 0.5
        for i in range(NS):
            xt[i] = x[i] + c * h * ks[j - 1, i]
        code = rhs(xt, ks[j], P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s + c * V * h, o_dummy)
        if code != 0:
            return code
    acc = 0.0
    for i in range(NS):
        x[i] += h / 6.0 * (ks[0, i] + 2.0 * ks[1, i] + 2.0 * ks[2, i] + ks[3, i])
        acc += x[i]
    if not math.isfinite(acc):
        return L.FAIL_NAN
    return 0


@nb.njit(cache=True, fastmath=FASTMATH)
def _run_one(
    x, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, dt, s_init, n_pre, n_sub, n_out, sos,
    out_series, n_fine,
):  # fmt: skip
    """Integrate one set from state x with the leading wheelset at track position
    ``s_init``; write filtered outputs (NOUT, n_out) from step ``n_pre`` on. Steps that start
    with a wheel near flange contact and closing on it are split into ``n_fine``. Returns
    (code, fail_time from the start). Allocates the work arrays; the steps run in
    :func:`_steps`, without Numba's runtime (kernel_cache.NO_RUNTIME: its row views of the stage
    derivatives and its calls of the right-hand side are not reference counted)."""
    ks = np.empty((4, NS))  # RK4 stage derivatives
    xt = np.empty(NS)
    o = np.zeros(L.N_OUT_WORK)
    o_dummy = np.zeros(L.N_OUT_WORK)
    zf = np.zeros((NOUT, sos.shape[0], 2))
    return _steps(
        x, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, dt, s_init, n_pre, n_sub, n_out, sos,
        out_series, n_fine, ks, xt, o, o_dummy, zf,
    )  # fmt: skip


@nb.njit(cache=True, fastmath=FASTMATH, **NO_RUNTIME)
def _steps(
    x, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, dt, s_init, n_pre, n_sub, n_out, sos,
    out_series, n_fine, ks, xt, o, o_dummy, zf,
):  # fmt: skip
    """The steps of :func:`_run_one` in the work arrays it allocated."""
    k1 = ks[0]
    n_sec = sos.shape[0]
    V = K[I_V]
    n_total = n_pre + n_out * n_sub
    # settle the filters on the static outputs
    code = rhs(x, k1, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_init, o)
    if code != 0:
        return code, 0.0
    for c in range(NOUT):
        u = o[c]
        for s in range(n_sec):
            b0, b1, b2, a1, a2 = sos[s, 0], sos[s, 1], sos[s, 2], sos[s, 4], sos[s, 5]
            # steady state of the transposed direct form II for constant input u
            gain = (b0 + b1 + b2) / (1.0 + a1 + a2)
            y = gain * u
            zf[c, s, 1] = b2 * u - a2 * y
            zf[c, s, 0] = b1 * u - a1 * y + zf[c, s, 1]
            u = y
    for n in range(n_total):
        t = n * dt
        s_front = s_init + V * t
        code = rhs(x, k1, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, o)
        if code != 0:
            return code, t
        # anti-alias filter at the internal rate
        for c in range(NOUT):
            u = o[c]
            for s in range(n_sec):
                b0, b1, b2, a1, a2 = sos[s, 0], sos[s, 1], sos[s, 2], sos[s, 4], sos[s, 5]
                y = b0 * u + zf[c, s, 0]
                zf[c, s, 0] = b1 * u - a1 * y + zf[c, s, 1]
                zf[c, s, 1] = b2 * u - a2 * y
                u = y
            if n >= n_pre and (n - n_pre) % n_sub == 0:
                out_series[c, (n - n_pre) // n_sub] = u
        # a wheel near its flange and closing on it splits the step (the jump to the flank is
        # the stiff event); one running steadily against it does not, and with no wheel near
        # its flange the rate is -1e9, below any split speed
        m = n_fine if o[L.OUT_FLANGE_RATE] > K[I_SPLIT_SPEED] else 1
        h = dt / m
        for sub in range(m):
            s_sub = s_front + sub * V * h
            if sub > 0:
                code = rhs(x, k1, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_sub, o_dummy)
                if code != 0:
                    return code, t + sub * h
            code = _rk4_finish(
                x, ks, xt, h, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_sub, V, o_dummy
            )
            if code != 0:
                return code, t + sub * h
    return L.OK, n_total * dt


@nb.njit(cache=True, fastmath=FASTMATH, parallel=True)
def integrate_batch(
    P, K, X0, tracks, track_index, s0, ds, ctab, y0, dy, H0L, H0R, dt, s_init, n_pre, n_sub,
    n_out, sos, n_fine, out, status, fail_time,
):  # fmt: skip
    """Integrate every set i (rows of P and K) on track ``tracks[track_index[i]]`` from its
    initial state ``X0[i]`` (zeros: static equilibrium on straight track) with the leading
    wheelset at ``s_init``."""
    n = P.shape[0]
    for i in nb.prange(n):
        x = X0[i].copy()
        code, tf = _run_one(
            x, P[i], K[i], tracks[track_index[i]], s0, ds, ctab, y0, dy, H0L, H0R, dt, s_init,
            n_pre, n_sub, n_out, sos, out[i], n_fine,
        )  # fmt: skip
        status[i] = code
        fail_time[i] = tf
        if code != 0:
            out[i, :, :] = np.nan
