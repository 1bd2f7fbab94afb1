"""What an earlier artefact left in its folder is not shown as a new one's (interrupt/resume
audit of stop 60): a validation's recovery table of another field's truth and a removed
condition's figure, an estimate's old validation, a removed condition's synthetic
recording; and a crash between atomic_folder's two renames loses nothing."""

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.measured import read_field, synthesise_field
from railsusp.params import ParameterSet
from railsusp.store import atomic_folder
from railsusp.validate import ValidationResult

SHORT = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)


def _series(n: int = 50) -> dict:
    t = np.arange(n) * 0.02
    run = np.stack([np.sin(t), 120.0 + np.cos(t)], axis=1)
    return {"time": t, "measured": run, "before": run + 0.1, "after": run}


def test_a_validation_removes_what_an_earlier_one_wrote_and_it_does_not(tmp_path):
    out = tmp_path / "validation"
    forces = pd.DataFrame({"condition": ["a"], "force": ["Q"], "measured_kN": [120.0]})
    recovery = pd.DataFrame({"parameter": ["X13"], "truth": [16.1], "estimate": [15.9]})
    ValidationResult(forces, recovery, {"a": _series(), "b": _series()}).save(out)
    (out / "notes.txt").write_text("the user's")
    assert {p.name for p in out.iterdir()} >= {"recovery.csv", "validation-b.png"}
    ValidationResult(forces, None, {"a": _series()}).save(out)  # measured field, one condition
    assert sorted(p.name for p in out.iterdir()) == [
        "notes.txt", "validation-a.png", "validation.csv", "validation.json"
    ]  # fmt: skip


def test_atomic_folder_drops_what_the_new_artefact_replaces_and_keeps_the_rest(tmp_path):
    art = tmp_path / "est"
    art.mkdir()
    (art / "validation").mkdir()
    (art / "validation" / "recovery.csv").write_text("old")
    (art / "mine.txt").write_text("kept")
    with atomic_folder(art, drop=("validation",)) as tmp:
        (tmp / "estimate.json").write_text("{}")
    assert sorted(p.name for p in art.iterdir()) == ["estimate.json", "mine.txt"]


def test_a_crash_between_the_two_renames_loses_nothing(tmp_path):
    """Killed after the old folder was set aside and before the new one went in, the next
    save deleted the only finished copy (a trained network and its checkpoint)."""
    art = tmp_path / "net"
    art.mkdir()
    (art / "model.pt").write_text("trained")
    (art / "checkpoint.pt").write_text("epoch 40")
    art.rename(tmp_path / ".net.old-abc123")  # the state such a crash leaves
    with atomic_folder(art) as tmp:
        (tmp / "model.pt").write_text("retrained")
    assert (art / "checkpoint.pt").read_text() == "epoch 40"  # put back, then carried
    assert (art / "model.pt").read_text() == "retrained"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["net"]


def test_glob_characters_in_a_folders_name_are_its_name_not_a_pattern(tmp_path):
    """The run-directory store audit: atomic_folder looked for its leftovers with the folder's
    name as a glob pattern. ``est[1]``'s pattern matched ``.est1.old-*``, not its own
    ``.est[1].old-*``, so a crash between the two renames lost the old folder's work (neither
    put back nor removed); ``run*``'s matched every sibling's, and a save removed another
    save's folder in the making (``.run2.new-*``)."""
    art = tmp_path / "est[1]"
    art.mkdir()
    (art / "checkpoint.pt").write_text("epoch 40")
    art.rename(tmp_path / ".est[1].old-abc123")  # the state such a crash leaves
    with atomic_folder(art) as tmp:
        (tmp / "model.pt").write_text("retrained")
    assert (art / "checkpoint.pt").read_text() == "epoch 40"  # put back, then carried
    assert sorted(p.name for p in tmp_path.iterdir()) == ["est[1]"]

    other = tmp_path / ".run2.new-xyz"  # another save of a sibling, under way
    other.mkdir()
    (other / "model.pt").write_text("being written")
    with atomic_folder(tmp_path / "run*") as tmp:
        (tmp / "model.pt").write_text("saved")
    assert (other / "model.pt").read_text() == "being written"
    assert (tmp_path / "run*" / "model.pt").read_text() == "saved"


def test_a_field_synthesised_again_holds_only_its_own_recordings(tmp_path):
    field = tmp_path / "field"
    other = SHORT.with_changes(name="other")
    synthesise_field(ParameterSet.nominal(), [SHORT, other], field)
    assert (field / "other.csv").exists()
    (field / "README.txt").write_text("the user's")
    (field / "straight.notes.txt").write_text("the user's too (a kept condition's name)")
    synthesise_field(ParameterSet.nominal(), [SHORT], field)
    assert sorted(p.name for p in field.iterdir()) == [
        "README.txt", "index.json", "straight.csv", "straight.json", "straight.notes.txt",
        "truth.json",
    ]  # fmt: skip
    assert [r.condition.name for r in read_field(field)] == ["straight"]


def test_an_estimate_again_in_its_folder_drops_the_earlier_ones_validation(tmp_path):
    runner = CliRunner()
    field, est = tmp_path / "field", tmp_path / "est"
    synthesise_field(ParameterSet.nominal(), [SHORT], field)
    args = ["estimate", "--measured", str(field), "--out", str(est), "--simulator",
            "--parameters", "X13", "--pop-size", "4", "--n-gen", "1"]  # fmt: skip
    assert runner.invoke(app, args).exit_code == 0
    (est / "validation").mkdir()
    (est / "validation" / "recovery.csv").write_text("the first estimate's")
    (est / "notes.txt").write_text("the user's")
    done = runner.invoke(app, [*args, "--seed", "1"])
    assert done.exit_code == 0, done.output
    assert not (est / "validation").exists() and (est / "notes.txt").exists()


def test_results_are_not_written_over_recordings(tmp_path):
    """`estimate --out` into its recordings' folder replaced a recording named ``estimate``
    with the results, `validate --out` wrote among them and `simulate --out` wrote over a
    recording's table (the command-line audit of stop 60)."""
    runner = CliRunner()
    field = tmp_path / "field"
    synthesise_field(ParameterSet.nominal(), [SHORT], field, fmt="parquet")
    before = {p.name: p.read_bytes() for p in field.iterdir()}
    cases = [
        (["estimate", "--measured", str(field), "--out", str(field), "--simulator"],
         "is a field folder of recordings"),
        (["validate", str(tmp_path / "est"), "--out", str(field)],
         "is a field folder of recordings"),
        (["simulate", "straight", "--out", str(field / "straight.parquet")],
         "is a recording (its sidecar straight.json says so)"),
        (["simulate", "straight", "--out", str(field / "straight.csv")],  # beside it
         "is a recording (its sidecar straight.json says so)"),
    ]  # fmt: skip
    for args, said in cases:
        result = runner.invoke(app, args)
        assert result.exit_code == 2, result.output
        assert said in result.output
    assert {p.name: p.read_bytes() for p in field.iterdir()} == before


def test_train_on_a_missing_device_says_so_before_anything_else(tmp_path):
    """`train --device cuda` without a GPU printed that it was replacing the saved network,
    then failed: the note was false (command-line audit of stop 60)."""
    import torch

    if torch.cuda.is_available():
        pytest.skip("a CUDA device is present: nothing to refuse")
    result = CliRunner().invoke(app, ["train", str(tmp_path / "camp"), "--device", "cuda"])
    assert result.exit_code == 2
    assert "--device cuda: device 'cuda' asked for but no CUDA device" in result.output
    assert "replacing" not in result.output
