"""Run directories and estimates of another force-law revision (the upgrade audit, M1 and
M2): ``railsusp.open_run`` read a run of older force laws as current, with every stage
``done`` and no word, although ``railsusp run`` on the folder simulates it all again; and
``validate`` re-simulated an estimate of older force laws with today's model and said
nothing (its "before" moved with the model alone). The old artefacts are the tiny run's,
their recorded revision edited (and pipeline.json's record of the edited file with it, as
the old run wrote its own), or this railsusp's revision moved on (an upgrade)."""

import json
import shutil
import warnings

import pytest
from typer.testing import CliRunner

import railsusp
import railsusp.vehicle
import test_pipeline
from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.store import file_hash
from railsusp.validate import validate

tiny = test_pipeline.tiny  # the tiny pipeline run, this module's own (module scope)
runner = CliRunner()
OLD = "2026-11-30.1"  # the revision before this one (the audit's r100 run)
RECORDS = ("campaign/campaign.json", "surrogate-campaign/campaign.json")


def _copy(tiny, tmp_path):
    """A copy of the tiny run directory, to edit."""
    copy = tmp_path / "run"
    shutil.copytree(tiny[1], copy)
    return copy


def _edit_json(run, rel, change):
    """Apply ``change`` to the JSON file ``rel`` of ``run`` and record its new size and
    SHA-256 in pipeline.json, as a run that wrote it so would have (else the tables that
    need it refuse it as changed since)."""
    path = run / rel
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc, indent=2))
    state_path = run / "pipeline.json"
    state = json.loads(state_path.read_text())
    for entry in state["stages"].values():
        if rel in entry.get("files", {}):
            entry["files"][rel] = path.stat().st_size
            if rel in (entry.get("sha256") or {}):
                entry["sha256"][rel] = file_hash(path)
            (entry.get("mtime_ns") or {}).pop(rel, None)
    state_path.write_text(json.dumps(state))


def _set_revision(revision):
    """A ``change`` for :func:`_edit_json`: the record states ``revision`` (None: none)."""

    def change(doc):
        doc.pop("model_revision", None)
        if revision is not None:
            doc["model_revision"] = revision

    return change


def _reads_every_table(result):
    """Every table of the run reads, as the run wrote it (an old run is a record)."""
    assert set(result.stages["state"]) == {"done"}
    assert result.estimate.loc["X13", "estimate"] > 0
    assert len(result.validation) and result.recovery is not None
    assert result.key_parameters and len(result.sensitivity)
    assert len(result.surrogate_accuracy)
    assert result.report_path.is_file()


