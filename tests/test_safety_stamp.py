"""Every reader of a run's sensitivity outputs checks their campaign stamp: the Python API
(``key_parameters``, ``largest_st``, ``sensitivity``), the summary's estimate table, the
report and ``identification_verdict.max_st``. A run whose campaign was replaced by hand (``railsusp
campaign --out RUN/campaign --force`` of another configuration) kept the old campaign's
analysis, and these read it as the new one's without a word. Each test failed on the code
before (only train, compare, campaign --keys-from and validate --sensitivity checked);
outputs made before the stamp are read as before. Hand-made run directories: no
simulation."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import railsusp
from railsusp import summary
from railsusp.errors import RailsuspInputError
from railsusp.identification_verdict import max_st
from railsusp.key_parameters import CAMPAIGN_STAMP, INDICES_STAMP
from railsusp.params import spec
from railsusp.report_doc import Doc
from railsusp.report_method import method_sections
from railsusp.store import write_parquet

PARAMS = ["X13", "X17"]
MAX_ST = {"X13": 0.5, "X17": 0.4, "X14": 0.2}


def _write(path: Path, doc: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))


def _indices() -> pd.DataFrame:
    """Sobol indices the key rule reads: one condition, Y and Q, mean and p99."""
    rows = []
    for q in ("Y", "Q"):
        for s in ("mean", "p99"):
            for p, st in MAX_ST.items():
                rows.append(
                    {"condition": "straight", "quantity": q, "statistic": s, "parameter": p,
                     "S1": st / 2, "cv": 0.1, "ST": st}
                )  # fmt: skip
    df = pd.DataFrame(rows * 20)  # pages of some size, for a bit flipped in one
    df["ST"] -= np.arange(len(df)) * 1e-9  # no two alike (no dictionary page): the first
    return df  # of each is the largest


def make_run(root: Path, stamp: str | None) -> Path:
    """A run directory with an estimate, a campaign of hash ``now`` and its sensitivity
    outputs stamped ``stamp`` (None: made before the stamp)."""
    pareto = [
        [spec(p).scale * v for p, v in zip(PARAMS, row, strict=True)]
        for row in ([12.0, 1.0], [20.0, 1.2], [16.0, 1.1])
    ]
    _write(root / "pipeline.json", {"config": {}, "stages": {}})
    _write(
        root / "estimate" / "estimate.json",
        {
            "parameters": PARAMS,
            "estimate_display": {"X13": 16.0, "X17": 1.1},
            "pareto_x_si": pareto,
            "pareto_spread_pct_range": {"X13": 10.0, "X17": 3.0},
            "refinement": None,
            "cramer_rao_pct_range": {},
        },
    )
    camp = root / "campaign"
    _write(
        camp / "campaign.json",
        {"config_hash": "now", "config": {"parameters": ["X13", "X14", "X17"]}},
    )
    sens = camp / "sensitivity"
    kp = {"key_parameters": {"keys": PARAMS, "max_st": MAX_ST, "rule": "the rule"}}
    if stamp is not None:
        kp[CAMPAIGN_STAMP] = stamp
    _write(sens / "key_parameters.json", kp)
    meta = {INDICES_STAMP: stamp} if stamp is not None else None
    write_parquet(sens / "indices.parquet", _indices(), metadata=meta)
    (sens / "study_comparison.csv").write_text("parameter,our_rank\nX13,1\n")
    return root


@pytest.fixture
def stale(tmp_path) -> Path:
    """The campaign replaced (hash "now") beside an analysis of the one before ("before")."""
    return make_run(tmp_path / "stale", "before")


def _refused(call, path: Path) -> None:
    with pytest.raises(RailsuspInputError) as info:
        call()
    text = str(info.value)
    assert text.startswith(f"{path} was computed from another campaign than the one in "), text
    assert "railsusp sensitivity" in text and "\n" not in text


def test_the_api_refuses_an_analysis_of_another_campaign(stale):
    result = railsusp.open_run(stale)
    sens = stale.resolve() / "campaign" / "sensitivity"
    _refused(lambda: result.key_parameters, sens / "key_parameters.json")
    _refused(lambda: result.largest_st, sens / "key_parameters.json")
    _refused(lambda: result.sensitivity, sens / "indices.parquet")


def test_the_estimate_table_refuses_an_analysis_of_another_campaign(stale):
    """Its verdicts take the largest ST of the analysis (the Sobol flag)."""
    _refused(
        lambda: summary.estimate_table(stale), stale / "campaign/sensitivity/key_parameters.json"
    )


def test_the_report_refuses_an_analysis_of_another_campaign(stale):
    _refused(
        lambda: method_sections(Doc(stale), stale, {}),
        stale / "campaign" / "sensitivity" / "key_parameters.json",
    )


def test_max_st_refuses_an_analysis_of_another_campaign(stale):
    sens = stale / "campaign" / "sensitivity"
    _refused(lambda: max_st(sens), sens / "key_parameters.json")
    _refused(lambda: max_st(sens / "key_parameters.json"), sens / "key_parameters.json")
    _refused(lambda: max_st(sens / "indices.parquet"), sens / "indices.parquet")


@pytest.mark.parametrize("stamp", [None, "now"], ids=["before the stamp", "its campaign"])
def test_an_analysis_of_its_campaign_or_made_before_the_stamp_is_read(tmp_path, stamp):
    run = make_run(tmp_path / "run", stamp)
    result = railsusp.open_run(run)
    assert result.key_parameters == PARAMS
    assert result.largest_st.to_dict() == MAX_ST
    assert len(result.sensitivity) == len(_indices())
    assert not summary.estimate_table(run).empty
    doc = Doc(run)
    method_sections(doc, run, {})
    assert any("Key parameters: X13, X17" in line for line in doc.md)
    sens = run / "campaign" / "sensitivity"
    assert max_st(sens) == MAX_ST
    assert max_st(sens / "indices.parquet") == pytest.approx(MAX_ST)
