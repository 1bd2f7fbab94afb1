"""A run directory read back (railsusp.pipeline_state.check_run_state, RunResult): a damaged
``pipeline.json`` is one line naming its key, for ``railsusp run`` (exit 2) and for
``open_run`` alike; ``recovery`` before the field stage is refused as the other tables are;
the validation's time-aligned rows say what their kN columns hold.

The QA pass found: ``{"stages": {"campaign": "done"}}`` an AttributeError's traceback from
``railsusp run``; ``seconds = "abc"`` a ValueError from its summary; an absolute path in a
stage's files a bare ValueError from ``open_run(...).estimate`` (and ``/etc/passwd``
checked as the run's); ``files = "x"`` read with no check at all; ``recovery`` None
("measured recordings") for a synthetic run stopped in its sensitivity stage.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

import railsusp
from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.pipeline import run_pipeline
from railsusp.pipeline_state import read_run_state
from railsusp.vehicle import MODEL_REVISION

CFG = {"conditions": [{"base": "straight", "name": "s", "duration_s": 1.0, "n_steps": 50}]}
TOML = 'conditions = [{base="straight", name="s", duration_s=1.0, n_steps=50}]\n'

#: a finished estimate stage's record, as the pipeline writes it
ESTIMATE = {
    "hash": "da38ede7ed435818",
    "state": "done",
    "info": {"estimate": {"X13": 15.9}},
    "seconds": 1.4,
    "finished": "2026-12-01T07:02:42+00:00",
    "made_by": {"railsusp": "1.0", "git_sha": None, "git_dirty": False},
    "files": {"estimate/estimate.json": 2},
    "sha256": {"estimate/estimate.json": "44136fa355b3678a"},
    "mtime_ns": {"estimate/estimate.json": 1},
}


def _run_dir(tmp_path: Path, state: dict) -> Path:
    """A run directory holding ``state`` as its pipeline.json and an estimate.json."""
    run = tmp_path / "run"
    (run / "estimate").mkdir(parents=True)
    # of this railsusp's force laws (open_run warns of others)
    (run / "estimate" / "estimate.json").write_text(json.dumps({"model_revision": MODEL_REVISION}))
    (run / "pipeline.json").write_text(json.dumps(state))
    return run


def _estimate_with(key: str, value: object) -> dict:
    return {"format": 1, "stages": {"estimate": {**ESTIMATE, key: value}}}


DAMAGED = [
    ({"stages": {"campaign": "done"}}, "stages.campaign = 'done': a table of the stage's state"),
    (_estimate_with("seconds", "abc"), "stages.estimate.seconds = 'abc': a number of seconds"),
    (_estimate_with("seconds", -1.0), "stages.estimate.seconds = -1.0: a number of seconds"),
    (
        _estimate_with("files", {"/etc/passwd": 5}),
        "stages.estimate.files names the file '/etc/passwd': a path inside the run directory",
    ),
    (
        _estimate_with("files", {"../other/estimate.json": 5}),
        "stages.estimate.files names the file '../other/estimate.json': a path inside",
    ),
    (_estimate_with("files", "x"), "stages.estimate.files = 'x': a table of the stage's files"),
    (_estimate_with("files", ["x"]), "stages.estimate.files = ['x']: a table of the stage's"),
    (
        _estimate_with("files", {"estimate/estimate.json": "2"}),
        "stages.estimate.files.\"estimate/estimate.json\" = '2': a whole number of bytes",
    ),
    (
        _estimate_with("sha256", {"estimate/estimate.json": 5}),
        'stages.estimate.sha256."estimate/estimate.json" = 5: a hash is needed',
    ),
    (_estimate_with("state", 5), "stages.estimate.state = 5: text is needed"),
    (_estimate_with("info", "x"), "stages.estimate.info = 'x': a table is needed"),
    ({"format": -1, "stages": {}}, "format = -1: a whole number (0 or more)"),
    ({"format": "1", "stages": {}}, "format = '1': a whole number (0 or more)"),
    ({"config": "x", "stages": {}}, "config = 'x': a table is needed"),
    ({"config": {"surrogate": 3}, "stages": {}}, "config.surrogate = 3: a table is needed"),
]


@pytest.mark.parametrize(("state", "said"), DAMAGED)
def test_a_damaged_pipeline_json_is_one_line_naming_its_key(tmp_path, state, said):
    run = _run_dir(tmp_path, state)
    before = (run / "pipeline.json").read_bytes()
    with pytest.raises(RailsuspInputError) as info:
        run_pipeline(railsusp.pipeline.PipelineConfig(**CFG), run)
    text = str(info.value)
    assert text.startswith(f"--out {run}: its pipeline.json is damaged: "), text
    assert said in text and "\n" not in text
    # refused as a pipeline.json that is not JSON is: the same remedy
    assert text.endswith(
        "; delete it to resume: a run directory without pipeline.json "
        "resumes from its stages' outputs"
    )
    assert (run / "pipeline.json").read_bytes() == before  # left as it is
    with pytest.raises(RailsuspInputError) as info:
        railsusp.open_run(run).estimate  # noqa: B018
    assert f"{run}: its pipeline.json is damaged: " in str(info.value)
    assert said in str(info.value)


def test_railsusp_run_on_a_damaged_pipeline_json_exits_2_with_one_line(tmp_path):
    """The QA's case: a traceback and exit 1 before."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(TOML)
    run = _run_dir(tmp_path, {"stages": {"campaign": "done"}})
    result = CliRunner().invoke(app, ["-q", "run", str(cfg), "--out", str(run)])
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit)  # not an AttributeError
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert lines[0].startswith("error: --out ") and "stages.campaign = 'done'" in result.output


