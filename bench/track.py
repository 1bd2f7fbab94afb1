"""Track-input benchmark: synthesis time and PSD accuracy per FRA class.

Prints a table and writes JSON (default bench/results/track.json). Accuracy: RMS of a long
realisation against the PSD band integral, and the worst 1/3-octave Welch-PSD ratio over
1.5-80 m wavelengths (with how many bands held a spectral line to score). Speed: seconds to
synthesise the section of one 20 s / 60 km/h run for 1, 16 and 256 seeds.

Gauge is scored as synthesised, that is after :func:`railsusp.vehicle.track.limit_gauge`
keeps it within the class's safety limits (since commit 4aab351): where the limit reshapes
many samples (the rough classes 1-3) its RMS and spectrum fall below the unlimited FRA
spectrum's by design. The share of gauge samples the limit reshaped is printed beside it.
``--length`` must hold one Welch segment (WELCH_SEGMENT samples, 1024 m): a shorter section
has 1/3-octave bands without a spectral line and an RMS its longest wavelengths dominate;
it is at most 1e6 m (MAX_LENGTH_M; 40 km by default).
"""

from __future__ import annotations

import itertools
import platform
import time

import numpy as np
from scipy.signal import welch

from _cli import parser, positive_float, run_main
from railsusp.conditions import get_condition
from railsusp.store import write_json
from railsusp.vehicle.track import (
    COMPONENTS,
    GAUGE_KNEE,
    GAUGE_LIMITS,
    band_rms,
    fra_psd,
    synthesise,
)

#: samples of a Welch segment; the accuracy section must hold one
WELCH_SEGMENT = 8192
#: the synthesis's default sampling interval (shortest wavelength 1 m / 8), m
DX = 1.0 / 8.0
#: the longest accuracy section, m: 8e6 samples of each component, about 2.5 GB while it is
#: synthesised (the default is 40 km; 1e12 m ended in NumPy's memory error)
MAX_LENGTH_M = 1e6


def third_octave_edges() -> np.ndarray:
    """Edges (rad/m) of the 1/3-octave bands scored, from 80 m down to 1.5 m wavelength."""
    edges = 2 * np.pi / 80.0 * 2 ** (np.arange(0, 20) / 3)
    return edges[edges <= 2 * np.pi / 1.5]


def psd_worst_ratio(
    x: np.ndarray, dx: float, component: str, track_class: int
) -> tuple[float, int]:
    """The worst |Welch PSD / FRA PSD - 1| over the 1/3-octave bands, and how many bands
    were scored (held a spectral line): NaN if one held none, not a worst over fewer bands
    than the table says."""
    f, p = welch(x, fs=1 / dx, nperseg=min(WELCH_SEGMENT, x.size))
    omega, s = 2 * np.pi * f, p / (2 * np.pi)
    worst, scored = 0.0, 0
    for lo, hi in itertools.pairwise(third_octave_edges()):
        sel = (omega >= lo) & (omega < hi)
        if not sel.any():
            worst = np.nan
            continue
        r = s[sel].mean() / fra_psd(component, omega[sel], track_class).mean()
        worst = max(worst, abs(r - 1))
        scored += 1
    return float(worst), scored


def limited_share(gauge: np.ndarray, track_class: int) -> float:
    """Share of the gauge samples that :func:`~railsusp.vehicle.track.limit_gauge` reshaped
    (beyond ``GAUGE_KNEE`` of either limit; the limit keeps them there, nearer the limit)."""
    beyond = np.zeros(gauge.shape, bool)
    for limit in GAUGE_LIMITS[track_class]:
        beyond |= (gauge - GAUGE_KNEE * limit) / limit > 0.0
    return float(beyond.mean())


def main() -> None:
    ap = parser(__doc__, whole=True)
    ap.add_argument("--out", default="bench/results/track.json")
    ap.add_argument(
        "--length",
        type=positive_float,
        default=40_000.0,
        help=f"accuracy section, m ({WELCH_SEGMENT * DX:g} to {MAX_LENGTH_M:g})",
    )
    args = ap.parse_args()
    if args.length < WELCH_SEGMENT * DX:
        ap.error(
            f"--length {args.length:g}: accepted {WELCH_SEGMENT * DX:g} m or more (one Welch "
            f"segment of {WELCH_SEGMENT} samples, which every 1/3-octave band needs)"
        )
    if args.length > MAX_LENGTH_M:
        ap.error(
            f"--length {args.length:g}: accepted {WELCH_SEGMENT * DX:g} to {MAX_LENGTH_M:g} m "
            "(the synthesis of 1e6 m takes about 2.5 GB of memory; a longer one runs out of it)"
        )
    bands = len(third_octave_edges()) - 1

    rows = []
    for cls in range(1, 7):
        irr = synthesise(args.length, cls, 0)
        dx = irr.s[1] - irr.s[0]
        for comp in COMPONENTS:
            x = irr.component(comp)[0]
            ref = band_rms(comp, cls, irr.wavelength_min, irr.wavelength_max)
            worst, scored = psd_worst_ratio(x, dx, comp, cls)
            rows.append(
                {
                    "class": cls,
                    "component": comp,
                    "rms_mm": float(x.std() * 1e3),
                    "expected_mm": ref * 1e3,
                    "rms_error": float(x.std() / ref - 1),
                    "psd_worst_third_octave_error": worst,
                    "psd_bands_scored": scored,
                    "psd_bands": bands,
                    "limited_share": limited_share(x, cls) if comp == "gauge" else None,
                }
            )
    section = get_condition("straight").section_length_m + 40.0
    timing = []
    for n in (1, 16, 256):
        t0 = time.perf_counter()
        synthesise(section, 5, list(range(n)))
        timing.append({"seeds": n, "seconds": time.perf_counter() - t0})

    print(
        f"{'class':>5} {'component':>11} {'RMS mm':>8} {'expected':>9} {'RMS err':>8} "
        f"{'PSD worst':>9} {'bands':>5} {'limited':>8}"
    )
    for r in rows:
        limited = "" if r["limited_share"] is None else f"{r['limited_share']:8.2%}"
        print(
            f"{r['class']:>5} {r['component']:>11} {r['rms_mm']:8.2f} {r['expected_mm']:9.2f} "
            f"{r['rms_error']:8.1%} {r['psd_worst_third_octave_error']:9.1%} "
            f"{r['psd_bands_scored']:>2}/{r['psd_bands']:<2} {limited:>8}"
        )
    print(
        "(PSD worst over the 1/3-octave bands scored, 1.5-80 m; gauge as synthesised, after "
        "the class's safety limits: 'limited' is the share of its samples they reshaped)"
    )
    print(f"\nsynthesis of one {section:.0f} m section (all four components):")
    for t in timing:
        print(f"  {t['seeds']:>4} seeds: {t['seconds'] * 1e3:8.1f} ms")
    payload = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": platform.platform(),
        "length_m": args.length,
        "accuracy": rows,
        "timing": timing,
    }
    out = write_json(args.out, payload)
    print(f"wrote {out}")


if __name__ == "__main__":
    run_main(main)
