"""The run report: one self-contained HTML file (figures embedded) and a Markdown twin,
regenerated from the run directory alone (``build_report(RUN)``).

The page answers first: a summary card (the wagon, the recordings, each suspension element's
estimate with its interval and verdict, the force agreement before and after) fits the first
screen; the method's stages follow. This module reads the run directory and never imports
the pipeline (the pipeline calls it).
"""

from __future__ import annotations

import html
import re
from pathlib import Path

import pandas as pd

import railsusp.summary as summary
from railsusp.report_doc import Doc, md_row, table_html
from railsusp.report_en14363 import en14363_section
from railsusp.report_estimate import estimate_section, validation_section
from railsusp.stages import STAGES
from railsusp.store import atomic_write_bytes, atomic_write_text, file_hash, read_json

#: bracket the stale banner of :func:`mark_report_stale` (in HTML and Markdown alike), so
#: that a later marking replaces it instead of adding a second
STALE_START, STALE_END = "<!-- railsusp:stale -->", "<!-- /railsusp:stale -->"

#: CSS class of each verdict in the summary card
_VERDICT_CLASS = {
    summary.DEGRADED: "v-degraded",
    summary.WITHIN: "v-within",
    summary.NOT_IDENTIFIABLE: "v-unknown",
    summary.NOT_IDENTIFIED: "v-unknown",
}
#: the card lists what is wrong first
_ORDER = {
    summary.DEGRADED: 0,
    summary.NOT_IDENTIFIABLE: 1,
    summary.NOT_IDENTIFIED: 1,
    summary.WITHIN: 2,
}


def summary_card(doc: Doc, run: Path, read: list | None = None) -> None:
    """The answer in the first screen: wagon, recordings, per-element verdicts, forces
    (``read``: the run's field recordings, where the caller has them already)."""
    est = summary.estimate_table(run)
    tol = summary.run_tolerances(run)
    recs = summary.recordings(run, read)
    synthetic = summary.is_synthetic(run)
    with_track = bool(len(recs)) and bool(recs.measured_track.all())
    rec_text = "; ".join(
        f"{r.recording} ({r.condition}, wheel {r.wheel}, {summary.sig3(r.duration_s)} s)"
        for r in recs.itertuples()
    )
    rec_kind = ("synthetic, from a hidden truth" if synthetic else "measured") + (
        ", with their measured track geometry" if with_track else ", without track geometry"
    )
    est = est.assign(_order=[_ORDER.get(v, 3) for v in est.verdict]).sort_values(
        "_order", kind="stable"
    )
    bases = {b for b in est.interval if b}
    short = "Pareto range" if not bases or any("Pareto" in b for b in bases) else "90 % interval"
    shown = pd.DataFrame(
        {
            "suspension element": [f"{p} {e}" for p, e in zip(est.index, est.element, strict=True)],
            "unit": est.unit,
            "nominal": est.nominal,
            "estimate": [
                v if not str(vd).startswith(summary.NOT_ESTIMATED) else float("nan")
                for v, vd in zip(est.estimate, est.verdict, strict=True)
            ],
            f"interval ({short})": [
                "" if lo != lo else f"{summary.sig3(lo)} – {summary.sig3(hi)}"
                for lo, hi in zip(est.low, est.high, strict=True)
            ],
            "change from nominal (%)": [
                c if not str(vd).startswith(summary.NOT_ESTIMATED) else float("nan")
                for c, vd in zip(est.change_pct, est.verdict, strict=True)
            ],
            "verdict": [
                v + (f" ({n})" if n and v in (summary.WITHIN, summary.DEGRADED) else "")
                for v, n in zip(est.verdict, est.note, strict=True)
            ],
        }
    )
    if "polished" in est:  # NSGA-II's estimate stays the estimate; the polish beside it
        shown.insert(4, "simulator polish", est.polished.to_numpy())
    classes = [_VERDICT_CLASS.get(v, "v-held") for v in est.verdict]
    why = [
        f"{p}: {n}"
        for p, v, n in zip(est.index, est.verdict, est.note, strict=True)
        if v in (summary.NOT_IDENTIFIABLE, summary.NOT_IDENTIFIED)
    ]
    tol_text = tolerance_text(tol)
    held: dict[str, list[str]] = {}
    for p, v, n in zip(est.index, est.verdict, est.note, strict=True):
        if str(v).startswith(summary.NOT_ESTIMATED):
            held.setdefault(n, []).append(p)
    held_text = "; ".join(f"{', '.join(ps)}: {n}" for n, ps in held.items())
    basis = "; ".join(sorted(bases)) or "none"
    lines = summary.agreement_lines(summary.force_agreement(run))
    parts = [
        "<section class='card' id='summary'>",
        "<h2>Answer: the suspension of this wagon, from these recordings</h2>",
        f"<p><b>Wagon</b>: {html.escape(summary.wagon_name(run))}. <b>Recordings</b> "
        f"({html.escape(rec_kind)}): {html.escape(rec_text)}.</p>",
        table_html(shown, headers=False, row_class=classes),
        f"<p class='note'>Interval: {html.escape(basis)}. {html.escape(tol_text)}."
        + (f" Not identified: {html.escape('; '.join(why))}." if why else "")
        + (f" Not estimated ({html.escape(held_text)})." if held else "")
        + "</p>",
        "<p><b>Force error, nominal → estimated parameters</b></p><ul>",
        *(f"<li>{html.escape(line)}</li>" for line in lines),
        "</ul></section>",
    ]
    md = [
        "\n## Answer: the suspension of this wagon, from these recordings\n",
        f"Wagon: {summary.wagon_name(run)}. Recordings ({rec_kind}): {rec_text}.\n",
        md_row(list(shown.columns)),
        "|" + "---|" * len(shown.columns),
        *(
            md_row([summary.sig3(v) if isinstance(v, float) else str(v) for v in r])
            for r in shown.itertuples(index=False)
        ),
        "",
        f"Interval: {basis}. {tol_text}."
        + (f" Not identified: {'; '.join(why)}." if why else "")
        + (f" Not estimated ({held_text})." if held else ""),
        "",
        "Force error, nominal → estimated parameters:\n",
        *(f"- {line}" for line in lines),
        "",
    ]
    doc.raw("\n".join(parts), "\n".join(md))


