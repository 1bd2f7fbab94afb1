"""Synthetic "field" recordings of hidden true parameters: a simulation made into a
recording, instrumented-wheelset errors (gain, bandwidth, noise) added, written as a field
folder whose truth the estimator never reads.
"""

from __future__ import annotations

import glob
from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import butter, sosfiltfilt

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError, repeated_names
from railsusp.measured.recording import (
    FORMAT,
    Recording,
    SimulationFailedError,
    recordings_digest,
)
from railsusp.measured.truth import RECORDING_FILES, RECORDINGS_DIGEST, recording_files
from railsusp.store import atomic_folder, write_json
from railsusp.vehicle.layout import WHEEL_NAMES
from railsusp.vehicle.track import Irregularities
from railsusp.vehicle.track_geometry import (
    read_track_geometry,
    with_measurement_error,
    write_track_geometry,
)


def recording_from_simulation(
    result, wheels: tuple[str, ...] | None = None, set_index: int = 0
) -> Recording:
    """A recording (kN) of the wheels of a simulation result (default: measured wheel); a
    failed simulation (derailment, divergence) is an error naming the reason and time."""
    if not result.ok[set_index]:
        reason = {i: (why, t) for i, why, t in result.failures()}[set_index]
        raise SimulationFailedError(
            f"simulation in condition {result.condition.name!r} failed at {reason[1]:.2f} s: "
            f"{reason[0]}; no recording can be made of it"
        )
    ws = wheels or (WHEEL_NAMES[result.measured_wheel()],)
    Y = {w: result.Y[set_index, WHEEL_NAMES.index(w)] / 1e3 for w in ws}
    Q = {w: result.Q[set_index, WHEEL_NAMES.index(w)] / 1e3 for w in ws}
    return Recording(result.time.copy(), Y, Q, result.condition, {"wagon": result.wagon_name})


def simulated_forces(pset, rec: Recording, wagon: Any = None) -> np.ndarray:
    """(T, 2) forces (kN) the simulator gives for ``pset`` in a recording's condition at its
    first measured wheel, the counterpart of :meth:`Recording.forces`; ``wagon``: its data
    (None: the packaged C80)."""
    from railsusp.vehicle.simulate import simulate

    result = simulate(pset, rec.condition, wagon=wagon)
    return recording_from_simulation(result, rec.wheels[:1]).forces()


@lru_cache(maxsize=64)
def _bandwidth_sos(fs: float, bandwidth_hz: float) -> np.ndarray:
    """The second-order sections of :func:`bandwidth_filter`, designed once per rate and
    bandwidth: the time-aligned objective filters every generation's predictions with the
    same few filters."""
    return butter(4, min(bandwidth_hz, 0.45 * fs), fs=fs, output="sos")


def bandwidth_filter(x: np.ndarray, fs: float, bandwidth_hz: float, axis: int = -1) -> np.ndarray:
    """An instrument's bandwidth limit: 4th-order Butterworth low-pass, zero phase (scipy
    ``sosfiltfilt``), cut-off ``bandwidth_hz`` capped at 0.45 of the sampling rate ``fs``."""
    return sosfiltfilt(_bandwidth_sos(float(fs), float(bandwidth_hz)), x, axis=axis)


def add_sensor_noise(
    rec: Recording, noise: float, seed: int, bandwidth_hz: float = 15.0, gain_error: float = 0.01
) -> Recording:
    """Instrumented-wheelset errors: a gain error (normal, sd ``gain_error``) per channel, a
    bandwidth limit (4th-order zero-phase low-pass), and white noise of ``noise`` times the
    channel's RMS. Draws wheel by wheel (Y, then Q), so the first wheel's errors are those
    of a recording of it alone."""
    rng = np.random.default_rng(seed)
    fs = rec.sampling_rate

    def corrupt(x: np.ndarray) -> np.ndarray:
        y = bandwidth_filter(x, fs, bandwidth_hz) * (1.0 + gain_error * rng.standard_normal())
        return y + noise * np.sqrt(np.mean(x**2)) * rng.standard_normal(len(x))

    # wheel by wheel, Y then Q: a recording of more wheels keeps its first wheel's noise
    Y, Q = {}, {}
    for w in rec.wheels:
        Y[w] = corrupt(rec.Y[w])
        Q[w] = np.maximum(corrupt(rec.Q[w]), 0.0)
    return Recording(
        rec.time.copy(),
        Y,
        Q,
        rec.condition,
        {**rec.meta, "filter_bandwidth_hz": bandwidth_hz, "synthetic": True},
    )


