"""Time-aligned comparison of predicted force series with a recording on measured track.

A model's series pass through the recording's documented filter and are limited to the band
in which the recording's track geometry is accurate; :func:`aligned_error` is then the RMS of
the sample-by-sample difference over the standard deviation of the measured series. With
``gains`` each channel's prediction is first scaled by its least-squares gain within the
instrument's calibration tolerance (:func:`channel_gains`): the channels' gain errors are then
nuisance parameters profiled out of the comparison, not misfit the parameters must absorb.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np

from railsusp.errors import RailsuspInputError
from railsusp.measured import Recording, bandwidth_filter
from railsusp.vehicle.track_geometry import (
    CHANNEL_COMPONENTS,
    accurate_wavelength_m,
    read_track_geometry,
)


def measurement_filter(series: np.ndarray, rec: Recording) -> np.ndarray:
    """Predicted series (n, T, channels) passed through the recording's documented filter
    (``filter_bandwidth_hz`` in its metadata), so that a model is compared with what the
    instrument could see; unchanged when the recording gives no bandwidth. Undefined leading
    steps (window surrogates) stay undefined, and so does the whole of a set whose series
    breaks off (a simulation flagged as failed)."""
    bw = rec.meta.get("filter_bandwidth_hz")
    if not bw:
        return series
    return _lowpass_defined(series, rec.sampling_rate, np.full(series.shape[-1], float(bw)))


def _leading_gaps(series: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Of series (n, T, channels): each set's first step with every channel defined, and
    whether the set is defined from there to its end (undefined steps only lead, as a window
    surrogate's first steps or a washout do; a set that breaks off is not defined)."""
    ok = np.isfinite(series).all(axis=-1)  # (n, T)
    first = np.argmax(ok, axis=1)
    after_first = np.arange(ok.shape[1])[None, :] >= first[:, None]
    return first, ok.any(axis=1) & np.all(ok | ~after_first, axis=1)


def _lowpass_defined(series: np.ndarray, fs: float, bandwidths: np.ndarray) -> np.ndarray:
    """Series (n, T, channels) low-passed along time, channel c at ``bandwidths[c]`` Hz
    (:func:`~railsusp.measured.bandwidth_filter`); leading undefined steps stay undefined,
    and a set whose series breaks off becomes wholly undefined.

    Sets defined from the same step on (a window surrogate's are all defined from its
    window's end) are filtered together in one call: the filter runs along time for each
    set and channel independently, so this gives what filtering set by set gives, at a
    fraction of the cost (the objective filters every set of every generation)."""

    def lowpass(x: np.ndarray) -> np.ndarray:  # (n, T, channels)
        out = np.empty_like(x)
        for c, bw in enumerate(bandwidths):
            out[..., c] = bandwidth_filter(x[..., c], fs, float(bw), axis=-1)
        return out

    if np.isfinite(series).all():
        return lowpass(series)
    out = np.full_like(series, np.nan)
    first, defined = _leading_gaps(series)
    usable = defined & (series.shape[1] - first > 30)
    for start in np.unique(first[usable]):
        sets = np.flatnonzero(usable & (first == start))
        out[sets, start:] = lowpass(series[sets, start:])
    return out


def comparison_band_hz(rec: Recording) -> np.ndarray | None:
    """(2,) upper frequency (Hz) of the time-aligned comparison of lateral and vertical
    force: the speed over the shortest wavelength down to which the recording's track
    geometry is accurate (:func:`~railsusp.vehicle.track_geometry.accurate_wavelength_m`, from the
    condition's ``track_accuracy_mm``; the components that drive each channel). None where
    the geometry is exact (accuracy 0): the whole instrument band is compared.

    Below that wavelength the geometry error outweighs the geometry, and a fit there would
    absorb the error into the parameters (an errors-in-variables bias)."""
    cond = rec.condition
    if cond.track_geometry is None or not cond.track_accuracy_mm:
        return None
    path = Path(cond.track_geometry)
    return np.array(
        _comparison_band(
            str(path.resolve()),
            path.stat().st_mtime_ns,
            cond.track_accuracy_mm,
            cond.wavelength_min_m,
            cond.speed,
        )
    )


