"""Running stability on straight track: the response to a lateral kink and the critical speed.

The nonlinear critical speed is the lowest speed at which a lateral oscillation of the
wheelsets, once started, no longer dies out. It is found as a vehicle-dynamics engineer
does in a simulation tool: the wagon runs on ideal (irregularity-free) straight track, meets
one lateral misalignment (a "kink": a one-wave alignment bump, both rails together) and
then runs on; at a stable speed the oscillation it starts decays, at an unstable one it
settles into a limit cycle (hunting) or grows. The kink enters as measured track geometry
(:func:`write_kink_geometry`), so no model code is involved beyond the ordinary simulator.

The observed quantity is the leading wheelset's track-shifting force H = ΣY (the force
EN 14363 judges running stability by), its oscillation measured as the standard deviation
over a window (the mean is a steady offset that Coulomb friction may lock in).
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle.setup import SolverSettings, axle_spread
from railsusp.vehicle.simulate import simulate
from railsusp.vehicle.track_grid import FADE_IN_M
from railsusp.vehicle.wagon import WagonData

#: the kink: a one-wave (1 - cos) lateral alignment bump, both rails, m
KINK_AMPLITUDE_M = 0.010
KINK_LENGTH_M = 10.0
#: where the leading wheelset meets the kink, m after the start
KINK_AT_M = 5.0
#: window over which the oscillation is measured at the end of the record, s
WINDOW_S = 5.0
#: the oscillation decays if its RMS in the last window is below this share of the window
#: before, or below FLOOR_N (friction has stopped it)
DECAY_RATIO = 0.95
FLOOR_N = 20.0
#: the shortest record the measurement needs: 5 s for the kink to pass, then the two windows
MIN_DURATION_S = 2 * WINDOW_S + 5.0


def write_kink_geometry(
    path: str | Path,
    record_length_m: float,
    spread_m: float,
    amplitude_m: float = KINK_AMPLITUDE_M,
    length_m: float = KINK_LENGTH_M,
    at_m: float = KINK_AT_M,
) -> Path:
    """Track-geometry file (docs/data-format.md) of straight ideal track with one lateral
    alignment bump a/2 (1 - cos(2 pi u)), u = (s - at) / length in 0..1, covering the
    wagon's axles over the record."""
    s = np.arange(-(spread_m + 15.0), record_length_m + 10.0, 0.25)
    u = np.clip((s - at_m) / length_m, 0.0, 1.0)
    zero = np.zeros_like(s)
    table = pd.DataFrame(
        {
            "distance_m": s,
            "vertical_mm": zero,
            "alignment_mm": 0.5 * amplitude_m * (1.0 - np.cos(2 * np.pi * u)) * 1e3,
            "crosslevel_mm": zero,
            "gauge_mm": zero,
        }
    )
    path = Path(path)
    table.to_csv(path, index=False, float_format="%.6f")
    return path


@dataclass(frozen=True)
class KinkResponse:
    """Oscillation of the leading wheelset's ΣY after the kink at one speed (forces in N)."""

    speed_kmh: float
    ok: bool  # the run completed (no derailment or divergence)
    rms_before: float  # ΣY standard deviation over the window before the last one
    rms_last: float  # ... over the last window
    amplitude_last: float  # largest |ΣY - mean| in the last window (limit-cycle amplitude)
    frequency_hz: float  # from the zero crossings in the last window (NaN if too few)

    @property
    def ratio(self) -> float:
        return self.rms_last / self.rms_before if self.rms_before > 0 else 0.0

    @property
    def decays(self) -> bool:
        """True when the oscillation dies out: the run completed and the last window's RMS
        is below DECAY_RATIO of the one before, or below FLOOR_N."""
        return self.ok and (self.rms_last < FLOOR_N or self.ratio < DECAY_RATIO)

    def to_dict(self) -> dict:
        return {**asdict(self), "ratio": self.ratio, "decays": self.decays}


def kink_condition(
    wagon: WagonData, speed_kmh: float, duration_s: float, geometry: str | Path
) -> WorkingCondition:
    """The condition of a kink run: ideal straight track with the kink's geometry file, a
    100 Hz record, and a lead-in that holds the simulator's fade-in from rest (without one
    the 30 m fade took the 10 mm kink 5 m into the record down to 2.8 mm: stop 59's
    audit)."""
    return WorkingCondition(
        name="kink",
        speed_kmh=speed_kmh,
        duration_s=duration_s,
        n_steps=round(duration_s * 100),
        lead_in_m=axle_spread(wagon) + FADE_IN_M,
        irregularity_class=None,
        track_geometry=str(geometry),
    )


def kink_response(
    wagon: WagonData,
    speed_kmh: float,
    duration_s: float = 30.0,
    amplitude_m: float = KINK_AMPLITUDE_M,
    params: ParameterSet | None = None,
    settings: SolverSettings | None = None,
) -> KinkResponse:
    """Run the wagon over the kink at ``speed_kmh`` and measure the leading wheelset's ΣY
    oscillation in the last two windows of :data:`WINDOW_S`. A record shorter than
    :data:`MIN_DURATION_S` is refused (:class:`~railsusp.errors.RailsuspInputError`)."""
    if duration_s < MIN_DURATION_S:
        raise RailsuspInputError(
            f"duration_s = {duration_s:g}: at least {MIN_DURATION_S:g} s needed (the kink's "
            f"passage, then two windows of {WINDOW_S:g} s)"
        )
    v = speed_kmh / 3.6
    with tempfile.TemporaryDirectory() as tmp:
        geo = write_kink_geometry(
            Path(tmp) / "kink.csv", v * duration_s, axle_spread(wagon), amplitude_m
        )
        cond = kink_condition(wagon, speed_kmh, duration_s, geo)
        r = simulate(params, cond, wagon=wagon, settings=settings)
    if not r.ok[0]:
        nan = math.nan
        return KinkResponse(speed_kmh, False, nan, nan, nan, nan)
    h, t = r.H[0, 0], r.time
    last = t >= duration_s - WINDOW_S
    before = (t >= duration_s - 2 * WINDOW_S) & ~last
    osc = h[last] - h[last].mean()
    crossings = np.count_nonzero(np.diff(np.signbit(osc)))
    freq = crossings / (2 * WINDOW_S) if crossings >= 4 else math.nan
    return KinkResponse(
        speed_kmh=speed_kmh,
        ok=True,
        rms_before=float(h[before].std()),
        rms_last=float(osc.std()),
        amplitude_last=float(np.abs(osc).max()),
        frequency_hz=freq,
    )