def _earlier_field(out: Path) -> list[str]:
    """What an earlier field in ``out`` wrote (its index, truth, and each recording it lists
    with its sidecar and track file, by exact name), as names not carried into the new one:
    a condition no longer synthesised left its recording beside the new ones, and the
    report listed it among the run's files (interrupt/resume audit of stop 60)."""
    from railsusp.measured.reader import read_index

    try:
        listed = read_index(out)
    except (RailsuspInputError, OSError):
        listed = []
    names = ["index.json", "truth.json"]
    for p in listed:  # the table, its sidecar and the track file this function writes
        names += [p.name, f"{p.stem}.json", f"{p.stem}.track.csv"]
    return [glob.escape(n) for n in names]


def synthesise_field(
    truth,
    conditions: list[WorkingCondition],
    out: str | Path,
    *,
    seed: int = 7,
    noise: float = 0.03,
    track_seed_offset: int = 1000,
    fmt: str = "csv",
    duration_s: float | None = None,
    with_track: bool = False,
    track_noise_mm: float = 0.0,
    stated_accuracy_mm: float | None = None,
    wheelset: bool = False,
    wagon: Any = None,
) -> Path:
    """Synthetic field recordings of the ``truth`` ParameterSet with hidden truth.

    Each condition is simulated on a track realisation different from the design track
    (seed + ``track_seed_offset``), sensor noise is added, the recordings are written in the
    documented format and listed in ``index.json``; the truth goes to ``truth.json``, a file
    the estimator never reads. ``duration_s`` records longer (or shorter) than the
    condition's duration at the same sampling rate: real runs span kilometres of track, and
    the track-realisation scatter of a statistic falls with the recorded length.

    ``with_track`` also writes the track the truth ran on as measured track geometry
    (``NAME.track.csv``, named by the recording's condition), as a track recording car run
    with the instrumented wagon would give, with a measurement error of ``track_noise_mm``
    (RMS, mm, within the measured wavelengths) on each component. The recordings state the
    geometry's accuracy (``track_accuracy_mm``) as ``stated_accuracy_mm``, by default the
    true ``track_noise_mm``: an engineer knows the specification of the geometry car. A
    condition that names its own ``track_geometry`` file is simulated on that track (no
    realisation is drawn), and its recording carries a copy of the file whatever
    ``with_track`` says: the track is known, and the recording's sidecar must not name a file
    outside its folder.

    ``wheelset``: both wheels of the instrumented wheelset are recorded (the measured wheel
    first, then its partner), as an instrumented wheelset measures them; the posterior's
    wheelset, coherence and cross-spectra statistics need the partner. Default: the
    measured wheel only. ``wagon``: the wagon data simulated (a WagonData or a wagon file;
    None: the packaged C80).
    """
    from railsusp.vehicle.simulate import simulate
    from railsusp.vehicle.wagon import load_wagon

    wagon = load_wagon(wagon)

    if not 0.0 <= track_noise_mm <= 10.0:
        raise RailsuspInputError(f"track_noise_mm = {track_noise_mm:g}: accepted 0 to 10 mm")
    if track_noise_mm and not with_track:  # the error of a geometry that is not written
        raise RailsuspInputError(
            f"track_noise_mm = {track_noise_mm:g} needs with_track = True (the measurement "
            "error of the track geometry written beside the recordings)"
        )
    if seed < 0:
        raise RailsuspInputError(f"seed = {seed}: accepted 0 or more")
    if not conditions:
        raise RailsuspInputError("conditions: none given, accepted at least one")
    named = [c.name for c in conditions]
    twice = repeated_names(named)
    if twice:  # each recording is written under its condition's name
        raise RailsuspInputError(
            f"conditions: {', '.join(twice)} named more than once; accepted distinct names"
        )
    out = Path(out)
    if out.exists() and not out.is_dir():  # never replace a file by a field folder
        raise RailsuspInputError(
            f"out = {out}: a file, not a folder; accepted a new or field folder"
        )
    # the folder as one artefact: a crash leaves the old folder as it was, never a table
    # without its sidecar or an index that lists recordings not written
    with atomic_folder(out, drop=_earlier_field(out)) as folder:
        names = []
        for i, cond in enumerate(conditions):
            if duration_s is not None:
                cond = cond.with_duration(duration_s)
            field_cond = cond.with_changes(seed=cond.seed + track_seed_offset)
            result = simulate(truth, field_cond, wagon=wagon)
            j = result.measured_wheel()
            both = (WHEEL_NAMES[j], WHEEL_NAMES[j ^ 1]) if wheelset else None
            rec = recording_from_simulation(result, both)
            rec = add_sensor_noise(rec, noise, seed + i)
            rec.condition = cond  # the engineer knows the condition, not the track realisation
            if with_track or cond.track_geometry is not None:
                # a condition's own track_geometry file is the track it names: the recording
                # carries it whatever with_track says (a copy beside it, unfaded, its offset
                # applied), as a measured recording on known track would
                irr = _track_of(field_cond, wagon)
                if track_noise_mm:
                    rng = np.random.default_rng([seed, i, 1])
                    irr = with_measurement_error(
                        irr, track_noise_mm * 1e-3, cond.wavelength_min_m, rng
                    )
                track_name = f"{cond.name}.track.csv"
                write_track_geometry(folder / track_name, irr, origin_m=cond.lead_in_m)
                rec.condition = cond.with_changes(
                    track_geometry=track_name,
                    track_offset_m=0.0,
                    track_accuracy_mm=track_noise_mm
                    if stated_accuracy_mm is None
                    else stated_accuracy_mm,
                )
            rec.meta["wagon"] = wagon.name
            rec.write(folder / cond.name, fmt)
            names.append(cond.name + (".csv" if fmt == "csv" else ".parquet"))
        write_json(
            folder / "index.json",
            {"format": FORMAT, "recordings": names, "noise": noise, "seed": seed},
        )
        from railsusp.measured.reader import read_field

        written = recordings_digest(read_field(folder, wagon=wagon))  # as validate reads them
        write_json(
            folder / "truth.json",
            {
                "parameters_display": truth.to_display(),
                "note": "hidden truth: the estimator must not read this",
                "track_seed_offset": track_seed_offset,
                # which recordings it is the truth of, by their tables' contents: validate
                # --truth refuses it for others (check_truth_of)
                RECORDING_FILES: recording_files(folder, names),
                RECORDINGS_DIGEST: written,
            },
        )
    return out


def _track_of(cond: WorkingCondition, wagon: Any) -> Irregularities:
    """The irregularities a synthetic recording of ``cond`` was simulated on, in section
    coordinates: its ``track_geometry`` file as read (the file's distances moved by
    ``track_offset_m``; not faded in, as the simulation's copy is), else the condition's
    synthesised realisation."""
    from railsusp.vehicle.track_grid import section_irregularities

    if cond.track_geometry is not None:
        irr = read_track_geometry(cond.track_geometry)
        return replace(irr, s=irr.s + cond.track_offset_m + cond.lead_in_m)
    irr = section_irregularities(cond, [cond.seed], wagon)
    if irr is None:
        raise RailsuspInputError(
            f"condition {cond.name!r}: perfect track (no irregularity_class) has no track "
            "geometry to write; accepted with_track = false for it"
        )
    return irr