def tolerance_text(tol: summary.Tolerances) -> str:
    """The summary card's sentence on the verdicts' tolerances, each number with its source:
    the wagon data's ``[tolerances]`` table, or railsusp's default
    (:data:`~railsusp.summary.DEFAULT_TOLERANCE_PCT`) where the table is absent or gives no
    ``default_pct`` (the default was once named beside the wagon's, as if it were the
    wagon's own)."""
    default = summary.sig3(tol.default_pct)
    listed = ", ".join(f"{p} ±{summary.sig3(v)} %" for p, v in tol.parameters.items())
    text = f"Within tolerance: change from nominal at most ±{default} %"
    in_brackets = f" ({listed})" if listed else ""
    if not tol.from_wagon:
        return (
            text + in_brackets + ", railsusp's default (the wagon data give no [tolerances], "
            "docs/wagon-data.md)"
        )
    if tol.default_pct != summary.DEFAULT_TOLERANCE_PCT:  # the table's own default_pct
        return text + in_brackets + ", all from the wagon data's [tolerances] (docs/wagon-data.md)"
    return (  # railsusp's default, unless the table's default_pct happens to repeat it
        text
        + (f" ({listed}, from the wagon data's [tolerances])" if listed else "")
        + f"; ±{default} % is railsusp's default, which the wagon data's [tolerances] "
        "keep (docs/wagon-data.md)"
    )


