"""The report QA pass's findings, on hand-made run directories (seconds, no pipeline run):
the surrogate the estimate ran on, the recovery table's three-way verdict (report and
``railsusp validate``), the features the key rule left out of the Sobol figures, the
provenance's libraries and labels, and the Markdown twin's escaping of the user's text."""

import json
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from railsusp import summary
from railsusp.params import ParameterSet
from railsusp.report_doc import Doc
from railsusp.report_estimate import estimate_section, validation_section
from railsusp.report_method import method_sections
from railsusp.report_provenance import provenance_section
from railsusp.report_summary_card import summary_card
from test_report_audit import ROWS, md_tables
from test_report_audit import make_run as card_run
from test_summary import make_run as summary_run
from test_summary import write

#: the tiny run's Table 7 (RUN/surrogate-campaign/surrogates/compare.csv), shortened
COMPARE = [
    ("bp", "Y", 4.73, 3.45, 0.270),
    ("bp", "Q", 120.4, 120.0, 0.0034),
    ("rbf", "Y", 4.73, 4.78, 0.0104),
    ("rbf", "Q", 120.4, 120.4, 0.00025),
    ("gp-stats", "Y", 4.73, 4.67, 0.0127),
    ("gp-stats", "Q", 120.4, 120.4, 0.00004),
]


def surrogate_run(root: Path, model: str | None, label: str = "{}") -> Path:
    """A run directory holding the surrogates' comparison (trained on the sensitivity
    campaign, ``samples = 0``; each row's model as ``label`` formats it) and an
    estimate.json recording ``model`` (None: none)."""
    sur = root / "campaign" / "surrogates"
    sur.mkdir(parents=True)
    pd.DataFrame(
        [
            {
                "condition": "short",
                "model": label.format(m),
                "target": t,
                "simulated_mean_kN": sim,
                "predicted_mean_kN": pred,
                "relative_error_of_mean": err,
                "relative_error_of_pooled_mean": err,
                "nrmse": 0.1,
                "r2": 0.9,
            }
            for m, t, sim, pred, err in COMPARE
        ]
    ).to_csv(sur / "compare.csv", index=False)
    info = {"parameters": ["X13"]} | ({"model": model} if model else {})
    write(root / "estimate" / "estimate.json", info)
    return root


def sections(run: Path, config_model: str = "bp") -> tuple[str, list]:
    doc = Doc(run)
    state = {"config": {"surrogate": {"model": config_model, "pretrained": None, "samples": 0}}}
    method_sections(doc, run, state)
    return "\n".join(doc.md), md_tables(doc.md)


def test_the_surrogates_table_marks_the_model_the_estimate_ran_on(tmp_path):
    """bp (lateral error 27 %), rbf (1.04 %) and gp-stats (1.27 %) were listed without a word
    on which one NSGA-II used; rbf, the best there, is a baseline surrogate.model refuses."""
    text, tables = sections(surrogate_run(tmp_path, "bp"))
    (table,) = [t for t in tables if "model" in t[0]]
    head, *rows = table
    role = {r[head.index("model")]: r[head.index("role in this run")] for r in rows}
    assert role == {
        "bp": "the estimate's force model",
        "rbf": "comparison only",
        "gp-stats": "comparison only",
    }
    assert "The estimate (NSGA-II) ran on bp (surrogate.model)" in text
    assert "rbf is a radial-basis-function baseline" in text
    assert "not a model surrogate.model accepts" in text
    # estimate.json says which, not the configuration (which may have changed since)
    text, tables = sections(surrogate_run(tmp_path / "gp", "gp-stats"), config_model="bp")
    (table,) = [t for t in tables if "model" in t[0]]
    marked = [r[1] for r in table[1:] if r[2] == "the estimate's force model"]
    assert marked == ["gp-stats"] and "ran on gp-stats" in text
    # a network set's rows name the force laws they were scored on: the model all the same
    run = surrogate_run(tmp_path / "set", "bp", label="{} (revision 2026-11-30.1)")
    text, tables = sections(run)
    (table,) = [t for t in tables if "model" in t[0]]
    marked = [r[1] for r in table[1:] if r[2] == "the estimate's force model"]
    assert marked == ["bp (revision 2026-11-30.1)"]


