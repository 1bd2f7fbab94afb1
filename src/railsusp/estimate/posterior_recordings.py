"""The summary statistics of recordings, in the form of the training simulations'
(:mod:`railsusp.estimate.posterior_data`): one recording per trained condition, cut into
sections of the training length, each section's statistics a row.

A recording that cannot be compared with what the estimator learnt from is refused in one
line: another wheel than the simulations record, a condition that differs from the trained
one, a record from a curve's entry spiral, an instrument bandwidth narrower than the
training's, a statistic undefined in a section. Recordings of conditions not trained on are
named in a warning. Why a module of its own: these are the checks of the measured side of
an estimate; the simulated side is :mod:`~railsusp.estimate.posterior_data`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from railsusp.errors import RailsuspInputError, cut_repr
from railsusp.estimate.posterior_data import BANDWIDTH_HZ, TrainingWheel
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.estimate.statistic_families import (
    section_statistics,
    statistic_names,
)
from railsusp.estimate.summaries import cut_sections


def recording_summaries(settings: PosteriorSettings, recordings) -> tuple[np.ndarray, dict]:
    """(n_sections, D) summary vectors of recordings, one recording per trained condition
    (matched by name, the condition otherwise equal but for duration and track), each cut
    into sections of the training length; a section of the whole is one section of every
    condition, so the shortest condition's count of sections is used. Returns the matrix
    and, per condition, the sections used and the seconds left out.

    A recording's first wheel is the one compared: one that is not the wheel the training
    simulations record (:class:`TrainingWheel`) is refused in one line, as the optimisation
    route refuses it (:func:`railsusp.estimate.problem.check_measured_wheel`: in a curve
    the outer and the inner wheel carry other forces; a recording of a left curve listing
    w1L before w1R was compared as the outer wheel, silently).

    A recording's own condition (its ``lead_in_m``, which may differ from the trained one)
    must put its sections in the steady arc of a curve, as the training conditions' are
    (:func:`~railsusp.estimate.posterior_uniform_track.check_uniform_record`: a record from
    the entry spiral was accepted and reported calibrated, its statistics far from any
    training case), and its stated instrument bandwidth (``filter_bandwidth_hz``) must be
    at least the training's :data:`BANDWIDTH_HZ` (a narrower filter removes the higher
    bands' content, which the flows then extrapolate from): each refused in one line."""
    from railsusp.estimate.posterior_uniform_track import check_uniform_record
    from railsusp.estimate.problem import check_measured_wheel

    recordings = check_recordings(recordings)
    by_name = {}
    for r in recordings:
        if r.condition.name in by_name:  # the later one was taken, the other dropped unsaid
            raise RailsuspInputError(
                f"two recordings of condition {r.condition.name!r}; accepted one per "
                "condition (a long run is one recording: its sections are cut here)"
            )
        by_name[r.condition.name] = r
    ignore = ("seed", "duration_s", "n_steps", "lead_in_m", "track_geometry",
              "track_offset_m", "track_accuracy_mm")  # fmt: skip
    per_condition, info = [], {}
    for cond in settings.conditions:
        rec = by_name.get(cond.name)
        if rec is None:
            raise MissingRecording(cond.name, [c.name for c in settings.conditions])
        diff = rec.condition.differences(cond, ignore=ignore)
        if diff:
            raise RailsuspInputError(
                f"recording {cond.name!r} differs from the trained condition in "
                f"{', '.join(diff)}; train an estimator for this condition"
            )
        check_measured_wheel(TrainingWheel(), [rec], aligned=False)
        _check_bandwidth(rec, cond.name)
        fs = 1.0 / cond.sample_interval
        if rec.sampling_rate < 0.99 * fs:  # (docs/posterior.md: at least the training's)
            raise RailsuspInputError(
                f"recording {cond.name!r}: sampled at {rec.sampling_rate:.4g} Hz, below the "
                f"{fs:.4g} Hz the estimator was trained at; accepted {fs:.4g} Hz or more (a "
                "slower recording upsampled lacks the bands the statistics take: it was read "
                "as calibrated)"
            )
        if abs(rec.sampling_rate - fs) > 0.01 * fs:
            rec = rec.resampled(fs)
        w = rec.wheels[0]
        _check_magnitudes(rec, w, settings.wagon)
        Yp = Qp = None
        if settings.partner:
            from railsusp.vehicle.layout import WHEEL_NAMES

            other = WHEEL_NAMES[WHEEL_NAMES.index(w) ^ 1]
            if other not in rec.Y or (settings.partner_q and other not in rec.Q):
                what = ("the wheelset force sumY" if settings.statistics == ("en14363",)
                        else f"statistics {','.join(settings.statistics)}")  # fmt: skip
                raise RailsuspInputError(
                    f"recording {cond.name!r}: the estimator uses {what} and needs wheel "
                    f"{other} as well as {w}"
                )
            Yp, Qp = rec.Y[other], rec.Q[other] if settings.partner_q else None
        sections = cut_sections(rec.time.size, cond.n_steps)
        if not sections:
            raise RailsuspInputError(
                f"recording {cond.name!r} is {rec.time.size / fs:.1f} s long; the estimator "
                f"needs at least one section of {settings.section_s:g} s"
            )
        check_uniform_record(
            rec.condition, len(sections) * settings.section_s, settings.wagon, recording=True
        )
        rows = [
            section_statistics(
                settings.statistics,
                rec.Y[w][s],
                rec.Q[w][s],
                fs,
                cond.speed,
                None if Yp is None else Yp[s],
                None if Qp is None else Qp[s],
                settings.sum_y,
            )
            for s in sections
        ]
        undefined = np.argwhere(~np.isfinite(rows))
        if undefined.size:  # the training leaves such cases out; a recording's is refused
            k, i = undefined[0]
            name = statistic_names(settings.statistics, settings.sum_y)[i]
            why = " (a wheel unloaded, Q <= 1 kN, in all of it)" if name.startswith("YQ") else ""
            raise RailsuspInputError(
                f"recording {cond.name!r}: statistic {name} undefined in section {k + 1}"
                f"{why}; accepted sections whose every statistic is defined"
            )
        per_condition.append(np.array(rows))
        info[cond.name] = (len(rows), rec.time.size / fs)
    n = min(len(r) for r in per_condition)
    used = {name: {"sections": n, "seconds_left_out": round(t - n * settings.section_s, 3)}
            for name, (_, t) in info.items()}  # fmt: skip
    return np.concatenate([r[:n] for r in per_condition], axis=1), used