def test_a_newer_railsusps_pipeline_json_is_refused_as_newer_not_as_damaged(tmp_path):
    """The review of stop 69: the structure check ran before the format's, so a newer
    railsusp's record (a key of another type) was called damaged, with "delete it to
    resume", and this railsusp would then write over the newer run."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(TOML)
    newer = {"format": 99, "stages": {"campaign": {"state": "done", "files": {"a": {"b": 1}}}}}
    run = _run_dir(tmp_path, newer)
    result = CliRunner().invoke(app, ["-q", "run", str(cfg), "--out", str(run)])
    assert result.exit_code == 2, result.output
    assert "written by a newer railsusp" in result.output and "damaged" not in result.output


def test_the_stages_own_records_pass_the_check(tmp_path):
    """What the pipeline writes (and what runs of before wrote: no format, no hashes, a
    stage running or failed) is not taken for damage."""
    state = {
        "config": {"surrogate": {"samples": 8}},
        "stages": {
            "campaign": {k: v for k, v in ESTIMATE.items() if k not in ("sha256", "mtime_ns")},
            "estimate": ESTIMATE,
            "validate": {"hash": "a", "state": "running"},
            "report": {"hash": "b", "state": "failed", "error": "out of memory"},
            "posterior": {"state": "done"},  # a stage this railsusp does not know
        },
        "made_by": "9.0.0",  # a key it does not know, at the top
    }
    run = _run_dir(tmp_path, state)
    assert read_run_state(run, "run")["stages"]["estimate"] == ESTIMATE


def test_recovery_before_the_field_stage_is_refused_not_none(tmp_path):
    """A synthetic run stopped before its field stage answered None, "measured recordings"."""
    run = _run_dir(tmp_path, {"format": 1, "stages": {}})
    with pytest.raises(RailsuspInputError, match="the field stage has not run"):
        railsusp.open_run(run).recovery  # noqa: B018
    (run / "field").mkdir()
    (run / "field" / "index.json").write_text('{"recordings": []}')
    assert railsusp.open_run(run).recovery is None  # measured: no hidden truth
    state = {"format": 1, "stages": {"field": {"state": "failed", "error": "x"}}}
    (run / "pipeline.json").write_text(json.dumps(state))
    with pytest.raises(RailsuspInputError, match="the field stage failed"):
        railsusp.open_run(run).recovery  # noqa: B018


def test_the_validation_says_what_an_aligned_rows_kn_columns_hold(tmp_path):
    """The kN columns of an ``aligned`` row hold the measured s.d. and RMS differences, not
    force statistics: ``statistic_label`` says so as the report does, and the terminal's
    table marks the row and says it under the table."""
    from railsusp.cli.pipeline import _has_aligned, _labelled
    from railsusp.report_estimate import ALIGNED_NOTE

    run = _run_dir(tmp_path, {"format": 1, "stages": {}})
    (run / "estimate" / "validation").mkdir()
    csv = run / "estimate" / "validation" / "validation.csv"
    pd.DataFrame(
        {
            "condition": ["s", "s", "s"],
            "wheel": ["w1L"] * 3,
            "force": ["Y", "Y", "Q"],
            "statistic": ["aligned", "mean", "mean"],
            "measured_kN": [3.7, 3.3, 117.0],
            "before_kN": [0.2, 3.2, 119.0],
            "before_error": [0.06, 0.02, 0.015],
        }
    ).to_csv(csv, index=False)
    val = railsusp.open_run(run).validation
    assert list(val.columns[3:5]) == ["statistic", "statistic_label"]
    assert list(val.statistic_label) == [
        "aligned (kN: measured s.d.; simulated: RMS difference)",
        "mean of |Y|",
        "mean of Q",
    ]
    shown = _labelled(pd.read_csv(csv))
    assert list(shown.statistic) == ["aligned*", "mean of |Y|", "mean of Q"]
    assert _has_aligned(csv) and ALIGNED_NOTE.startswith("* aligned: measured (kN) is the")
    assert "standard deviation" in ALIGNED_NOTE and "RMS" in ALIGNED_NOTE
