"""The report's EN 14363 section: the recordings' forces as EN 14363 processes them (20 Hz
low-pass, 2 m sliding mean, percentiles 0.15 / 50 / 99.85 %), per recording, wheel and force.

A field folder cut from a long run (``railsusp sections --write``, or ``railsusp run`` with
``[field] recording``) carries ``en14363.csv``, processed from the run at its own sampling
rate; that table is shown. Any other field folder (synthetic, or written by hand) is
processed here from its recordings. Reads the run directory only.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from railsusp.en14363 import section_statistics
from railsusp.report_doc import Doc

#: the table a cut long run's field folder carries
EN14363_CSV = "en14363.csv"


def en14363_table(run: str | Path, read: list | None = None) -> tuple[pd.DataFrame, str]:
    """The EN 14363 percentiles (kN) of the run's recordings, and where they come from:
    ``RUN/field/en14363.csv`` if present, else computed from the field recordings
    (``read``: the run's :func:`~railsusp.summary.field_recordings`, where the caller has
    them already)."""
    from railsusp.summary import field_recordings

    field = Path(run) / "field"
    if (field / EN14363_CSV).exists():
        return pd.read_csv(
            field / EN14363_CSV
        ), f"the long run, at its sampling rate ({EN14363_CSV})"
    rows = []
    for rec in field_recordings(run) if read is None else read:  # as the run's wagon's
        for w in rec.wheels:
            for force, x in (("Y", rec.Y[w]), ("Q", rec.Q[w])):
                st = section_statistics(x, rec.sampling_rate, rec.condition.speed)
                rows.append(
                    {"section": rec.condition.name, "wheel": w, "force": force}
                    | {f"{k}_kN": round(v, 2) for k, v in st.to_dict().items()}
                )
    return pd.DataFrame(rows), "the field recordings"


def en14363_section(doc: Doc, run: str | Path, read: list | None = None) -> None:
    """Add the section to ``doc`` (nothing when the run has no field recordings; ``read``:
    as :func:`en14363_table`)."""
    if not (Path(run) / "field" / "index.json").exists():
        return
    table, source = en14363_table(run, read)
    if table.empty:
        return
    doc.h("Measured forces, EN 14363 processing")
    doc.p(
        "Each recording's wheel forces low-passed at 20 Hz (a 4th-order Butterworth run "
        "forwards and backwards, zero phase: its amplitude response squared, "
        "1/(1 + (f/20 Hz)^8), an 8th-order roll-off, -6 dB (half amplitude) at 20 Hz), "
        "averaged over 2 m of track, and described by the percentiles 0.15 %, 50 % "
        "and 99.85 % of the samples whose 2 m window lies inside the record (EN 14363: the "
        "99.85 % value is the estimated maximum, the estimation statistic 'p99.85'). "
        f"Processed from {source}."
    )
    doc.table(table)
