"""A force model's expected forces on a track measured with error: the mean of its series
over draws of the true geometry given the measured one.

On a recording whose track geometry states its accuracy, the time-aligned comparison
(:mod:`railsusp.estimate.comparison`) should compare the measured forces with what the
model predicts on average over the tracks the measurement allows, not with its response to
the measured geometry itself, which carries the measurement error as extra roughness (the
error-in-variables bias of :mod:`railsusp.vehicle.geometry_posterior`). :class:`ExpectedForces`
wraps any series model (a window surrogate, the simulator): in a condition with a stated
accuracy it predicts the mean over ``draws`` geometries drawn from the true geometry's
conditional distribution (:func:`~railsusp.vehicle.geometry_posterior.geometry_posterior`);
elsewhere it predicts as the model does. The draws are made once per condition (seeded by
the seed, the condition's name and its measured geometry, so the same in every call,
whatever the order of the conditions and wherever the file lies: the least squares sees one
smooth function of the parameters) and kept, as geometry files, for the model's life.

With the simulator as the model, on issue 19's 12 sets (60 s per condition, 0.5 mm
geometry), its least squares from the truth puts the wedge friction X18 -0.9 to +2.6 % of
range off (mean +0.9; on the measured geometry +8.2 to +13.8, and +1.6 to +5.7 after the
first SIMEX step) and the primary lateral stiffness X14 -9.2 to +6.2 % (mean -0.5; on the
measured geometry -15.3 to +0.9, mean -6.5, and mean -7.9 after the SIMEX step), with no
SIMEX step: 39 of 44 identifiable key parameters within 5 % of range, against 33 with the
SIMEX step (bench/README.md, "Expected forces on a track measured with error").
"""

from __future__ import annotations

import tempfile
import weakref
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.estimate.forces import ForceModel, series_in_conditions
from railsusp.vehicle.geometry_posterior import geometry_posterior
from railsusp.vehicle.track import COMPONENTS
from railsusp.vehicle.track_geometry import read_track_geometry, write_track_geometry

#: draws of the true geometry whose mean response is predicted (four antithetic pairs): the
#: part of the mean's Monte-Carlo error that the least squares pays for shrinks with more
#: draws (on the toy wagon of tests/estimate/test_expected_forces.py 3 % of b with 4 draws,
#: 2 % with 8, 1 % with 32); 8 is what bench/estimate_ceiling.py measured (bench/README.md)
EXPECTED_DRAWS = 8


class ExpectedForces:
    """``model``'s series averaged over ``draws`` draws of the true track geometry given
    each condition's measured one (conditions that state a ``track_accuracy_mm``), seeded
    by ``seed``. The parameters are the model's. :meth:`close` (or the end of the object)
    removes the drawn geometry files."""

    def __init__(
        self,
        model: ForceModel,
        draws: int = EXPECTED_DRAWS,
        seed: int = 0,
        antithetic: bool = True,
    ):
        if draws < 1:
            raise ValueError(f"expected-force draws {draws}: accepted 1 or more")
        self.model = model
        self.parameters = tuple(model.parameters)  # type: ignore[attr-defined]
        self.draws = draws
        self.seed = seed
        self.antithetic = antithetic
        self._folder = tempfile.TemporaryDirectory(prefix="railsusp-expected-")
        self._finalizer = weakref.finalize(self, self._folder.cleanup)
        self._drawn: dict[str, list[WorkingCondition]] = {}

    def close(self) -> None:
        """Remove the drawn geometry files (the model cannot predict afterwards)."""
        self._finalizer()
        self._drawn.clear()

    def __enter__(self) -> ExpectedForces:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def drawn_conditions(self, condition: WorkingCondition) -> list[WorkingCondition]:
        """The conditions whose series are averaged for ``condition``: itself where its
        geometry is exact or absent, else one per draw, each on a drawn geometry file
        (exact: accuracy 0), made on first use and kept."""
        if condition.track_geometry is None or not condition.track_accuracy_mm:
            return [condition]
        key = condition.model_dump_json()
        if key not in self._drawn:
            if not self._finalizer.alive:
                raise RuntimeError("expected forces closed: their drawn geometry is removed")
            tag = f"{len(self._drawn):03d}-{condition.name}"
            drawn = draw_true_tracks(
                condition, self.draws, self.seed, Path(self._folder.name), tag, self.antithetic
            )
            reads = getattr(self.model, "reads_track", None)
            if reads is not None and not reads(drawn[0]):
                raise RailsuspInputError(_one_track_text(self.draws, condition.name))
            self._drawn[key] = drawn
        return self._drawn[key]

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        """(n, T, 2) the mean series over the condition's drawn geometries."""
        return self.series_conditions(x_si, [condition])[0]

    def series_conditions(
        self, x_si: np.ndarray, conditions: Sequence[WorkingCondition]
    ) -> list[np.ndarray]:
        """:meth:`series` in each condition, every draw of every condition given to the
        model at once (:func:`~railsusp.estimate.forces.series_in_conditions`: the simulator
        shares its parallel calls; a network computes the inputs of the tracks drawn in this
        call together, once: later calls find them kept)."""
        known = len(self._drawn)
        groups = [self.drawn_conditions(c) for c in conditions]
        flat = [c for g in groups for c in g]
        prime = getattr(self.model, "prime_tracks", None)
        if prime is not None and len(self._drawn) > known:
            prime(flat)
        series = series_in_conditions(self.model, x_si, flat)
        out, at = [], 0
        for g in groups:
            out.append(np.mean(series[at : at + len(g)], axis=0))
            at += len(g)
        return out


