"""Force models of the calibration: what predicts the measured wheel's forces for parameter sets.

A trained window surrogate per condition (:class:`SurrogateForces`, the study's route) or the
batched simulator itself (:class:`SimulatorForces`, slow, the reference); statistics
surrogates, which predict no series, are :mod:`railsusp.estimate.statistics_forces`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.store import canonical_json, file_hash_cached


class ForceModel(Protocol):
    """Predicts the measured wheel's force series for parameter sets in a condition."""

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        """(n, T, 2) lateral and vertical force (kN), NaN where undefined."""
        ...


def check_parameters(
    folder: Path, trained: dict[str, tuple[str, ...]], parameters: tuple[str, ...], given: bool
) -> None:
    """Refuse, in one line, key ``parameters`` that a surrogate of ``folder`` (``trained``:
    condition -> its inputs) does not take: named as the setting ``parameters`` where the
    caller ``given`` them (``--parameters`` on the command line), else as surrogates of one
    folder trained on different inputs."""
    for name, inputs in trained.items():
        if inputs == parameters:
            continue
        if given:
            raise RailsuspInputError(
                f"parameters {','.join(parameters)}: the surrogate of condition {name!r} in "
                f"{folder} takes {','.join(inputs)}; accepted those (or leave the parameters "
                "out: the surrogates' own)"
            )
        raise RailsuspInputError(
            f"{folder}: the surrogate of condition {name!r} takes {','.join(inputs)}, another "
            f"{','.join(parameters)}; accepted a folder of surrogates trained on one set of "
            "key parameters"
        )


def check_force_laws(folder: Path, metas: dict[str, dict]) -> None:
    """Refuse, in one line, surrogates trained on a campaign of other force laws than this
    railsusp simulates (their bundle's ``model_revision``, recorded since stop 60): the
    simulator corrections and the refinement would mix two models. A bundle that records
    no revision was trained on a campaign from before revisions were recorded (the
    trainers copy the campaign's: :func:`railsusp.surrogate.fit.train_surrogate`,
    :func:`railsusp.surrogate.statistics.train_statistics_surrogate`; the shipped sets'
    bundles record theirs), so on older force laws than any revision: refused too (it was
    opened silently, the upgrade audit's H2, where the posterior refused the same case)."""
    from railsusp.vehicle.revision import mismatch

    retrain = (
        "run the campaign again and train the surrogates on it (`railsusp campaign` and "
        "`railsusp train`; in a run directory `railsusp run` does both)"
    )
    for name, meta in metas.items():
        revision = (meta or {}).get("model_revision")
        said = mismatch(revision, retrain)
        if said is not None:
            raise RailsuspInputError(
                f"{folder / name}: trained on a campaign simulated with {said}"
            )


