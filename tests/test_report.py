"""The report and the Python API on a tiny run: the README's and docs/api.md's Python blocks
run as pasted, the summary card comes first and says what it should, tables are readable,
and (marker ``browser``) the page renders in headless Chromium."""

import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import railsusp
from railsusp import summary
from railsusp.estimate.intervals import PARETO, describe
from railsusp.params import MAIN_SUSPENSION
from railsusp.pipeline_state import STAGES

ROOT = Path(__file__).resolve().parents[1]


def python_blocks(markdown: Path) -> list[str]:
    """The ```python blocks of a Markdown file, in order."""
    return re.findall(r"```python\n(.*?)```", markdown.read_text("utf-8"), re.S)


def run_blocks(markdown: Path, cwd: Path) -> dict:
    """Execute a page's Python blocks in one namespace, in ``cwd``, as a reader would."""
    namespace: dict = {"__name__": "__main__"}
    old = Path.cwd()
    os.chdir(cwd)
    try:
        for i, block in enumerate(python_blocks(markdown)):
            exec(compile(block, f"{markdown.name}[block {i}]", "exec"), namespace)
    finally:
        os.chdir(old)
    return namespace


@pytest.fixture(scope="module")
def readme(tmp_path_factory):
    """The README's Python blocks, run in a folder holding a copy of examples/."""
    cwd = tmp_path_factory.mktemp("readme")
    shutil.copytree(ROOT / "examples", cwd / "examples")
    ns = run_blocks(ROOT / "README.md", cwd)
    return cwd, ns


@pytest.fixture(scope="module")
def run_dir(readme):
    return readme[0] / "runs" / "tiny"


def test_readme_python_blocks_run_as_pasted(readme):
    _, ns = readme
    assert len(python_blocks(ROOT / "README.md")) >= 2
    # the simulator block: statistics of one run are floats, a batch gives one per set
    stats = ns["r"].statistics()
    assert all(isinstance(v, float) for v in stats.values())
    assert stats["Q_mean"] > 0 and stats["YQ_max"] > 0
    per_set = ns["batch"].statistics(set_index=None)["Y_mean"]
    assert per_set.shape == (2,) and per_set[0] != per_set[1]
    straight, curve = ns["both"]
    np.testing.assert_array_equal(straight.Y, ns["batch"].Y)  # the same as alone
    assert curve.condition.name == "curve" and curve.ok.all()
    assert isinstance(ns["result"], railsusp.RunResult)


def test_docs_api_example_runs_and_the_result_reopens(readme):
    cwd, _ = readme
    ns = run_blocks(ROOT / "docs" / "api.md", cwd)
    table = ns["table"]
    assert list(table.index) == list(MAIN_SUSPENSION)
    assert (cwd / "runs" / "tiny" / "estimate-summary.png").stat().st_size > 1000
    assert ns["again"].report_path == (cwd / "runs" / "tiny" / "report.html").resolve() or (
        ns["again"].report_path.samefile(cwd / "runs" / "tiny" / "report.html")
    )


def test_estimate_table_of_the_run(run_dir):
    """Estimated parameters carry an interval around the estimate and a change from nominal
    that matches their values; the others are held at nominal and say why."""
    res = railsusp.open_run(run_dir)
    est = res.estimate
    keys = res.key_parameters
    for p in MAIN_SUSPENSION:
        row = est.loc[p]
        if p in keys:
            assert row.low <= row.estimate <= row.high
            assert row.change_pct == pytest.approx(100 * (row.estimate / row.nominal - 1))
            assert row.interval == describe(PARETO, None)  # the tiny run is not refined
            assert row.verdict == summary.NOT_IDENTIFIED  # a Pareto range never identifies
        else:
            assert row.verdict.startswith("not estimated: held at")
            assert row.note in (
                "not varied in the campaign",
                "not a key parameter of the sensitivity analysis",
            )
    # the validation errors are in %, the same numbers as the agreement summary
    val, ag = res.validation, res.agreement
    y = val[(val.force == "Y") & (val.statistic == ag.statistic[0])]
    assert ag.lateral_after_pct[0] == pytest.approx(y.after_error_pct.iloc[0])
    assert set(res.stages.state) == {"done"}


def test_open_run_of_a_folder_that_is_not_a_run(tmp_path):
    with pytest.raises(railsusp.RailsuspInputError, match="not a run directory"):
        railsusp.open_run(tmp_path)
    with pytest.raises(railsusp.RailsuspInputError, match="config: a TOML path"):
        railsusp.run(42, out=tmp_path)
    with pytest.raises(railsusp.RailsuspInputError, match=r"estimate\.n_gen"):
        railsusp.run({"estimate": {"n_gen": 0}}, out=tmp_path)


