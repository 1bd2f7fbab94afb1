"""The report's provenance section: what made this run, so that its answer can be traced
and repeated. The run's recorded provenance, each stage's state, time, input hash and the
railsusp code that made it (a stage kept from an earlier run says so), the campaign
configuration's hash, and the SHA-256 (its first 16 hex digits) of the data files the answer
rests on (design, features, the recordings and the surrogate files the estimate ran on).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from railsusp.report_doc import Doc
from railsusp.stages import STAGES
from railsusp.store import file_hash

#: the data files' hash column: the SHA-256's first 16 hex digits, not the whole hash
HASH_HEADER = "sha256 (first 16 hex digits)"
#: labels of the provenance record's times (``utc``: when the run's stages began)
STARTED = "started (UTC)"
FINISHED = "finished (UTC)"


def provenance_rows(prov: dict, stages: dict) -> list[dict]:
    """The provenance record ``prov`` as the report's rows (item, value), its times first:
    ``utc`` is when the run started (it read as a bare "utc"), ``finished`` when it
    finished, which the run records after its report (while the report is written that is
    said, with the time the stage before it finished, from ``stages``)."""
    rows = []
    if "utc" in prov:
        rows.append({"item": STARTED, "value": str(prov["utc"])})
        rows.append({"item": FINISHED, "value": _finished(prov, stages)})
    rows += [{"item": k, "value": str(v)} for k, v in prov.items() if k not in ("utc", "finished")]
    return rows


def _finished(prov: dict, stages: dict) -> str:
    """When the run finished, as recorded (``finished``); while its report, the run's last
    stage, is written that is not yet recorded: said so, with the time the last stage of
    this run before the report finished (one kept from an earlier run is not this run's)."""
    if prov.get("finished"):
        return str(prov["finished"])
    started = str(prov.get("utc", ""))
    done = [
        (str(v["finished"]), s)
        for s, v in stages.items()
        if isinstance(v, dict) and v.get("finished") and s != "report"
        and str(v["finished"]) >= started
    ]  # fmt: skip
    text = "not recorded yet: the run finishes with this report"
    if done:
        at, stage = max(done)
        text += f" (its stage before it, {stage}, finished {at})"
    return text


def provenance_section(doc: Doc, run: Path, state: dict, meta: dict) -> None:
    """Who and what made the run: its provenance record, each stage's state, hash and the
    code that made it, and the SHA-256 of the data files it read, so that a reader can tell
    whether two reports describe the same run."""
    doc.h("Provenance")
    stages = state.get("stages", {})  # pipeline.json keeps them by name: put in order
    doc.table(pd.DataFrame(provenance_rows(state.get("provenance", {}), stages)))
    rows = []
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
                {"data file": str(f.relative_to(run)), HASH_HEADER: file_hash(f)[:16]}
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
