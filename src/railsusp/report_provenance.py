"""The report's provenance section: what made this run, so that its answer can be traced
and repeated. The run's recorded provenance, each stage's state, time, input hash and the
railsusp code that made it (a stage kept from an earlier run says so), the campaign
configuration's hash, and the SHA-256 of the data files the answer rests on (design,
features, the recordings and the surrogate files the estimate ran on).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from railsusp.report_doc import Doc
from railsusp.stages import STAGES
from railsusp.store import file_hash


def provenance_section(doc: Doc, run: Path, state: dict, meta: dict) -> None:
    """Who and what made the run: its provenance record, each stage's state, hash and the
    code that made it, and the SHA-256 of the data files it read, so that a reader can tell
    whether two reports describe the same run."""
    doc.h("Provenance")
    prov = state.get("provenance", {})
    doc.table(pd.DataFrame([{"item": k, "value": str(v)} for k, v in prov.items()]))
    rows = []
    stages = state.get("stages", {})  # pipeline.json keeps them by name: put in order
    for s, v in ((s, stages[s]) for s in STAGES if s in stages):
        writing = s == "report" and v.get("state") == "running"
        rows.append(
            {
                "stage": s,
                "state": "writing this report" if writing else v.get("state"),
                "seconds": v.get("seconds", float("nan")),
                "input hash": v.get("hash"),
                "made by": _made_by(v.get("made_by")),
            }
        )
    doc.table(pd.DataFrame(rows))
    makers = {r["made by"] for r in rows if r["made by"]}
    if len(makers) > 1:
        doc.p(
            "The stages were made by different railsusp code ("
            + ", ".join(sorted(makers))
            + "): a stage that was up to date was kept from the run that made it."
        )
    doc.p(f"Campaign configuration hash {meta['config_hash']}.")
    camp = run / "campaign"
    files = [
        camp / "design.parquet",
        camp / "features.parquet",
        *sorted((run / "field").glob("*.csv")),
        *sorted((run / "field").glob("*.parquet")),
        *_estimate_networks(run, state),
    ]
    doc.table(
        pd.DataFrame(
            [
                {"data file": str(f.relative_to(run)), "sha256": file_hash(f)[:16]}
                for f in files
                if f.exists()
            ]
        )
    )


def _estimate_networks(run: Path, state: dict) -> list[Path]:
    """The surrogate files the estimate ran on: its configured model's folder in the run's
    surrogates folder (:func:`~railsusp.surrogate.pretrained.surrogates_run`), its networks
    (``model.pt``) or statistics surrogates (``statistics.json``). A glob over every
    ``surrogate*`` folder listed another configuration's leftovers and missed the
    sensitivity campaign's networks that a configuration of ``samples = 0`` ran on."""
    from railsusp.surrogate.pretrained import surrogates_run

    scfg = state.get("config", {}).get("surrogate", {})
    model = scfg.get("model")
    if not model:  # a pipeline.json without its configuration: nothing to name
        return []
    folder = run / surrogates_run(scfg.get("pretrained"), scfg.get("samples", 0))
    folder = folder / "surrogates" / model
    return sorted([*folder.glob("**/model.pt"), *folder.glob("**/statistics.json")])


def _made_by(made: dict | None) -> str:
    """A stage's code, short: version, commit (7 hex digits) and "+modified" where its
    tree had uncommitted changes; '' for a stage recorded before this was."""
    if not made:
        return ""
    sha = (made.get("git_sha") or "")[:7]
    return (
        f"{made.get('railsusp', '?')}"
        + (f" {sha}" if sha else "")
        + ("+modified" if made.get("git_dirty") else "")
    )
