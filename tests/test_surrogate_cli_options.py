"""``railsusp train`` and ``compare``: every option typed is used or refused, and checked
before any training (the surrogate options audit; each test failed on the code before)."""

from __future__ import annotations

import shutil

import pytest
import torch
from typer.testing import CliRunner

from railsusp.campaign import make_config, run_campaign
from railsusp.cli import app
from railsusp.conditions import get_condition

runner = CliRunner()
SHORT = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0, name="short")
#: the quickest training there is (a network's results are not looked at here)
QUICK = ["--epochs", "1", "--batches-per-epoch", "1", "--batch-size", "8"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("opts") / "run"
    run_campaign(make_config([SHORT], 12, batch_size=12, seed=2, parameters=("X13", "X14")), out)
    return out


@pytest.fixture
def run(campaign, tmp_path):
    """A copy of the campaign of its own, whose surrogates each test makes."""
    return shutil.copytree(campaign, tmp_path / "run")


def _error(args: list[str]) -> str:
    """The one error line of a refused command (exit status 2)."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def _files(run) -> dict:
    """The files under ``run/surrogates`` and their contents (nothing written: the same)."""
    folder = run / "surrogates"
    return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} if folder.exists() else {}


def _ok(args: list[str]) -> str:
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result.output


# ---------------------------------------------------------------- 1. train --model gp-stats
@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--epochs", "5"], "--epochs"),
        (["--device", "cuda"], "--device"),
        (["--window", "30"], "--window"),
        (["--seed", "3"], "--seed"),
        (["--no-record-correction"], "--no-record-correction"),
        (["--fine-tune-epochs", "4"], "--fine-tune-epochs"),
        (["--batch-size", "7", "--batches-per-epoch", "9"], "--batches-per-epoch, --batch-size"),
        (["--epochs", "40"], "--epochs"),  # the default typed out: given all the same
    ],
)
def test_gp_stats_refuses_the_training_options_it_does_not_use(tmp_path, args, named):
    """All of them exited 0 (and --device cuda without CUDA too): the GPs were fitted on
    every sample, the options unread."""
    line = _error(["train", tmp_path / "none", "--model", "gp-stats", *args])
    assert line.startswith(f"error: {named}: accepted only with the network models")


def test_the_sequence_network_refuses_batch_size(tmp_path):
    line = _error(["train", tmp_path / "none", "--model", "cnn-gru-seq", "--batch-size", "7"])
    assert line.startswith("error: --batch-size: accepted only with the window networks")


@pytest.mark.skipif(torch.cuda.is_available(), reason="a machine without CUDA")
def test_device_names_its_option(tmp_path):
    assert _error(["train", tmp_path, "--device", "gpu"]).startswith(
        "error: --device 'gpu': accepted cpu, cuda, auto"
    )


# ---------------------------------------------------------------- 2. compare's options
@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--epochs", "3"], "--epochs: accepted only with a network among --models"),
        (["--device", "auto"], "--device: accepted only with a network among --models"),
        (["--batch-size", "8"], "--batch-size: accepted only with a network among --models"),
    ],
)
def test_compare_refuses_network_options_without_a_network(run, args, named):
    """``--models rbf,gp-stats --epochs 3`` fitted both and exited 0."""
    before = _files(run)
    assert _error(["compare", run, "--models", "rbf,gp-stats", *args]).startswith(f"error: {named}")
    assert _files(run) == before


def test_compare_refuses_batch_size_for_the_sequence_network_alone(run):
    line = _error(["compare", run, "--models", "cnn-gru-seq,gp-stats", "--batch-size", "8"])
    assert line.startswith("error: --batch-size: accepted only with a window network")


@pytest.mark.skipif(torch.cuda.is_available(), reason="a machine without CUDA")
def test_compare_checks_the_device_before_any_model(run):
    """--device cuda without CUDA: the RBF was fitted first, then "device 'cuda' asked for
    ..." (no option named), from inside the networks' training."""
    before = _files(run)
    line = _error(["compare", run, "--models", "rbf,bp", "--device", "cuda", *QUICK])
    assert line.startswith("error: --device cuda: device 'cuda' asked for")
    assert _files(run) == before


def test_compare_seeds_the_rbf_and_the_gps_by_seed(campaign, monkeypatch):
    """They took seed 0 whatever --seed said."""
    import railsusp.surrogate.compare as cmp
    from railsusp.surrogate import TrainConfig

    seeds = []

    class Rbf(cmp.RBFWindowModel):
        def __init__(self, *args, seed=0, **kw):
            seeds.append(("rbf", seed))
            super().__init__(*args, seed=seed, **kw)

    class Gp(cmp.StatisticsGP):
        def __init__(self, *args, seed=0, **kw):
            seeds.append(("gp-stats", seed))
            super().__init__(*args, seed=seed, **kw)

    monkeypatch.setattr(cmp, "RBFWindowModel", Rbf)
    monkeypatch.setattr(cmp, "StatisticsGP", Gp)
    monkeypatch.setattr(cmp, "write_csv", lambda *a, **k: None)  # the campaign is shared
    monkeypatch.setattr(cmp, "write_json", lambda *a, **k: None)
    cmp.compare(campaign, models=["rbf", "gp-stats"], train=TrainConfig(seed=5))
    assert seeds == [("rbf", 5), ("gp-stats", 5)]


# ---------------------------------------------------------------- 3. and 5. replaced networks
def test_compare_says_it_replaces_a_network_train_made_otherwise(run):
    """compare trained its own bp over one of --window 10, then over one without a record
    correction, without the line train prints."""
    _ok(["train", run, "--model", "bp", "--window", "10", *QUICK])
    out = _ok(["compare", run, "--models", "bp", *QUICK])
    folder = run / "surrogates" / "bp" / "short"
    assert f"note: replacing the network in {folder}, trained with other settings " in out
    assert "(window 10 -> 20)" in out
    _ok(["train", run, "--model", "bp", "--no-record-correction", *QUICK])
    out = _ok(["compare", run, "--models", "bp", *QUICK])
    assert "(record_correction False -> True)" in out
    again = _ok(["compare", run, "--models", "bp", *QUICK])  # the same settings: resumed
    assert "replacing" not in again


def test_train_says_it_replaces_a_network_when_the_window_goes_back_to_the_default(run):
    """The window was compared only when --window was given."""
    _ok(["train", run, "--model", "bp", "--window", "10", *QUICK])
    out = _ok(["train", run, "--model", "bp", *QUICK])
    assert "trained with other settings (window 10 -> 20)" in out
    assert "replacing" not in _ok(["train", run, "--model", "bp", "--window", "20", *QUICK])


# ---------------------------------------------------------------- 7. checked before training
def test_conditions_are_checked_before_any_training(run):
    """``--conditions short,bogus`` trained short, then failed on bogus; compare also drew
    short's overlay beside the older compare.csv."""
    _ok(["compare", run, "--models", "gp-stats"])
    before = _files(run)
    for cmd in (["train", run, "--model", "bp", *QUICK], ["compare", run, "--models", "rbf"]):
        line = _error([*cmd, "--conditions", "short,bogus"])
        assert line == "error: --conditions 'bogus': accepted one or more of the campaign's short"
        assert _files(run) == before


def test_records_too_short_for_a_model_are_refused_before_any_training(run):
    """compare --models bp,cnn-gru-seq on 50-step records trained bp, scored it on an empty
    slice ("Degrees of freedom <= 0"), then failed naming ``washout (window) = 100``, an
    option compare does not have; train --window 50 said it replaced the network, then
    refused."""
    _ok(["train", run, "--model", "bp", *QUICK])
    before = _files(run)
    line = _error(["compare", run, "--models", "bp,cnn-gru-seq", *QUICK])
    assert line == (
        "error: --models cnn-gru-seq: its washout of 100 steps needs records longer than 100 "
        "steps; condition 'short' has 50"
    )
    line = _error(["train", run, "--model", "bp", "--window", "50", *QUICK])
    assert line.startswith("error: --window 50 steps: accepted 2 to 49, fewer than the 50 steps")
    assert _files(run) == before
