"""The run report: one self-contained HTML file (figures embedded) and a Markdown twin,
regenerated from the run directory alone (``build_report(RUN)``)."""

from __future__ import annotations

import base64
import html
from pathlib import Path

import pandas as pd

from railsusp.store import atomic_write_bytes, file_hash, read_json

CSS = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;
color:#222}table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#f2f2f2}
td:first-child,th:first-child{text-align:left}img{max-width:100%;border:1px solid #eee}
h2{border-bottom:2px solid #ddd;padding-bottom:.2em;margin-top:2em}.note{color:#555}"""


#: marks every image that decoded (``data-ok="true"``), for the headless-browser test
_IMG_CHECK = (
    "<script>window.addEventListener('load',()=>{for(const i of "
    "document.images){i.dataset.ok=String(i.complete&&i.naturalWidth>0)}});</script>"
)


class _Doc:
    """Collects sections; renders HTML (embedded images) and Markdown (linked images)."""

    def __init__(self, root: Path):
        self.root = root
        self.html: list[str] = []
        self.md: list[str] = []
        self.figures: list[Path] = []

    def h(self, text: str, level: int = 2) -> None:
        self.html.append(f"<h{level}>{html.escape(text)}</h{level}>")
        self.md.append(f"\n{'#' * level} {text}\n")

    def p(self, text: str) -> None:
        self.html.append(f"<p class='note'>{html.escape(text)}</p>")
        self.md.append(f"{text}\n")

    def table(self, df: pd.DataFrame, floatfmt: str = "{:.4g}") -> None:
        def cell(v):
            if isinstance(v, float):
                return "" if v != v else floatfmt.format(v)
            return str(v)

        head = "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns)
        rows = "".join(
            "<tr>" + "".join(f"<td>{html.escape(cell(v))}</td>" for v in r) + "</tr>"
            for r in df.itertuples(index=False)
        )
        self.html.append(f"<table><tr>{head}</tr>{rows}</table>")
        self.md.append("| " + " | ".join(map(str, df.columns)) + " |")
        self.md.append("|" + "---|" * len(df.columns))
        for r in df.itertuples(index=False):
            self.md.append("| " + " | ".join(cell(v) for v in r) + " |")
        self.md.append("")

    def figure(self, path: Path, caption: str) -> None:
        if not path.exists():
            self.p(f"(figure missing: {path.name})")
            return
        data = base64.b64encode(path.read_bytes()).decode()
        self.html.append(
            f"<figure><img alt='{html.escape(caption)}' "
            f"src='data:image/png;base64,{data}'><figcaption>"
            f"{html.escape(caption)}</figcaption></figure>"
        )
        self.md.append(f"![{caption}]({path.relative_to(self.root)})\n")
        self.figures.append(path)


def build_report(run: str | Path) -> list[Path]:
    """Write ``RUN/report.html`` and ``RUN/report.md`` from the stages' outputs."""
    from railsusp.report import plot_track_irregularities
    from railsusp.vehicle.track import irregularities_for

    run = Path(run)
    state = read_json(run / "pipeline.json")
    camp = run / "campaign"
    meta = read_json(camp / "campaign.json")
    doc = _Doc(run)
    title = state.get("config", {}).get("name", "railsusp run")
    doc.h(f"railsusp report: {title}", 1)
    doc.p(
        "Suspension parameter estimation of a heavy-haul wagon from wheel-rail forces: "
        "campaign, Sobol sensitivity, surrogate, NSGA-II estimation, validation."
    )

    doc.h("Wagon and working conditions")
    cfg = meta["config"]
    doc.p(
        f"Wagon: {cfg['wagon']['wagon']['name']}. Sampled parameters: "
        f"{', '.join(cfg['parameters'])}; {cfg['samples']} samples ({cfg['design']})."
    )
    from railsusp.params import CATALOGUE

    truth_path = run / "field" / "truth.json"
    truth = read_json(truth_path)["parameters_display"] if truth_path.exists() else {}
    wagon = cfg["wagon"]
    doc.table(
        pd.DataFrame(
            [
                {"item": "car body mass, kg", "value": wagon["car_body"]["mass"]},
                {
                    "item": "bogie centre distance, m",
                    "value": 2 * wagon["car_body"]["bogie_half_spacing"],
                },
                {"item": "wheelbase, m", "value": 2 * wagon["bogie"]["half_wheelbase"]},
                {"item": "wheel radius, m", "value": wagon["wheelset"]["rolling_radius"]},
                {
                    "item": "spring nest vertical stiffness, N/m",
                    "value": wagon["secondary"]["vertical_stiffness"],
                },
            ]
        )
    )
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
    conds = pd.DataFrame(
        [
            {
                k: c[k]
                for k in (
                    "name",
                    "speed_kmh",
                    "curve_radius_m",
                    "cant_mm",
                    "grade_permille",
                    "coupler_force_kN",
                    "irregularity_class",
                    "seed",
                )
            }
            for c in cfg["conditions"]
        ]
    )
    doc.table(conds)

    doc.h("Track input")
    from railsusp.conditions import WorkingCondition

    first = WorkingCondition(**cfg["conditions"][0])
    irr = irregularities_for(first)
    if irr is not None:
        png = plot_track_irregularities(irr, run / "report_assets" / "track.png")
        doc.figure(png, f"Irregularities of '{first.name}' and their PSD vs the FRA spectrum")

    sens = camp / "sensitivity"
    if (sens / "key_parameters.json").exists():
        doc.h("Sobol sensitivity and key parameters (study Figure 2)")
        kp = read_json(sens / "key_parameters.json")["key_parameters"]
        doc.p(f"Key parameters: {', '.join(kp['keys'])}. Rule: {kp['rule']}.")
        doc.table(pd.read_csv(sens / "study_comparison.csv"))
        for png in sorted(sens.glob("sobol-*.png")):
            doc.figure(png, f"Sobol indices, statistic '{png.stem.removeprefix('sobol-')}'")

    own = state.get("config", {}).get("surrogate", {}).get("samples", 0)
    sur_camp = run / "surrogate-campaign"
    sur = (sur_camp if own else camp) / "surrogates"
    if (sur / "compare.csv").exists():
        from railsusp.surrogate.compare import table7

        doc.h("Surrogates on held-out simulations (study Table 7, Figures 10/11)")
        if own:
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
        doc.p(
            "The window networks' series are scaled by a record correction, a Gaussian "
            "process of the record mean's error fitted on the training runs; the column "
            "'network alone' gives the lateral error without it."
        )
        doc.table(table7(pd.read_csv(sur / "compare.csv")))
        for png in sorted(sur.glob("overlay-*.png")):
            doc.figure(png, png.stem.replace("overlay-", "Held-out run, "))

    est = run / "estimate"
    if (est / "estimate.csv").exists():
        doc.h("NSGA-II estimation (study Tables 3-5, Figures 8/9)")
        log = pd.read_csv(est / "nsga_log.csv")
        doc.p("First and last generations of the NSGA-II log:")
        doc.table(pd.concat([log.head(4), log.tail(4)]))
        ref = read_json(est / "estimate.json").get("refinement")
        if ref:
            doc.p(
                "NSGA-II's choice (nsga_estimate) was refined by output-error least squares "
                "with the simulator on the recordings' measured track: time-aligned cost "
                f"{ref['cost_start']:.4g} -> {ref['cost']:.4g} in {ref['n_evaluations']} "
                "evaluations; standard errors assume white residuals (optimistic)"
                + (
                    f" and include the track geometry's stated measurement error "
                    f"(geometry_error_pct_range, from {ref['geometry_draws']} draws of it)."
                    if ref.get("geometry_draws")
                    else "."
                )
                + (
                    " The estimate is the refined point less the bias those draws estimate "
                    "(geometry_bias_pct_range, the first SIMEX step)."
                    if ref.get("geometry_bias_removed")
                    else ""
                )
            )
        bound = read_json(est / "estimate.json").get("cramer_rao_pct_range") or {}
        if bound:
            doc.p(
                "cramer_rao_pct_range: the smallest standard deviation (% of the range) that "
                "any estimator can reach from these statistics (Cramér-Rao bound at the "
                "estimate); above 5 % the data cannot fix the parameter to that precision."
            )
        doc.table(pd.read_csv(est / "estimate.csv"))
        doc.figure(est / "pareto.png", "Pareto front")
        doc.figure(est / "convergence.png", "Convergence of the estimate")

    val = est / "validation"
    if (val / "validation.csv").exists():
        doc.h("Validation before and after calibration (study Tables 8/9, Figures 12/13)")
        doc.table(pd.read_csv(val / "validation.csv"))
        for line in read_json(val / "validation.json").get("failures", []):
            doc.p(f"Simulation stopped (its rows are empty): {line}")
        for png in sorted(val.glob("validation-*.png")):
            doc.figure(png, png.stem.replace("validation-", "Measured vs simulated, "))
        if (val / "recovery.csv").exists():
            doc.h("Parameter recovery against the hidden truth", 3)
            doc.table(pd.read_csv(val / "recovery.csv"))

    doc.h("Provenance")
    prov = state.get("provenance", {})
    doc.table(pd.DataFrame([{"item": k, "value": str(v)} for k, v in prov.items()]))
    from railsusp.pipeline import STAGES

    stages = state.get("stages", {})
    rows = [
        {
            "stage": s,
            "state": stages[s].get("state"),
            "seconds": stages[s].get("seconds", float("nan")),
            "input hash": stages[s].get("hash"),
        }
        for s in STAGES
        if s in stages
    ]
    doc.table(pd.DataFrame(rows))
    doc.p(f"Campaign configuration hash {meta['config_hash']}.")
    files = [
        camp / "design.parquet",
        camp / "features.parquet",
        *sorted((run / "field").glob("*.csv")),
        *sorted((run / "field").glob("*.parquet")),
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
    page = (
        f"<!doctype html><html><head><meta charset='utf-8'><title>"
        f"{html.escape(title)}</title><style>{CSS}</style></head><body>"
        + "\n".join(doc.html)
        + _IMG_CHECK
        + "</body></html>"
    )
    html_path = atomic_write_bytes(run / "report.html", page.encode())
    md_path = atomic_write_bytes(run / "report.md", "\n".join(doc.md).encode())
    return [html_path, md_path]