@lru_cache(maxsize=32)
def _comparison_band(
    path: str, _mtime_ns: int, accuracy_mm: float, wavelength_min_m: float, speed: float
) -> tuple[float, float]:
    """:func:`comparison_band_hz` of one geometry file, cached: every time-aligned
    comparison asks for it, and the geometry's PSD need not be estimated each time."""
    lam = accurate_wavelength_m(read_track_geometry(path), accuracy_mm * 1e-3, wavelength_min_m)
    y, q = (speed / max(lam[c] for c in CHANNEL_COMPONENTS[ch]) for ch in ("Y", "Q"))
    return (y, q)


def comparison_filter(series: np.ndarray, rec: Recording) -> np.ndarray:
    """Predicted series (n, T, 2) as the time-aligned comparison sees them: through the
    recording's filter (:func:`measurement_filter`) and limited to its comparison band
    (:func:`comparison_band_hz`)."""
    series = measurement_filter(series, rec)
    band = comparison_band_hz(rec)
    return series if band is None else _lowpass_defined(series, rec.sampling_rate, band)


def compared_measurement(rec: Recording) -> np.ndarray:
    """(T, 2) the recording's lateral and vertical force limited to its comparison band."""
    meas = rec.forces()
    band = comparison_band_hz(rec)
    return meas if band is None else _lowpass_defined(meas[None], rec.sampling_rate, band)[0]