def _open_quietly(run):
    """open_run of ``run`` with the warnings it gives, as a list."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        result = railsusp.open_run(run)
    return result, [str(w.message) for w in seen]


def test_the_estimate_records_the_force_law_revision_it_was_made_with(tiny):
    doc = json.loads((tiny[1] / "estimate" / "estimate.json").read_text())
    assert doc["model_revision"] == railsusp.vehicle.MODEL_REVISION


def test_open_run_warns_of_a_run_of_older_force_laws_and_still_reads_it(tiny, tmp_path):
    """The audit's r100 run: its campaigns simulated with revision 2026-11-30.1, its
    estimate.json recording none (written before estimates recorded one)."""
    run = _copy(tiny, tmp_path)
    for rel in RECORDS:
        _edit_json(run, rel, _set_revision(OLD))
    _edit_json(run, "estimate/estimate.json", _set_revision(None))
    now = railsusp.vehicle.MODEL_REVISION
    with pytest.warns(UserWarning) as seen:
        result = railsusp.open_run(run)
    (line,) = [str(w.message) for w in seen if "force-law revision" in str(w.message)]
    assert f"made with force-law revision {OLD}, older than this railsusp's {now} " in line
    assert "(campaign/campaign.json)" in line
    assert f"railsusp run CONFIG --out {run.resolve()} would simulate every stage again" in line
    assert result.model_revision == OLD
    _reads_every_table(result)


def test_open_run_warns_of_a_run_that_records_no_revision(tiny, tmp_path):
    """The audit's r24 run (2026-11-24.2): no record states a revision; made before they
    were recorded, so with older force laws than any railsusp that records them."""
    run = _copy(tiny, tmp_path)
    for rel in (*RECORDS, "estimate/estimate.json"):
        _edit_json(run, rel, _set_revision(None))
    result, seen = _open_quietly(run)
    (line,) = [w for w in seen if "force-law revision" in w]
    assert "made with force laws older than any recorded force-law revision (it records" in line
    assert "would simulate every stage again" in line
    assert result.model_revision is None
    _reads_every_table(result)


def test_open_run_after_an_upgrade_of_the_force_laws(tiny, tmp_path, monkeypatch):
    """The same run, unedited, opened by a railsusp whose force laws moved on (then
    validate refuses its estimate: test below)."""
    run = _copy(tiny, tmp_path)
    made = railsusp.vehicle.MODEL_REVISION
    monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", "2099-01-01.1")
    result, seen = _open_quietly(run)
    (line,) = [w for w in seen if "force-law revision" in w]
    assert f"made with force-law revision {made}, older than this railsusp's 2099-01-01.1" in line
    assert result.model_revision == made
    _reads_every_table(result)


def test_open_run_of_a_newer_railsusps_run_says_to_open_it_with_that_one(
    tiny, tmp_path, monkeypatch
):
    """Opened by an older railsusp: `railsusp run` refuses the folder (it would discard the
    newer simulations), so the warning does not send the user there."""
    run = _copy(tiny, tmp_path)
    monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", "2026-11-24.2")
    result, seen = _open_quietly(run)
    (line,) = [w for w in seen if "force-law revision" in w]
    assert "open it with the newer railsusp that made it (railsusp run refuses it)" in line
    assert "would simulate" not in line
    assert result.estimate.loc["X13", "estimate"] > 0


def test_a_run_of_this_revision_opens_without_a_warning(tiny, tmp_path):
    """Also one whose estimate.json records none (written before estimates recorded one)
    beside campaigns of this revision: nothing says it is of another model."""
    run = _copy(tiny, tmp_path)
    result, seen = _open_quietly(run)
    assert not [w for w in seen if "force-law revision" in w]
    assert result.model_revision == railsusp.vehicle.MODEL_REVISION
    _edit_json(run, "estimate/estimate.json", _set_revision(None))
    result, seen = _open_quietly(run)
    assert not [w for w in seen if "force-law revision" in w]
    assert result.model_revision == railsusp.vehicle.MODEL_REVISION


def _never(*_a, **_k):
    raise AssertionError("simulated before the refusal")


def _estimate_copy(tiny, tmp_path, revision):
    """A copy of the tiny run's estimate folder whose estimate.json states ``revision``
    (None: none), its recordings the run's own."""
    est = tmp_path / "est"
    shutil.copytree(tiny[1] / "estimate", est, ignore=shutil.ignore_patterns("validation"))
    doc = json.loads((est / "estimate.json").read_text())
    _set_revision(revision)(doc)
    (est / "estimate.json").write_text(json.dumps(doc))
    return est


def test_validate_refuses_an_estimate_of_other_force_laws(tiny, tmp_path, monkeypatch):
    est = _estimate_copy(tiny, tmp_path, OLD)
    now = railsusp.vehicle.MODEL_REVISION
    monkeypatch.setattr("railsusp.vehicle.simulate.simulate_conditions", _never)
    with pytest.raises(RailsuspInputError) as e:
        validate(est)
    text = str(e.value)
    assert f"made with force-law revision {OLD}, older than this railsusp's {now}" in text
    result = runner.invoke(app, ["validate", str(est)])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert f"{est / 'estimate.json'}: made with force-law revision {OLD}" in lines[0]
    assert "estimate again (`railsusp run` on its run directory, or `railsusp" in lines[0]
    assert not (est / "validation").exists()


def test_validate_refuses_an_estimate_after_an_upgrade(tiny, tmp_path, monkeypatch):
    """The tiny run's own estimate (this revision) validated by a railsusp whose force laws
    moved on."""
    est = _estimate_copy(tiny, tmp_path, railsusp.vehicle.MODEL_REVISION)
    monkeypatch.setattr("railsusp.vehicle.simulate.simulate_conditions", _never)
    monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", "2099-01-01.1")
    with pytest.raises(RailsuspInputError, match="older than this railsusp's 2099-01-01.1"):
        validate(est)


def test_validate_warns_of_an_estimate_that_records_no_revision(tiny, tmp_path):
    """Written before estimates recorded it: it cannot tell, so it says so, and validates."""
    est = _estimate_copy(tiny, tmp_path, None)
    with pytest.warns(UserWarning, match="records no force-law revision") as seen:
        res = validate(est)
    (line,) = [str(w.message) for w in seen if "force-law revision" in str(w.message)]
    assert "validate cannot tell" in line and railsusp.vehicle.MODEL_REVISION in line
    assert set(res.forces.force) == {"Y", "Q"}
    # one of this revision is validated without a word about it
    est = _estimate_copy(tiny, tmp_path / "current", railsusp.vehicle.MODEL_REVISION)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        validate(est)
    assert not [w for w in seen if "force-law revision" in str(w.message)]