class SurrogateForces:
    """Window surrogates, one per condition name (a folder of ``<condition>/`` bundles)."""

    def __init__(self, folder: str | Path, parameters: Sequence[str] | None = None):
        from railsusp.surrogate import load

        self.folder = Path(folder)
        self._models: dict[str, Any] = {}
        self._warned: set[str] = set()
        self._tracks: dict[str, np.ndarray] = {}
        for sub in sorted(self.folder.iterdir()) if self.folder.is_dir() else []:
            if (sub / "surrogate.json").exists():
                self._models[sub.name] = load(sub)
        if not self._models:
            raise FileNotFoundError(f"{self.folder}: no surrogate bundles (<condition>/)")
        check_force_laws(self.folder, {n: m.meta for n, m in self._models.items()})
        first = next(iter(self._models.values()))
        self.parameters = tuple(parameters) if parameters else tuple(first.spec.parameters)
        check_parameters(
            self.folder,
            {n: tuple(m.spec.parameters) for n, m in self._models.items()},
            self.parameters,
            given=bool(parameters),
        )

    @property
    def conditions(self) -> list[str]:
        return list(self._models)

    @property
    def wagon(self) -> Any:
        """The wagon data the networks were trained on (their first bundle's)."""
        return next(iter(self._models.values())).wagon

    def surrogate(self, name: str) -> Any:
        """The :class:`~railsusp.surrogate.bundle.Surrogate` of condition ``name``."""
        return self._models[name]

    def _model_of(self, condition: WorkingCondition) -> Any:
        """The surrogate of a condition, refused in one line when the folder has none."""
        if condition.name not in self._models:
            raise ValueError(
                f"no surrogate for condition {condition.name!r} in {self.folder} "
                f"(has {', '.join(self._models)})"
            )
        return self._models[condition.name]

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        model = self._model_of(condition)
        # on a measured track the network reads that track, if it can; otherwise it predicts
        # its training track, whose statistics the recording's are compared with
        on = condition if self.reads_track(condition) else None
        unread = on is None and condition.track_geometry is not None
        if unread and condition.name not in self._warned:
            from railsusp.surrogate.bundle import OneTrackWarning

            self._warned.add(condition.name)  # once per condition, not per generation
            warnings.warn(
                f"the surrogate of {condition.name!r} was trained on one track realisation: "
                "its statistics on that track are compared with the recording's, whose "
                "measured track it cannot read",
                OneTrackWarning,
                stacklevel=2,
            )
        if on is None:
            return model.predict(x_si)
        return model.predict(x_si, condition=on, track=self.track_input(on))

    def series_conditions(
        self, x_si: np.ndarray, conditions: Sequence[WorkingCondition]
    ) -> list[np.ndarray]:
        """:meth:`series` in each condition, those whose sequence CNN-GRUs read their
        measured tracks and share an architecture, segment and record length predicted in
        step (:func:`~railsusp.surrogate.in_step.predict_in_step`: one loop through all
        their networks, each condition's series those it gets alone to float32 rounding;
        an NSGA-II generation of the study's three conditions in 0.63-0.80 of the time,
        bench/README.md), the others one by one. (The import is lazy: importing
        ``railsusp.estimate`` loads neither torch nor the surrogates.)"""
        from railsusp.surrogate.in_step import in_step_key, predict_in_step

        for c in conditions:  # a condition without a surrogate, refused before any work
            self._model_of(c)
        self.prime_tracks(conditions)  # the nominal wagon on new tracks, in parallel calls
        groups: dict[tuple, list[int]] = {}
        tracks: dict[int, np.ndarray] = {}  # the measured tracks' inputs, looked up once
        for i, c in enumerate(conditions):
            if self.reads_track(c):
                tracks[i] = self.track_input(c)
                key = in_step_key(self._models[c.name], tracks[i])
                if key is not None:
                    groups.setdefault(key, []).append(i)
        out: dict[int, np.ndarray] = {}
        for members in groups.values():
            if len(members) < 2:
                continue
            chosen = [conditions[i] for i in members]
            series = predict_in_step(
                [self._models[c.name] for c in chosen],
                x_si,
                chosen,
                [tracks[i] for i in members],
            )
            out.update(zip(members, series, strict=True))
        return [out[i] if i in out else self.series(x_si, c) for i, c in enumerate(conditions)]

    def series_condition(self, condition: WorkingCondition) -> WorkingCondition:
        """The condition whose record :meth:`series` samples in ``condition``: that condition
        where the network reads its measured track (and predicts on its time base), else the
        network's own training condition, whose series it predicts whatever the
        recording's record length and time step. Statistics of the series are taken at its
        rate (a 50 Hz network's series read at a 100 Hz recording's interval put EN 14363's
        2 m window and 20 Hz filter at twice their length and half their frequency)."""
        if self.reads_track(condition):
            return condition
        return self._model_of(condition).condition

    def check_condition(self, condition: WorkingCondition, series: bool = True) -> None:
        """Refuse, in one line naming the field, its value and what the network was trained
        on, a condition its surrogate cannot serve: no surrogate of that name, or a field
        the surrogate was not trained on
        (:meth:`~railsusp.surrogate.bundle.Surrogate.untrained_fields`: one that differs from
        its condition outside the track family, or a family field outside the family's
        range). Checked before any optimisation, not in its first generation. ``series``
        False (record statistics: the network predicts its own training series, whatever
        the recording's time base) leaves the sampling interval out."""
        model = self._models.get(condition.name)
        if model is None:
            raise RailsuspInputError(
                f"recording {condition.name!r}: no surrogate of that condition in "
                f"{self.folder} (has {', '.join(self._models)})"
            )
        outside = model.untrained_fields(condition)
        if not series:
            outside = [o for o in outside if o[0] != "sample_interval"]
        if outside:
            name, value, trained = outside[0]
            raise RailsuspInputError(
                f"recording {condition.name!r}: {name} = {value!r} is outside what its "
                f"surrogate in {self.folder} was trained on ({trained}); accepted: a recording "
                "in that range, or a surrogate trained on a family that holds it"
            )

    def track_input(self, condition: WorkingCondition) -> np.ndarray:
        """(T, n_track) the network's track input on a condition's measured track, as
        :meth:`~railsusp.surrogate.bundle.Surrogate.predict` computes it from the condition
        (the geometry read, lined up and sampled at the axles, and for a network that reads
        it the nominal wagon simulated on that geometry): computed once per condition and
        kept, since an objective predicts on the same track every generation (by the
        geometry's content, :meth:`track_key`)."""
        key = self.track_key(condition)
        if key not in self._tracks:
            self._compute_tracks({key: condition})
        return self._tracks[key]

    def track_key(self, condition: WorkingCondition) -> str:
        """What a track input is kept by: the condition with its geometry file named by
        the SHA-256 of its bytes, not by its path. The same drawn true tracks written again
        elsewhere (the expected-forces polish, then each simulator correction, draw them
        with the same seed into their own temporary folders) are then computed once: 24
        nominal-wagon simulations, which took a correction on issue 19's sets from 12.5 to
        9.6 s on average (bench/README.md). The digest is read once per file (by absolute
        path, modification time and size), not every generation."""
        if condition.track_geometry is None:
            return condition.model_dump_json()
        fields = condition.model_dump(mode="json")
        fields["track_geometry"] = f"sha256:{file_hash_cached(condition.track_geometry)}"
        return canonical_json(fields)

    def prime_tracks(self, conditions: Sequence[WorkingCondition]) -> None:
        """Compute the :meth:`track_input` of every condition whose network reads its track
        and that is not yet kept, together (:meth:`_compute_tracks`): the draws of a
        geometry error (:func:`~railsusp.estimate.output_error.geometry_error_series`) are
        each a track of their own, 24 one-set simulations one after another otherwise. Each
        input is the one :meth:`track_input` computes alone, bit for bit, and is kept as it
        keeps them (one per condition, for the model's life)."""
        todo: dict[str, WorkingCondition] = {}
        for c in conditions:
            self._model_of(c)  # a condition without a surrogate, refused in one line
            if not self.reads_track(c):
                continue
            key = self.track_key(c)
            if key not in self._tracks:
                todo.setdefault(key, c)
        self._compute_tracks(todo)

    def _compute_tracks(self, todo: dict[str, WorkingCondition]) -> None:
        """Compute and keep the track inputs of ``todo`` (key -> condition), the nominal
        wagon's simulations of those whose networks read it in as few parallel calls as
        their settings allow (:func:`~railsusp.surrogate.nominal.nominal_forces_many`; one
        call per wagon, solver settings, targets and context)."""
        from railsusp.surrogate.features import track_features
        from railsusp.surrogate.nominal import nominal_forces_many

        groups: list[tuple[tuple, list[str]]] = []  # (what one call shares, keys)
        for key, c in todo.items():
            model = self._models[c.name]
            spec = model.spec
            if not spec.nominal_response:
                continue
            shared = (model.wagon, model.solver_settings(), spec.targets, spec.nominal_context)
            for have, keys in groups:
                if have == shared:
                    keys.append(key)
                    break
            else:
                groups.append((shared, [key]))
        nominal: dict[str, np.ndarray] = {}
        for (wagon, settings, targets, context), keys in groups:
            tracks = [(todo[k], todo[k].seed) for k in keys]
            nominal.update(
                zip(
                    keys,
                    nominal_forces_many(tracks, wagon, targets, settings, context),
                    strict=True,
                )
            )
        for key, c in todo.items():
            model = self._models[c.name]
            self._tracks[key] = track_features(
                c, c.seed, model.spec, model.wagon, model.solver_settings(), nominal.get(key)
            )

    def reads_track(self, condition: WorkingCondition) -> bool:
        """Whether the network of ``condition`` predicts on its measured track: not when it
        was trained on one other track realisation (it learns that track's windows, not the
        dynamics: :attr:`~railsusp.surrogate.bundle.Surrogate.one_track`)."""
        if condition.track_geometry is None:
            return False
        model = self._models[condition.name]
        return not model.one_track or model.reads_training_track(condition)

    def reads_any_track(self, condition: WorkingCondition) -> bool:
        """Whether the network of ``condition`` predicts on any track geometry (trained on a
        track family), not only on the one it was trained on: what drawn true tracks need
        (:class:`~railsusp.estimate.expected_forces.ExpectedForces`)."""
        return condition.track_geometry is not None and not self._models[condition.name].one_track