def test_the_nsga_section_names_its_force_model(tmp_path):
    est = tmp_path / "estimate"
    est.mkdir()
    pd.DataFrame({"n_gen": [1, 2], "n_eval": [6, 12]}).to_csv(est / "nsga_log.csv", index=False)
    pd.DataFrame({"parameter": ["X13"], "estimate": [15.9]}).to_csv(
        est / "estimate.csv", index=False
    )
    info = {"parameters": ["X13"], "choice_rule": "closest to the ideal point", "model": "bp"}
    write(est / "estimate.json", info)
    doc = Doc(tmp_path)
    estimate_section(doc, est)
    text = "\n".join(doc.md)
    assert "NSGA-II ran on the surrogate bp (surrogate.model)" in text
    assert "its rows are marked 'the estimate's force model'" in text
    # railsusp estimate records its surrogate's folder, or the simulator
    info["model"] = "/runs/a/surrogate-campaign/surrogates/cnn-gru"
    write(est / "estimate.json", info)
    doc = Doc(tmp_path)
    estimate_section(doc, est)
    said = "\n".join(doc.md)
    assert "ran on the surrogate cnn-gru:" in said and "surrogate.model" not in said


def recovery_of(run: Path, max_st: dict) -> pd.DataFrame:
    """The validator's recovery table of ``run``'s estimate against a truth at nominal, with
    ``max_st`` as the sensitivity's largest total indices."""
    from railsusp.validate import _recovery

    est = json.loads((run / "estimate" / "estimate.json").read_text())
    sens = run / "campaign" / "sensitivity" / "key_parameters.json"
    write(sens, {"key_parameters": {"keys": est["parameters"], "max_st": max_st}})
    chosen = ParameterSet(est["estimate_display"], units="display")
    return _recovery(est["parameters"], chosen, ParameterSet.nominal(), est, sens)


def test_the_recovery_verdict_is_the_summary_cards(tmp_path):
    """NSGA-II alone (a Pareto range): 'identifiable = no, why not identifiable: no
    confidence interval' where the card says 'not identified' (the route's fault, not the
    recordings'); a small Sobol index is the recordings' fault."""
    run = summary_run(tmp_path / "pareto", {"X13": 16.0, "X17": 1.9}, None)
    rec = recovery_of(run, {"X13": 0.5, "X17": 0.02}).set_index("parameter")
    card = summary.estimate_table(run)
    assert rec.loc["X13", "verdict"] == summary.NOT_IDENTIFIED == card.loc["X13", "verdict"]
    assert rec.loc["X17", "verdict"] == summary.NOT_IDENTIFIABLE == card.loc["X17", "verdict"]
    assert "largest Sobol ST 0.02 < 0.1" in rec.loc["X17", "why_not"]
    assert not rec.identified.any() and not rec.identifiable.any()
    # refined: a narrow 90 % interval identifies X13, a wide one is the recordings' fault
    ref = {"standard_error_pct_range": {"X13": 2.0, "X17": 7.0}}
    run = summary_run(tmp_path / "refined", {"X13": 14.0, "X17": 1.9}, ref)
    rec = recovery_of(run, {"X13": 0.5, "X17": 0.4}).set_index("parameter")
    assert rec.loc["X13", "verdict"] == "identified" and rec.loc["X13", "identified"]
    assert rec.loc["X13", "why_not"] == "" and rec.loc["X13", "identifiable"]
    assert rec.loc["X17", "verdict"] == summary.NOT_IDENTIFIABLE
    assert summary.estimate_table(run).loc["X17", "verdict"] == summary.NOT_IDENTIFIABLE