def averaged_model(model: ForceModel) -> ForceModel:
    """The model an :class:`ExpectedForces` averages, through any nesting (``model`` itself
    otherwise): what checks of the model's kind look at."""
    while isinstance(model, ExpectedForces):
        model = model.model
    return model


def check_drawable(model: ForceModel, recordings: Sequence, draws: int) -> None:
    """Refuse, before any work, ``draws`` expected-force draws with a surrogate that cannot
    predict on a drawn track: one trained on one track realisation, in a recording that
    states its geometry's accuracy (elsewhere nothing is drawn). The same one-line input
    error as on first use (:meth:`ExpectedForces.drawn_conditions`), but before NSGA-II's
    generations rather than after them."""
    if draws and not any(
        r.condition.track_geometry is not None and r.condition.track_accuracy_mm for r in recordings
    ):  # it did nothing, silently (the command-line audit of stop 60)
        import warnings

        warnings.warn(
            f"expected_draws {draws}: no recording states its track geometry's accuracy "
            "(track_accuracy_mm), so no true track is drawn and the estimate is not polished "
            "on expected forces",
            stacklevel=2,
        )
    reads = getattr(model, "reads_any_track", None)
    if not draws or reads is None:
        return
    for rec in recordings:
        c = rec.condition
        if c.track_geometry is not None and c.track_accuracy_mm and not reads(c):
            raise RailsuspInputError(_one_track_text(draws, c.name))


def _one_track_text(draws: int, name: str) -> str:
    return (
        f"expected_draws {draws}: the surrogate of condition {name!r} was trained on one "
        "track and predicts only that one, not drawn geometries; use a surrogate trained on "
        "a track family (docs/data-format.md) or expected_draws = 0"
    )


def draw_true_tracks(
    condition: WorkingCondition,
    draws: int,
    seed: int,
    folder: Path,
    tag: str = "",
    antithetic: bool = True,
) -> list[WorkingCondition]:
    """``condition`` on ``draws`` draws of its true track geometry given its measured one
    and stated accuracy (:func:`~railsusp.vehicle.geometry_posterior.geometry_posterior`),
    each written to ``folder`` (named by ``tag``) and stated exact; itself alone where its
    geometry is exact or absent. Seeded by ``seed`` and what the track is (the condition's
    name and its measured geometry), not where its file lies: the same recording in another
    run folder gets the same draws, and so do the estimate and its validation."""
    if condition.track_geometry is None or not condition.track_accuracy_mm:
        return [condition]
    irr = read_track_geometry(condition.track_geometry)
    post = geometry_posterior(irr, condition.track_accuracy_mm * 1e-3, condition.wavelength_min_m)
    content = zlib.crc32(
        np.stack([irr.component(c)[0] for c in COMPONENTS]).tobytes(),
        zlib.crc32(condition.name.encode()),
    )
    rng = np.random.default_rng([seed, content])
    drawn = []
    for d, geometry in enumerate(post.draws(draws, rng, antithetic)):
        path = Path(folder) / f"{tag or condition.name}-{d}.parquet"
        write_track_geometry(path, geometry)
        drawn.append(condition.with_changes(track_geometry=str(path), track_accuracy_mm=0.0))
    return drawn
