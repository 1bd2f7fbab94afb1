"""The true track geometry given a measured one: its conditional mean and draws about it.

A track-recording car's geometry is the true geometry plus an error of known accuracy
(:func:`~railsusp.vehicle.track_geometry.with_measurement_error`: white within the measured
band, ``accuracy`` RMS per component). A model that runs on the measured geometry as if it
were true is excited by the error as well: at short wavelengths, where the error's power
approaches the geometry's, the measured track is rougher than the true one. In a wagon with
friction wedges that extra roughness is not a zero-mean disturbance the comparison averages
out (it outlasts the comparison's low-pass band: short-wavelength excitation presumably
keeps the wedges slipping and so changes their damping at all frequencies), and a fit of
the forces pays it back with a wedge friction (X18) 8-14 % of its range too high and a
primary lateral stiffness (X14) up to 15 % too low (the simulator's own fit on 0.5 mm
geometry; in two sets the same over eight fresh draws of the error, so a bias and not a
scatter; taking the excess power alone out of the measured geometry removes X18's:
bench/README.md, "Expected forces on a track measured with error"). SIMEX's linear
extrapolation takes most of X18's off and leaves X14's.

What a model on an uncertain track should predict is the expected force given the
measurement, the mean over the true geometries the measurement allows (a Berkson
error-in-variables model after regression calibration: Carroll, Ruppert, Stefanski &
Crainiceanu, *Measurement Error in Nonlinear Models*, 2nd ed., 2006, ch. 4). For a
stationary Gaussian geometry (what the FRA and Chinese track spectra describe) and the error
above, that conditional distribution is Gaussian, independent per wavenumber k:

    mean  = W(k) G_m(k),   W = S_g / (S_g + S_e)       (Wiener filter, Wiener 1949)
    PSD of the true geometry about it:  W(k) S_e(k)

with S_e the error's PSD (:func:`measurement_error_psd`) and S_g the geometry's, estimated
as the measured PSD less S_e (Welch over 128 m segments, as
:func:`~railsusp.vehicle.track_geometry.accurate_wavelength_m` does). Each draw
(:meth:`GeometryPosterior.draws`) has the true geometry's spectrum, not the measured one's,
and the draws' mean response is what the measured forces are compared with
(:class:`railsusp.estimate.expected_forces.ExpectedForces`). Each component is taken alone
(their cross-spectra, e.g. vertical with cross-level, are left out: the synthetic tracks'
components are independent), and the grid is taken as uniform (its median spacing), as
:func:`~railsusp.vehicle.track_geometry.with_measurement_error` takes it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from railsusp.vehicle.track import COMPONENTS, Irregularities
from railsusp.vehicle.track_geometry import measurement_error_filter, welch_segment

#: reflected padding at each end before the Wiener filter, m: longer than its impulse
#: response, so the record's ends are filtered as its middle is (no circular wrap)
PAD_M = 64.0


def measurement_error_psd(
    k: np.ndarray, accuracy_m: float, wavelength_min_m: float, dx: float
) -> np.ndarray:
    """One-sided PSD (m² per 1/m) at wavenumbers ``k`` (1/m) of the measurement error that
    :func:`~railsusp.vehicle.track_geometry.with_measurement_error` adds on a grid of spacing
    ``dx``: white noise through a 4th-order Butterworth low-pass at 1 / ``wavelength_min_m``
    applied forwards and backwards (power gain |H|⁴), scaled to ``accuracy_m`` RMS (its
    integral over 0 .. 1/(2 dx) is accuracy²)."""
    from scipy.signal import sosfreqz

    if not accuracy_m > 0.0 or not wavelength_min_m > 0.0 or not dx > 0.0:
        raise ValueError(
            f"accuracy_m {accuracy_m:g}, wavelength_min_m {wavelength_min_m:g}, dx {dx:g}: "
            "all must be positive"
        )
    fs = 1.0 / dx
    sos = measurement_error_filter(wavelength_min_m, dx)
    grid = np.linspace(0.0, fs / 2.0, 4097)
    power = np.abs(sosfreqz(sos, worN=grid, fs=fs)[1]) ** 4
    norm = accuracy_m**2 / np.trapezoid(power, grid)
    return norm * np.abs(sosfreqz(sos, worN=np.asarray(k, float), fs=fs)[1]) ** 4


@dataclass(frozen=True, eq=False)
class GeometryPosterior:
    """The true geometry given a measured one (:func:`geometry_posterior`): ``mean`` (the
    Wiener-filtered measurement), and per component ``wiener`` the filter W(k) and
    ``spread_psd`` W(k) S_e(k), the true geometry's PSD about the mean, at the wavenumbers
    ``k`` of the record's real FFT."""

    measured: Irregularities
    mean: Irregularities
    k: np.ndarray
    wiener: dict[str, np.ndarray]
    spread_psd: dict[str, np.ndarray]

    def draws(
        self, n: int, rng: np.random.Generator, antithetic: bool = False
    ) -> list[Irregularities]:
        """``n`` geometries drawn from the true geometry's conditional distribution: the mean
        plus Gaussian noise of PSD :attr:`spread_psd` per component (white noise shaped in
        the frequency domain; a unit-variance white sequence has the one-sided PSD 2 dx).

        ``antithetic``: in pairs, the mean plus and minus the same noise (an odd ``n`` ends
        with one unpaired draw). A mean over such pairs has no Monte-Carlo error from the
        part of a response that is linear in the geometry, only from its curvature
        (antithetic variates: Hammersley & Morton, Proc. Camb. Phil. Soc. 52, 1956)."""
        if n < 0:
            raise ValueError(f"draws {n}: accepted 0 or more")
        s = self.mean.s
        dx = float(np.median(np.diff(s)))
        noise: list[dict[str, np.ndarray]] = []
        while len(noise) < n:
            u = {}
            for c in COMPONENTS:
                shape = np.sqrt(self.spread_psd[c] / (2.0 * dx))
                u[c] = np.fft.irfft(np.fft.rfft(rng.standard_normal(s.size)) * shape, s.size)
            noise.append(u)
            if antithetic and len(noise) < n:
                noise.append({c: -v for c, v in u.items()})
        return [
            replace(self.mean, **{c: self.mean.component(c)[:1] + u[c] for c in COMPONENTS})
            for u in noise
        ]