def _wagon_section(doc: Doc, run: Path, cfg: dict) -> None:
    from railsusp.params import CATALOGUE

    doc.h("Wagon and working conditions")
    doc.p(
        f"Wagon: {cfg['wagon']['wagon']['name']}. Sampled parameters: "
        f"{', '.join(cfg['parameters'])}; {cfg['samples']} samples ({cfg['design']})."
    )
    truth_path = run / "field" / "truth.json"
    truth = read_json(truth_path)["parameters_display"] if truth_path.exists() else {}
    wagon = cfg["wagon"]
    items = [
        ("car body mass (kg)", wagon["car_body"]["mass"]),
        ("bogie centre distance (m)", 2 * wagon["car_body"]["bogie_half_spacing"]),
        ("wheelbase (m)", 2 * wagon["bogie"]["half_wheelbase"]),
        ("wheel radius (m)", wagon["wheelset"]["rolling_radius"]),
        ("spring nest vertical stiffness (MN/m)", wagon["secondary"]["vertical_stiffness"] / 1e6),
    ]
    doc.table(pd.DataFrame(items, columns=["item", "value"]))
    doc.table(
        pd.DataFrame(
            [
                {
                    "symbol": s.symbol,
                    "parameter": s.description,
                    "unit": s.display_unit,
                    "nominal": s.nominal_display,
                    "range": ""
                    if s.bounds_display is None
                    else f"{s.bounds_display[0]:g}-{s.bounds_display[1]:g}",
                    **({"hidden truth": truth.get(s.symbol, float("nan"))} if truth else {}),
                }
                for s in CATALOGUE
                if s.is_sampled
            ]
        )
    )
    keys = (
        "name",
        "speed_kmh",
        "curve_radius_m",
        "cant_mm",
        "grade_permille",
        "coupler_force_kN",
        "irregularity_class",
        "seed",
    )
    conds = pd.DataFrame([{k: c[k] for k in keys} for c in cfg["conditions"]])
    doc.table(
        conds.rename(
            columns={
                "speed_kmh": "speed (km/h)",
                "curve_radius_m": "curve radius (m)",
                "cant_mm": "cant (mm)",
                "grade_permille": "grade (‰)",
                "coupler_force_kN": "coupler force (kN)",
                "irregularity_class": "FRA class",
                "seed": "track seed",
            }
        )
    )


def _network_set_text(doc: Doc, manifest: dict, assumed: list[dict]) -> None:
    """What a shipped network set is, how its other parameters entered its training (from
    its bundles' ``assumed_parameters``), and how to reproduce it."""
    varied = [a["symbol"] for a in assumed if a.get("assumed") == "varied"]
    held = [f"{a['symbol']} = {a.get('value')}" for a in assumed if a.get("assumed") != "varied"]
    others = []
    if varied:
        others.append(
            f"{', '.join(varied)} varied over their ranges in its training (their effect is "
            "in its spread, not held at nominal)"
        )
    if held:
        others.append(f"{', '.join(held)} held in its training")
    note = manifest.get("model_revision_note")
    laws = (
        f"It serves the force laws of revision {manifest['model_revision']}, to which it was "
        f"carried over without training: {note}. The table below gives its accuracy on "
        "held-out tracks and parameter sets, each row labelled with the force-law revision "
        "it was scored on."
        if note
        else f"Force laws of revision {manifest['model_revision']}. The table below is its "
        "accuracy on its campaign's held-out tracks and parameter sets."
    )
    doc.p(
        f"Network set '{manifest['name']}' ({manifest['kind']}, inputs "
        f"{', '.join(manifest['parameters'])}), trained once on many track realisations and "
        f"shipped with railsusp, not trained in this run: {manifest.get('description', '')} "
        + laws
        + (f" Not its inputs: {'; '.join(others)}." if others else "")
    )
    doc.p(
        ("Trained by (on the force laws of its training): " if note else "Reproduced by: ")
        + " ; ".join(manifest.get("reproduce", []))
    )


def _method_sections(doc: Doc, run: Path, state: dict) -> None:
    from railsusp.key_parameters import read_key_parameters

    camp = run / "campaign"
    sens = camp / "sensitivity"
    if (sens / "key_parameters.json").exists():
        doc.h("Sobol sensitivity and key parameters (study Figure 2)")
        kp = read_key_parameters(camp)["key_parameters"]  # of this campaign, or refused
        doc.p(f"Key parameters: {', '.join(kp['keys'])}. Rule: {kp['rule']}.")
        doc.table(pd.read_csv(sens / "study_comparison.csv"))
        for png in sorted(sens.glob("sobol-*.png")):
            doc.figure(png, f"Sobol indices, statistic '{png.stem.removeprefix('sobol-')}'")

    from railsusp.surrogate.pretrained import MANIFEST, surrogates_run

    scfg = state.get("config", {}).get("surrogate", {})
    pretrained, own = scfg.get("pretrained"), scfg.get("samples", 0)
    sur_camp = run / surrogates_run(pretrained, own)
    sur = sur_camp / "surrogates"
    if (sur / "compare.csv").exists():
        from railsusp.surrogate.compare import table7

        doc.h("Surrogates on held-out simulations (study Table 7, Figures 10/11)")
        if pretrained is not None and (sur / MANIFEST).exists():
            manifest = read_json(sur / MANIFEST)
            first = sur / manifest["kind"] / manifest["conditions"][0] / "surrogate.json"
            meta = read_json(first).get("meta", {}) if first.exists() else {}
            _network_set_text(doc, manifest, meta.get("assumed_parameters") or [])
        elif own:
            sc = read_json(sur_camp / "campaign.json")["config"]
            doc.p(
                f"Trained on their own campaign: {sc['samples']} LHS samples of the key "
                f"parameters ({', '.join(sc['parameters'])}), the others nominal, as the "
                "estimation uses them; split into train, validation and test runs by sample."
            )
        else:
            doc.p(
                "Trained on the sensitivity campaign: the parameters that are not inputs "
                "vary there unseen and limit the surrogates' accuracy."
            )
        table = table7(pd.read_csv(sur / "compare.csv"))
        alone = [c for c in table.columns if "network alone" in str(c)]
        if alone and table[alone].notna().to_numpy().any():  # only where a network has one
            doc.p(
                "The window networks' series are scaled by a record correction, a Gaussian "
                "process of the record mean's error fitted on the training runs; the column "
                "'network alone' gives the lateral error without it."
            )
        doc.table(table)
        for png in sorted(sur.glob("overlay-*.png")):
            doc.figure(png, png.stem.replace("overlay-", "Held-out run, "))

    est = run / "estimate"
    if (est / "estimate.csv").exists():
        estimate_section(doc, est)
    validation_section(doc, est / "validation")


