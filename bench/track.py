"""Track-input benchmark: synthesis time and PSD accuracy per FRA class.

Prints a table and writes JSON (default bench/results/track.json). Accuracy: RMS of a long
realisation against the PSD band integral, and the worst 1/3-octave Welch-PSD ratio over
1.5-80 m wavelengths. Speed: seconds to synthesise the section of one 20 s / 60 km/h run for
1, 16 and 256 seeds.
"""

from __future__ import annotations

import argparse
import itertools
import platform
import time

import numpy as np
from scipy.signal import welch

from railsusp.conditions import get_condition
from railsusp.store import write_json
from railsusp.vehicle.track import COMPONENTS, band_rms, fra_psd, synthesise


def psd_worst_ratio(x: np.ndarray, dx: float, component: str, track_class: int) -> float:
    f, p = welch(x, fs=1 / dx, nperseg=8192)
    omega, s = 2 * np.pi * f, p / (2 * np.pi)
    edges = 2 * np.pi / 80.0 * 2 ** (np.arange(0, 20) / 3)
    edges = edges[edges <= 2 * np.pi / 1.5]
    worst = 0.0
    for lo, hi in itertools.pairwise(edges):
        sel = (omega >= lo) & (omega < hi)
        r = s[sel].mean() / fra_psd(component, omega[sel], track_class).mean()
        worst = max(worst, abs(r - 1))
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default="bench/results/track.json")
    ap.add_argument("--length", type=float, default=40_000.0, help="accuracy section, m")
    args = ap.parse_args()

    rows = []
    for cls in range(1, 7):
        irr = synthesise(args.length, cls, 0)
        dx = irr.s[1] - irr.s[0]
        for comp in COMPONENTS:
            x = irr.component(comp)[0]
            ref = band_rms(comp, cls, irr.wavelength_min, irr.wavelength_max)
            rows.append(
                {
                    "class": cls,
                    "component": comp,
                    "rms_mm": float(x.std() * 1e3),
                    "expected_mm": ref * 1e3,
                    "rms_error": float(x.std() / ref - 1),
                    "psd_worst_third_octave_error": psd_worst_ratio(x, dx, comp, cls),
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
        f"{'PSD worst':>9}"
    )
    for r in rows:
        print(
            f"{r['class']:>5} {r['component']:>11} {r['rms_mm']:8.2f} {r['expected_mm']:9.2f} "
            f"{r['rms_error']:8.1%} {r['psd_worst_third_octave_error']:9.1%}"
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
    main()
