"""``railsusp sensitivity`` on campaigns that cannot give the answer it writes (the campaign
audit of stop 59): each failed on the code before, as its docstring says."""

from __future__ import annotations

import json

import pytest

from railsusp.campaign import CampaignError, make_config, run_campaign
from railsusp.conditions import get_condition
from railsusp.sensitivity import analyse
from railsusp.sensitivity_indices import MIN_DIRECT_BASE

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
    from railsusp.config_sections import CampaignSection
    from railsusp.errors import RailsuspInputError
    from railsusp.sensitivity_metamodel import MIN_METAMODEL_RUNS

    with pytest.raises((RailsuspInputError, ValueError), match="samples"):
        CampaignSection(samples=MIN_METAMODEL_RUNS - 1)
    CampaignSection(samples=MIN_METAMODEL_RUNS)


# ---------------------------------------------------------------- the options audit
def _cli_error(args: list) -> str:
    """The one error line of a refused ``railsusp`` command (exit status 2)."""
    from typer.testing import CliRunner

    from railsusp.cli import app

    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1, result.output
    return lines[0]


def test_base_samples_on_a_saltelli_campaign_is_refused_not_ignored(tmp_path, lhs_run):
    """A Saltelli campaign is analysed directly: --base-samples (the metamodel's N) was
    accepted and not used. With an LHS campaign to compare against, it is used there."""
    from railsusp.campaign import CampaignConfig
    from railsusp.errors import RailsuspInputError
    from railsusp.vehicle.wagon import load_wagon

    kw = {"design": "sobol", "batch_size": 8, "seed": 1, "parameters": ("X13", "X14")}
    cfg = CampaignConfig(conditions=tuple(SHORT), samples=2, wagon=load_wagon(), **kw)
    run_campaign(cfg, tmp_path / "sob", max_batches=0)  # its configuration is enough
    line = _cli_error(["sensitivity", tmp_path / "sob", "--base-samples", "64"])
    assert line.startswith("error: --base-samples 64: accepted only where a campaign is analysed")
    assert "Saltelli (sobol design) campaign" in line
    with pytest.raises(RailsuspInputError, match="^base_samples 2048: accepted only where"):
        analyse(tmp_path / "sob", base_samples=2048)
    # not given: the campaign's own state is what stops it (here: no batch ran)
    assert "--base-samples" not in _cli_error(["sensitivity", tmp_path / "sob"])
    with pytest.raises(CampaignError, match="incomplete"):  # used on the compared LHS one
        analyse(tmp_path / "sob", base_samples=64, compare=lhs_run)


def test_the_compared_run_and_the_key_statistics_are_named_as_typed(lhs_run, tmp_path):
    """--compare /nonexistent failed after the analysis without naming --compare;
    --key-statistics foo was reported as --statistics foo."""
    line = _cli_error(["sensitivity", lhs_run, "--compare", tmp_path / "none"])
    assert line.startswith(f"error: --compare {tmp_path / 'none'}: ")
    assert "is not a campaign run directory" in line
    line = _cli_error(["sensitivity", lhs_run, "--key-statistics", "foo"])
    assert line.startswith("error: --key-statistics foo: accepted one or more of mean")
    line = _cli_error(["sensitivity", lhs_run, "--statistics", "foo"])
    assert line.startswith("error: --statistics foo: accepted one or more of mean")


def test_the_stages_own_sobol_figures_mark_the_features_the_key_rule_left_out(lhs_run, monkeypatch):
    """The key rule leaves out features that hardly vary (``ignored_features``), whatever
    their indices; the stage's own campaign/sensitivity/sobol-*.png showed their panels
    unmarked (only the report's redrawn copies were marked)."""
    import railsusp.report as report

    drawn = {}
    real = report.plot_sobol

    def spy(indices, path, statistic="mean", left_out=None):
        drawn[statistic] = dict(left_out or {})
        return real(indices, path, statistic=statistic, left_out=left_out)

    monkeypatch.setattr(report, "plot_sobol", spy)
    kw = {"statistics": ("mean",), "key_statistics": ("mean",), "base_samples": 64}
    out = analyse(lhs_run, **kw)  # the short run's vertical force varies by 0.1 %
    ignored = out["key_parameters"]["ignored_features"]
    assert ignored == ["short Q mean"] and set(drawn["mean"]) == set(ignored)
    assert "coefficient of variation 0.10% < 0.5%" in drawn["mean"]["short Q mean"]
    written = json.loads((lhs_run / "sensitivity" / "key_parameters.json").read_text())
    assert written["figures_mark_left_out"] is True  # the report shows them as drawn
    # kept by a smaller limit, its metamodel explains it too poorly: left out for that
    out = analyse(lhs_run, **kw, min_cv=1e-5)
    assert out["key_parameters"]["unfitted_features"] == ["short Q mean"]
    assert drawn["mean"]["short Q mean"].startswith("metamodel held-out R² 0.")
    assert "< 0.25 (its indices split a fit" in drawn["mean"]["short Q mean"]
    analyse(lhs_run, **kw)