def test_the_reports_recovery_table_gives_the_verdict_not_identifiable(tmp_path):
    val = tmp_path / "estimate" / "validation"
    val.mkdir(parents=True)
    pd.DataFrame(
        [{"condition": "short", "force": "Y", "statistic": "mean", "after_error": 0.1}]
    ).to_csv(val / "validation.csv", index=False)
    write(val / "validation.json", {"failures": []})
    run = summary_run(tmp_path, {"X13": 16.0, "X17": 1.9}, None)
    recovery_of(run, {"X13": 0.5, "X17": 0.02}).to_csv(val / "recovery.csv", index=False)
    doc = Doc(tmp_path)
    validation_section(doc, val)
    text = "\n".join(doc.md)
    (table,) = [t for t in md_tables(doc.md) if "truth" in t[0]]
    head = table[0]
    assert "why not identifiable" not in text and "identifiable" not in head
    assert {"identified", "verdict", "why not identified"} <= set(head)
    verdict = {r[0]: r[head.index("verdict")] for r in table[1:]}
    assert verdict == {"X13": summary.NOT_IDENTIFIED, "X17": summary.NOT_IDENTIFIABLE}
    assert "not identifiable from these recordings where the recordings are the reason" in text


def test_railsusp_validate_prints_the_verdict(tmp_path, monkeypatch):
    """The command's recovery table said 'identified: no' and 'why not' for both kinds."""
    import railsusp.validate as validate_module
    from railsusp.cli import app

    run = summary_run(tmp_path / "run", {"X13": 16.0, "X17": 1.9}, None)
    recovery = recovery_of(run, {"X13": 0.5, "X17": 0.02})

    class Result:
        def __init__(self):
            self.forces = pd.DataFrame(columns=["condition", "force", "statistic"])
            self.failures: list = []
            self.recovery = recovery

        def save(self, out):
            return out

    monkeypatch.setattr(validate_module, "validate", lambda *a, **k: Result())
    result = CliRunner().invoke(app, ["validate", str(run / "estimate")])
    assert result.exit_code == 0, result.output
    out = " ".join(result.output.split())
    assert "verdict" in out and "why not identified" in out
    assert "not identifiable from these" in out and "not identified: no confidence" in out


def test_railsusp_runs_recovery_table_shows_the_verdict_once(tmp_path):
    """`railsusp run`'s printout showed recovery.csv whole: "identified" beside the older
    column "identifiable" of the same values."""
    from rich.console import Console

    from railsusp.cli.pipeline import _summary_parts

    run = summary_run(tmp_path / "run", {"X13": 16.0, "X17": 1.9}, None)
    folder = run / "estimate" / "validation"
    folder.mkdir(parents=True, exist_ok=True)
    recovery_of(run, {"X13": 0.5, "X17": 0.02}).to_csv(folder / "recovery.csv", index=False)
    (run / "pipeline.json").write_text(json.dumps({"format": 1, "stages": {}}))
    console = Console(record=True, width=400)
    for part in _summary_parts(run):
        console.print(part)
    header = next(line for line in console.export_text().splitlines() if "┃ truth ┃" in line)
    assert "┃ verdict ┃" in " ".join(header.split()) and "identifiable" not in header


