"""A run directory's report after a standalone command wrote into one of its stages'
folders, and ``railsusp run``'s summary read under the run's lock (the concurrency audit):
``railsusp estimate --out RUN/estimate`` left RUN/report.html presenting the estimate it
replaced as the answer, with no banner, and ``open_run(RUN).report_path`` returned it while
``.estimate`` was refused; ``railsusp run`` printed its summary after letting the run
directory go, so a second run finishing in between put its tables in the first's printout."""

import json
from html import unescape

import pytest
from typer.testing import CliRunner

import railsusp
import test_pipeline
from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.pipeline import load_config, run_pipeline
from railsusp.run_lock import run_lock

_up_to_date_copy = test_pipeline._up_to_date_copy
tiny = test_pipeline.tiny  # the tiny pipeline run, this module's own (module scope)

runner = CliRunner()


def _banner(run) -> str:
    """The stale banner of RUN/report.md ('' where there is none)."""
    md = (run / "report.md").read_text()
    if "<!-- railsusp:stale -->" not in md:
        return ""
    return md[: md.index("<!-- /railsusp:stale -->")]


@pytest.mark.parametrize(
    "command, stage",
    [
        (
            lambda run: [
                "estimate",
                "--surrogate",
                str(run / "surrogate-campaign" / "surrogates" / "bp"),
                "--measured",
                str(run / "field"),
                "--out",
                str(run / "estimate"),
                "--n-gen",
                "2",
                "--pop-size",
                "6",
                "--seed",
                "5",
            ],
            "estimate",
        ),
        # names RUN/estimate, writes RUN/estimate/validation: the banner names its stage
        (lambda run: ["validate", str(run / "estimate")], "validate"),
    ],
    ids=["estimate", "validate"],
)
def test_a_standalone_command_in_a_run_directory_marks_its_report_stale(
    tiny, tmp_path, command, stage
):
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    assert _banner(copy) == "" and railsusp.open_run(copy).report_path.is_file()
    result = runner.invoke(app, ["-q", *command(copy)])
    assert result.exit_code == 0, result.output
    banner = _banner(copy)
    assert f"`railsusp {command(copy)[0]}` was started on" in banner
    assert f"stage '{stage}'" in banner and "`railsusp run`" in banner
    html = unescape((copy / "report.html").read_text())
    assert html.count("STALE") == 1 and f"railsusp {command(copy)[0]}" in html
    # the report no longer answers for the run directory, as the tables it shows do not
    with pytest.raises(RailsuspInputError, match="report"):
        _ = railsusp.open_run(copy).report_path
    # and `railsusp run` makes the changed stages and the report again, without the banner
    run_pipeline(load_config(tiny[0]), copy)
    assert _banner(copy) == "" and railsusp.open_run(copy).report_path.is_file()


def test_a_command_writing_no_stages_outputs_leaves_the_report_alone(tiny, tmp_path):
    """A folder inside the run directory where no stage recorded a file (the report reads
    nothing there) leaves the report as it is."""
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    result = runner.invoke(app, ["-q", "example-recording", "--out", str(copy / "examples")])
    assert result.exit_code == 0, result.output
    assert _banner(copy) == "" and railsusp.open_run(copy).report_path.is_file()


def test_report_path_refuses_a_report_whose_earlier_stage_changed(tiny, tmp_path):
    """The report summarises every earlier stage: one not done, or a file of one changed
    since, makes report_path refuse in one line, as the table read from it is refused."""
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    result = railsusp.open_run(copy)
    assert result.report_path == copy.resolve() / "report.html"
    log = copy / "estimate" / "nsga_log.csv"
    kept = log.read_bytes()
    log.write_bytes(kept + b"\n")
    with pytest.raises(RailsuspInputError, match="estimate stage") as refused:
        _ = result.report_path
    message = str(refused.value)
    assert "estimate/nsga_log.csv changed" in message
    assert "report.html was made from that stage's outputs" in message
    assert "\n" not in message
    log.write_bytes(kept)
    assert result.report_path.is_file()
    state_path = copy / "pipeline.json"
    state = json.loads(state_path.read_text())
    state["stages"]["validate"]["state"] = "stale"
    state_path.write_text(json.dumps(state))
    with pytest.raises(RailsuspInputError, match="validate stage is stale.*report.html"):
        _ = result.report_path


def test_the_run_summary_is_read_while_the_run_directory_is_held(tiny, tmp_path, monkeypatch):
    """``railsusp run`` reads the tables it prints before it lets the run directory go: a
    reader's lock on it is refused while the summary reads the estimate (it was granted,
    the run's lock let go, and a second run could rewrite the tables in between)."""
    import railsusp.summary as summary

    cfg_path, _, _, _ = tiny
    _, _, copy = _up_to_date_copy(tiny, tmp_path)
    held = []
    inner = summary.estimate_table

    def probed(run, *args, **kwargs):
        try:
            with run_lock(run, "probe", shared=True):
                held.append(False)
        except RailsuspInputError:
            held.append(True)
        return inner(run, *args, **kwargs)

    monkeypatch.setattr(summary, "estimate_table", probed)
    result = runner.invoke(app, ["-q", "run", str(cfg_path), "--out", str(copy)])
    assert result.exit_code == 0, result.output
    assert held == [True]
    assert "Answer" in result.output and "Stage timings" in result.output
    assert "report: " in result.output and "report.html" in result.output
