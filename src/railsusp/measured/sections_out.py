"""Sections written out: each kept section as a recording of the field folder, with its
working condition, the cut as a table, the conditions for a campaign, a ``railsusp run``
configuration, and a plot of the cut along the line."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from railsusp.conditions import WorkingCondition
from railsusp.en14363 import section_statistics
from railsusp.errors import RailsuspInputError
from railsusp.measured.field_folder import source_fingerprint
from railsusp.measured.line import FILE_NAME, RESERVED_NAMES
from railsusp.measured.recording import FORMAT, Recording, recordings_digest
from railsusp.measured.run import MeasuredRun
from railsusp.measured.sections import Section, sections_table
from railsusp.measured.truth import RECORDING_FILES, RECORDINGS_DIGEST
from railsusp.store import atomic_write_bytes, atomic_write_figure, file_hash, write_json
from railsusp.vehicle.layout import WHEEL_NAMES
from railsusp.vehicle.simulation_result import measured_wheel_index


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


def en14363_table(run: MeasuredRun, sections: list[Section]) -> pd.DataFrame:
    """Per kept section, wheel and force: the percentiles 0.15 / 50 / 99.85 % (kN) of the
    force low-passed at 20 Hz and averaged over 2 m of track (:mod:`railsusp.en14363`)."""
    rows = []
    for s in sections:
        if not s.kept:
            continue
        sl = slice(s.start, s.end)
        for w in run.wheels:
            for force, x in (("Y", run.Y[w]), ("Q", run.Q[w])):
                st = section_statistics(x[sl] / 1e3, run.rate_hz, run.speed[sl])
                rows.append(
                    {"section": s.name, "wheel": w, "force": force}
                    | {f"{k}_kN": round(v, 2) for k, v in st.to_dict().items()}
                )
    return pd.DataFrame(rows)


def write_sections(
    run: MeasuredRun,
    sections: list[Section],
    out: str | Path,
    rate_hz: float = 50.0,
    final: str | Path | None = None,
    wheel_load_N: float | None = None,
) -> Path:
    """The kept sections as a field folder: one recording per section, ``index.json``,
    ``sections.csv`` (the whole cut, with the reasons), ``en14363.csv`` (the EN 14363
    percentiles of every kept section's forces), ``conditions.toml`` (the
    sections' conditions, for a campaign: ``railsusp campaign --conditions``) and
    ``pipeline.toml`` (a quick ``railsusp run`` configuration on these recordings).
    ``final``: where the folder will live when ``out`` is a temporary one (the path that
    ``pipeline.toml`` names; default ``out``). ``wheel_load_N``: the static wheel load of
    the wagon the run was read as (default the packaged loaded C80's), with which the
    sections are read back for their digest."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RailsuspInputError(
            f"--write {out}: a file, not a folder; accepted a new folder or a field folder "
            "of sections written before (replaced whole)"
        )
    kept = [s for s in sections if s.kept]
    if not kept:
        raise RailsuspInputError(f"{run.source}: no section kept; nothing to write")
    _check_names(kept)
    names = []
    conds = []
    for s in kept:
        rec = section_recording(run, s, rate_hz)
        rec.write(out / f"{s.name}.csv")  # a dot in the name stays (km0.5 was km0.csv)
        names.append(f"{s.name}.csv")
        conds.append(rec.condition)
    table = sections_table(sections).to_csv(index=False).encode()
    atomic_write_bytes(out / "sections.csv", table)
    en = en14363_table(run, sections).to_csv(index=False).encode()
    atomic_write_bytes(out / "en14363.csv", en)
    atomic_write_bytes(out / "conditions.toml", conditions_toml(conds).encode())
    folder = Path(final) if final is not None else out
    atomic_write_bytes(out / "pipeline.toml", pipeline_toml(conds, folder).encode())
    index = {"format": FORMAT, "recordings": names, **source_fingerprint(run.source)}
    # each section by its table's SHA-256 and all of them as read (as read_field reads the
    # index's tables): the truth of the run they were cut from takes these tables only, in
    # these bytes or others that read the same (measured.truth.check_truth_of)
    from railsusp.measured.recording_reader import read_recording

    index[RECORDING_FILES] = {name: file_hash(out / name) for name in names}
    try:  # read as the run's wagon (a tare wagon's sections were refused as a loaded one's)
        read = [read_recording(out / name, wheel_load_N=wheel_load_N) for name in names]
        index[RECORDINGS_DIGEST] = recordings_digest(read)
    except RailsuspInputError:  # sections a reader refuses: told by their tables' hashes only
        pass
    write_json(out / "index.json", index)
    return out


def _check_names(kept: list[Section]) -> None:
    """Refuse kept sections whose names are no plain file names or repeat (case aside, as
    a file system may): one recording was written over another, the index listing both."""
    seen: dict[str, str] = {}
    for s in kept:
        if not FILE_NAME.fullmatch(s.name) or s.name.casefold() in RESERVED_NAMES:
            raise RailsuspInputError(
                f"section name {s.name!r}: accepted letters, digits, '.', '_', '-', starting "
                f"with a letter or digit, and not {', '.join(RESERVED_NAMES)}"
            )
        if s.name.casefold() in seen:
            raise RailsuspInputError(
                f"sections {seen[s.name.casefold()]!r} and {s.name!r} would be one recording "
                f"({s.name}.csv); accepted a name per section"
            )
        seen[s.name.casefold()] = s.name


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
    the sections' conditions (inline tables), campaign and NSGA-II sizes as
    examples/quick.toml's, but a BP network trained on the sections' conditions (the
    shipped networks are of the standard conditions) and no refinement (the recordings
    carry no measured track geometry)."""
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
            "# railsusp run configuration written by `railsusp sections --write` on the",
            "# sections' conditions and recordings: campaign and NSGA-II sizes as",
            "# examples/quick.toml's, but a BP network trained here on these conditions",
            "# (the shipped networks are of the standard conditions) and no refinement",
            "# (the recordings carry no measured track geometry).",
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
    try:
        return atomic_write_figure(fig, path, dpi=100)
    finally:
        plt.close(fig)
