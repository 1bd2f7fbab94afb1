"""The report's sections on how the answer was found, in the method's order: the wagon and
the working conditions its campaign simulated, Sobol sensitivity and the key parameters
(study Figure 2; the features the key rule left out named and their panels marked), the
surrogate force models on held-out simulations (study Table 7, trained here or a shipped
network set; the row of the model the estimate ran on marked), then the estimate and its
validation (:mod:`railsusp.report_estimate`). Each section is written only where its stage
left its outputs in the run directory, which is all it reads.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from railsusp.report_doc import Doc
from railsusp.report_estimate import (
    ROLE_COMPARED,
    ROLE_USED,
    estimate_section,
    force_model_name,
    validation_section,
)
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
    carried = manifest.get("carried_over") or []
    some = [c for c in manifest.get("conditions", []) if c not in carried]
    if note and carried and some:  # a set of networks trained on today's laws and others not
        laws = (
            f"It serves the force laws of revision {manifest['model_revision']}: its "
            f"{', '.join(some)} network{'s were' if len(some) > 1 else ' was'} trained on "
            f"them, its {', '.join(carried)} network{'s were' if len(carried) > 1 else ' was'} "
            f"carried over to them without training ({note}). The table below gives its "
            "accuracy on held-out tracks and parameter sets, each row labelled with the "
            "force-law revision it was scored on where it was carried over."
        )
    elif note:
        laws = (
            f"It serves the force laws of revision {manifest['model_revision']}, to which it "
            f"was carried over without training: {note}. The table below gives its accuracy "
            "on held-out tracks and parameter sets, each row labelled with the force-law "
            "revision it was scored on."
        )
    else:
        laws = (
            f"Force laws of revision {manifest['model_revision']}. The table below is its "
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


#: the models of the study's comparison that ``surrogate.model`` does not accept
BASELINES = {"rbf": "a radial-basis-function baseline of the study's Table 7"}


def estimate_model(run: Path, state: dict) -> str | None:
    """The force model the run's estimate ran on: ``estimate.json``'s ``model`` (a model's
    name; ``railsusp estimate`` records its surrogate's folder, whose name is the model's,
    or "simulator"), else the configuration's ``surrogate.model`` where no estimate was
    made yet; None where neither says."""
    path = run / "estimate" / "estimate.json"
    model = None
    if path.exists():
        info = read_json(path)
        model = info.get("model") if isinstance(info, dict) else None
    if model is None:
        model = state.get("config", {}).get("surrogate", {}).get("model")
    return force_model_name(model)


def model_name(label: object) -> str:
    """A Table 7 row's model without the force-law revision a network set's rows are
    labelled with ("cnn-gru-seq (revision 2026-11-30.1)": scored on those laws)."""
    return str(label).split(" (revision ")[0]


#: a network set's row of a condition the run does not have (the set is installed whole)
ROLE_NOT_RUN = "not a condition of this run"


def _run_conditions(run: Path) -> set[str]:
    """The names of the run's working conditions (its campaign's), empty where unknown."""
    from railsusp.summary_files import campaign_config

    if not (run / "campaign" / "campaign.json").exists():
        return set()
    conds = campaign_config(run).get("conditions") or []
    return {c["name"] for c in conds if isinstance(c, dict) and "name" in c}


def _network_set_inputs(run: Path, state: dict) -> list[str]:
    """The inputs of the network set the run's surrogate stage installed (the estimate's
    parameters on that route), empty where it ran on surrogates of its own."""
    from railsusp.surrogate.network_set import MANIFEST
    from railsusp.surrogate.pretrained import surrogates_run

    scfg = state.get("config", {}).get("surrogate", {})
    pretrained = scfg.get("pretrained")
    if pretrained is None:
        return []
    path = run / surrogates_run(pretrained, scfg.get("samples", 0)) / "surrogates" / MANIFEST
    return list(read_json(path).get("parameters") or []) if path.exists() else []


def surrogate_roles_text(used: str | None, models: list[str]) -> str:
    """Which of the Surrogates table's ``models`` the estimate ran on (``used``,
    :func:`estimate_model`) and that the others are compared only: the table listed bp,
    rbf and gp-stats without a word, and rbf, the most accurate there, is a baseline that
    ``surrogate.model`` refuses."""
    others = [m for m in models if m != used]
    baselines = [
        f"{m} is {BASELINES[m]}, not a model surrogate.model accepts"
        for m in others
        if m in BASELINES
    ]
    if used == "simulator":
        head = (
            "The estimate ran on the simulator itself, not on a surrogate: every row is "
            "comparison only."
        )
    elif used is None:
        head = "Which of these models the estimate ran on is not recorded."
    elif used in models:
        compared = f"; {', '.join(others)}: comparison only" if others else ""
        head = (
            f"The estimate (NSGA-II) ran on {used} (surrogate.model), the rows marked "
            f"'{ROLE_USED}'{compared}."
        )
    else:
        head = f"The estimate ran on {used} (surrogate.model), which has no row here."
    return head + (f" Of these, {'; '.join(baselines)}." if baselines else "")


def _indices(sens: Path) -> pd.DataFrame | None:
    """The Sobol indices of ``sens`` (``indices.parquet``, checked to be of its campaign),
    or None where the file is absent."""
    from railsusp.key_parameters import check_sensitivity_output
    from railsusp.store import read_parquet

    path = sens / "indices.parquet"
    if not path.exists():
        return None
    check_sensitivity_output(path)
    return read_parquet(path, f"railsusp sensitivity {sens.parent} again")


def _sobol_figures(
    doc: Doc,
    run: Path,
    sens: Path,
    analysis: dict,
    indices: pd.DataFrame | None,
    left_out: dict[str, str],
) -> None:
    """The Sobol figures of the sensitivity stage, with the features the key rule left out
    (``left_out``) marked: the stage's own where it marked them (``figures_marked`` in
    ``key_parameters.json``), else drawn again into ``RUN/report_assets`` (a stage run
    before its figures were marked) where the indices are read; a statistic the rule does
    not read is said so in its caption."""
    from railsusp.key_parameters import FIGURES_MARKED
    from railsusp.report import plot_sobol

    stage_marked = bool(analysis.get(FIGURES_MARKED))
    rule_stats = list(analysis["key_parameters"].get("statistics") or [])
    assets = run / "report_assets"
    drawn = set()
    for png in sorted(sens.glob("sobol-*.png")):
        st = png.stem.removeprefix("sobol-")
        caption = f"Sobol indices, statistic '{st}'"
        if rule_stats and st not in rule_stats:
            caption += f" (not one the key rule reads: {', '.join(rule_stats)})"
        marked = [f for f in left_out if f.endswith(f" {st}")]
        redraw = not stage_marked and indices is not None and (indices.statistic == st).any()
        if marked and redraw:
            png = plot_sobol(indices, assets / png.name, statistic=st, left_out=left_out)
            drawn.add(png.name)
        if marked and (stage_marked or redraw):
            caption += "; grey panels: left out of the key rule (" + ", ".join(marked) + ")"
        doc.figure(png, caption)
    for old in assets.glob("sobol-*.png"):  # an earlier report's, of what is not marked now
        if old.name not in drawn:
            old.unlink()


def method_sections(doc: Doc, run: Path, state: dict) -> None:
    """The method's stages as the run made them, in the study's order: Sobol sensitivity
    and the key parameters, the surrogates, the estimate and its validation."""
    from railsusp.key_parameters import left_out_features, read_key_parameters

    camp = run / "campaign"
    sens = camp / "sensitivity"
    if (sens / "key_parameters.json").exists():
        doc.h("Sobol sensitivity and key parameters (study Figure 2)")
        analysis = read_key_parameters(camp)  # of this campaign, or refused
        kp = analysis["key_parameters"]
        doc.p(f"Key parameters: {', '.join(kp['keys'])}. Rule: {kp['rule']}.")
        inputs = _network_set_inputs(run, state)
        if inputs and set(inputs) != set(kp["keys"]):
            doc.p(
                "The estimate's parameters are not these: a network set's are its inputs "
                f"({', '.join(inputs)}), whatever this campaign's key parameters."
            )
        doc.table(pd.read_csv(sens / "study_comparison.csv"))
        indices = _indices(sens)
        left_out = left_out_features(analysis, indices)
        if left_out:
            grey = " (their panels are grey in the figure)" if indices is not None else ""
            doc.p(
                f"Left out of the key rule, whatever their indices{grey}: "
                + "; ".join(f"{f}: {why}" for f, why in left_out.items())
                + "."
            )
        _sobol_figures(doc, run, sens, analysis, indices, left_out)

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
        used = estimate_model(run, state)
        models = [model_name(m) for m in table.model]
        ran = _run_conditions(run)
        roles = [
            ROLE_COMPARED if m != used else ROLE_USED if not ran or c in ran else ROLE_NOT_RUN
            for m, c in zip(models, table.condition, strict=True)
        ]
        table.insert(2, "role", roles)
        doc.p(surrogate_roles_text(used, list(dict.fromkeys(models))))
        if ROLE_NOT_RUN in roles:
            doc.p(
                "Rows marked '" + ROLE_NOT_RUN + "' are the network set's networks of "
                "conditions this run has none of: the estimate did not use them."
            )
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
