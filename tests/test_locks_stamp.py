"""A sensitivity analysis is stamped with the campaign it was computed from, and read only
beside that campaign (the concurrency audit: ``campaign --force`` replaced a campaign while
``sensitivity`` analysed it, and C then held the seed-4 campaign beside a complete analysis
of the seed-3 one, whose key parameters ``train`` took without a word). Each test failed on
the code before: no stamp was written, none was checked, and the second process was not
refused."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from railsusp.campaign import make_config, run_campaign
from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.sensitivity import analyse
from railsusp.store import read_json

runner = CliRunner()

SHORT = [get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0, name="short")]
TOML = '[[condition]]\nbase = "straight"\nname = "short"\nduration_s = 1.0\nn_steps = 50\n'


def _campaign(out, seed):
    run_campaign(make_config(SHORT, 8, batch_size=8, seed=seed, parameters=("X13", "X14")), out)
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """An analysed campaign (seed 1) and another, not analysed (seed 2)."""
    root = tmp_path_factory.mktemp("stamp")
    analysed = _campaign(root / "a", 1)
    analyse(analysed, statistics=("mean",), key_statistics=("mean",), base_samples=64)
    return analysed, _campaign(root / "b", 2)


@pytest.fixture
def stale(runs, tmp_path):
    """Campaign b with campaign a's analysis beside it (as the race left it)."""
    a, b = runs
    copy = tmp_path / "b"
    shutil.copytree(b, copy)
    shutil.copytree(a / "sensitivity", copy / "sensitivity")
    return copy


def one_line(args) -> str:
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    return lines[0]


def test_the_analysis_is_stamped_with_its_campaign(runs):
    a, _ = runs
    want = read_json(a / "campaign.json")["config_hash"]
    assert read_json(a / "sensitivity" / "key_parameters.json")["campaign_hash"] == want
    meta = pq.read_schema(a / "sensitivity" / "indices.parquet").metadata
    assert meta[b"railsusp.campaign_hash"].decode() == want


def test_an_analysis_of_another_campaign_is_refused_where_it_is_read(stale, tmp_path):
    from railsusp.surrogate import key_parameters

    path = stale / "sensitivity" / "key_parameters.json"
    with pytest.raises(RailsuspInputError) as info:
        key_parameters(stale)
    text = str(info.value)
    assert text.startswith(f"{path} was computed from another campaign than the one in {stale}")
    assert text.endswith(f"run `railsusp sensitivity {stale}` again") and "\n" not in text
    # the command line: train (before any training), campaign --keys-from, validate
    line = one_line(["train", stale, "--model", "bp", "--epochs", "1", "--batches-per-epoch",
                     "1", "--batch-size", "8", "--no-record-correction"])  # fmt: skip
    assert line == f"error: {text}"
    args = ["campaign", "--out", tmp_path / "keys", "--keys-from", stale, "--samples", "4"]
    assert one_line([*args, "--conditions", "straight"]) == f"error: {text}"
    assert not (tmp_path / "keys").exists()
    estimate = tmp_path / "estimate"
    estimate.mkdir()
    line = one_line(["validate", estimate, "--sensitivity", stale / "sensitivity"])
    assert line == f"error: {text}"
    indices = stale / "sensitivity" / "indices.parquet"
    line = one_line(["validate", estimate, "--sensitivity", indices])
    assert line.startswith(f"error: {indices} was computed from another campaign")


def test_an_analysis_made_before_the_stamp_is_read_as_before(stale, runs):
    """Files without the stamp predate it: their keys are read (the campaign cannot be
    told); with the stamp, the same file is refused (the case above)."""
    from railsusp.surrogate import key_parameters

    path = stale / "sensitivity" / "key_parameters.json"
    with pytest.raises(RailsuspInputError, match="railsusp sensitivity"):
        key_parameters(stale)
    doc = json.loads(path.read_text())
    del doc["campaign_hash"]
    path.write_text(json.dumps(doc))
    assert key_parameters(stale) == tuple(doc["key_parameters"]["keys"])
    assert key_parameters(runs[0]) == tuple(doc["key_parameters"]["keys"])  # its own


def test_a_campaign_force_is_refused_while_sensitivity_analyses_the_folder(
    runs, tmp_path, monkeypatch
):
    """The audit's race: ``railsusp sensitivity C`` running, then ``railsusp campaign --out C
    --seed 4 --force`` from another process. It replaced the campaign (exit 0), and the
    analysis wrote the old campaign's indices beside the new one; it is refused now, and the
    analysis is of the campaign in C."""
    import railsusp.sensitivity

    a, _ = runs
    copy = tmp_path / "c"
    shutil.copytree(a, copy, ignore=shutil.ignore_patterns("sensitivity"))
    conditions = tmp_path / "short.toml"
    conditions.write_text(TOML + "lead_in_m = 20.0\n")
    before = read_json(copy / "campaign.json")["config_hash"]
    real, other = railsusp.sensitivity.analyse, []

    def analyse_meanwhile(run, **kwargs):  # the second command starts mid-analysis
        env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
        other.append(
            subprocess.run(
                [sys.executable, "-m", "railsusp.cli", "campaign", "--out", str(copy),
                 "--conditions", str(conditions), "--samples", "8", "--batch-size", "8",
                 "--parameters", "X13,X14", "--seed", "4", "--force"],
                capture_output=True, text=True, env=env, timeout=300,
            )
        )  # fmt: skip
        return real(run, **kwargs)

    monkeypatch.setattr(railsusp.sensitivity, "analyse", analyse_meanwhile)
    result = runner.invoke(
        app, ["sensitivity", str(copy), "--statistics", "mean", "--key-statistics", "mean",
              "--base-samples", "64"]
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    (done,) = other
    assert done.returncode == 2, done.stdout + done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line == (
        f"error: --out {copy}: another railsusp run is working in this folder (process "
        f"{os.getpid()}); wait for it to end, or give another folder"
    )
    assert read_json(copy / "campaign.json")["config_hash"] == before  # not replaced
    stamp = read_json(copy / "sensitivity" / "key_parameters.json")["campaign_hash"]
    assert stamp == before