def sobol_run(root: Path) -> Path:
    """The tiny run's sensitivity analysis: the vertical force's mean varies by 0.19 % over
    the campaign, ignored by the key rule, where X17's ST is 0.32."""
    sens = root / "campaign" / "sensitivity"
    sens.mkdir(parents=True)
    rows = [
        ("Y", p, s1, st, 0.0679)
        for p, s1, st in (("X13", 0.49, 0.447), ("X14", 0.43, 0.442), ("X17", 0.06, 0.087))
    ] + [
        ("Q", p, s1, st, 0.0019)
        for p, s1, st in (("X13", 0.24, 0.277), ("X14", 0.39, 0.405), ("X17", 0.25, 0.324))
    ]
    indices = pd.DataFrame(
        [
            {
                "condition": "short",
                "quantity": q,
                "statistic": "mean",
                "parameter": p,
                "S1": s1,
                "S1_conf": 0.1,
                "ST": st,
                "ST_conf": 0.1,
                "method": "metamodel",
                "cv": cv,
                "r2_holdout": 0.95,
            }
            for q, p, s1, st, cv in rows
        ]
    )
    indices.to_parquet(sens / "indices.parquet")
    write(
        sens / "key_parameters.json",
        {
            "key_parameters": {
                "keys": ["X13", "X14"],
                "rule": "the rule",
                "statistics": ["mean"],
                "min_cv": 0.005,
                "min_r2": 0.25,
                "max_st": {"X13": 0.447, "X14": 0.442, "X17": 0.087},
                "ignored_features": ["short Q mean"],
                "unfitted_features": [],
            },
            "metamodel_r2": [],
        },
    )
    pd.DataFrame({"parameter": ["X13"], "our_rank": [1]}).to_csv(
        sens / "study_comparison.csv", index=False
    )
    (sens / "sobol-mean.png").write_bytes(b"the sensitivity stage's figure")
    return root


def test_the_sobol_section_names_the_features_the_key_rule_left_out(tmp_path):
    run = sobol_run(tmp_path)
    text, _ = sections(run)
    assert (
        "Left out of the key rule, whatever their indices (their panels are grey in the "
        "figure): short Q mean: coefficient of variation 0.19% &lt; 0.5% over the campaign"
    ) in text
    # a stage run before its figures were marked: drawn again with that panel marked
    assert "(<report_assets/sobol-mean.png>)" in text
    assert "grey panels: left out of the key rule (short Q mean)" in text
    png = run / "report_assets" / "sobol-mean.png"
    assert png.read_bytes().startswith(b"\x89PNG")


def test_a_stage_that_marked_its_sobol_figures_is_shown_as_drawn(tmp_path):
    """The sensitivity stage greys the left-out panels itself (``figures_mark_left_out``):
    the report shows its figure, not a second drawing of it."""
    run = sobol_run(tmp_path)
    kp = run / "campaign" / "sensitivity" / "key_parameters.json"
    kp.write_text(json.dumps({**json.loads(kp.read_text()), "figures_mark_left_out": True}))
    text, _ = sections(run)
    assert "(<campaign/sensitivity/sobol-mean.png>)" in text
    assert "grey panels: left out of the key rule (short Q mean)" in text
    assert not (run / "report_assets" / "sobol-mean.png").exists()


def test_plot_sobol_marks_the_panels_left_out(tmp_path, monkeypatch):
    import railsusp.report as report

    run = sobol_run(tmp_path)
    indices = pd.read_parquet(run / "campaign" / "sensitivity" / "indices.parquet")
    figures = []
    monkeypatch.setattr(report, "save_figure", lambda fig, path: figures.append(fig) or path)
    why = "coefficient of variation 0.19% < 0.5%"
    report.plot_sobol(indices, tmp_path / "s.png", "mean", left_out={"short Q mean": why})
    (fig,) = figures
    titles = {}
    for ax in fig.axes:
        if ax.get_visible():  # "short: vertical force Q (mean, CV 0.2%)..." by its force
            titles[ax.get_title().split(": ")[1].split(" (")[0]] = ax.get_title()
    assert f"LEFT OUT of the key rule: {why}" in titles["vertical force Q"]
    assert "LEFT OUT" not in titles["lateral force Y"]
    assert "grey: features the key rule left out" in fig._suptitle.get_text()


