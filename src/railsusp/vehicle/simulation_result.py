"""What a simulation returns: the wheel-rail forces of a batch of runs in one working
condition (:class:`SimulationResult`), with the derived quantities (H, Y/Q, dQ/Q), the
measured wheel of a condition (:func:`measured_wheel_index`: the outer wheel in a curve)
and the record statistics every campaign reduces a run to (:func:`record_statistic`: the
study's 20 s segments averaged over a longer record).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_whole
from railsusp.vehicle import layout as L
from railsusp.vehicle.setup import SolverSettings

WHEEL_NAMES = L.WHEEL_NAMES


RECORD_STATISTICS = ("mean", "rms", "p99", "std")

#: Length of record over which a statistic is taken: the study's 20 s record. A longer
#: record's statistic is the average over its consecutive segments of about this length, so
#: that its expected value does not depend on the record length (the p99 or std of 200 s is
#: not that of 20 s) while the scatter between track realisations falls as 1/sqrt(segments).
STATISTIC_SEGMENT_S = 20.0


def statistic_segments(n_samples: int, dt_s: float) -> int:
    """Number of segments of about :data:`STATISTIC_SEGMENT_S` in a record (at least 1, at
    most one a sample: 20 samples over 600 s made 30 segments, ten of them empty, and NaN
    statistics). The record's duration is taken to the microsecond and a half segment
    rounds up: a 30 s record's 1.5 segments read 1 when its interval came from a
    recording's time column (1500 x 0.0199999...) and 2 from its condition's 0.02 s, so a
    validation compared two halves of a simulation with one whole recording."""
    duration = round(n_samples * dt_s, 6)
    return max(1, min(n_samples, math.floor(duration / STATISTIC_SEGMENT_S + 0.5)))


def record_statistic(x: np.ndarray, statistic: str, lateral: bool, segments: int = 1) -> np.ndarray:
    """Statistic of force series along the last axis (NaN-aware): mean, rms, p99 or std
    (standard deviation, the dynamic part) of |Y| for lateral forces, of Q for vertical ones;
    with ``segments`` > 1 the average of the statistic over that many consecutive equal
    parts (:func:`statistic_segments`). The one definition that surrogates, calibration and
    validation share."""
    if segments > 1:
        parts = np.array_split(np.asarray(x), segments, axis=-1)
        return np.mean([record_statistic(p, statistic, lateral) for p in parts], axis=0)
    if statistic not in _STATISTIC:
        raise ValueError(f"statistic {statistic!r}: accepted {', '.join(RECORD_STATISTICS)}")
    with warnings.catch_warnings():  # a failed set's all-NaN series gives NaN, quietly
        warnings.simplefilter("ignore", RuntimeWarning)
        return _STATISTIC[statistic](np.abs(x) if lateral else x)


_STATISTIC = {
    "mean": lambda v: np.nanmean(v, axis=-1),
    "rms": lambda v: np.sqrt(np.nanmean(v * v, axis=-1)),
    "p99": lambda v: np.nanpercentile(v, 99, axis=-1),
    "std": lambda v: np.nanstd(v, axis=-1),
}


def outer_wheel_index(curve_direction: str) -> int:
    """Index of the leading wheelset's outer wheel in a curve of ``curve_direction`` (left
    or right): the wheel 'auto' measures there (w1R in a left-hand curve)."""
    return 1 if curve_direction == "left" else 0


def measured_wheel_index(condition: WorkingCondition, which: str | int = "auto") -> int:
    """Index 0..7 of the measured wheel: 'auto' = leading wheelset, outer wheel in a curve
    (left wheel on tangent); or a name like 'w1R' or an index."""
    if is_whole(which):
        which = int(which)  # type: ignore[arg-type]
        if not 0 <= which < 8:
            raise RailsuspInputError(f"measured wheel index {which} outside 0..7")
        return which
    if not isinstance(which, str):
        raise RailsuspInputError(
            f"measured wheel {which!r}: accepted 'auto', a wheel name ({', '.join(WHEEL_NAMES)}) "
            "or an index 0..7"
        )
    if which == "auto":
        if condition.curve_radius_m is None:
            return 0
        return outer_wheel_index(condition.curve_direction)
    if which not in WHEEL_NAMES:
        raise RailsuspInputError(
            f"measured wheel {which!r} unknown; accepted 'auto' or {', '.join(WHEEL_NAMES)}"
        )
    return WHEEL_NAMES.index(which)


@dataclass
class SimulationResult:
    """Wheel-rail forces of a batch of runs in one working condition.

    Arrays (SI): ``Y`` and ``Q`` (n_sets, 8, n_t), wheel order w1L, w1R, ... w4R (w1 the
    leading wheelset); Y is the lateral force of the wheel on the rail, + towards the field
    side (flange force +); Q the vertical force on the rail, + down. ``car_acc_y``/``_z``
    (n_sets, n_t) car-body CG accelerations (lateral uncompensated). ``status`` 0 = ok, else a
    code of ``layout.FAILURE_REASONS``; failed sets hold NaN series; ``fail_time`` counts
    from the leading wheelset's passing the section start (s = 0), whichever start a set
    had (``settled_start``).
    """

    condition: WorkingCondition
    params: np.ndarray  # (n_sets, 20) SI, X1..X20
    time: np.ndarray
    Y: np.ndarray
    Q: np.ndarray
    car_acc_y: np.ndarray
    car_acc_z: np.ndarray
    status: np.ndarray
    fail_time: np.ndarray
    #: N; per set (n_sets,) where the sets' masses differ and so their static loads
    static_wheel_load: float | np.ndarray
    wall_time: float = 0.0
    settings: SolverSettings = field(default_factory=SolverSettings)
    wagon_name: str = ""
    #: per set, whether it started from the settled state (else it ran the lead-in)
    settled_start: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    @property
    def n_sets(self) -> int:
        return self.Y.shape[0]

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask of sets that completed."""
        return self.status == L.OK

    def failures(self) -> list[tuple[int, str, float]]:
        """(set index, reason, time s) of each failed set."""
        return [
            (int(i), L.FAILURE_REASONS[int(self.status[i])], float(self.fail_time[i]))
            for i in np.flatnonzero(self.status != L.OK)
        ]

    @property
    def H(self) -> np.ndarray:
        """Wheelset lateral force on the track (n_sets, 4, n_t), N, + to the left."""
        return self.Y[:, 0::2] - self.Y[:, 1::2]

    @property
    def derailment_quotient(self) -> np.ndarray:
        """Y/Q per wheel (n_sets, 8, n_t); NaN where the wheel is unloaded."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.Q > 1.0, self.Y / self.Q, np.nan)

    @property
    def unloading_ratio(self) -> np.ndarray:
        """Wheel-unloading ratio dQ/Q per wheel (n_sets, 8, n_t): (Q_static - Q)/Q_static."""
        q0 = np.asarray(self.static_wheel_load, dtype=float)
        q0 = q0[:, None, None] if q0.ndim else q0  # each set's own static load
        return (q0 - self.Q) / q0

    def measured_wheel(self, which: str | int = "auto") -> int:
        """Index of the measured wheel (see :func:`measured_wheel_index`)."""
        return measured_wheel_index(self.condition, which)

    def _one_set(self, set_index: object) -> int:
        """``set_index`` checked (a whole number 0 .. n_sets - 1), with a warning where that
        set failed: its series are NaN from the start (a failed integration's forces are not
        kept), and so are its statistics."""
        if not is_whole(set_index) or not 0 <= int(set_index) < self.n_sets:  # type: ignore[arg-type]
            raise RailsuspInputError(
                f"set_index = {set_index!r}: accepted a whole number 0..{self.n_sets - 1} "
                "(this result holds " + f"{self.n_sets} set{'s' if self.n_sets > 1 else ''})"
            )
        i = int(set_index)  # type: ignore[arg-type]
        if self.status[i] != L.OK:
            reason, t = L.FAILURE_REASONS[int(self.status[i])], float(self.fail_time[i])
            warnings.warn(
                f"set {i} failed ({reason} at {t:.3g} s): its forces and statistics are NaN; "
                "result.failures() lists the failed sets, result.ok says which ran",
                RuntimeWarning,
                stacklevel=3,
            )
        return i

    def statistics(
        self, wheel: str | int = "auto", set_index: int | None = 0
    ) -> dict[str, float] | dict[str, np.ndarray]:
        """Statistics (kN for forces) of the measured wheel: mean, RMS, p99 (averaged over
        the record's segments, :func:`record_statistic`), max of |Y| and Q, max Y/Q, max
        dQ/Q; floats of one set (``set_index``, the first by default, as
        :meth:`to_dataframe`), or with ``set_index=None`` arrays over every set of a batch."""
        j = self.measured_wheel(wheel)
        i = None if set_index is None else self._one_set(set_index)  # checked before the work
        segments = statistic_segments(self.time.size, self.condition.sample_interval)
        stats = {}
        for name, arr in (("Y", self.Y[:, j] / 1e3), ("Q", self.Q[:, j] / 1e3)):
            for st in ("mean", "rms", "p99"):
                stats[f"{name}_{st}"] = record_statistic(arr, st, name == "Y", segments)
            stats[f"{name}_max"] = np.abs(arr).max(axis=1)
        with warnings.catch_warnings():  # failed sets: all-NaN series give NaN, quietly
            warnings.simplefilter("ignore", RuntimeWarning)
            stats["YQ_max"] = np.nanmax(np.abs(self.derailment_quotient[:, j]), axis=1)
        stats["dQQ_max"] = np.max(self.unloading_ratio[:, j], axis=1)
        if set_index is None:
            return stats
        return {k: float(v[i]) for k, v in stats.items()}

    def to_dataframe(self, set_index: int = 0):
        """Time series of one set as a pandas DataFrame (kN, m/s^2), time in s as index."""
        import pandas as pd

        set_index = self._one_set(set_index)
        cols = {}
        for j, name in enumerate(WHEEL_NAMES):
            cols[f"Y_{name}_kN"] = self.Y[set_index, j] / 1e3
        for j, name in enumerate(WHEEL_NAMES):
            cols[f"Q_{name}_kN"] = self.Q[set_index, j] / 1e3
        for w in range(4):
            cols[f"H_w{w + 1}_kN"] = self.H[set_index, w] / 1e3
        cols["car_acc_y_m_s2"] = self.car_acc_y[set_index]
        cols["car_acc_z_m_s2"] = self.car_acc_z[set_index]
        return pd.DataFrame(cols, index=pd.Index(self.time, name="time_s"))

    def to_xarray(self):
        """All sets as an xarray Dataset: Y, Q (set, wheel, time) in N; accelerations."""
        import xarray as xr

        coords = {
            "set": np.arange(self.n_sets),
            "wheel": list(WHEEL_NAMES),
            "time": self.time,
            "parameter": [f"X{i}" for i in range(1, 21)],
        }
        ds = xr.Dataset(
            {
                "Y": (
                    ("set", "wheel", "time"),
                    self.Y,
                    {
                        "units": "N",
                        "long_name": "lateral force on the rail, + towards the field side",
                    },
                ),
                "Q": (
                    ("set", "wheel", "time"),
                    self.Q,
                    {"units": "N", "long_name": "vertical force on the rail, + down"},
                ),
                "car_acc_y": (("set", "time"), self.car_acc_y, {"units": "m/s^2"}),
                "car_acc_z": (("set", "time"), self.car_acc_z, {"units": "m/s^2"}),
                "params": (("set", "parameter"), self.params, {"units": "SI"}),
                "status": (("set",), self.status),
            },
            coords=coords,
            attrs={"condition": self.condition.model_dump_json(), "wagon": self.wagon_name},
        )
        return ds

    def to_parquet(self, path: str | Path, set_index: int = 0) -> Path:
        """Write one set's series to Parquet atomically, with the condition in the metadata."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        from railsusp.input_checks import check_output_file
        from railsusp.store import atomic_write_bytes

        if not isinstance(path, str | os.PathLike):
            raise RailsuspInputError(f"path = {path!r}: a file path (str or Path) is needed")
        path = check_output_file(path, "path")  # not a folder, nor under a file
        table = pa.Table.from_pandas(self.to_dataframe(set_index))  # set_index checked there
        set_index = int(set_index)
        meta = dict(table.schema.metadata or {})
        meta[b"railsusp.condition"] = self.condition.model_dump_json().encode()
        meta[b"railsusp.params"] = ",".join(f"{v:.9g}" for v in self.params[set_index]).encode()
        meta[b"railsusp.status"] = L.FAILURE_REASONS[int(self.status[set_index])].encode()
        buffer = pa.BufferOutputStream()
        pq.write_table(table.replace_schema_metadata(meta), buffer)
        return atomic_write_bytes(path, buffer.getvalue().to_pybytes())
