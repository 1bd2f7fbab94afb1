"""``railsusp sensitivity`` on campaigns that cannot give the answer it writes (the campaign
audit of stop 59): each failed on the code before, as its docstring says."""

from __future__ import annotations

import json

import pytest

from railsusp.campaign import CampaignError, make_config, run_campaign
from railsusp.conditions import get_condition
from railsusp.sensitivity import MIN_DIRECT_BASE, analyse

SHORT = [get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0, name="short")]


@pytest.fixture(scope="module")
def lhs_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sens") / "lhs"
    run_campaign(make_config(SHORT, 8, batch_size=8, seed=1, parameters=("X13", "X14")), out)
    return out


def test_an_incomplete_campaign_is_refused(tmp_path):
    """8 of 12 samples (and in a campaign of two conditions, one left out entirely) were
    analysed with exit 0 and no warning."""
    cfg = make_config(SHORT, 12, batch_size=4, seed=1, parameters=("X13", "X14"))
    run_campaign(cfg, tmp_path / "part", max_batches=2)
    with pytest.raises(CampaignError, match="run the same `railsusp campaign` command again"):
        analyse(tmp_path / "part", base_samples=64)
    assert not (tmp_path / "part" / "sensitivity").exists()


def test_a_failed_comparison_leaves_the_earlier_analysis_whole(lhs_run):
    """A --compare naming no campaign wrote the new indices, then failed, leaving them
    beside the old key_parameters.json; an earlier comparison and figures of other
    statistics stayed as if this analysis' own."""
    out = lhs_run / "sensitivity"
    analyse(lhs_run, statistics=("mean",), key_statistics=("mean",), base_samples=64)
    (out / "agreement.csv").write_text("an earlier comparison")
    (out / "sobol-p99.png").write_bytes(b"an earlier figure")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(CampaignError):
        analyse(lhs_run, statistics=("rms",), key_statistics=("rms",), base_samples=64,
                compare=lhs_run / "nonexistent")  # fmt: skip
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    analyse(lhs_run, statistics=("mean",), key_statistics=("mean",), base_samples=64)
    assert not (out / "agreement.csv").exists() and not (out / "sobol-p99.png").exists()
    keys = json.loads((out / "key_parameters.json").read_text())["key_parameters"]
    assert keys["statistics"] == ["mean"]


def test_a_saltelli_design_too_small_for_its_indices_is_refused(tmp_path):
    """N = 2 base samples gave total indices of 19.8 +- 54 and 9.7, both taken as key. Such
    a campaign is refused when made; one stored before that is refused by the analysis."""
    from railsusp.campaign import CampaignConfig
    from railsusp.vehicle.wagon import load_wagon

    kw = {"design": "sobol", "batch_size": 16, "seed": 1, "parameters": ("X13", "X14")}
    with pytest.raises(CampaignError, match=f"needs N >= {MIN_DIRECT_BASE}"):
        make_config(SHORT, 2, **kw)
    cfg = CampaignConfig(conditions=tuple(SHORT), samples=2, wagon=load_wagon(), **kw)
    run_campaign(cfg, tmp_path / "sob")
    with pytest.raises(ValueError, match=f"need N >= {MIN_DIRECT_BASE}"):
        analyse(tmp_path / "sob")


def test_the_pipeline_refuses_a_campaign_too_small_for_the_metamodel():
    """samples = 4 was accepted and the sensitivity stage then failed on every run."""
    from railsusp.errors import RailsuspInputError
    from railsusp.pipeline_config import CampaignSection
    from railsusp.sensitivity import MIN_METAMODEL_RUNS

    with pytest.raises((RailsuspInputError, ValueError), match="samples"):
        CampaignSection(samples=MIN_METAMODEL_RUNS - 1)
    CampaignSection(samples=MIN_METAMODEL_RUNS)