def _provenance(doc: Doc, run: Path, state: dict, meta: dict) -> None:
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
    _wagon_section(doc, run, cfg)
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
    _method_sections(doc, run, state)
    en14363_section(doc, run, read)
    _provenance(doc, run, state, meta)
    html_path = atomic_write_bytes(run / "report.html", doc.page(title).encode())
    md_path = atomic_write_bytes(run / "report.md", "\n".join(doc.md).encode())
    return [html_path, md_path]


def stale_text(stage: str, by: str | None = None) -> str:
    """The stale banner's words: why the report no longer answers for the run directory
    and what to do. ``by``: the standalone command (``railsusp estimate``) started on the
    folder of ``stage`` outside ``railsusp run``; running that command again would not
    remake the report, ``railsusp run`` does."""
    if by is not None:
        return (
            f"STALE: `{by}` was started on the outputs of this run directory's stage "
            f"'{stage}' after this report was made, outside `railsusp run`, so the answer "
            "below may no longer be what the run directory holds. `railsusp run` with the "
            "run directory's configuration on this folder makes the changed stages and this "
            "report again (it replaces that command's outputs with the configuration's)."
        )
    return (
        "STALE: this report was made by an earlier run of this run directory, before its "
        f"stage '{stage}' was started again (a changed configuration, changed files or a "
        "restart from a stage). That run has not finished (it is running, failed or was "
        "interrupted), so the answer below is the earlier run's and may not match the run "
        "directory's configuration. Run the same command again to remake the report "
        "(pipeline.json says which stages are stale)."
    )


def mark_report_stale(run: str | Path, stage: str, by: str | None = None) -> list[Path]:
    """Put a stale banner at the top of ``RUN/report.html`` and ``RUN/report.md``, where
    they exist, when ``stage`` starts to run again: the pipeline marks the report stage
    stale then (every later stage runs again), and the files, which the command line points
    to, must not present the run before's estimate as the answer if the run fails or is
    interrupted. ``by``: a standalone command (``railsusp estimate --out RUN/estimate``)
    about to write the stage's outputs instead (:func:`stale_text`). A banner already there
    is replaced; :func:`build_report` writes the files anew, without it. Returns the files
    marked."""
    run = Path(run)
    text = stale_text(stage, by)
    marked = []
    banners = {
        "report.html": (
            "<div role='alert' style='border:3px solid #a40000;background:#fff0f0;"
            "color:#a40000;font-weight:bold;padding:.5em .8em;margin:.5em 0'>"
            f"{html.escape(text)}</div>"
        ),
        "report.md": f"> **{text}**\n",  # a blank line after it ends the quote
    }
    for name, banner in banners.items():
        path = run / name
        if not path.is_file():
            continue
        old = path.read_text("utf-8", errors="replace")
        old = re.sub(
            re.escape(STALE_START) + r".*?" + re.escape(STALE_END) + r"\n?", "", old, flags=re.S
        )
        block = f"{STALE_START}\n{banner}\n{STALE_END}\n"  # markers on lines of their own
        body = re.search(r"<body[^>]*>", old) if name.endswith(".html") else None
        new = old[: body.end()] + block + old[body.end() :] if body else block + old
        marked.append(atomic_write_text(path, new))
    return marked