class MissingRecording(RailsuspInputError):
    """No recording of the trained condition ``condition``; ``trained``: the conditions
    the estimator was trained on, which the message names. A joint posterior reads each
    part's conditions apart (:func:`railsusp.estimate.posterior_joint.recording_sections`)
    and names all of its own (:meth:`of_estimator`): a part's alone read as if the joint
    estimator knew only those."""

    def __init__(self, condition: str, trained: list[str]) -> None:
        self.condition, self.trained = condition, list(trained)
        super().__init__(
            f"no recording of condition {condition!r}; the estimator was trained on "
            f"{', '.join(self.trained)}"
        )

    def of_estimator(self, trained: list[str]) -> MissingRecording:
        """The same refusal, naming ``trained`` as the estimator's conditions."""
        return MissingRecording(self.condition, trained)


def check_recordings(recordings) -> list:
    """``recordings`` as a list, or a one-line error naming the argument and what is
    accepted where it is not a list (or a tuple) of
    :class:`~railsusp.measured.Recording`: a field folder's path, or a list of file names,
    failed with an AttributeError deep in the reading (docs/api.md promises one line naming
    the argument)."""
    from railsusp.measured.recording import Recording

    how = "railsusp.measured.read_field(folder) reads a field folder's"
    if not isinstance(recordings, list | tuple):  # a path, a Recording alone, ...
        raise RailsuspInputError(
            f"recordings = {cut_repr(recordings)}: accepted a list of Recording ({how})"
        )
    for i, r in enumerate(recordings):
        if not isinstance(r, Recording):
            raise RailsuspInputError(
                f"recordings[{i}] = {cut_repr(r)}: accepted a list of Recording ({how}; "
                "railsusp.measured.read_recording(path) reads one file)"
            )
    return list(recordings)


def _check_magnitudes(rec: Any, wheel: str, wagon: Any) -> None:
    """Refuse, in one line, forces whose magnitude contradicts the wagon's static wheel
    load (the field reader's check, :func:`~railsusp.measured.checks.check_forces`, here
    for a Recording built in Python: forces in N given as kN were estimated from and read
    as calibrated where the estimator had too few cases to compare their range; stop 78)."""
    from railsusp.measured.checks import check_forces
    from railsusp.vehicle.setup import static_wheel_load
    from railsusp.vehicle.wagon import load_wagon

    problems = check_forces(
        rec.Y[wheel] * 1e3, rec.Q[wheel] * 1e3, (f"Y {wheel}", f"Q {wheel}"), ("kN", "kN"),
        static_wheel_load(load_wagon(wagon)), 0,
    )  # fmt: skip
    if problems:
        raise RailsuspInputError(f"recording {rec.condition.name!r}: {problems[0]}")


def _check_bandwidth(rec, name: str) -> None:
    """Refuse, in one line, a recording whose sidecar states an instrument bandwidth
    (``filter_bandwidth_hz``) below the training simulations' :data:`BANDWIDTH_HZ`: its
    statistics of the higher bands lie outside anything the estimator learnt from
    (measured: a recording low-passed at 4 Hz put Q_band_8-15Hz at -1.33 against the
    training cases' 0.33 to 0.71, and was reported calibrated). None stated: not checked."""
    bw = (rec.meta or {}).get("filter_bandwidth_hz")
    if isinstance(bw, int | float) and not isinstance(bw, bool) and bw < BANDWIDTH_HZ:
        raise RailsuspInputError(
            f"recording {name!r}: filter_bandwidth_hz = {bw:g} Hz is below the "
            f"{BANDWIDTH_HZ:g} Hz instrument bandwidth the estimator was trained with (its "
            f"higher bands are cut); accepted {BANDWIDTH_HZ:g} Hz or more (or none stated)"
        )


def unused_recordings(recordings, trained: list[str]) -> list[str]:
    """The warning naming the recordings of conditions none of the ``trained`` conditions
    is (they were left out unsaid); none where every recording is used."""
    unused = [r.condition.name for r in recordings if r.condition.name not in trained]
    if not unused:
        return []
    return [
        f"recordings of conditions the estimator was not trained on are not used: "
        f"{', '.join(unused)} (trained on {', '.join(trained)})"
    ]
