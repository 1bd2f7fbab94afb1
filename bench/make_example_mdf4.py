"""Make the example recording shipped with railsusp (src/railsusp/data/example_run.mf4): a
run of the C80 wagon along a stretch of line, as an instrumented-wheelset system would
record it in ASAM MDF4, simulated with hidden true parameters.

    PYTHONPATH=src python bench/make_example_mdf4.py [--out src/railsusp/data]

Five sections of one working condition each (tangent at 65 km/h, a left-hand 600 m curve
at 55 km/h, a right-hand 350 m curve at 45 km/h, a 12 permille up-grade at 40 km/h, tangent
at 70 km/h), 30 s each, joined by 12 s transitions in which the speed, curvature and grade
channels ramp from one section to the next. Each section is simulated at its constant
speed on a track realisation other than the design track (the unknown real track), with
instrumented-wheelset errors (1 % gain, 15 Hz bandwidth, 3 % noise). The transitions'
forces are a tangent simulation at their mean speed: they are no working condition, and
``railsusp sections`` leaves them out.

Channels as a measurement system writes them, at their own rates: wheel forces of wheelset
1 (``WS1_Y_R`` and ``WS1_Y_L`` in kN, ``WS1_Q_R`` and ``WS1_Q_L`` in N) at 200 Hz; train
speed (km/h), odometer position (m), track curvature (1/km), cant (mm) and grade
(permille) from the train's line database at 10 Hz; a bogie lateral acceleration
(``acc_bogie_y_g``, g) at 100 Hz that the estimation does not use. Also writes the
channel map (``example_run.map.toml``, from the same channel names) and the line
description (``example_line.csv``). The hidden truth is in ``example_run.truth.json``
beside them (the estimator never reads it). The ``railsusp run`` configuration shipped
beside them (``example_run.pipeline.toml``) is written by hand, not by this script.
The output is deterministic (seeded tracks, noise and bogie channel): run again on the
same model it gives the same channels.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np
from asammdf import MDF, Signal

from _cli import parser, run_main
from railsusp.measured import add_sensor_noise, recording_from_simulation
from railsusp.measured.sections import Section
from railsusp.measured.truth import RECORDING_FILES, recording_files
from railsusp.params import ParameterSet
from railsusp.store import atomic_write_text
from railsusp.vehicle.simulate import simulate

TRUTH = {"X13": 16.1, "X14": 8.3, "X15": 164.0}
RATE = 200.0  # force channels, Hz
SLOW = 10.0  # speed, position, line data, Hz
SECTION_S = 30.0
TRANSITION_S = 12.0
#: (radius m or None, direction, cant mm, grade permille, speed km/h)
SECTIONS = [
    (None, "left", 0.0, 0.0, 65.0),
    (600.0, "left", 60.0, 0.0, 55.0),
    (350.0, "right", 100.0, 0.0, 45.0),
    (None, "left", 0.0, 12.0, 40.0),
    (None, "left", 0.0, 0.0, 70.0),
]
TRACK_SEED_OFFSET = 1000
#: the channels written, by the quantity each is (the channel map's keys)
LINE_CHANNELS = {
    "speed": "v_train",
    "position": "s_odo",
    "curvature": "track_curvature",
    "cant": "track_cant",
    "grade": "track_grade",
}
WHEEL_CHANNELS = {"w1R": {"Y": "WS1_Y_R", "Q": "WS1_Q_R"}, "w1L": {"Y": "WS1_Y_L", "Q": "WS1_Q_L"}}
IGNORED_CHANNEL = "acc_bogie_y_g"


def channel_map_text() -> str:
    """The channel map of the recording (``example_run.map.toml``, docs/data-format.md):
    which channel is which quantity, built from the names the channels are written under,
    so that the two cannot disagree."""
    lines = [
        "# Channel map of example_run.mf4: which recorded channel is which quantity.",
        "# Units come from the file (kN, N, km/h, m, 1/km, mm, permille).",
        *(f'{key} = "{name}"' for key, name in LINE_CHANNELS.items()),
        f'ignore = ["{IGNORED_CHANNEL}"]',
    ]
    for wheel, forces in WHEEL_CHANNELS.items():
        lines += ["", f"[wheels.{wheel}]", *(f'{k} = "{v}"' for k, v in forces.items())]
    return "\n".join(lines) + "\n"


def _condition(radius, direction, cant, grade, speed, duration, name):
    sec = Section(name, 0, 0, 0.0, 0.0, radius, direction, cant, grade, speed, 0.0)
    return sec.condition(duration, RATE)


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--out", type=Path, default=Path("src/railsusp/data"))
    args = ap.parse_args()
    truth = ParameterSet(TRUTH, units="display")
    pieces = []  # (time-series dict at RATE) per piece
    for k, (radius, direction, cant, grade, speed) in enumerate(SECTIONS):
        cond = _condition(radius, direction, cant, grade, speed, SECTION_S, f"sec{k}")
        pieces.append(("section", cond, (radius, direction, cant, grade), (speed, speed)))
        if k + 1 < len(SECTIONS):
            nxt = SECTIONS[k + 1]
            mid = 0.5 * (speed + nxt[4])
            cond = _condition(None, "left", 0.0, 0.0, mid, TRANSITION_S, f"tr{k}")
            pieces.append(
                ("transition", cond, ((radius, direction, cant, grade), nxt[:4]), (speed, nxt[4]))
            )
    t_all, ch = [], {k: [] for k in ("YR", "YL", "QR", "QL", "v", "curv", "cant", "grade")}
    t0 = 0.0
    for i, (kind, cond, geo, (v0, v1)) in enumerate(pieces):
        field = cond.with_changes(seed=cond.seed + TRACK_SEED_OFFSET + i)
        print(f"simulating {kind} {cond.name}: {cond.speed_kmh:g} km/h, R {cond.curve_radius_m}")
        rec = recording_from_simulation(simulate(truth, field), ("w1R", "w1L"))
        rec = add_sensor_noise(rec, 0.03, seed=100 + i)
        n = rec.time.size
        frac = np.arange(n) / n
        ch["YR"].append(rec.Y["w1R"])
        ch["YL"].append(rec.Y["w1L"])
        ch["QR"].append(rec.Q["w1R"] * 1e3)  # N
        ch["QL"].append(rec.Q["w1L"] * 1e3)
        ch["v"].append(v0 + (v1 - v0) * frac)

        def curvature(g):
            radius, direction, _, _ = g
            return 0.0 if radius is None else (1e3 / radius) * (1 if direction == "left" else -1)

        if kind == "section":
            ch["curv"].append(np.full(n, curvature(geo)))
            ch["cant"].append(np.full(n, geo[2]))
            ch["grade"].append(np.full(n, geo[3]))
        else:
            a, b = geo
            for key, fa, fb in (
                ("curv", curvature(a), curvature(b)),
                ("cant", a[2], b[2]),
                ("grade", a[3], b[3]),
            ):
                ch[key].append(fa + (fb - fa) * frac)
        t_all.append(t0 + np.arange(n) / RATE)
        t0 += n / RATE
    t = np.concatenate(t_all)
    data = {k: np.concatenate(v) for k, v in ch.items()}
    pos = np.concatenate([[0.0], np.cumsum(data["v"][1:] / 3.6 / RATE)])
    ts = np.arange(0.0, t[-1] + 1.0 / SLOW, 1.0 / SLOW)

    def slow(x):
        return np.interp(ts, t, x).astype(np.float32)

    rng = np.random.default_rng(5)
    ta = np.arange(0.0, t[-1] + 0.01, 0.01)
    acc = (0.03 * rng.standard_normal(ta.size)).astype(np.float32)
    f32 = np.float32
    right, left, name = WHEEL_CHANNELS["w1R"], WHEEL_CHANNELS["w1L"], LINE_CHANNELS
    signals = [
        Signal(data["YR"].astype(f32), t, name=right["Y"], unit="kN"),
        Signal(data["QR"].astype(f32), t, name=right["Q"], unit="N"),
        Signal(data["YL"].astype(f32), t, name=left["Y"], unit="kN"),
        Signal(data["QL"].astype(f32), t, name=left["Q"], unit="N"),
    ]
    line = [
        Signal(slow(data["v"]), ts, name=name["speed"], unit="km/h"),
        Signal(slow(pos), ts, name=name["position"], unit="m"),
        Signal(slow(data["curv"]), ts, name=name["curvature"], unit="1/km"),
        Signal(slow(data["cant"]), ts, name=name["cant"], unit="mm"),
        Signal(slow(data["grade"]), ts, name=name["grade"], unit="permille"),
    ]
    mdf = MDF(version="4.10")
    mdf.append(signals, comment="wheelset 1 forces, 200 Hz")
    mdf.append(line, comment="train speed, odometer and line data, 10 Hz")
    mdf.append([Signal(acc, ta, name=IGNORED_CHANNEL, unit="g")], comment="bogie, 100 Hz")
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "example_run.mf4"
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=".example_run.") as tmp:
        saved = mdf.save(Path(tmp) / path.name, overwrite=True, compression=2)
        os.replace(saved, path)  # packaged data: never left half written
    mdf.close()
    # the line description: km posts of every piece (transitions as the spirals they are)
    rows = ["km_start,km_end,radius_m,direction,cant_mm,grade_permille"]
    s = 0.0
    for kind, cond, geo, (v0, v1) in pieces:
        length = 0.5 * (v0 + v1) / 3.6 * cond.duration_s
        if kind == "section":
            radius, direction, cant, grade = geo
            rows.append(
                f"{s / 1e3:.4f},{(s + length) / 1e3:.4f},{radius or ''},{direction},"
                f"{cant:g},{grade:g}"
            )
        s += length
    atomic_write_text(args.out / "example_line.csv", "\n".join(rows) + "\n")
    atomic_write_text(args.out / "example_run.map.toml", channel_map_text())
    atomic_write_text(
        args.out / "example_run.truth.json",
        json.dumps(
            {
                "parameters_display": TRUTH,
                "note": "hidden truth of example_run.mf4; the estimator never reads it",
                # the run it is the truth of, by content: validate --truth accepts it for
                # the sections cut from this run (measured/truth.py)
                RECORDING_FILES: recording_files(args.out, [path.name]),
            },
            indent=1,
        )
        + "\n",
    )
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB), {t[-1]:.0f} s, {pos[-1]:.0f} m")


if __name__ == "__main__":
    run_main(main)
