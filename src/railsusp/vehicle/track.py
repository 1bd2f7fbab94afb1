"""Track input: design geometry along the section and random irregularities (FRA/AAR PSDs).

Conventions (track frame): x along the track in the running direction, y to the LEFT, z UP.
Rail irregularities are deviations of each rail from its design position:

* left rail:  z_L = z_v + z_c / 2,  y_L = y_a + g / 2
* right rail: z_R = z_v - z_c / 2,  y_R = y_a - g / 2

with z_v the vertical profile, y_a the alignment, z_c the cross-level (left rail high is +) and
g the gauge deviation (+ is wide gauge), all in metres.

The PSDs are the six-class FRA spectra in the form used in vehicle-track studies (e.g. Garg &
Dukkipati, *Dynamics of Railway Vehicle Systems*, 1984; FRA track classes 1-6):

* S_v = k A_v Ω_c² / (Ω² (Ω² + Ω_c²)),  S_a = k A_a Ω_c² / (Ω² (Ω² + Ω_c²))
* S_c = S_g = 4 k A_v Ω_c² / ((Ω² + Ω_c²)(Ω² + Ω_s²))

with Ω in rad/m, A in cm²·rad/m, S in cm²/(rad/m), one-sided; k = 0.25, Ω_c = 0.8245 rad/m.
Class 5 A_v and the Class 6 row are confirmed in two independent open codes; the other rows
follow the widely reproduced table and are marked unverified in :data:`FRA_CLASSES`.
Synthesised gauge is kept within the class's safety limits (49 CFR 213.53), as on a
maintained track (:func:`limit_gauge`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from railsusp.conditions import CANT_BASE_M, WorkingCondition

#: Shape constant k and cut-off Ω_c (rad/m) of the FRA spectra.
FRA_K = 0.25
FRA_OMEGA_C = 0.8245

#: class -> (A_v, A_a in cm²·rad/m, Ω_s in rad/m). Class 5 (A_v) and Class 6 checked in two
#: codes; the other values are the common literature table (not independently confirmed).
FRA_CLASSES: dict[int, tuple[float, float, float]] = {
    1: (1.2107, 3.3634, 0.6046),
    2: (1.0181, 1.2107, 0.9308),
    3: (0.6816, 0.4128, 0.8520),
    4: (0.5376, 0.3027, 1.1312),
    5: (0.2095, 0.0762, 0.8209),
    6: (0.0339, 0.0339, 0.4380),
}

COMPONENTS: tuple[str, ...] = ("vertical", "alignment", "crosslevel", "gauge")
#: grid steps per shortest wavelength of a synthesised track (its default step)
GRID_STEPS_PER_WAVE = 8

#: class -> (tightest, widest) gauge deviation allowed, m: 49 CFR 213.53(b) (4'8" to
#: 4'10" / 4'9-3/4" / 4'9-1/2") and 213.323 (class 6: 4'9-1/4") against 4'8-1/2" nominal.
GAUGE_LIMITS: dict[int, tuple[float, float]] = {
    1: (-0.0127, 0.0381),
    2: (-0.0127, 0.03175),
    3: (-0.0127, 0.03175),
    4: (-0.0127, 0.0254),
    5: (-0.0127, 0.0254),
    6: (-0.0127, 0.01905),
}
#: share of a gauge limit below which synthesised gauge is left untouched
GAUGE_KNEE = 2.0 / 3.0


def limit_gauge(gauge: np.ndarray, track_class: int) -> np.ndarray:
    """Synthesised gauge deviation (m) kept inside the class's safety limits, as on a
    maintained track: values beyond ``GAUGE_KNEE`` of a limit approach it smoothly
    (tanh, continuous slope), the rest are unchanged. The Gaussian synthesis alone narrows
    Class 5 gauge by 13-18 mm a few times per 3 km, beyond the 12.7 mm that 49 CFR 213.53
    allows, and such spots jammed wheelsets into derailment in long runs."""
    out = np.array(gauge, dtype=float)
    for limit in GAUGE_LIMITS[track_class]:
        knee = GAUGE_KNEE * limit
        span = limit - knee
        beyond = (out - knee) / span > 0.0
        out[beyond] = knee + span * np.tanh((out[beyond] - knee) / span)
    return out


_CM2_TO_M2 = 1.0e-4


def _check_class(track_class: int) -> tuple[float, float, float]:
    if track_class not in FRA_CLASSES:
        raise ValueError(f"irregularity class {track_class!r} not in 1..6 (FRA track classes)")
    return FRA_CLASSES[track_class]


def fra_psd(component: str, omega: np.ndarray, track_class: int = 5) -> np.ndarray:
    """One-sided FRA irregularity PSD, m²/(rad/m), at spatial frequencies ``omega`` (rad/m).

    ``component`` is one of ``vertical``, ``alignment``, ``crosslevel`` (as a rail height
    difference), ``gauge``.
    """
    a_v, a_a, omega_s = _check_class(track_class)
    w2 = np.asarray(omega, dtype=float) ** 2
    oc2 = FRA_OMEGA_C**2
    if component == "vertical":
        s = FRA_K * a_v * oc2 / (w2 * (w2 + oc2))
    elif component == "alignment":
        s = FRA_K * a_a * oc2 / (w2 * (w2 + oc2))
    elif component in ("crosslevel", "gauge"):
        s = 4.0 * FRA_K * a_v * oc2 / ((w2 + oc2) * (w2 + omega_s**2))
    else:
        raise ValueError(f"unknown irregularity component {component!r}; accepted {COMPONENTS}")
    return s * _CM2_TO_M2


def smoothstep(u: np.ndarray) -> np.ndarray:
    """3u² - 2u³ of u clipped to [0, 1]: a ramp from 0 to 1 with zero slope at both ends,
    for fading irregularities in without a jolt."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def band_rms(
    component: str, track_class: int, wavelength_min: float, wavelength_max: float, n: int = 20001
) -> float:
    """Expected RMS (m) of one component over a wavelength band (integral of the PSD)."""
    omega = np.linspace(2 * np.pi / wavelength_max, 2 * np.pi / wavelength_min, n)
    return float(np.sqrt(np.trapezoid(fra_psd(component, omega, track_class), omega)))


