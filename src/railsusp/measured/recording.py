"""Measured wheel-rail force recordings of one working condition each: the
:class:`Recording` (time, kN forces per wheel, its condition) and its documented file
format (docs/data-format.md): a table ``NAME.csv`` or ``NAME.parquet`` with ``time_s`` and
``Y_<wheel>_kN`` / ``Q_<wheel>_kN`` columns, and a JSON sidecar ``NAME.json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.signal import resample_poly

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.numbers import is_real
from railsusp.store import write_json, write_parquet

FORMAT = "railsusp-recording/1"


class RecordingError(RailsuspInputError):
    """A recording that cannot be used; ``problems`` lists every issue found."""

    def __init__(self, path: str | Path, problems: list[str]):
        self.path = str(path)
        self.problems = problems
        super().__init__(f"{path}: {len(problems)} problem(s): " + "; ".join(problems))


class SimulationFailedError(RailsuspInputError):
    """A simulation that a recording was to be made of stopped (see its reason)."""


#: the version of :func:`recordings_digest` written today, as the digest's prefix ``"v2:"``;
#: a digest without a prefix is version 1 (before stop 76), which hashed a track-geometry
#: file's bytes, so a geometry file checked out with other line endings read as other
#: recordings. :func:`same_recordings` compares a stored digest in its own version.
DIGEST_VERSION = 2
#: the versions :func:`recordings_digest` computes
DIGEST_VERSIONS = (1, 2)


def recordings_digest(recordings: list[Recording], version: int = DIGEST_VERSION) -> str:
    """SHA-256 of what an estimate read of its recordings: each one's condition, time and
    forces of every wheel, and its track geometry, in name order. Stored
    with an estimate, so that validating it later against its recordings' folder tells a
    folder written again since (other recordings under the same path were validated as the
    estimate's without a word), and with a synthetic field's truth.

    Version 2 (``"v2:"``, the default) hashes the geometry as read (its distances and four
    components, :func:`~railsusp.vehicle.track_geometry.read_track_geometry`): the same
    geometry in other bytes (CRLF line endings, Parquet instead of CSV) is the same
    recording. Version 1 (no prefix) hashed the file's bytes; it is computed only to compare
    a digest stored before (:func:`same_recordings`)."""
    import hashlib

    from railsusp.store import file_hash

    if version not in DIGEST_VERSIONS:
        raise ValueError(f"recordings digest version {version}: accepted {DIGEST_VERSIONS}")
    h = hashlib.sha256()
    for rec in sorted(recordings, key=lambda r: r.condition.name):
        # the geometry by its contents, not its path (read from a relative folder at the
        # estimate and from the resolved one at the validation)
        h.update(rec.condition.model_dump_json(exclude={"track_geometry"}).encode())
        if rec.condition.track_geometry is not None:
            if version == 1:
                try:
                    h.update(file_hash(rec.condition.track_geometry).encode())
                except OSError:
                    h.update(b"geometry unreadable")
            else:
                h.update(_geometry_as_read(rec.condition.track_geometry))
        h.update(np.ascontiguousarray(rec.time, dtype=float).tobytes())
        for w in rec.wheels:
            h.update(w.encode())
            h.update(np.ascontiguousarray(rec.Y[w], dtype=float).tobytes())
            h.update(np.ascontiguousarray(rec.Q[w], dtype=float).tobytes())
    return h.hexdigest() if version == 1 else f"v{version}:{h.hexdigest()}"


def same_recordings(recordings: list[Recording], stored: str) -> bool:
    """Whether ``recordings`` read as those whose :func:`recordings_digest` is ``stored``,
    computed in the stored digest's own version (an estimate or truth written before
    version 2 keeps matching its recordings)."""
    version = 1
    if stored.startswith("v") and ":" in stored:
        try:
            version = int(stored[1 : stored.index(":")])
        except ValueError:
            return False
        if version not in DIGEST_VERSIONS:
            return False
    return recordings_digest(recordings, version) == stored


def _geometry_as_read(path: str) -> bytes:
    """A track-geometry file's distances and components as read, for the digest; a file
    that cannot be read hashes as such (the reader of the recordings says why)."""
    from railsusp.vehicle.track import COMPONENTS
    from railsusp.vehicle.track_geometry import read_track_geometry

    try:
        irr = read_track_geometry(path)
    except (OSError, RailsuspInputError):
        return b"geometry unreadable"
    parts = [irr.s, *(irr.component(c) for c in COMPONENTS)]
    return b"".join(np.ascontiguousarray(x, dtype=float).tobytes() for x in parts)


@dataclass
class Recording:
    """One instrumented-wheelset recording in one working condition (SI time, kN forces)."""

    time: np.ndarray
    Y: dict[str, np.ndarray]
    Q: dict[str, np.ndarray]
    condition: WorkingCondition
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def wheels(self) -> tuple[str, ...]:
        return tuple(self.Y)

    @property
    def sampling_rate(self) -> float:
        return 1.0 / float(np.median(np.diff(self.time)))

    def forces(self) -> np.ndarray:
        """(T, 2) lateral and vertical force of the first measured wheel, kN."""
        w = self.wheels[0]
        return np.stack([self.Y[w], self.Q[w]], axis=1)

    def to_dataframe(self) -> pd.DataFrame:
        cols = {"time_s": self.time}
        for w in self.wheels:
            cols[f"Y_{w}_kN"] = self.Y[w]
            cols[f"Q_{w}_kN"] = self.Q[w]
        return pd.DataFrame(cols)

    def write(self, path: str | Path, fmt: str = "csv") -> Path:
        """Write ``NAME.csv`` (or ``.parquet``) and the ``NAME.json`` sidecar atomically.
        ``path`` is ``NAME`` or ``NAME.csv`` / ``.parquet`` / ``.json``; any other dot is
        part of the name (``km0.5`` and ``km0.7`` were both written as ``km0.csv``)."""
        path = Path(path)
        known = path.suffix.lower() in (".csv", ".parquet", ".json")
        stem = path.with_suffix("") if known else path
        meta = {
            "format": FORMAT,
            "wheels": list(self.wheels),
            "sampling_rate_hz": self.sampling_rate,
            "condition": self.condition.model_dump(),
            **self.meta,
        }
        if fmt == "parquet":
            table_path = write_parquet(_named(stem, ".parquet"), self.to_dataframe())
        elif fmt == "csv":
            table_path = _named(stem, ".csv")
            from railsusp.store import atomic_write_bytes

            table = self.to_dataframe()
            # the forces to 6 significant digits; the time in full (at 6, a 2400 Hz
            # section's 100.0004 s read back as 100, the same time twice)
            table["time_s"] = np.char.mod("%.12g", table["time_s"].to_numpy())
            atomic_write_bytes(table_path, table.to_csv(index=False, float_format="%.6g").encode())
        else:
            raise ValueError(f"format {fmt!r}: accepted csv or parquet")
        write_json(_named(stem, ".json"), meta)
        return table_path

    def head(self, seconds: float) -> Recording:
        """The recording's first ``seconds`` (the whole of it if shorter), its condition
        recording as long on the same track (measured geometry and its stated accuracy
        kept): what NSGA-II's preview generations compare
        (:attr:`~railsusp.estimate.config.NSGAConfig.preview_generations`)."""
        n = round(seconds * self.sampling_rate)  # the table's rate may not be the condition's
        if seconds >= self.condition.duration_s or n >= self.time.size:
            return self
        cond = self.condition.with_duration(round(n / self.sampling_rate, 6))
        return Recording(
            self.time[:n].copy(),
            {w: v[:n].copy() for w, v in self.Y.items()},
            {w: v[:n].copy() for w, v in self.Q.items()},
            cond,
            dict(self.meta),
        )

    def resampled(self, rate_hz: float) -> Recording:
        """The recording at another rate: zero-phase anti-alias filter, polyphase resampling
        (scipy ``resample_poly``) on a uniform time base."""
        from fractions import Fraction

        src = self.sampling_rate
        lo, hi = src / 1000.0, src * 1000.0  # the ratio's denominator is at most 1000
        if not (is_real(rate_hz) and lo <= rate_hz <= hi):
            raise RailsuspInputError(
                f"rate_hz = {rate_hz!r}: accepted a number from {lo:g} to {hi:g} Hz (a "
                f"thousandth to a thousand times this recording's {src:g} Hz)"
            )
        frac = Fraction(float(rate_hz) / src).limit_denominator(1000)
        up, down = frac.numerator, frac.denominator

        def conv(x):
            return resample_poly(x, up, down, padtype="line")

        n = len(conv(self.time * 0.0))
        t = self.time[0] + np.arange(n) / rate_hz
        return Recording(
            t,
            {w: conv(v) for w, v in self.Y.items()},
            {w: conv(v) for w, v in self.Q.items()},
            self.condition,
            {**self.meta, "resampled_from_hz": src},
        )


def _named(stem: Path, suffix: str) -> Path:
    """``stem`` with ``suffix`` appended (``Path.with_suffix`` would replace a dotted
    name's last part: ``km0.5`` -> ``km0.csv``)."""
    return stem.with_name(stem.name + suffix)
