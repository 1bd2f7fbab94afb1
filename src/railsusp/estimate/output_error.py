"""The time-aligned least-squares problem of the output-error refinement, and its simulations.

:class:`OutputError` holds what :func:`railsusp.estimate.refine.refine` minimises: the
residuals of every recording's lateral and vertical force on its measured track, in unit
parameters (and channel gains), with forward-difference Jacobians. Its predictions are
simulated in as few calls as the method allows: every set a step needs goes in one batch per
recording, sets already simulated come from a cache, and several starts refined together
(:func:`railsusp.estimate.refine.refine_starts`) share their batches through a
:class:`~railsusp.estimate.lockstep.Lockstep`. :func:`geometry_error_series` and
:func:`gauss_newton_step` propagate the track geometry's measurement error.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.estimate.comparison import (
    GAIN_LIMIT,
    compared_measurement,
    comparison_filter,
    comparison_samples,
)
from railsusp.estimate.forces import ForceModel, series_in_conditions
from railsusp.estimate.lockstep import Lockstep
from railsusp.estimate.problem import check_aligned, check_recordings
from railsusp.measured import Recording
from railsusp.params import bounds
from railsusp.vehicle import track_geometry

#: forward-difference step of the refinement's Jacobian, share of each parameter's range:
#: wider than the small-scale roughness of the time-aligned cost (wedge friction, contact
#: tables), on which a 2 % step stalled in flat valleys 3-5 % of the range from the optimum
REFINE_STEP = 0.05


class OutputError:
    """The time-aligned least-squares problem of :func:`~railsusp.estimate.refine.refine` in
    unit parameters (and channel gains): the compared measurement and its scale per
    recording and channel, predictions with a cache, residuals and forward-difference
    Jacobians. ``lockstep`` gathers the simulations of several solvers on this problem."""

    def __init__(
        self,
        model: ForceModel,
        recordings: Sequence[Recording],
        parameters: Sequence[str],
        step: float = REFINE_STEP,
        gains: bool = True,
    ):
        self.model = model
        self.parameters = tuple(parameters)
        self.recordings = list(recordings)
        check_aligned(model, self.recordings)
        # a constant or zero channel has no spread to scale by: refused in one line here,
        # not as scipy's "Residuals are not finite in the initial point"
        check_recordings(self.recordings, aligned=True)
        self.lo, self.hi = bounds(self.parameters)
        self.k = len(self.parameters)
        self.step = step
        self.gains = gains
        self.n_gain = 2 * len(self.recordings) if gains else 0
        # per recording and channel (Y, Q): the compared measurement at the samples compared
        # and its scale, so that each channel's part of the cost is half its squared
        # aligned_error
        self.samples = [comparison_samples(rec) for rec in self.recordings]
        self.scales: list[list[float]] = []
        self.targets: list[np.ndarray] = []  # scaled measurement per recording and channel
        for rec, used in zip(self.recordings, self.samples, strict=True):
            meas = compared_measurement(rec)
            self.scales.append([meas[:, c].std() * np.sqrt(used[c].size) for c in range(2)])
            self.targets += [meas[used[c], c] / self.scales[-1][c] for c in range(2)]
        self._cache: dict[bytes, list[np.ndarray]] = {}
        #: per (recording, channel), the compared samples left out at the start (undefined
        #: leading steps of the model's predictions)
        self._leading: dict[tuple[int, int], int] = {}
        self.lockstep: Lockstep[np.ndarray] = Lockstep(self._simulate)

    def predictions(self, unit: np.ndarray) -> list[np.ndarray]:
        """Compared series (n, T, 2) per recording; undefined leading steps count zero (and
        are left out of the targets, :meth:`_keep`).
        Parameter sets already simulated (the start, the base point of each Jacobian) are
        taken from a cache, the others simulated in one batch per recording, together with
        those of the other solvers running in step (:attr:`lockstep`)."""
        rows = np.atleast_2d(unit)
        new = [u for u in rows if u.tobytes() not in self._cache]
        if new:
            self.lockstep.request(np.array(new))
        return [
            np.stack([self._cache[u.tobytes()][r] for u in rows])
            for r in range(len(self.recordings))
        ]

    def _simulate(self, requests: list[np.ndarray]) -> None:
        """Simulate the sets of all ``requests`` (unit rows) not yet in the cache, each once,
        in one batch per recording, and cache their compared series."""
        rows: dict[bytes, np.ndarray] = {}
        for u in np.vstack(requests):
            if u.tobytes() not in self._cache:
                rows.setdefault(u.tobytes(), u)
        if not rows:
            return
        unit = np.array(list(rows.values()))
        x = self.lo + unit * (self.hi - self.lo)
        series = series_in_conditions(self.model, x, [rec.condition for rec in self.recordings])
        self._keep(unit, series)

    def _keep(self, unit: np.ndarray, series: list[np.ndarray]) -> None:
        """Cache the compared series of the unit rows from their raw series per recording.
        A prediction's undefined leading steps (a network's washout, the same for every set)
        are left out of the comparison, as :func:`~railsusp.estimate.comparison.aligned_error`
        leaves them out: their target is set to zero with the prediction (before, the
        recording's 120 kN wheel load was compared with zero there, a constant that made a
        network's cost 11 where the simulator's was 0.1 at the same point)."""
        filtered = [
            comparison_filter(s, rec) for s, rec in zip(series, self.recordings, strict=True)
        ]
        for r, f in enumerate(filtered):
            self._leave_out_leading(r, f)
        compared = [np.nan_to_num(f) for f in filtered]
        for j, u in enumerate(unit):
            self._cache[u.tobytes()] = [c[j] for c in compared]

    def compared_rows(self) -> tuple[np.ndarray, tuple[int, ...]]:
        """(mask over the residual rows, the rows kept per recording's channel): the rows
        of the samples compared, without the left-out leading ones (:meth:`_keep`); what
        the noise's standard errors are formed from."""
        masks, blocks = [], []
        for r, used in enumerate(self.samples):
            for c in range(2):
                first = self._leading.get((r, c), 0)
                m = np.ones(used[c].size, dtype=bool)
                m[:first] = False
                masks.append(m)
                blocks.append(int(m.sum()))
        return np.concatenate(masks), tuple(blocks)

    def _leave_out_leading(self, r: int, filtered: np.ndarray) -> None:
        """Zero recording ``r``'s targets at the compared samples before the first one that
        some set of ``filtered`` (n, T, 2) defines, in each channel (once; a batch whose sets
        all failed says nothing about the model's leading steps)."""
        for c, used in enumerate(self.samples[r]):
            key = (r, c)
            defined = np.isfinite(filtered[:, used, c]).any(axis=0)
            if key in self._leading or not defined.any():
                continue
            first = int(np.argmax(defined))
            self._leading[key] = first
            if first == 0:
                continue
            # the cost stays half the sum of squared aligned errors: each channel over the
            # square root of the samples it compares
            old = self.scales[r][c]
            self.scales[r][c] = old * np.sqrt((used.size - first) / used.size)
            target = self.targets[2 * r + c]
            target *= old / self.scales[r][c]
            target[:first] = 0.0

    def remember(self, x_si: np.ndarray, series: list[np.ndarray]) -> int:
        """Cache series already simulated elsewhere: ``series`` (n, T, 2) per recording of the
        parameter sets ``x_si`` (n, k), SI, in their recordings' conditions (the screening of
        starts). Only sets that this problem would simulate bit for bit alike are kept: those
        inside the ranges whose unit coordinates map back to ``x_si`` exactly (a start is
        taken to unit coordinates and back). Returns how many were kept."""
        x = np.atleast_2d(np.asarray(x_si, dtype=float))
        unit = np.clip((x - self.lo) / (self.hi - self.lo), 0.0, 1.0)
        exact = np.all(self.lo + unit * (self.hi - self.lo) == x, axis=1)
        fresh = np.array(
            [e and u.tobytes() not in self._cache for u, e in zip(unit, exact, strict=True)],
            dtype=bool,
        )
        if fresh.any():
            self._keep(unit[fresh], [s[fresh] for s in series])
        return int(fresh.sum())

    def blocks(self, preds: list[np.ndarray]) -> list[np.ndarray]:
        """(n, T_c) scaled prediction per recording and channel, the gains' Jacobian too."""
        return [
            p[:, used[c], c] / sc[c]
            for p, used, sc in zip(preds, self.samples, self.scales, strict=True)
            for c in range(2)
        ]

    def residuals(self, preds: list[np.ndarray], g: np.ndarray) -> np.ndarray:
        g = g if self.gains else np.ones(2 * len(self.recordings))
        return np.concatenate(
            [b * gc - t for b, gc, t in zip(self.blocks(preds), g, self.targets, strict=True)],
            axis=1,
        )

    def profiled_cost(self, unit: np.ndarray) -> float:
        """The cost at the unit point ``unit`` (k,) with each channel's gain at its best
        (within ±:data:`~railsusp.estimate.comparison.GAIN_LIMIT`; 1 without gains): what the
        least squares minimises, as a function of the parameters alone. A channel's residual
        is linear in its gain, so its best gain is the closed-form g = <b, t> / <b, b>,
        clipped (the cost is convex in each gain apart)."""
        total = 0.0
        for b, t in zip(self.blocks(self.predictions(unit)), self.targets, strict=True):
            b = b[0]
            g, bb = 1.0, float(b @ b)
            if self.gains and bb > 0.0:
                g = float(np.clip((b @ t) / bb, 1.0 - GAIN_LIMIT, 1.0 + GAIN_LIMIT))
            r = g * b - t
            total += 0.5 * float(r @ r)
        return total

    def steps(self, unit: np.ndarray) -> np.ndarray:
        """(k + 1, k) the point and its forward-difference neighbours, stepping inwards at
        the upper bound."""
        h = np.where(unit + self.step <= 1.0, self.step, -self.step)
        return np.vstack([unit, unit + np.diag(h)])

    def jacobian_of(self, preds: list[np.ndarray], z: np.ndarray) -> np.ndarray:
        """Jacobian at ``z`` from the predictions at :meth:`steps` of ``z``."""
        k = self.k
        h = np.diag(self.steps(z[:k])[1:] - z[:k])
        r = self.residuals(preds, z[k:])
        jac = np.zeros((r.shape[1], k + self.n_gain))
        jac[:, :k] = ((r[1:] - r[0]) / h[:, None]).T
        if self.gains:  # d r / d gain of a channel: its scaled prediction, in its rows only
            row = 0
            for j, b in enumerate(self.blocks(preds)):
                jac[row : row + b.shape[1], k + j] = b[0]
                row += b.shape[1]
        return jac

    def geometry_shifts(self, z: np.ndarray, draws: int, seed: int) -> np.ndarray:
        """(draws, k) shift of the estimate ``z``, SI, that each draw of geometry error of
        the recordings' stated accuracy causes: a :func:`gauss_newton_step` on the residuals
        and Jacobian with the perturbed geometry (:func:`geometry_error_series`), less the
        step on the measured geometry itself (zero at a converged interior optimum).
        Empty where no recording states an accuracy or ``draws`` is 0."""
        k = self.k
        if draws <= 0 or not any(rec.condition.track_accuracy_mm for rec in self.recordings):
            return np.zeros((0, k))
        batch = self.steps(z[:k])
        base = self.predictions(batch)
        drawn = geometry_error_series(
            self.model, self.recordings, self.lo + batch * (self.hi - self.lo), draws, seed
        )

        def shift(preds: list[np.ndarray]) -> np.ndarray:
            jac = self.jacobian_of(preds, z)
            return gauss_newton_step(jac, self.residuals(preds, z[k:])[0])[:k]

        unmoved = shift(base)
        return np.stack(
            [
                shift([b if d is None else d for b, d in zip(base, draw, strict=True)]) - unmoved
                for draw in drawn
            ]
        ) * (self.hi - self.lo)


#: conditions (draws x recordings) given to the model at once by
#: :func:`geometry_error_series`: the study's 8 draws of 3 recordings in two calls, and a
#: bounded memory for the 100 draws a configuration may ask (the simulator holds each call's
#: series twice, float64)
DRAW_CHUNK = 12


def geometry_error_series(
    model: ForceModel,
    recordings: Sequence[Recording],
    x_si: np.ndarray,
    draws: int,
    seed: int,
) -> list[list[np.ndarray | None]]:
    """Per draw and recording, the compared series (n, T, 2) of the parameter sets ``x_si``
    (n, k) with the recording's measured geometry perturbed by a fresh draw of its stated
    measurement error (:func:`~railsusp.vehicle.track_geometry.with_measurement_error`:
    ``track_accuracy_mm`` RMS, down to ``wavelength_min_m``); None for recordings on exact
    geometry. The perturbed geometries go to a temporary folder, as the simulator reads
    geometry files; every draw of every recording is a condition of its own geometry, and
    they go to the model :data:`DRAW_CHUNK` at a time (all drawn first, so the draws do not
    depend on the chunks): a network model computes their track inputs together
    (:meth:`~railsusp.estimate.forces.SurrogateForces.prime_tracks`: the nominal wagons in
    batched parallel calls) and then predicts each alone, as before, bit for bit; the
    simulator runs a chunk in shared parallel calls
    (:func:`~railsusp.estimate.forces.series_in_conditions`), each set's series bit for bit
    its own."""
    rng = np.random.default_rng(seed)
    out: list[list[np.ndarray | None]] = [[None] * len(recordings) for _ in range(draws)]
    with tempfile.TemporaryDirectory(prefix="railsusp-geometry-") as tmp:
        where: list[tuple[int, int]] = []  # (draw, recording) of each condition
        conditions: list[WorkingCondition] = []
        for i, rec in enumerate(recordings):
            cond = rec.condition
            if not cond.track_accuracy_mm:
                continue
            irr = track_geometry.read_track_geometry(cond.track_geometry)
            rms_m = cond.track_accuracy_mm * 1e-3
            for d in range(draws):
                path = Path(tmp) / f"{i}-{d}.parquet"
                noisy = track_geometry.with_measurement_error(
                    irr, rms_m, cond.wavelength_min_m, rng
                )
                track_geometry.write_track_geometry(path, noisy)
                where.append((d, i))
                conditions.append(cond.with_changes(track_geometry=str(path)))
        prime = getattr(model, "prime_tracks", None)
        for lo in range(0, len(conditions), DRAW_CHUNK):
            chunk = conditions[lo : lo + DRAW_CHUNK]
            if prime is not None:
                prime(chunk)
                series = [model.series(x_si, c) for c in chunk]
            else:
                series = series_in_conditions(model, x_si, chunk)
            for (d, i), s in zip(where[lo : lo + DRAW_CHUNK], series, strict=True):
                out[d][i] = np.nan_to_num(comparison_filter(s, recordings[i]))
    return out


def gauss_newton_step(jac: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The Gauss-Newton step -(JᵀJ)⁻¹Jᵀr of least squares with Jacobian ``jac`` and
    residuals ``r``; columns the residuals do not depend on stay put. At an estimate, with
    the Jacobian and residuals of perturbed input data, it is the estimate's shift that the
    perturbation causes (exact where the residuals are linear in the parameters), the
    propagation of errors-in-variables used by SIMEX (Cook & Stefanski, JASA 89, 1994)."""
    d = np.einsum("ij,ij->j", jac, jac)
    active = d > 1e-12 * max(float(d.max()), 1e-300)
    out = np.zeros(jac.shape[1])
    out[active] = -np.linalg.lstsq(jac[:, active], r, rcond=None)[0]
    return out