@dataclass(frozen=True)
class Irregularities:
    """Rail irregularities sampled on a uniform distance grid, for one or many seeds.

    ``s``: distances (m), shape (n_s,). Component arrays have shape (n_seeds, n_s), in m.
    """

    s: np.ndarray
    vertical: np.ndarray
    alignment: np.ndarray
    crosslevel: np.ndarray
    gauge: np.ndarray
    track_class: int | None
    wavelength_min: float
    wavelength_max: float
    seeds: tuple[int, ...]
    #: the measured-geometry file these came from (None: synthesised)
    source: str | None = None

    @property
    def left_vertical(self) -> np.ndarray:
        """z_L = z_v + z_c/2, m (+ up)."""
        return self.vertical + 0.5 * self.crosslevel

    @property
    def right_vertical(self) -> np.ndarray:
        """z_R = z_v - z_c/2, m (+ up)."""
        return self.vertical - 0.5 * self.crosslevel

    @property
    def left_lateral(self) -> np.ndarray:
        """y_L = y_a + g/2, m (+ to the left)."""
        return self.alignment + 0.5 * self.gauge

    @property
    def right_lateral(self) -> np.ndarray:
        """y_R = y_a - g/2, m (+ to the left)."""
        return self.alignment - 0.5 * self.gauge

    def component(self, name: str) -> np.ndarray:
        """A component array by name (one of COMPONENTS)."""
        if name not in COMPONENTS:
            raise ValueError(f"unknown irregularity component {name!r}; accepted {COMPONENTS}")
        return getattr(self, name)

    def at(self, s: np.ndarray) -> dict[str, np.ndarray]:
        """Rail irregularities interpolated at distances ``s`` (m): keys zL, zR, yL, yR.

        Each value has shape (n_seeds, *s.shape). Outside the grid the values are zero.
        """
        s = np.asarray(s, dtype=float)
        out = {}
        for key, arr in (
            ("zL", self.left_vertical),
            ("zR", self.right_vertical),
            ("yL", self.left_lateral),
            ("yR", self.right_lateral),
        ):
            out[key] = np.stack([np.interp(s, self.s, row, left=0.0, right=0.0) for row in arr])
        return out