class SimulatorForces:
    """The batched simulator on the track of each condition (its measured geometry where it
    carries one, else the design track; slow reference). The parameters not in
    ``parameters`` are held at ``base`` (nominal by default); ``wagon``: the wagon data
    simulated (a WagonData, a wagon file; None: the packaged C80)."""

    def __init__(
        self,
        parameters: Sequence[str],
        wheel: str = "auto",
        base: ParameterSet | None = None,
        wagon: Any = None,
    ):
        self.parameters = tuple(parameters)
        self.wheel = wheel
        self.base = base
        self.wagon = wagon

    def series(self, x_si: np.ndarray, condition: WorkingCondition) -> np.ndarray:
        return self.series_conditions(x_si, [condition])[0]

    def series_conditions(
        self, x_si: np.ndarray, conditions: Sequence[WorkingCondition]
    ) -> list[np.ndarray]:
        """:meth:`series` in each condition, the conditions sharing the simulator's parallel
        calls (:func:`~railsusp.vehicle.simulate.simulate_conditions`)."""
        from railsusp.vehicle.simulate import simulate_conditions

        x = np.atleast_2d(np.asarray(x_si, dtype=float))
        if self.base is None:
            runs = simulate_conditions(x, conditions, symbols=self.parameters, wagon=self.wagon)
        else:
            sets = [self.base.replace(dict(zip(self.parameters, row, strict=True))) for row in x]
            runs = simulate_conditions(sets, conditions, wagon=self.wagon)
        out = []
        for r in runs:
            j = r.measured_wheel(self.wheel)
            out.append(np.stack([r.Y[:, j], r.Q[:, j]], axis=2) / 1e3)
        return out


def series_in_conditions(
    model: ForceModel, x_si: np.ndarray, conditions: Sequence[WorkingCondition]
) -> list[np.ndarray]:
    """``model``'s series for ``x_si`` in each condition: in one go where the model offers it
    (the simulator shares its parallel calls between conditions, so a trial point's one set
    on three recordings keeps two cores busy), else condition by condition."""
    together = getattr(model, "series_conditions", None)
    if together is not None:
        return together(x_si, conditions)
    return [model.series(x_si, c) for c in conditions]