def test_summary_card_comes_first_and_answers(run_dir):
    page = (run_dir / "report.html").read_text("utf-8")
    card = page.index("id='summary'")
    assert card < page.index("<img") and card < page.index("Wagon and working conditions")
    card_html = page[card : page.index("</section>", card)]
    assert "C80 / K6" in card_html and "short.csv" in card_html
    for p in MAIN_SUSPENSION:
        assert f"<td class=text>{p} " in card_html
    assert "held at" in card_html and "→" in card_html
    assert "Interval: range of the NSGA-II Pareto set" in card_html
    # the Markdown twin starts with the same answer
    md = (run_dir / "report.md").read_text("utf-8")
    assert md.index("## Answer") < md.index("## Wagon and working conditions")


def test_tables_have_readable_headers_errors_in_percent(run_dir):
    page = (run_dir / "report.html").read_text("utf-8")
    heads = re.findall(r"<th[^>]*>([^<]*)</th>", page)
    for raw in ("before_error", "our_max_ST", "pareto_spread_pct_range", "measured_kN"):
        assert raw not in heads
    assert "error, estimate (%)" in heads
    # the validation table's errors are the CSV's fractions x 100, to three figures
    val = pd.read_csv(run_dir / "estimate" / "validation" / "validation.csv")
    assert summary.sig3(100 * val.after_error[0]) in page
    assert "<table>" not in page.replace("<div class='scroll'><table>", "")
    assert "writing this report" in page and ">running<" not in page


def test_sig3():
    assert [summary.sig3(v) for v in (91600.0, 0.0003976, 1.5, -48.347, 0.0)] == [
        "91600",
        "0.000398",
        "1.50",
        "-48.3",
        "0",
    ]
    assert summary.sig3(float("inf")) == "∞" and summary.sig3(2.5e7) == "2.50e+07"
    # rounding up to the next power of ten keeps three figures (9.99944 read "10.00")
    assert [summary.sig3(v) for v in (9.99944, -9.9996, 0.0009996, 99.96)] == [
        "10.0",
        "-10.0",
        "0.00100",
        "100",
    ]


def test_validation_caption_follows_the_recordings():
    from railsusp.report import validation_caption

    assert "unknown" in validation_caption(False)
    assert "unknown" not in validation_caption(True) and "time-aligned" in validation_caption(True)


browser = pytest.mark.skipif(
    not Path("/usr/bin/chromium").exists(),
    reason="Debian's chromium absent (make test installs it: apt-get install chromium)",
)

#: what the page reports about itself at 1024 x 768
_LAYOUT = """JSON.stringify({
  images: Array.from(document.images).map(i => i.complete && i.naturalWidth > 0),
  card: document.getElementById('summary').getBoundingClientRect().toJSON(),
  pageWidth: document.documentElement.scrollWidth,
  viewWidth: window.innerWidth,
  tables: Array.from(document.querySelectorAll('.scroll')).map(
    d => d.getBoundingClientRect().right)
})"""


@browser
@pytest.mark.browser
def test_report_in_headless_chromium(run_dir, tmp_path):
    """No console errors, every image loads, the summary card is whole in the first screen
    (1024 x 768), and no table makes the page wider than the window."""
    import json

    from cdp import Page

    with Page(tmp_path / "profile", 1024, 768) as page:
        page.open((run_dir / "report.html").as_uri())
        layout = json.loads(page.evaluate(_LAYOUT))
        shot = page.screenshot(Path(os.environ.get("RAILSUSP_SCREENSHOT", tmp_path / "s.png")))
        errors = page.errors
    assert errors == []
    assert layout["images"] and all(layout["images"]), layout["images"]
    assert layout["card"]["top"] >= 0 and layout["card"]["bottom"] <= 768, layout["card"]
    assert layout["pageWidth"] <= layout["viewWidth"] == 1024
    assert max(layout["tables"]) <= 1024
    assert shot.stat().st_size > 10_000


def test_report_shows_the_recordings_en14363_percentiles(run_dir):
    """A synthetic run's field folder has no en14363.csv: the report processes its
    recordings (20 Hz low-pass, 2 m mean) and shows the percentiles of each wheel's forces."""
    from railsusp.en14363 import section_statistics
    from railsusp.measured import read_field

    page = (run_dir / "report.html").read_text("utf-8")
    assert "Measured forces, EN 14363 processing" in page
    rec = read_field(run_dir / "field")[0]
    w = rec.wheels[0]
    st = section_statistics(rec.Q[w], rec.sampling_rate, rec.condition.speed)
    assert summary.sig3(round(st.p99_85, 2)) in page