def synthesise(
    length: float,
    track_class: int = 5,
    seeds: int | Sequence[int] = 0,
    *,
    wavelength_min: float = 1.0,
    wavelength_max: float = 120.0,
    start: float = 0.0,
    dx: float | None = None,
) -> Irregularities:
    """Synthesise irregularities over ``[start, start + length]`` m for one or many seeds.

    Random-phase harmonic superposition evaluated by inverse FFT (Cooley-Tukey): each
    spectral line Ω_k in the band gets amplitude sqrt(2 S(Ω_k) ΔΩ) and a uniform random phase,
    so the realisation's variance equals the PSD integral over the band. The FFT period is at
    least four times both the section and the longest wavelength, so the profile does not
    repeat within the section. Components are independent; the four phase streams of a seed
    are spawned from ``numpy.random.SeedSequence(seed)``, so a seed gives the same track
    whatever else is asked for in the call. Output grid spacing ``dx`` defaults to
    wavelength_min / :data:`GRID_STEPS_PER_WAVE` (8). The gauge is then kept within the
    class's safety limits (:func:`limit_gauge`).
    """
    _check_class(track_class)
    if not (0 < wavelength_min < wavelength_max):
        raise ValueError(
            f"wavelength band must satisfy 0 < min < max, got {wavelength_min}, {wavelength_max}"
        )
    if length <= 0:
        raise ValueError(f"section length must be positive, got {length} m")
    seed_list = [int(seeds)] if np.isscalar(seeds) else [int(s) for s in seeds]  # type: ignore[arg-type]
    if any(s < 0 for s in seed_list):
        raise ValueError(f"seeds must be non-negative integers, got {seed_list}")
    dx = wavelength_min / GRID_STEPS_PER_WAVE if dx is None else float(dx)
    period = max(4.0 * length, 4.0 * wavelength_max)
    n = 1 << int(np.ceil(np.log2(period / dx)))
    d_omega = 2.0 * np.pi / (n * dx)
    omega = np.arange(n // 2 + 1) * d_omega
    band = (omega >= 2 * np.pi / wavelength_max) & (omega <= 2 * np.pi / wavelength_min)
    n_out = int(np.floor(length / dx + 1e-9)) + 1
    s = start + dx * np.arange(n_out)

    result: dict[str, np.ndarray] = {c: np.empty((len(seed_list), n_out)) for c in COMPONENTS}
    amplitudes = {}
    for comp in COMPONENTS:
        amp = np.zeros_like(omega)
        amp[band] = np.sqrt(2.0 * fra_psd(comp, omega[band], track_class) * d_omega)
        amplitudes[comp] = amp
    for i, seed in enumerate(seed_list):
        streams = np.random.SeedSequence(seed).spawn(len(COMPONENTS))
        for comp, stream in zip(COMPONENTS, streams, strict=True):
            phase = np.random.default_rng(stream).uniform(0.0, 2 * np.pi, omega.size)
            # x(s) = sum_k A_k cos(Ω_k s + φ_k) = Re(sum_k A_k e^{iφ_k} e^{iΩ_k s})
            spec = amplitudes[comp] * np.exp(1j * phase)
            series = np.fft.irfft(spec, n=n) * (n / 2.0)
            # irfft halves the interior lines' weight relative to a sum of cosines: x2 above.
            result[comp][i] = series[:n_out]
        result["gauge"][i] = limit_gauge(result["gauge"][i], track_class)
    return Irregularities(
        s=s,
        **result,
        track_class=track_class,
        wavelength_min=wavelength_min,
        wavelength_max=wavelength_max,
        seeds=tuple(seed_list),
    )


@dataclass(frozen=True)
class TrackLayout:
    """Design geometry of a section: tangent, clothoid spiral, arc, spiral, tangent.

    Curvature and cant vary linearly along the spirals (clothoid with linear cant ramp).
    Distances in m from the section start; negative distances lie on the approach tangent.
    """

    curvature: float = 0.0  # 1/m, + left-hand
    cant: float = 0.0  # m, outer-rail superelevation in the arc
    curve_start: float = 0.0  # m, start of the entry spiral
    entry_spiral: float = 0.0  # m
    arc_length: float = float("inf")  # m
    exit_spiral: float = 0.0  # m
    grade: float = 0.0  # ratio, + up

    @classmethod
    def from_condition(cls, condition: WorkingCondition) -> TrackLayout:
        """The design layout of a working condition."""
        arc = float("inf") if condition.arc_length_m is None else condition.arc_length_m
        return cls(
            curvature=condition.curvature,
            cant=condition.cant,
            curve_start=condition.curve_start_m,
            entry_spiral=condition.entry_spiral_m,
            arc_length=arc,
            exit_spiral=condition.exit_spiral_m,
            grade=condition.grade,
        )

    def transitions(self, pad: float) -> tuple[float, float, float, float]:
        """(from, to) of the entry and of the exit transition, each widened by ``pad`` (m)
        on both sides: outside them curvature and cant are constant, so the track-following
        frame neither accelerates in yaw nor in roll there (an abrupt start or end of the
        arc, a spiral of 0 m, is a transition of no length). No curve, or an arc without
        end: (inf, -inf) for the part that never comes."""
        if self.curvature == 0.0:
            return math.inf, -math.inf, math.inf, -math.inf
        a = self.curve_start
        b = a + self.entry_spiral
        c = b + self.arc_length
        if math.isinf(c):
            return a - pad, b + pad, math.inf, -math.inf
        return a - pad, b + pad, c - pad, c + self.exit_spiral + pad

    def _ramp(self, s: np.ndarray) -> np.ndarray:
        """Fraction 0..1 of full curvature/cant at distance s."""
        s = np.asarray(s, dtype=float)
        a = self.curve_start
        b = a + self.entry_spiral
        c = b + self.arc_length
        d = c + self.exit_spiral
        up = (
            np.clip((s - a) / self.entry_spiral, 0.0, 1.0)
            if self.entry_spiral > 0
            else ((s >= a).astype(float))
        )
        if np.isinf(c):
            down = np.ones_like(s)
        elif self.exit_spiral > 0:
            down = np.clip((d - s) / self.exit_spiral, 0.0, 1.0)
        else:
            down = (s < c).astype(float)
        return up * down

    def curvature_at(self, s: np.ndarray) -> np.ndarray:
        """Signed horizontal curvature, 1/m."""
        return self.curvature * self._ramp(s)

    def cant_at(self, s: np.ndarray) -> np.ndarray:
        """Signed cant, m: left-rail height minus right-rail height (as cross-level).

        The outer rail is raised, so a left-hand curve (curvature > 0) has negative cant.
        """
        sign = -1.0 if self.curvature > 0 else 1.0
        return sign * self.cant * self._ramp(s)

    def cant_angle_at(self, s: np.ndarray) -> np.ndarray:
        """Track roll angle about +x, rad (right-hand rule: + lifts the left rail)."""
        return np.arcsin(self.cant_at(s) / CANT_BASE_M)

    def grade_at(self, s: np.ndarray) -> np.ndarray:
        """Grade (ratio, + up) at distance s; constant along the section."""
        return np.full(np.shape(s), self.grade, dtype=float)
