"""Settled start: each run begins from the wagon's steady state on the record's design track.

A run that starts at rest at the section start spends the condition's lead-in (100 m, 6 s
at 60 km/h) letting the start transient and the entry spiral die out before the record.
A settled start instead puts the wagon, at rest relative to the track-following frame, in
its steady state on the design track (no irregularities) that it stands on at the record
start, ``run_in_m`` ahead of the record, and fades the irregularities in over that run-in.
The recorded stretch of track is the same: the same design geometry and the same
irregularity samples under every wheel at every record time.

The steady state solves the equations of motion for zero accelerations with zero
velocities: Newton's method on the 49 displacements (finite-difference Jacobian of the
compiled equations, steps limited and backtracked on the largest generalised force), by
continuation from straight track in :data:`HOMOTOPY_STAGES` steps of curvature and cant,
as a slow spiral brings the wagon into the curve. The friction states (wedges,
body-bolster yaw, centre-bowl roll) start at zero, as at the static start, and follow each
step as sticking or sliding sliders, so the bolsters leave the "spiral" with their yaw
friction at its limit, as the lead-in run does; with zero velocities they then stay put.
A set whose solve does not converge runs the lead-in instead. Solved states are kept in
memory, keyed by a hash of everything they depend on (parameter set, constants, contact
table, design curvature and cant), so a set run again on other seeds or track files is
not solved again.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from dataclasses import dataclass

import numba as nb
import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.vehicle import layout as L
from railsusp.vehicle.kernel_cache import FASTMATH  # (sets the kernel cache before any compiles)
from railsusp.vehicle.model import rhs, side_frame_roll
from railsusp.vehicle.operating_point import dof_inertia
from railsusp.vehicle.setup import ContactArrays, SolverSettings, axle_spread
from railsusp.vehicle.suspension import SLIDER_RELAXATION
from railsusp.vehicle.track import TrackLayout
from railsusp.vehicle.wagon import WagonData

NQ = L.N_DOF
NS = L.N_STATE

#: length over which a settled start fades the irregularities in, from its start position, m
FADE_IN_M = 10.0
#: largest generalised force (N, or N m for rotations) left unbalanced in a settled state
SETTLE_TOLERANCE = 1.0e-3
#: Newton iterations before a set is handed to the lead-in
SETTLE_MAX_ITER = 40
#: displacement step of the finite-difference Jacobian, m or rad
FD_STEP = 1.0e-8
#: largest Newton step of any displacement, m or rad
MAX_STEP = 2.0e-3
#: continuation stages from straight to the design curvature and cant
HOMOTOPY_STAGES = 2
#: force left unbalanced at the intermediate stages, N or N m
STAGE_TOLERANCE = 1.0
#: evaluations that hold the friction states to their limits (a wedge's limit depends on
#: its own state)
CLAMP_PASSES = 1

I_KW, I_KYAW, I_KROLL = L.K["k_wedge"], L.K["k_yaw"], L.K["k_roll"]
I_LC, I_B2, I_LW, I_SFN = L.K["l_c"], L.K["b2"], L.K["l_wedge"], L.K["sf_arm_nest"]
#: solved states kept in memory
CACHE_SIZE = 4096


@dataclass(frozen=True)
class StartPlan:
    """Where and how a condition's runs start.

    ``s_start``: leading wheelset's track position at the start, m; ``n_pre``: internal
    steps before the record; ``settled``: start from the settled state (else at rest at
    s = 0, the lead-in); ``uniform_before`` and ``fade_in``: the track changes of a settled
    start (:func:`railsusp.vehicle.track_grid.track_arrays`).
    """

    s_start: float
    n_pre: int
    settled: bool
    uniform_before: float | None = None
    fade_in: tuple[float, float] | None = None

    @property
    def track_options(self) -> dict:
        """Keyword arguments of :func:`railsusp.vehicle.track_grid.track_arrays`."""
        return {"uniform_before": self.uniform_before, "fade_in": self.fade_in}


def lead_in_plan(condition: WorkingCondition, dt: float) -> StartPlan:
    """The plain start: at rest at s = 0, the whole lead-in run before the record."""
    return StartPlan(0.0, round(condition.lead_in_m / condition.speed / dt), False)


def design_is_uniform(condition: WorkingCondition, s_from: float, s_to: float) -> bool:
    """Whether curvature and cant of the design track are constant over [s_from, s_to]."""
    lay = TrackLayout.from_condition(condition)
    s = np.linspace(s_from, s_to, max(2, math.ceil((s_to - s_from) / 0.05) + 1))
    kappa, cant = lay.curvature_at(s), lay.cant_at(s)
    return bool(np.ptp(kappa) <= 1e-12 and np.ptp(cant) <= 1e-12)


def start_plan(
    condition: WorkingCondition, wagon: WagonData, settings: SolverSettings, dt: float
) -> StartPlan:
    """The start of a condition's runs with internal step ``dt``.

    Settled (``settings.start``) where it applies: the lead-in is at least ``run_in_m`` long
    and the design geometry is uniform under the whole wagon at the record start (a record
    that starts in a spiral runs the lead-in). The settled run starts ``run_in_m`` (to a
    whole number of steps) ahead of the record, so that its record falls on the same track
    positions as the lead-in run's; the design track behind the trailing wheelset's
    position at the record start continues its curvature and cant, and the irregularities
    fade in from the start position to that point.
    """
    lead = lead_in_plan(condition, dt)
    if settings.start == "lead-in":
        return lead
    spread = axle_spread(wagon)
    if settings.run_in_m < spread + FADE_IN_M:
        raise RailsuspInputError(
            f"run_in_m = {settings.run_in_m:g} m: wagon {wagon.name!r} spans {spread:.4g} m "
            f"from the leading to the trailing wheelset, and the irregularities fade in over "
            f"{FADE_IN_M:g} m; accepted at least {spread + FADE_IN_M:.4g} m"
        )
    V = condition.speed
    n_pre = round(settings.run_in_m / V / dt)
    if n_pre >= lead.n_pre:
        return lead
    s_record = V * lead.n_pre * dt  # where the lead-in run's record starts
    rear = s_record - spread  # the trailing wheelset at the record start
    if not design_is_uniform(condition, rear, s_record):
        return lead
    s_start = s_record - V * n_pre * dt
    fade = (s_start, s_start + FADE_IN_M)
    return StartPlan(s_start, n_pre, True, uniform_before=rear, fade_in=fade)


# ---------------------------------------------------------------- steady state
@nb.njit(cache=True, fastmath=FASTMATH)
def _slip(x, kappa, K, out):
    """Relative displacements whose rates are the friction sliders' velocities in the
    equations of motion, per friction state (order of the states from AUX_WEDGE): per nest
    its front and its rear wedge's vertical and lateral slip on the column (the lateral one
    with the warp, +- l_w times the side frame's yaw less the bolster's) and the slope's
    longitudinal slip (the lateral ones at the nest's height on a side frame that rolls with
    its wheelsets), per bogie the body-bolster yaw (with the chord angle -κ d at the
    bolster's track position d) and the bowl roll; of the displacements of x on uniform
    track of curvature ``kappa``."""
    b2 = K[I_B2]
    l_w = K[I_LW]
    for k in range(2):
        d = K[I_LC] if k == 0 else -K[I_LC]
        ib = L.BOL0 + 4 * k
        for sidx in range(2):
            side = 1.0 if sidx == 0 else -1.0
            n = 2 * k + sidx
            jf = L.SF0 + 5 * n
            i0 = L.WEDGE_STATES * n
            dz = x[jf + 2] - (x[ib + 1] + side * b2 * x[ib + 2])
            dy = x[jf + 1] - K[I_SFN] * side_frame_roll(x, k) - x[ib]
            warp = l_w * (x[jf + 4] - x[ib + 3])
            out[i0 + L.W_FRONT_Z] = dz
            out[i0 + L.W_FRONT_Y] = dy + warp
            out[i0 + L.W_REAR_Z] = dz
            out[i0 + L.W_REAR_Y] = dy - warp
            out[i0 + L.W_LONG] = x[jf] + side * b2 * x[ib + 3]
        out[L.N_WEDGE_AUX + k] = x[L.CB_YAW] - x[ib + 3] - kappa * d
        out[L.N_WEDGE_AUX + 2 + k] = x[ib + 2] - x[L.CB_ROLL]


@nb.njit(cache=True, fastmath=FASTMATH)
def _stick_stiffness(i, K):
    """Stick stiffness of friction state ``i`` (from AUX_WEDGE): each wedge's column slider
    has half the nest's, the slope slider the nest's, then the yaw and roll sliders'."""
    if i < L.N_WEDGE_AUX:
        return K[I_KW] if i % L.WEDGE_STATES == L.W_LONG else 0.5 * K[I_KW]
    return K[I_KYAW] if i < L.N_WEDGE_AUX + 2 else K[I_KROLL]


@nb.njit(cache=True, fastmath=FASTMATH)
def _residual(x, f, r, m, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, kappa, fref, uref):
    """Generalised forces m * acceleration of the displacements of x into r, the friction
    states following them as sticking sliders do: reference force plus stick stiffness
    times the slip from the reference displacements, held to the friction limits as the
    equations hold them (a state beyond its limit relaxes at the rate that the limit minus
    the state over SLIDER_RELAXATION gives). Returns (code, max |r|)."""
    o = np.zeros(L.N_OUT_WORK)  # (zero: no warm start of the shared-rail solve from garbage)
    u = np.empty(L.N_AUX)
    _slip(x, kappa, K, u)
    for i in range(L.N_AUX):
        x[L.AUX_WEDGE + i] = fref[i] + _stick_stiffness(i, K) * (u[i] - uref[i])
    for _ in range(CLAMP_PASSES):  # a wedge's limit depends on its own state: clamp again
        code = rhs(x, f, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, o)
        if code != 0:
            return code, math.inf
        for i in range(L.N_AUX):
            x[L.AUX_WEDGE + i] += f[L.AUX_WEDGE + i] * SLIDER_RELAXATION
    code = rhs(x, f, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, o)
    if code != 0:
        return code, math.inf
    worst = 0.0
    for i in range(NQ):
        r[i] = f[NQ + i] * m[i]
        worst = max(worst, abs(r[i]))
    if not math.isfinite(worst):
        return L.FAIL_NAN, math.inf
    return 0, worst


@nb.njit(cache=True, fastmath=FASTMATH)
def _newton(
    x, m, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, kappa, fref, uref, tol, max_iter
):
    """Newton's method on the displacements of x (velocities zero, friction states
    following, :func:`_residual`) for zero accelerations; steps limited to
    :data:`MAX_STEP` and backtracked until the largest generalised force falls. The
    finite-difference Jacobian is kept while each step at least halves that force. Returns
    (converged, largest force left)."""
    f = np.empty(NS)
    r = np.empty(NQ)
    rt = np.empty(NQ)
    J = np.empty((NQ, NQ))
    xt = x.copy()
    code, norm = _residual(
        x, f, r, m, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, kappa, fref, uref
    )
    if code != 0:
        return False, norm
    renew = True  # compute J at x before the next step
    fresh = False  # J is the Jacobian at x
    for _ in range(max_iter):
        if norm < tol:
            return True, norm
        if renew:
            for j in range(NQ):
                xt[:] = x
                xt[j] += FD_STEP
                code, _n = _residual(
                    xt, f, rt, m, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, kappa,
                    fref, uref,
                )  # fmt: skip
                if code != 0:
                    return False, norm
                for i in range(NQ):
                    J[i, j] = (rt[i] - r[i]) / FD_STEP
            renew = False
            fresh = True
        dq = np.linalg.solve(J, -r)
        cap = min(1.0, MAX_STEP / max(np.max(np.abs(dq)), 1e-300))
        lam = cap
        before = norm
        while lam > 1e-4:
            xt[:] = x
            for i in range(NQ):
                xt[i] += lam * dq[i]
            code, trial = _residual(
                xt, f, rt, m, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, kappa, fref,
                uref,
            )  # fmt: skip
            if code == 0 and trial < norm:
                x[:] = xt
                r[:] = rt
                norm = trial
                break
            lam *= 0.5
        if norm >= before and fresh:
            break  # no progress even with the Jacobian at x
        # the Jacobian is kept after a whole, uncut step that cut the force tenfold
        renew = not (cap == 1.0 and lam == 1.0 and norm <= 0.1 * before)
        fresh = False
    return norm < tol, norm


@nb.njit(cache=True, fastmath=FASTMATH)
def _settle_one(x, m, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, kappa, tol, max_iter):
    """Steady state by continuation in the design track's curvature and cant, as a slow
    entry spiral brings it about: from the static start on straight track (displacements and
    friction forces zero), curvature and cant are raised in :data:`HOMOTOPY_STAGES` equal
    steps, each solved from the last (a curve's steady state can be far from the straight
    one's: a single Newton step jumps the wheels up their flanges), with the friction
    states following each stage's slips as sticking or sliding sliders."""
    stage = trk.copy()
    fref = np.zeros(L.N_AUX)
    uref = np.zeros(L.N_AUX)
    for k in range(HOMOTOPY_STAGES + 1):
        frac = k / HOMOTOPY_STAGES
        for ch in (L.TR_KAPPA, L.TR_CANT, L.TR_HEAD, L.TR_OFFSET):
            for i in range(trk.shape[1]):
                stage[ch, i] = frac * trk[ch, i]
        last = k == HOMOTOPY_STAGES
        ok, norm = _newton(
            x, m, P, K, stage, s0, ds, ctab, y0, dy, H0L, H0R, s_front, frac * kappa, fref,
            uref, tol if last else STAGE_TOLERANCE, max_iter,
        )  # fmt: skip
        if not ok:
            return False, norm
        _slip(x, frac * kappa, K, uref)
        fref[:] = x[L.AUX_WEDGE :]
    return True, norm


@nb.njit(cache=True, fastmath=FASTMATH, parallel=True)
def _settle_batch(
    X, M, P, K, trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, kappa, tol, max_iter, ok, res
):
    """:func:`_settle_one` for every set (rows of X, M, P, K) in parallel."""
    for i in nb.prange(X.shape[0]):
        ok[i], res[i] = _settle_one(
            X[i], M[i], P[i], K[i], trk, s0, ds, ctab, y0, dy, H0L, H0R, s_front, kappa, tol,
            max_iter,
        )  # fmt: skip


_CACHE: OrderedDict[bytes, np.ndarray] = OrderedDict()


def clear_cache() -> None:
    """Forget the settled states kept in memory (for timings and tests)."""
    _CACHE.clear()


def settled_states(
    P: np.ndarray,
    K: np.ndarray,
    track: np.ndarray,
    s0: float,
    ds: float,
    ca: ContactArrays,
    s_front: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Steady states (n, N_STATE) of the sets (rows of P and K) with the leading wheelset
    at ``s_front`` on ``track`` (one set of channels; its irregularities are ignored), and
    a mask of the sets whose solve converged (the others hold zeros)."""
    design = np.array(track, dtype=float, copy=True)
    design[L.TR_ZL : L.TR_YR + 1] = 0.0
    i = int(np.clip(round((s_front - s0) / ds), 0, design.shape[1] - 1))
    kappa = float(design[L.TR_KAPPA, i])  # uniform under the wagon
    n = P.shape[0]
    X = np.zeros((n, NS))
    ok = np.zeros(n, dtype=np.bool_)
    keys = _state_keys(P, K, design, ca, s_front, s0, ds)
    todo = []
    for i, key in enumerate(keys):
        hit = _CACHE.get(key)
        if hit is None:
            todo.append(i)
        else:
            _CACHE.move_to_end(key)
            X[i] = hit
            ok[i] = True
    if todo:
        idx = np.array(todo)
        Pt, Kt = np.ascontiguousarray(P[idx]), np.ascontiguousarray(K[idx])
        M = np.stack([dof_inertia(k, p) for p, k in zip(Pt, Kt, strict=True)])
        Xt = np.zeros((idx.size, NS))
        okt = np.zeros(idx.size, dtype=np.bool_)
        res = np.zeros(idx.size)
        _settle_batch(
            Xt, M, Pt, Kt, design, s0, ds, ca.table, ca.y0, ca.dy, ca.H0L, ca.H0R,
            float(s_front), kappa, SETTLE_TOLERANCE, SETTLE_MAX_ITER, okt, res,
        )  # fmt: skip
        for j, i in enumerate(todo):
            if okt[j]:
                X[i] = Xt[j]
                ok[i] = True
                _CACHE[keys[i]] = Xt[j].copy()
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    return X, ok


def _state_keys(P, K, design, ca, s_front, s0, ds) -> list[bytes]:
    """Hash of everything a settled state depends on, per row of P: the contact table, the
    design curvature and cant under the wagon, the parameter set and the constants."""
    base = hashlib.blake2b(digest_size=16)
    base.update(np.ascontiguousarray(ca.table).tobytes())
    base.update(np.array([ca.y0, ca.dy, ca.H0L, ca.H0R]).tobytes())
    i = int(np.clip(round((s_front - s0) / ds), 0, design.shape[1] - 1))
    base.update(np.array([design[L.TR_KAPPA, i], design[L.TR_CANT, i]]).tobytes())
    keys = []
    for p, k in zip(P, K, strict=True):
        h = base.copy()
        h.update(np.ascontiguousarray(p).tobytes())
        h.update(np.ascontiguousarray(k).tobytes())
        keys.append(h.digest())
    return keys
