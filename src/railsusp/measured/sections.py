"""A long run cut into sections of one working condition each.

A section is a stretch of one kind of track (tangent, or a curve whose radius lies in one
band, on one band of grade) run at about one speed. The track comes from the run's
curvature/cant/grade channels, or from its position against a line description (a table of
km posts with radius, cant, grade), or the user gives the sections as a table of positions.
Every section's speed is the recording's; a stretch whose speed varies by more than the
tolerance is split into pieces that hold it, and pieces (and transitions between kinds)
shorter than the minimum length are left out with the reason. The kept sections become
the recordings of a field folder (:func:`write_sections`) that the estimation reads.
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp.conditions import WorkingCondition, make_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured.recording import FORMAT, Recording
from railsusp.measured.run import MeasuredRun
from railsusp.store import atomic_write_bytes, write_json
from railsusp.vehicle.layout import WHEEL_NAMES
from railsusp.vehicle.simulate import measured_wheel_index

#: a section name, which becomes a file name: no path separators, no leading dot
SAFE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,59}")


@dataclass(frozen=True)
class SectionRules:
    """How a run is cut. Radii are banded by ``radius_edges_m`` (a curve of 550 m and one
    of 580 m are one condition); curvature below 1/``tangent_radius_m`` is tangent."""

    radius_edges_m: tuple[float, ...] = (150.0, 250.0, 350.0, 450.0, 600.0, 800.0, 1200.0, 2000.0)
    tangent_radius_m: float = 3000.0
    grade_band_permille: float = 5.0
    speed_tolerance: float = 0.10  # (max - min) / mean speed within a section
    min_length_m: float = 150.0
    max_duration_s: float = 120.0
    smoothing_m: float = 10.0  # geometry channels averaged over this length
    #: curvature changing faster than this (1/m per m) is a transition (spiral), not a
    #: condition: about 1/5000 m over 100 m
    spiral_rate: float = 2e-6
    #: grade changing faster than this (per m) is a vertical curve: 1 permille over 100 m
    grade_rate: float = 1e-5

    def __post_init__(self) -> None:
        for name, value, low, high in (
            ("speed_tolerance", self.speed_tolerance, 0.0, 1.0),
            ("min_length_m", self.min_length_m, 1.0, 100_000.0),
            ("max_duration_s", self.max_duration_s, 1.0, 600.0),
            ("grade_band_permille", self.grade_band_permille, 0.1, 80.0),
            ("tangent_radius_m", self.tangent_radius_m, 100.0, 100_000.0),
        ):
            if not low <= value <= high:
                raise RailsuspInputError(f"{name} = {value:g}: accepted {low:g} to {high:g}")


@dataclass
class Section:
    """One cut stretch of the run (sample indices ``start`` to ``end``, end exclusive)."""

    name: str
    start: int
    end: int
    start_m: float
    end_m: float
    radius_m: float | None  # None: tangent
    direction: str  # left / right
    cant_mm: float
    grade_permille: float
    speed_kmh: float
    speed_spread: float  # (max - min) / mean
    kept: bool = True
    reason: str = ""

    @property
    def kind(self) -> str:
        return "tangent" if self.radius_m is None else f"curve R{self.radius_m:.0f}"

    def condition(self, duration_s: float, rate_hz: float) -> WorkingCondition:
        """The working condition of this section: steady on its track from the start of
        the record (the curve, if any, begins with a 50 m spiral inside the 100 m lead-in),
        at its mean speed, on synthesised class-5 track (the unknown real track)."""
        fields = {
            "name": self.name,
            "speed_kmh": round(self.speed_kmh, 2),
            "duration_s": round(duration_s, 3),
            "n_steps": max(10, round(duration_s * rate_hz)),
            "grade_permille": round(self.grade_permille, 2),
            "cant_mm": round(self.cant_mm, 1) if self.radius_m is not None else 0.0,
        }
        if self.radius_m is not None:
            fields |= {
                "curve_radius_m": round(self.radius_m, 0),
                "curve_direction": self.direction,
                "curve_start_m": 0.0,
                "entry_spiral_m": 50.0,
            }
        return make_condition(fields)


def geometry_from_line(position_m: np.ndarray, line: pd.DataFrame) -> dict[str, np.ndarray]:
    """Curvature (1/m, + left), cant (m) and grade (1) under each position from a line
    description with columns ``km_start, km_end, radius_m, cant_mm, grade_permille`` and
    optional ``direction`` (left/right); radius 0 or empty is tangent. Positions outside
    every row are NaN."""
    curv = np.full(position_m.shape, np.nan)
    cant = np.full(position_m.shape, np.nan)
    grade = np.full(position_m.shape, np.nan)
    for r in line.itertuples(index=False):
        inside = (position_m >= r.km_start * 1e3) & (position_m < r.km_end * 1e3)
        radius = float(r.radius_m) if np.isfinite(r.radius_m) else 0.0
        sign = -1.0 if str(getattr(r, "direction", "left")).strip().lower() == "right" else 1.0
        curv[inside] = sign / radius if radius > 0 else 0.0
        cant[inside] = (r.cant_mm if np.isfinite(r.cant_mm) else 0.0) * 1e-3
        grade[inside] = (r.grade_permille if np.isfinite(r.grade_permille) else 0.0) * 1e-3
    return {"curvature": curv, "cant": cant, "grade": grade}


def read_line(path: str | Path) -> pd.DataFrame:
    """A line description CSV (see :func:`geometry_from_line`), checked."""
    need = ["km_start", "km_end", "radius_m", "cant_mm", "grade_permille"]
    df = _read_csv(path, need)
    if (df.km_end <= df.km_start).any():
        i = int(np.flatnonzero((df.km_end <= df.km_start).to_numpy())[0])
        raise RailsuspInputError(f"line description {path}, row {i + 2}: km_end <= km_start")
    return df


def read_section_table(path: str | Path) -> pd.DataFrame:
    """A user section table CSV: ``start_m, end_m`` and optional ``name``, checked. Names
    become file names, so they must be plain: letters, digits, ``.``, ``_``, ``-``."""
    df = _read_csv(path, ["start_m", "end_m"])
    if "name" in df:
        for i, name in enumerate(df["name"].astype(str)):
            if not SAFE_NAME.fullmatch(name):
                raise RailsuspInputError(
                    f"section table {path}, row {i + 2}: name {name!r}: accepted 1-60 "
                    "letters, digits, '.', '_', '-', starting with a letter or digit"
                )
    if (df.end_m <= df.start_m).any():
        i = int(np.flatnonzero((df.end_m <= df.start_m).to_numpy())[0])
        raise RailsuspInputError(f"section table {path}, row {i + 2}: end_m <= start_m")
    return df


def _read_csv(path: str | Path, need: list[str]) -> pd.DataFrame:
    try:
        df = pd.read_csv(path, skipinitialspace=True)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise RailsuspInputError(f"{path}: cannot read the table ({exc})") from None
    missing = [c for c in need if c not in df.columns]
    if missing or df.empty:
        raise RailsuspInputError(f"{path}: columns {need} with at least one row needed")
    for c in need:
        vals = pd.to_numeric(df[c], errors="coerce")
        bad = vals.isna() & df[c].notna()
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            raise RailsuspInputError(f"{path}, row {i + 2}: {c} = {df[c].iloc[i]!r} not a number")
        df[c] = vals
    return df


def cut_sections(
    run: MeasuredRun,
    rules: SectionRules | None = None,
    *,
    line: pd.DataFrame | None = None,
    table: pd.DataFrame | None = None,
) -> list[Section]:
    """The run cut into sections (left-out ones included, ``kept`` False with the reason)."""
    rules = rules or SectionRules()
    geo = _geometry(run, line, rules)
    if table is not None:
        spans = []
        for r in table.itertuples(index=False):
            idx = np.flatnonzero((run.position >= r.start_m) & (run.position < r.end_m))
            spans.append((int(idx[0]), int(idx[-1]) + 1) if idx.size else (0, 0))
        names = [str(n) for n in table["name"]] if "name" in table else None
    else:
        spans, names = _label_runs(geo, rules), None
    out: list[Section] = []
    for k, (a, b) in enumerate(spans):
        label = names[k] if names else None
        for sec in _pieces(run, geo, a, b, rules, label):
            if out and not out[-1].kept and not sec.kept and out[-1].end == sec.start:
                out[-1] = _merged(run, out[-1], sec)  # one row per left-out stretch
            else:
                out.append(sec)
    if names:
        for name in set(names):
            same = [s for s in out if s.kept and s.name == name]
            if len(same) > 1:  # a user's section split by speed or duration
                for j, sec in enumerate(same):
                    sec.name = f"{name}-{j + 1}"
    kept = [s for s in out if s.kept]
    width = len(str(len(kept)))
    n = 0
    for s in out:
        if s.kept:
            n += 1
            s.name = s.name or f"s{n:0{width}d}-" + s.kind.replace(" ", "-")
    return out


def _geometry(run: MeasuredRun, line: pd.DataFrame | None, rules: SectionRules) -> dict:
    """Smoothed curvature (1/m), cant (m), grade (1) per sample."""
    if line is not None:
        geo = geometry_from_line(run.position, line)
    else:
        zero = np.zeros_like(run.time)
        geo = {
            "curvature": run.curvature if run.curvature is not None else zero,
            "cant": run.cant if run.cant is not None else zero,
            "grade": run.grade if run.grade is not None else zero,
        }
    ds = float(np.median(np.abs(np.diff(run.position)))) or 1.0
    k = max(1, round(rules.smoothing_m / ds))
    kernel = np.ones(k) / k
    out = {
        key: np.convolve(np.pad(v, (k // 2, k - 1 - k // 2), mode="edge"), kernel, "valid")
        for key, v in geo.items()
    }
    ds = np.maximum(np.abs(np.gradient(run.position)), 1e-9)
    with np.errstate(invalid="ignore"):
        out["transition"] = (np.abs(np.gradient(out["curvature"])) / ds > rules.spiral_rate) | (
            np.abs(np.gradient(out["grade"])) / ds > rules.grade_rate
        )
    return out


def _label_runs(geo: dict, rules: SectionRules) -> list[tuple[int, int]]:
    """Runs of samples on one kind of track (radius band, direction, grade band)."""
    curv = geo["curvature"]
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = np.where(np.abs(curv) > 1.0 / rules.tangent_radius_m, 1 / np.abs(curv), np.inf)
    band = np.digitize(radius, rules.radius_edges_m)
    band = np.where(np.isfinite(radius), band, -1)
    band = np.where(np.isnan(curv), -2, band)  # outside the line description
    band = np.where(geo["transition"] & (band != -2), -3, band)  # a transition: own label
    label = np.where(
        band == -3,
        -3,
        band * 4
        + np.where(curv < 0, 1, 0)
        + 1000 * np.round(geo["grade"] * 1e3 / rules.grade_band_permille),
    )
    edges = np.flatnonzero(np.diff(label)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [label.size]])
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True) if band[a] != -2]


def _pieces(
    run: MeasuredRun, geo: dict, a: int, b: int, rules: SectionRules, name: str | None
) -> list[Section]:
    """Stretch a..b as sections: split where the speed leaves the tolerance or the
    duration passes the maximum; pieces shorter than the minimum left out."""
    v = run.speed
    if geo["transition"][a:b].mean() > 0.5 and name is None:
        return [_section(run, geo, a, b, rules, name, split=False)]
    out = []
    i = a
    while i < b:
        j, lo, hi = i + 1, v[i], v[i]
        while j < b:
            lo, hi = min(lo, v[j]), max(hi, v[j])
            if (hi - lo) > rules.speed_tolerance * 0.5 * (hi + lo) or (
                run.time[j] - run.time[i] > rules.max_duration_s
            ):
                break
            j += 1
        out.append(_section(run, geo, i, j, rules, name, split=(j < b or i > a)))
        i = j
    return out


def _merged(run: MeasuredRun, a: Section, b: Section) -> Section:
    """Two adjacent left-out stretches as one row, with both reasons."""
    v = run.speed[a.start : b.end]
    reason = a.reason if b.reason in a.reason.split("; ") else f"{a.reason}; {b.reason}"
    return Section(
        "",
        a.start,
        b.end,
        a.start_m,
        b.end_m,
        None,
        "left",
        0.0,
        0.5 * (a.grade_permille + b.grade_permille),
        float(v.mean()) * 3.6,
        float((v.max() - v.min()) / max(v.mean(), 1e-9)),
        False,
        reason,
    )


def _section(
    run: MeasuredRun, geo: dict, i: int, j: int, rules: SectionRules, name: str | None, split: bool
) -> Section:
    sl = slice(i, j)
    curv = float(np.median(geo["curvature"][sl]))
    radius = 1.0 / abs(curv) if abs(curv) > 1.0 / rules.tangent_radius_m else None
    v = run.speed[sl]
    length = float(abs(run.position[j - 1] - run.position[i]))
    spread = float((v.max() - v.min()) / max(v.mean(), 1e-9))
    sec = Section(
        name or "",
        i,
        j,
        float(run.position[i]),
        float(run.position[j - 1]),
        radius,
        "right" if curv < 0 else "left",
        float(np.median(geo["cant"][sl])) * 1e3,
        float(np.median(geo["grade"][sl])) * 1e3,
        float(v.mean()) * 3.6,
        spread,
    )
    if np.mean(geo["transition"][sl]) > 0.5:
        sec.kept = False
        sec.reason = "transition (curvature or grade changing)"
    elif length < rules.min_length_m:
        sec.kept = False
        sec.reason = f"{length:.0f} m, shorter than {rules.min_length_m:g} m" + (
            " (speed varies beyond the tolerance)" if split else " (a transition)"
        )
    elif float(v.mean()) * 3.6 < 1.0:
        sec.kept, sec.reason = False, "standing"
    return sec


def sections_table(sections: list[Section]) -> pd.DataFrame:
    """One row per section, kept or not, with the reason."""
    rows = []
    for s in sections:
        d = asdict(s)
        rows.append(
            {
                "section": s.name or "-",
                "kind": s.kind if s.kept or "transition" not in s.reason else "transition",
                "from_m": round(d["start_m"], 1),
                "to_m": round(d["end_m"], 1),
                "length_m": round(d["end_m"] - d["start_m"], 1),
                "speed_kmh": round(s.speed_kmh, 1),
                "speed_spread_pct": round(100 * s.speed_spread, 1),
                "cant_mm": round(s.cant_mm, 0),
                "grade_permille": round(s.grade_permille, 1),
                "kept": "yes" if s.kept else "no",
                "reason": s.reason,
            }
        )
    return pd.DataFrame(rows)


def section_recording(run: MeasuredRun, sec: Section, rate_hz: float) -> Recording:
    """The section as a recording (kN) at ``rate_hz``, its condition from the section."""
    sl = slice(sec.start, sec.end)
    t = run.time[sl] - run.time[sec.start]
    rec = Recording(
        t,
        {w: y[sl] / 1e3 for w, y in run.Y.items()},
        {w: q[sl] / 1e3 for w, q in run.Q.items()},
        None,  # type: ignore[arg-type]
        {"source": Path(run.source).name, "from_m": sec.start_m, "to_m": sec.end_m},
    )
    if abs(rec.sampling_rate / rate_hz - 1.0) > 1e-6:
        rec = rec.resampled(rate_hz)
    duration = len(rec.time) / rate_hz
    cond = sec.condition(duration, rate_hz)
    first = WHEEL_NAMES[measured_wheel_index(cond)]
    order = sorted(rec.Y, key=lambda w: w != first)  # the measured wheel first
    return Recording(
        rec.time, {w: rec.Y[w] for w in order}, {w: rec.Q[w] for w in order}, cond, rec.meta
    )


def write_sections(
    run: MeasuredRun, sections: list[Section], out: str | Path, rate_hz: float = 50.0
) -> Path:
    """The kept sections as a field folder: one recording per section, ``index.json``,
    ``sections.csv`` (the whole cut, with the reasons), ``conditions.toml`` (the
    sections' conditions, for a campaign: ``railsusp campaign --conditions``) and
    ``pipeline.toml`` (a quick ``railsusp run`` configuration on these recordings)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RailsuspInputError(f"--write {out}: exists and is not a folder")
    kept = [s for s in sections if s.kept]
    if not kept:
        raise RailsuspInputError(f"{run.source}: no section kept; nothing to write")
    names = []
    conds = []
    for s in kept:
        rec = section_recording(run, s, rate_hz)
        rec.write(out / s.name)
        names.append(f"{s.name}.csv")
        conds.append(rec.condition)
    table = sections_table(sections).to_csv(index=False).encode()
    atomic_write_bytes(out / "sections.csv", table)
    atomic_write_bytes(out / "conditions.toml", conditions_toml(conds).encode())
    atomic_write_bytes(out / "pipeline.toml", pipeline_toml(conds, out).encode())
    write_json(
        out / "index.json",
        {"format": FORMAT, "recordings": names, "source": Path(run.source).name},
    )
    return out


def conditions_toml(conditions: list[WorkingCondition]) -> str:
    """``[[condition]]`` tables of the conditions (docs/conditions.md)."""
    parts = []
    for c in conditions:
        lines = ["[[condition]]"]
        for k, v in c.model_dump().items():
            if v is None:
                continue
            lines.append(f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"')
        parts.append("\n".join(lines))
    return "\n\n".join(parts) + "\n"


def pipeline_toml(conditions: list[WorkingCondition], field: Path) -> str:
    """A ``railsusp run`` configuration that estimates from the recordings in ``field``:
    the sections' conditions (inline tables), the quick settings of examples/quick.toml,
    no refinement (the recordings carry no measured track geometry)."""
    rows = []
    for c in conditions:
        items = ", ".join(
            f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"'
            for k, v in c.model_dump().items()
            if v is not None
        )
        rows.append(f"    {{ {items} }},")
    measured = json_string(str(field.resolve()))
    return "\n".join(
        [
            "# railsusp run configuration written by `railsusp sections --write`: the quick",
            "# settings (examples/quick.toml) on the sections' conditions and recordings.",
            'name = "sections of a measured run"',
            "conditions = [",
            *rows,
            "]",
            "",
            "[campaign]\nsamples = 64\nseed = 0\nbatch_size = 32",
            "",
            "[sensitivity]\nthreshold = 0.05\nmax_keys = 6\nbase_samples = 512",
            "",
            '[surrogate]\nmodel = "bp"\nsamples = 128\nseed = 1\nepochs = 8',
            "",
            f"[field]\nmeasured = {measured}",
            "",
            '[estimate]\npop_size = 50\nn_gen = 100\nstatistic = "mean"\nrefine = false',
            "",
        ]
    )


def json_string(text: str) -> str:
    """A TOML basic string (JSON's escaping is TOML's)."""
    import json

    return json.dumps(text)


def plot_sections(run: MeasuredRun, sections: list[Section], path: str | Path) -> Path:
    """Speed and curvature along the line with the sections shaded (kept green, left out
    grey), saved as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = run.position / 1e3
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(10, 5))
    ax1.plot(x, run.speed * 3.6, "k-", lw=1)
    ax1.set_ylabel("speed, km/h")
    if run.curvature is not None:
        ax2.plot(x, run.curvature * 1e3, "b-", lw=1)
    ax2.set_ylabel("curvature, 1/km")
    ax2.set_xlabel("position, km")
    for s in sections:
        for ax in (ax1, ax2):
            ax.axvspan(s.start_m / 1e3, s.end_m / 1e3, color="g" if s.kept else "0.8", alpha=0.3)
        if s.kept:
            ax1.annotate(
                s.name,
                ((s.start_m + s.end_m) / 2e3, 0.02),
                xycoords=("data", "axes fraction"),
                ha="center",
                fontsize=7,
                rotation=90,
            )
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