def comparison_samples(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """Per channel (Y, Q), the samples of a recording the time-aligned comparison uses: all
    of them without a comparison band; with one, four per period of the band's upper
    frequency (residuals closer than that are not independent), leaving out one period at
    each end, where the zero-phase filter's start and end transients lie."""
    n = rec.forces().shape[0]
    band = comparison_band_hz(rec)
    if band is None:
        return (np.arange(n), np.arange(n))
    fs = rec.sampling_rate
    edge = min(int(np.ceil(fs / band.min())), n // 4)
    y, q = (np.arange(edge, n - edge, max(1, int(fs / (4.0 * f)))) for f in band)
    return (y, q)


def check_time_base(recordings: Sequence[Recording], use: str) -> None:
    """Refuse, in one line naming the recording, its ``condition.n_steps`` and its table's
    rows and rate, a recording whose condition samples its record otherwise than its table
    does, where ``use`` (the time-aligned comparison, the refinement, validate's time-aligned
    errors, align-track) compares a simulation of the condition with the table sample by
    sample. The reader accepts such a recording (a condition may simulate a 2400 Hz table's
    record at 50 Hz: record statistics are each taken at their own rate), so the refusal is
    here, where the same time base is needed, and before any simulation, not after NSGA-II
    (or all of validate's simulations) as the comparison's own check came."""
    for rec in recordings:
        cond = rec.condition
        rows = int(rec.time.size)
        if cond.n_steps == rows:
            continue
        raise RailsuspInputError(
            f"recording {cond.name!r}: condition.n_steps {cond.n_steps} samples its "
            f"{cond.duration_s:g} s at {1.0 / cond.sample_interval:.6g} Hz, its table has {rows} "
            f"rows at {rec.sampling_rate:.6g} Hz; {use} compares the simulated series with the "
            f"table sample by sample: accepted condition.n_steps {rows} in its sidecar (the "
            "table's rows), or the table resampled to the condition's rate"
        )


#: time-aligned error given to a prediction that is undefined (a failed simulation)
FAILED_ALIGNED_ERROR = 1e3

#: an instrumented wheelset's channel gain (its calibration factor) lies within 1 ± this
GAIN_LIMIT = 0.1


def channel_gains(pred: np.ndarray, meas: np.ndarray) -> np.ndarray:
    """(n,) the gain g of each row of predicted samples ``pred`` (n, S) that minimises
    |g p - m|² against the measured samples ``meas`` (S,) within 1 ± :data:`GAIN_LIMIT`:
    <p, m> / <p, p> clipped to the interval, which is the constrained minimum of this
    one-dimensional convex quadratic. Non-finite predicted samples are left out; a row with
    no signal keeps gain 1.

    A strain-gauge wheelset's calibration factor is known to about 1 % (the synthetic
    recordings draw it with that standard deviation:
    :func:`~railsusp.measured.synthetic.add_sensor_noise`); on the time-aligned forces that
    is 1.2 kN of wheel load, more than most parameters move it. Profiling the gain out of
    each channel's misfit (variable projection: Golub & Pereyra, SIAM J. Numer. Anal. 10,
    1973) is the same least squares as estimating it alongside, as the refinement does, at
    the cost of two dot products."""
    p = np.where(np.isfinite(pred), pred, 0.0)
    pp = np.einsum("ns,ns->n", p, p)
    pm = p @ meas
    g = np.divide(pm, pp, out=np.ones_like(pp), where=pp > 0.0)
    return np.clip(g, 1.0 - GAIN_LIMIT, 1.0 + GAIN_LIMIT)


def aligned_error(pred: np.ndarray, rec: Recording, gains: bool = False) -> np.ndarray:
    """(n, 2) time-aligned mismatch of predicted lateral and vertical series (n, T, 2) with a
    recording made on measured track: RMS of the sample-by-sample difference over the
    standard deviation of the measured series (its dynamic part), after the recording's
    filter is applied to the prediction and both are limited to the band where the track
    geometry is accurate (:func:`comparison_band_hz`); with ``gains`` each set's channel
    scaled by its :func:`channel_gains` first. Zero for a perfect model and
    noise-free data;
    :data:`FAILED_ALIGNED_ERROR` for a set without a defined prediction. An objective that
    compares many predictions with one recording keeps an :class:`AlignedComparison`."""
    return AlignedComparison(rec).error(pred, gains)


class AlignedComparison:
    """:func:`aligned_error` against one recording, its measurement side (the measured
    forces in the comparison band, the samples compared, their scale) computed once: an
    objective compares every generation's predictions with the same recordings."""

    def __init__(self, rec: Recording):
        self.recording = rec
        self.n_samples = rec.forces().shape[0]
        self.measured = compared_measurement(rec)
        self.samples = comparison_samples(rec)
        self.scale = self.measured.std(axis=0)

    def gains(self, pred: np.ndarray) -> np.ndarray:
        """(n, 2) each set's :func:`channel_gains` of the lateral and vertical force: the
        factor by which the recording's channel reads the predicted series (n, T, 2)."""
        self._check(pred)
        return self._gains(comparison_filter(pred, self.recording))

    def _gains(self, compared: np.ndarray) -> np.ndarray:
        return np.stack(
            [
                channel_gains(compared[:, used, c], self.measured[used, c])
                for c, used in enumerate(self.samples)
            ],
            axis=1,
        )

    def _check(self, pred: np.ndarray) -> None:
        if pred.shape[-2] != self.n_samples:
            raise ValueError(
                f"recording {self.recording.condition.name!r} has {self.n_samples} samples, "
                f"the model predicts {pred.shape[-2]}: time-aligned comparison needs the same "
                "time base (the recording's condition.n_steps its table's rows; "
                "check_time_base refuses it before any work)"
            )

    def error(self, pred: np.ndarray, gains: bool = False) -> np.ndarray:
        """(n, 2) :func:`aligned_error` of predicted series (n, T, 2), each set's channel
        scaled by its :func:`channel_gains` first with ``gains``."""
        return self.profiled(pred, gains)[0]

    def profiled(self, pred: np.ndarray, gains: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(:meth:`error`, the (n, 2) gains it scaled each set's channels by: their
        :func:`channel_gains` with ``gains``, else ones)."""
        rec = self.recording
        self._check(pred)
        _, defined = _leading_gaps(pred)
        compared = comparison_filter(pred, rec)
        g = self._gains(compared) if gains else np.ones(compared.shape[::2])
        err = np.empty(compared.shape[::2])
        for c, used in enumerate(self.samples):
            p = compared[:, used, c]
            d = (g[:, c, None] * p if gains else p) - self.measured[used, c]
            sq = np.where(np.isfinite(d), d**2, 0.0).sum(axis=1)
            count = np.isfinite(d).sum(axis=1)
            err[:, c] = np.where(count > 0, np.sqrt(sq / np.maximum(count, 1)), np.inf)
        err /= self.scale
        return np.where(defined[:, None] & np.isfinite(err), err, FAILED_ALIGNED_ERROR), g