def test_provenance_is_this_runs_and_the_stages_are_in_pipeline_order(run_dir):
    """The provenance was written after every stage, the report's included: a first run's
    report showed an empty table, a rerun's the invocation before; the stage rows came in
    pipeline.json's alphabetical order."""
    state = json.loads((run_dir / "pipeline.json").read_text("utf-8"))
    md = (run_dir / "report.md").read_text("utf-8")
    prov = md[md.index("## Provenance") :]
    assert f"| started (UTC) | {state['provenance']['utc']} |" in prov
    assert "| finished (UTC) | not recorded yet: the run finishes with this report" in prov
    assert state["provenance"]["finished"] >= state["provenance"]["utc"]
    rows = [s for s in STAGES if f"| {s} |" in prov]
    assert rows == list(STAGES)
    assert sorted(STAGES, key=lambda s: prov.index(f"| {s} |")) == list(STAGES)


def test_the_apis_largest_st_is_the_rules_as_the_report_shows_it(run_dir):
    """``plot_sensitivity`` and docs/api.md took the largest ST over every feature, the
    flat ones the key-parameter rule ignores among them (the tiny run: X17 0.17 against
    the report's 0.033); ``largest_st`` is the rule's, which the report prints."""
    result = railsusp.open_run(run_dir)
    rule = json.loads((run_dir / "campaign/sensitivity/key_parameters.json").read_text())
    st = result.largest_st
    assert st.to_dict() == pytest.approx(rule["key_parameters"]["max_st"])
    assert list(st) == sorted(st, reverse=True)
    md = (run_dir / "report.md").read_text("utf-8")
    top = st.index[0]
    assert re.search(rf"\| {top} \|[^\n]*\| {re.escape(summary.sig3(st[top]))} \|", md)
    bars = result.plot_sensitivity()
    assert [round(p.get_height(), 12) for p in bars.patches] == [round(v, 12) for v in st]


def test_the_record_correction_is_explained_only_where_a_network_has_one(run_dir):
    """The paragraph on the record correction and its 'network alone' column came in every
    report, also where the column was empty (the tiny run's BP network has none)."""
    md = (run_dir / "report.md").read_text("utf-8")
    table = pd.read_csv(run_dir / "surrogate-campaign" / "surrogates" / "compare.csv")
    alone = table.filter(like="network_alone")
    assert alone.isna().all().all()  # this run: no record correction
    assert "scaled by a record correction" not in md


def test_a_recordings_duration_is_its_samples_times_their_interval(run_dir):
    """The tiny run's 1 s record of 50 samples read 0.980 s (first to last sample)."""
    rec = summary.recordings(run_dir).iloc[0]
    assert rec.duration_s == pytest.approx(1.0)


def test_the_api_says_which_parameters_were_estimated(run_dir):
    result = railsusp.open_run(run_dir)
    est = json.loads((run_dir / "estimate" / "estimate.json").read_text())
    assert result.estimated_parameters == est["parameters"]
    assert set(result.estimated_parameters) == set(result.estimate.dropna(subset="low").index)


def test_the_tiny_runs_report_after_the_report_qa_pass(run_dir, tmp_path):
    """The report QA pass on the tiny run: which surrogate the estimate ran on, the
    recovery's verdict (not "identifiable = no"), the flat vertical force the key rule left
    out (its Sobol panel marked), and a run name of raw HTML made HTML in report.md."""
    from railsusp.report_html import build_report

    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    state = json.loads((copy / "pipeline.json").read_text("utf-8"))
    state["config"]["name"] = "<img src=x onerror=alert(1)> Wagon 4711 | line"
    (copy / "pipeline.json").write_text(json.dumps(state))
    build_report(copy)
    md = (copy / "report.md").read_text("utf-8")
    assert "<img" not in md
    assert md.lstrip().startswith(
        r"# railsusp report: &lt;img src=x onerror=alert(1)&gt; Wagon 4711 \| line"
    )
    page = (copy / "report.html").read_text("utf-8")
    assert "<img src=x" not in page and "&amp;lt;img" not in page
    model = json.loads((copy / "estimate" / "estimate.json").read_text())["model"]
    assert re.search(rf"\| short \| {model} \| the estimate's force model \|", md)
    assert "| short | rbf | comparison only |" in md
    assert f"NSGA-II ran on the surrogate {model} (surrogate.model)" in md
    assert "why not identifiable" not in md and "| verdict | why not identified |" in md
    recovery = md[md.index("### Parameter recovery") : md.index("## Measured forces")]
    rows = [line for line in recovery.splitlines() if line.startswith("| X")]
    assert rows and all(f"| no | {summary.NOT_IDENTIFIED} |" in r for r in rows)  # pareto
    kp = json.loads((copy / "campaign/sensitivity/key_parameters.json").read_text())
    ignored = kp["key_parameters"]["ignored_features"]
    assert ignored  # the tiny run: the mean vertical force on tangent track is flat
    assert "Left out of the key rule, whatever their indices" in md and ignored[0] in md
    # the sensitivity stage marked its own figure: shown as drawn, not drawn again
    assert kp["figures_mark_left_out"] is True
    assert "(<campaign/sensitivity/sobol-mean.png>)" in md
    assert "grey panels: left out of the key rule" in md
    assert not (copy / "report_assets" / "sobol-mean.png").exists()
