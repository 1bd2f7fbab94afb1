"""The report's findings of the report audit, on hand-made run directories (seconds, no
pipeline run): the Markdown twin's table columns, the provenance's networks, the estimation
text against its table, the tolerance sentence and a force error that is not a number."""

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from railsusp import summary
from railsusp.report_doc import Doc
from railsusp.report_estimate import estimate_section, validation_section
from railsusp.report_provenance import provenance_section
from railsusp.report_summary_card import summary_card
from test_summary import make_run as summary_run
from test_summary import write


def md_tables(lines: list[str]) -> list[list[list[str]]]:
    """The Markdown tables in ``lines``, each a list of rows of cells, split as a
    Markdown renderer splits them: at every ``|`` not escaped by a backslash."""
    tables, rows = [], []
    for line in [*"\n".join(lines).splitlines(), ""]:
        if line.startswith("|"):
            cells = re.split(r"(?<!\\)\|", line.strip())[1:-1]
            if not all(re.fullmatch(r"-+", c) for c in cells):  # not the rule under the header
                rows.append([c.strip() for c in cells])
        elif rows:
            tables.append(rows)
            rows = []
    return tables


def test_markdown_validation_table_keeps_its_columns_on_the_abs_y_rows(tmp_path):
    """The lateral rows are labelled "mean of |Y|": their unescaped bars split the cell, so
    "measured (kN)" showed "Y" and every later column sat under the wrong header."""
    val = tmp_path / "estimate" / "validation"
    rows = [
        {
            "condition": "straight",
            "wheel": "w1L",
            "force": force,
            "statistic": "mean",
            "measured_kN": measured,
            "before_kN": measured * 1.2,
            "before_error": 0.2,
            "after_kN": measured * 1.01,
            "after_error": 0.01,
        }
        for force, measured in (("Y", 5.25), ("Q", 117.3))
    ]
    val.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(val / "validation.csv", index=False)
    write(val / "validation.json", {"failures": []})
    doc = Doc(tmp_path)
    validation_section(doc, val)
    (table,) = md_tables(doc.md)
    head, *body = table
    assert [len(r) for r in body] == [len(head)] * 2
    y = dict(zip(head, body[0], strict=True))
    assert y["statistic"] == r"mean of \|Y\|"
    assert y["measured (kN)"] == "5.25"
    assert y["error, estimate (%)"] == "1.00"


def test_markdown_cells_with_a_bar_or_a_line_break_stay_one_cell(tmp_path):
    doc = Doc(tmp_path)
    doc.table(pd.DataFrame({"a": ["x | y", "two\nlines"], "b": [1.0, 2.0]}))
    (table,) = md_tables(doc.md)
    assert table == [["a", "b"], [r"x \| y", "1.00"], ["two lines", "2.00"]]


def test_provenance_names_the_networks_the_estimate_ran_on(tmp_path):
    """``samples = 0``: the estimate ran on the sensitivity campaign's networks
    (campaign/surrogates/bp); the glob over surrogate* named the networks an earlier
    configuration left in surrogate-campaign, and not those."""
    run = tmp_path
    used = run / "campaign" / "surrogates" / "bp" / "short" / "model.pt"
    left = run / "surrogate-campaign" / "surrogates" / "bp" / "short" / "model.pt"
    other = run / "campaign" / "surrogates" / "rbf" / "short" / "model.pt"  # not the model
    for i, f in enumerate((used, left, other)):
        f.parent.mkdir(parents=True)
        f.write_bytes(bytes([i]) * 10)
    surrogate = {"model": "bp", "pretrained": None, "samples": 0}

    def listed() -> list[str]:
        doc = Doc(run)
        provenance_section(
            doc, run, {"config": {"surrogate": surrogate}, "stages": {}}, {"config_hash": "abc"}
        )
        head = ["data file", "sha256 (first 16 hex digits)"]
        (table,) = [t for t in md_tables(doc.md) if t[0] == head]
        return [r[0] for r in table[1:]]

    assert listed() == ["campaign/surrogates/bp/short/model.pt"]
    surrogate["samples"] = 8  # its own campaign's, now the one the estimate runs on
    assert listed() == ["surrogate-campaign/surrogates/bp/short/model.pt"]