def test_the_provenance_records_scikit_learn_and_matplotlib():
    """The GP metamodel (scikit-learn) computes the Sobol indices of an LHS campaign and
    matplotlib draws every figure; neither version was recorded."""
    from railsusp.provenance import RECORDED_LIBRARIES, provenance

    assert {"scikit-learn", "matplotlib"} <= set(RECORDED_LIBRARIES)
    prov = provenance({"railsusp": "x", "git_sha": None, "git_dirty": None})
    assert prov["scikit-learn"] and prov["matplotlib"]


def provenance_md(run: Path, prov: dict, stages: dict) -> str:
    doc = Doc(run)
    state = {"config": {}, "stages": stages, "provenance": prov}
    provenance_section(doc, run, state, {"config_hash": "abc"})
    return "\n".join(doc.md)


def test_the_provenance_labels_its_times_and_its_short_hashes(tmp_path):
    (tmp_path / "campaign").mkdir()
    (tmp_path / "campaign" / "design.parquet").write_bytes(b"design")
    prov = {"railsusp": "0.1.0", "utc": "2026-12-01T09:59:25+00:00"}
    stages = {
        "validate": {"state": "done", "finished": "2026-12-01T09:59:30+00:00"},
        "report": {"state": "running"},
    }
    md = provenance_md(tmp_path, prov, stages)
    assert "| started (UTC) | 2026-12-01T09:59:25+00:00 |" in md and "| utc |" not in md
    assert (
        "| finished (UTC) | not recorded yet: the run finishes with this report (its stage "
        "before it, validate, finished 2026-12-01T09:59:30+00:00) |"
    ) in md
    assert "| data file | sha256 (first 16 hex digits) |" in md
    assert "| campaign/design.parquet | " in md
    # a report written again on a finished run: the finished time recorded
    md = provenance_md(tmp_path, {**prov, "finished": "2026-12-01T09:59:31+00:00"}, stages)
    assert "| finished (UTC) | 2026-12-01T09:59:31+00:00 |" in md


#: a run name of the QA pass: raw HTML and a table bar in report.md's first heading
NAME = "<img src=x onerror=alert(1)> Wagon 4711 | line"


def test_markdown_escapes_the_users_text_and_html_is_not_escaped_twice(tmp_path):
    doc = Doc(tmp_path)
    doc.h(f"railsusp report: {NAME}", 1)
    doc.p(f"Condition *{NAME}* [x](javascript:alert(1))")
    doc.table(pd.DataFrame({"name": [NAME], "value": [1.0]}))
    md = "\n".join(doc.md)
    assert "<img" not in md and "[x](" not in md and "*W" not in md
    assert r"# railsusp report: &lt;img src=x onerror=alert(1)&gt; Wagon 4711 \| line" in md
    assert r"\*&lt;img" in md and r"[x\](javascript:alert(1))" in md
    (table,) = md_tables(doc.md)
    assert table[1] == [r"&lt;img src=x onerror=alert(1)&gt; Wagon 4711 \| line", "1.00"]
    page = doc.page(NAME)
    assert "<img src=x" not in page and "&amp;lt;" not in page
    assert "<h1>railsusp report: &lt;img src=x onerror=alert(1)&gt; Wagon 4711 | line</h1>" in page
    # a paragraph is one paragraph: no list item, no blank line ending it
    doc = Doc(tmp_path)
    doc.p("- a\n\n# b")
    assert doc.md == [r"\- a \# b" + "\n"]


def test_the_summary_cards_markdown_escapes_the_wagon_name(tmp_path):
    tol = {"default_pct": 15.0, "parameters": {}, "from_wagon": False}
    run = card_run(tmp_path, tol, ROWS)
    write(
        run / "campaign" / "campaign.json",
        {"config": {"parameters": ["X13", "X17"], "wagon": {"wagon": {"name": NAME}}}},
    )
    doc = Doc(run)
    summary_card(doc, run, read=[])
    md = "\n".join(doc.md)
    assert "<img" not in md and "Wagon: &lt;img src=x onerror=alert(1)&gt; Wagon 4711" in md
    card = "\n".join(doc.html)
    assert "&lt;img src=x" in card and "&amp;lt;" not in card
    # the two kinds of "not identified" are named apart, as in the card's table
    assert "Not identified by this route (it gives no confidence interval" in md