def geometry_posterior(
    irr: Irregularities, accuracy_m: float, wavelength_min_m: float
) -> GeometryPosterior:
    """The conditional distribution of the true geometry given ``irr`` (its first
    realisation), measured to ``accuracy_m`` RMS per component down to ``wavelength_min_m``
    (the module's docstring: Wiener mean, spread W S_e). The geometry's PSD is the measured
    one's Welch estimate less the error's, so W = 1 - S_e / S_m clipped to [0, 1]: 1 where
    the geometry dominates, 0 where the measurement is error alone. The filter runs on the
    record padded by reflection (:data:`PAD_M`) at each end."""
    from scipy.signal import welch

    s = irr.s
    n = s.size
    dx = float(np.median(np.diff(s)))
    pad = min(round(PAD_M / dx), n - 1)
    k = np.fft.rfftfreq(n, dx)
    k_pad = np.fft.rfftfreq(n + 2 * pad, dx)
    nperseg = welch_segment(n, dx)
    error_pad = measurement_error_psd(k_pad, accuracy_m, wavelength_min_m, dx)
    error = measurement_error_psd(k, accuracy_m, wavelength_min_m, dx)
    mean, wiener, spread = {}, {}, {}
    for c in COMPONENTS:
        x = irr.component(c)[0]
        measured_psd = welch(x, 1.0 / dx, nperseg=nperseg)
        padded = np.pad(x, pad, mode="reflect")
        w_pad = _wiener(measured_psd, k_pad, error_pad)
        mean[c] = np.fft.irfft(np.fft.rfft(padded) * w_pad, padded.size)[pad : pad + n][None]
        wiener[c] = _wiener(measured_psd, k, error)
        spread[c] = wiener[c] * error
    return GeometryPosterior(
        measured=irr, mean=replace(irr, **mean), k=k, wiener=wiener, spread_psd=spread
    )


def _wiener(
    measured_psd: tuple[np.ndarray, np.ndarray], k: np.ndarray, error_psd: np.ndarray
) -> np.ndarray:
    """W(k) = 1 - S_e / S_m clipped to [0, 1], the measured PSD (Welch: wavenumbers, PSD)
    interpolated to ``k``."""
    s_m = np.interp(k, *measured_psd)
    return np.clip(1.0 - error_psd / np.maximum(s_m, np.finfo(float).tiny), 0.0, 1.0)
