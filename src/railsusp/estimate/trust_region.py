"""The simulator's check of each first-order correction's step, and the trust box it sets.

A first-order correction (:func:`~railsusp.estimate.level_correction.correct_by_simulator`
with slopes) makes the surrogate agree with the simulator in value and slopes at one point
and trusts it within a box about that point. The next correction simulates the point the
step proposed anyway, so the simulator's cost there comes at no extra simulation. Each step
is therefore checked as in the classical trust-region method (Nocedal & Wright, *Numerical
Optimization*, 2nd ed., 2006, Algorithm 4.1; for corrected surrogates Alexandrov, Dennis,
Lewis & Torczon, Structural Optimization 15, 1998). The check is the ratio

    rho = (f(x) - f(y)) / (f(x) - m(y)),

where f is the simulator's time-aligned cost, m the corrected surrogate's (m(x) = f(x) by
construction), x the step's start and y the point it proposed. The point is kept when rho
>= :data:`ACCEPT_RATIO`; otherwise the next least squares starts from x again in a smaller
box, and the proposed point's slopes are not simulated (with Broyden's slopes,
:func:`~railsusp.estimate.level_correction.broyden_slopes`, the corrected surrogate takes the
rejected point's secant; otherwise it stays as it was). The box shrinks to :data:`SHRINK` of
the step's extent (not below :data:`BOX_MIN`) when the point is rejected, for whatever reason,
or kept with rho < :data:`SHRINK_BELOW`. A rejected step of a few per cent of the range or
less thus leaves the steps after it within a quarter of it about the last kept point: there
the simulator's cost is rough on the scale of the falls judged (a few millionths of it,
bench/README.md), and staying is the corrections' convergence. It doubles, up to :data:`BOX_MAX`,
when rho > :data:`EXPAND_ABOVE` and the step reached its edge. Costs are profiled over the
channel gains (:meth:`~railsusp.estimate.output_error.OutputError.profiled_cost`), so that
the comparison does not depend on where the gains were left.

A point whose simulation stopped (derailment, divergence) is rejected like one that raised
the cost. The last step's point is the estimate unchecked, as without the check: checking it
would take one more simulation per recording and drawn track.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from railsusp.estimate.config import TRUST_BOX
from railsusp.estimate.forces import ForceModel
from railsusp.estimate.output_error import OutputError
from railsusp.measured import Recording
from railsusp.params import bounds

#: a proposed point is kept when the simulator's cost fell by at least this share of the fall
#: the corrected surrogate predicted (Nocedal & Wright's eta, within their [0, 1/4))
ACCEPT_RATIO = 0.1
#: below this ratio the box shrinks ...
SHRINK_BELOW = 0.25
#: ... to this share of the step's extent (the largest move of a key, share of its range)
SHRINK = 0.25
#: above this ratio, with the step on the box's edge, the box grows ...
EXPAND_ABOVE = 0.75
#: ... by this factor, up to :data:`BOX_MAX`
EXPAND = 2.0
#: the largest box, as a fraction of each range: twice the first
#: (:data:`~railsusp.estimate.config.TRUST_BOX`)
BOX_MAX = 2.0 * TRUST_BOX
#: a step whose extent is at least this share of its box is on the box's edge
ON_EDGE = 0.99
#: the smallest box, as a fraction of each range: small enough that a rejected step of less
#: than a few per cent of the range is not proposed again (the box a quarter of it), so that
#: the steps left stay near the last kept point, which is what convergence looks like here;
#: large enough that the least squares' bounds stay apart (scipy refuses equal bounds)
BOX_MIN = 1e-4
#: a predicted and an actual fall of the cost both within this share of it are taken as
#: converged (the point kept, the box as it was): the ratio of two such falls is rounding
CONVERGED = 1e-9


@dataclass
class StepCheck:
    """The simulator's verdict on the point one correction step proposed."""

    #: the trust box the step's least squares was kept in, fraction of each range
    box: float
    #: the simulator's profiled cost where the step started (the corrected surrogate's, by
    #: construction)
    cost_start: float
    #: the corrected surrogate's profiled cost at the point the step proposed
    cost_predicted: float
    #: the step's largest move of a key within the box, share of its range (before any
    #: geometry bias is taken off the point)
    extent: float = 0.0
    #: the simulator's there, once the next step simulated it (None: not simulated, or the
    #: simulation stopped)
    cost_simulated: float | None = None
    #: actual over predicted fall of the cost (None where not checked, or the predicted
    #: fall is not positive)
    ratio: float | None = None
    #: whether the point was kept (None: not checked, as the last step's point)
    accepted: bool | None = None
    #: why the point's simulation stopped, if it did
    stopped: str = ""

    def judge(self, cost_simulated: float) -> None:
        """Keep or reject the proposed point by the simulator's cost there. Where the
        corrected surrogate predicted no fall (the least squares ended above its start's
        profiled cost: evaluations spent, or a bias taken off after it), the point is kept
        if the simulator's cost did not rise, and no ratio is given."""
        self.cost_simulated = float(cost_simulated)
        predicted = self.cost_start - self.cost_predicted
        actual = self.cost_start - self.cost_simulated
        tol = CONVERGED * abs(self.cost_start)
        if abs(predicted) <= tol and abs(actual) <= tol:  # converged: nothing to judge
            self.accepted = True
        elif predicted > 0.0:
            self.ratio = actual / predicted
            self.accepted = self.ratio >= ACCEPT_RATIO
        else:
            self.accepted = actual >= 0.0

    def reject_stopped(self, reason: str) -> None:
        """The proposed point's simulation stopped: rejected."""
        self.accepted, self.stopped = False, reason

    def next_box(self) -> float:
        """The box for the next least squares after this verdict: a quarter of the step's
        extent (at least :data:`BOX_MIN`) after a rejection or a poor ratio, twice the box
        (at most :data:`BOX_MAX`) after a good one on the box's edge, else the same."""
        shrink = not self.accepted or (self.ratio is not None and self.ratio < SHRINK_BELOW)
        if shrink:
            return max(SHRINK * self.extent, BOX_MIN)
        on_edge = self.extent >= ON_EDGE * self.box
        if self.ratio is not None and self.ratio > EXPAND_ABOVE and on_edge:
            return min(EXPAND * self.box, BOX_MAX)
        return self.box

    def to_dict(self) -> dict:
        return asdict(self)


def step_extent(parameters: Sequence[str], start_si: np.ndarray, end_si: np.ndarray) -> float:
    """The largest move of a key from ``start_si`` to ``end_si``, share of its range (the
    box's own norm)."""
    lo, hi = bounds(tuple(parameters))
    return float(np.max(np.abs(np.asarray(end_si) - np.asarray(start_si)) / (hi - lo)))


def profiled_cost(
    model: ForceModel,
    recordings: Sequence[Recording],
    parameters: Sequence[str],
    x_si: np.ndarray,
    gains: bool,
) -> float:
    """``model``'s time-aligned cost at ``x_si`` (SI) against the recordings, as the
    corrections' least squares compares (channel gains profiled where ``gains``)."""
    problem = OutputError(model, recordings, parameters, gains=gains)
    unit = np.clip((np.asarray(x_si, dtype=float) - problem.lo) / (problem.hi - problem.lo), 0, 1)
    return problem.profiled_cost(unit)