@pytest.mark.parametrize("text", ["a_b_c", "remove_geometry_bias = false", "X13/X14 1.5e+07"])
def test_markdown_leaves_plain_text_as_it_is(tmp_path, text):
    doc = Doc(tmp_path)
    doc.p(text)
    assert doc.md == [text + "\n"]


def test_a_figures_caption_with_brackets_stays_the_images_text(tmp_path):
    """The review of stop 70: the alt text escaped "]" only before "(", "[" or ":", so a
    caption "cap ] x [y](z)" ended the image's text at its lone "]"."""
    png = tmp_path / "f.png"
    png.write_bytes(b"\x89PNG figure")
    doc = Doc(tmp_path)
    doc.figure(png, "cap ] x [y](z)")
    assert doc.md[-1] == "![cap \\] x \\[y\\](z)](<f.png>)\n"
    markdown_it = pytest.importorskip("markdown_it")
    page = markdown_it.MarkdownIt("commonmark").render(doc.md[-1])
    assert page.strip() == '<p><img src="f.png" alt="cap ] x [y](z)" /></p>'


def test_a_network_sets_rows_of_conditions_the_run_lacks_are_not_the_estimates(tmp_path):
    """A network set is installed whole: on a run of straight and curve its uphill rows were
    marked 'the estimate's force model', though no uphill recording or network was used."""
    run = surrogate_run(tmp_path, "bp")
    sur = run / "campaign" / "surrogates" / "compare.csv"
    rows = pd.read_csv(sur)
    pd.concat([rows, rows.assign(condition="uphill")]).to_csv(sur, index=False)
    write(run / "campaign" / "campaign.json", {"config": {"conditions": [{"name": "short"}]}})
    text, tables = sections(run)
    (table,) = [t for t in tables if "model" in t[0]]
    head, *body = table
    role = {
        (r[head.index("condition")], r[head.index("model")]): r[head.index("role in this run")]
        for r in body
    }
    assert role[("short", "bp")] == "the estimate's force model"
    assert role[("uphill", "bp")] == "not a condition of this run"
    assert role[("uphill", "rbf")] == "comparison only"
    assert "the estimate did not use them" in text


def test_the_sensitivity_section_knows_a_network_sets_inputs(tmp_path):
    """On a network set the estimate's parameters are the set's inputs, not the Sobol keys."""
    from railsusp.report_method import _network_set_inputs

    sur = tmp_path / "surrogate-pretrained" / "surrogates"
    write(sur / "networks.json", {"parameters": ["X18", "X13", "X19"]})
    state = {"config": {"surrogate": {"pretrained": "c80_k6", "samples": 0}}}
    assert _network_set_inputs(tmp_path, state) == ["X18", "X13", "X19"]
    state["config"]["surrogate"]["pretrained"] = None
    assert _network_set_inputs(tmp_path, state) == []


def test_a_refinement_of_one_start_is_not_said_to_end_lowest_of_them():
    """``refine_starts = 1`` read "of the 1 starts refined (...) it ended lowest" (stop 79's
    report hunt); two or more starts keep the comparison."""
    from railsusp.report_estimate import _start

    one = {"start_origin": "a Latin-hypercube point", "starts": [[1.0]], "screened_starts": 7}
    assert _start(one) == (
        " from a Latin-hypercube point, not NSGA-II's choice: the one start refined (the best "
        "of 7 screened by time-aligned cost)"
    )
    two = {**one, "starts": [[1.0], [2.0]]}
    assert "of the 2 starts refined" in _start(two) and _start(two).endswith("it ended lowest")
