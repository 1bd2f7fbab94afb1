"""The run report: one self-contained HTML file (figures embedded) and a Markdown twin,
regenerated from the run directory alone (``build_report(RUN)``).

The page answers first: a summary card (the wagon, the recordings, each suspension element's
estimate with its interval and verdict, the force agreement before and after) fits the first
screen; the method's stages follow. This module puts the sections in that order, adds the
track input, and writes the two files; the sections are the report_* modules' (summary card,
method, estimate, EN 14363, provenance), the stale banner :mod:`railsusp.report_stale`'s.
It reads the run directory and never imports the pipeline (the pipeline calls it).
"""

from __future__ import annotations

from pathlib import Path

import railsusp.summary as summary
from railsusp.report_doc import Doc
from railsusp.report_en14363 import en14363_section
from railsusp.report_method import method_sections, wagon_section
from railsusp.report_provenance import provenance_section
from railsusp.report_summary_card import summary_card
from railsusp.store import atomic_write_bytes, read_json


def _measured_track(read: list):
    """The condition of the first of the run's recordings ``read`` that carries its track
    geometry, or None."""
    for rec in read:
        if rec.condition.track_geometry is not None:
            return rec.condition
    return None


def build_report(run: str | Path) -> list[Path]:
    """Write ``RUN/report.html`` and ``RUN/report.md`` from the stages' outputs."""
    from railsusp.conditions import WorkingCondition
    from railsusp.report import plot_track_irregularities
    from railsusp.vehicle.track_geometry import irregularities_for

    run = Path(run)
    state = read_json(run / "pipeline.json")
    meta = read_json(run / "campaign" / "campaign.json")
    doc = Doc(run)
    title = state.get("config", {}).get("name", "railsusp run")
    doc.h(f"railsusp report: {title}", 1)
    has_field = (run / "field" / "index.json").exists()
    read = summary.field_recordings(run) if has_field else []  # once, for every section
    if (run / "estimate" / "validation" / "validation.csv").exists():
        summary_card(doc, run, read)
    doc.p(
        "How it was found: a simulation campaign of the wagon, Sobol sensitivity (which "
        "parameters the forces reveal), surrogate force models, NSGA-II estimation (refined "
        "with the simulator where the recordings carry their track) and validation against "
        "the recordings. The sections below follow these stages."
    )
    cfg = meta["config"]
    wagon_section(doc, run, cfg)
    doc.h("Track input")
    first = WorkingCondition(**cfg["conditions"][0])
    caption = (
        f"The campaign's design track of '{first.name}' (seed {first.seed}): irregularities "
        "and their PSD vs the FRA spectrum"
    )
    measured = _measured_track(read)
    if measured is not None:  # the track the estimate compared on, not the design track
        first = measured
        caption = (
            f"The measured track geometry of the recording of '{first.name}' (the track the "
            "estimate and the validation simulated): irregularities and their PSD vs the FRA "
            "spectrum"
        )
    elif has_field:
        caption += "; the recordings ran on their own track, which they do not carry"
    irr = irregularities_for(first)
    if irr is not None:
        png = plot_track_irregularities(irr, run / "report_assets" / "track.png")
        doc.figure(png, caption)
    method_sections(doc, run, state)
    en14363_section(doc, run, read)
    provenance_section(doc, run, state, meta)
    html_path = atomic_write_bytes(run / "report.html", doc.page(title).encode())
    md_path = atomic_write_bytes(run / "report.md", "\n".join(doc.md).encode())
    return [html_path, md_path]