def test_the_estimation_text_compares_the_standard_error_the_table_shows(tmp_path):
    """The demo's X19: Pareto spread 3.02 % of range, the refinement's own (noise and
    geometry) standard error 3.00 %, the total the table shows 4.61 %. The text said
    "every standard error is below the spread" from the 3.00."""
    est = tmp_path / "estimate"
    est.mkdir()
    pd.DataFrame({"n_gen": [1, 2], "n_eval": [8, 16], "eps": [0.1, 0.01]}).to_csv(
        est / "nsga_log.csv", index=False
    )
    spread = {"X13": 67.8, "X19": 3.02}
    own = {"X13": 0.587, "X19": 3.003}
    total = {"X13": 2.24, "X19": 4.61}
    write(
        est / "estimate.json",
        {
            "parameters": ["X13", "X19"],
            "choice_rule": "closest to the ideal point",
            "pareto_spread_pct_range": spread,
            "refinement": {
                "cost_start": 2.0,
                "cost": 1.0,
                "n_evaluations": 30,
                "standard_error_pct_range": own,
            },
            "intervals": {
                "description": "90 % confidence intervals",
                "details": {"total_standard_error_pct_range": total},
            },
        },
    )
    pd.DataFrame(
        {
            "parameter": ["X13", "X19"],
            "pareto_spread_pct_range": [spread[p] for p in ("X13", "X19")],
            "standard_error_pct_range": [total[p] for p in ("X13", "X19")],
            "refinement_standard_error_pct_range": [own[p] for p in ("X13", "X19")],
        }
    ).to_csv(est / "estimate.csv", index=False)
    doc = Doc(tmp_path)
    estimate_section(doc, est)
    text = "\n".join(doc.md)
    assert "every standard error" not in text
    assert "tell them apart for X13; for X19 the standard error (the table's total)" in text
    # what it claims holds in the table beside it
    (table,) = [t for t in md_tables(doc.md) if "standard error (% of range)" in t[0]]
    row = {r[0]: dict(zip(table[0], r, strict=True)) for r in table[1:]}
    x19 = row["X19"]
    assert float(x19["standard error (% of range)"]) >= float(x19["Pareto spread (% of range)"])


def make_run(root: Path, tolerances: dict, validation: list[dict]) -> Path:
    """A run directory with the files the summary card reads: X13 and X17 estimated (the
    Pareto set as the interval, test_summary's run), one recording list, ``validation`` as
    validation.csv, the wagon data's ``tolerances``."""
    summary_run(root, {"X13": 16.0, "X17": 1.9}, None)
    params = ["X13", "X17"]
    write(
        root / "pipeline.json",
        {"config": {"wagon": None}, "stages": {}, "tolerances": tolerances},
    )
    write(
        root / "campaign" / "campaign.json",
        {"config": {"parameters": params, "wagon": {"wagon": {"name": "C80 / K6"}}}},
    )
    write(root / "field" / "index.json", {"recordings": []})
    val = root / "estimate" / "validation"
    val.mkdir(parents=True)
    pd.DataFrame(validation).to_csv(val / "validation.csv", index=False)
    return root


def card(run: Path) -> str:
    doc = Doc(run)
    summary_card(doc, run, read=[])
    return "\n".join(doc.md)


ROWS = [
    {
        "condition": "short",
        "force": force,
        "statistic": "mean",
        "before_error": before,
        "after_error": np.nan,  # the validation's simulation stopped: its rows are empty
        "truth_error": truth,
    }
    for force, before, truth in (("Y", 0.85, 0.887), ("Q", 0.0318, 0.0313))
]


def tolerance_sentence(run: Path) -> str:
    """The card's sentence on the tolerances (it ends with its docs/wagon-data.md)."""
    return re.search(r"Within tolerance.*?wagon-data\.md\)", card(run)).group()


def test_the_tolerance_sentence_says_where_each_number_comes_from(tmp_path):
    """A wagon file's [tolerances] of default 10 % and X13 20 %: the card added "(default
    15.0 %, ...)", railsusp's fallback, as if it were the wagon's default."""
    wagon = {"default_pct": 10.0, "parameters": {"X13": 20.0}, "from_wagon": True}
    line = tolerance_sentence(make_run(tmp_path / "a", wagon, ROWS))
    assert "±10.0 % (X13 ±20.0 %), all from the wagon data's [tolerances]" in line
    assert "15" not in line
    # the wagon's table keeps railsusp's 15 % default: said so, the listed one the wagon's
    keep = {"default_pct": 15.0, "parameters": {"X13": 20.0}, "from_wagon": True}
    line = tolerance_sentence(make_run(tmp_path / "b", keep, ROWS))
    assert "(X13 ±20.0 %, from the wagon data's [tolerances])" in line
    assert "±15.0 % is railsusp's default" in line
    # no table: railsusp's default, as before
    none = {"default_pct": 15.0, "parameters": {}, "from_wagon": False}
    line = tolerance_sentence(make_run(tmp_path / "c", none, ROWS))
    assert "±15.0 %, railsusp's default (the wagon data give no [tolerances]" in line


def test_a_force_error_that_is_not_a_number_reads_n_a_in_the_card(tmp_path):
    """A stopped validation simulation leaves NaN errors: the card read "85.0 % →  %"."""
    tol = {"default_pct": 15.0, "parameters": {}, "from_wagon": False}
    text = card(make_run(tmp_path, tol, ROWS))
    (line,) = [x for x in text.splitlines() if x.startswith("- short:")]
    assert "→  %" not in line and "nan" not in line.lower().replace(summary.NO_ERROR, "")
    assert f"lateral Y 85.0 % → {summary.NO_ERROR} (true parameters: 88.7 %)" in line
    assert f"vertical Q 3.18 % → {summary.NO_ERROR}" in line
    assert not math.isfinite(summary.force_agreement(tmp_path).lateral_after_pct[0])
