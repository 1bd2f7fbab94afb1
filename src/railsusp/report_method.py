"""The report's sections on how the answer was found, in the method's order: the wagon and
the working conditions its campaign simulated, Sobol sensitivity and the key parameters
(study Figure 2), the surrogate force models on held-out simulations (study Table 7, trained
here or a shipped network set), then the estimate and its validation
(:mod:`railsusp.report_estimate`). Each section is written only where its stage left its
outputs in the run directory, which is all it reads.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from railsusp.report_doc import Doc
from railsusp.report_estimate import estimate_section, validation_section
from railsusp.store import read_json


def wagon_section(doc: Doc, run: Path, cfg: dict) -> None:
    """The wagon's data, the sampled parameters' catalogue and the working conditions, from
    the run's configuration ``cfg``: what the method was applied to, before its stages."""
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


def method_sections(doc: Doc, run: Path, state: dict) -> None:
    """The method's stages as the run made them, in the study's order: Sobol sensitivity
    and the key parameters, the surrogates, the estimate and its validation."""
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

    from railsusp.surrogate.network_set import MANIFEST
    from railsusp.surrogate.pretrained import surrogates_run

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
