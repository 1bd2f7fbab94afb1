"""Sobol campaigns and analysis that gave answers they could not support (the sensitivity
audit): Saltelli designs broken by per-row variation or too small, key parameters chosen
from metamodels that do not fit, a comparison with an unfinished campaign, key statistics
never analysed, a repeated index. Each test failed on the code before, as its docstring
says."""

from __future__ import annotations

import json
import shutil
import warnings

import numpy as np
import pandas as pd
import pytest

from railsusp.campaign import (
    CampaignConfig,
    CampaignError,
    load_campaign,
    make_config,
    run_campaign,
)
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.key_parameters import MIN_METAMODEL_R2, select_key_parameters
from railsusp.sensitivity import analyse, check_settings
from railsusp.sensitivity_indices import MIN_DIRECT_BASE
from railsusp.sensitivity_metamodel import sobol_metamodel
from railsusp.store import write_parquet
from railsusp.variation import TrackFamily
from railsusp.vehicle.wagon import load_wagon

SHORT = [get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0, name="short")]
CURVE = get_condition("curve", duration_s=1.0, n_steps=50, lead_in_m=20.0, name="arc")


def stored_config(samples: int, **kw) -> CampaignConfig:
    """A configuration as a campaign stored before make_config refused it (its loading
    validates the model alone)."""
    return CampaignConfig(conditions=tuple(SHORT), samples=samples, wagon=load_wagon(), **kw)


@pytest.fixture(scope="module")
def lhs_runs(tmp_path_factory):
    """A complete 12-run LHS campaign and one stopped after two of its three batches."""
    root = tmp_path_factory.mktemp("audit")
    cfg = make_config(SHORT, 12, batch_size=4, seed=1, parameters=("X13", "X14"))
    run_campaign(cfg, root / "full")
    part = make_config(SHORT, 12, batch_size=4, seed=2, parameters=("X13", "X14"))
    run_campaign(part, root / "part", max_batches=2)
    return root / "full", root / "part"


# ---------------------------------------------------------------- 1. Saltelli campaigns
@pytest.mark.parametrize(
    "kw, named",
    [
        ({"independent_seeds": True}, "independent_seeds"),
        ({"other_parameters": {"X15": (85e6, 255e6)}}, "other_parameters"),
        (
            {"independent_seeds": True, "track_family": TrackFamily(cant_mm=(0.0, 100.0))},
            "independent_seeds, track_family",
        ),
    ],
)
def test_a_saltelli_design_with_per_row_variation_is_refused_when_made(kw, named):
    """design="sobol" with independent_seeds, a track family or other_parameters was
    accepted: every row of a Saltelli block (A, AB_i, B) then ran on its own track or
    non-key values, which adds their variance to every total index (inert parameters passed
    the 0.05 key threshold)."""
    conds = [*SHORT, CURVE]
    with pytest.raises(CampaignError, match=f"design sobol with {named}: accepted only without"):
        make_config(conds, 16, design="sobol", parameters=("X13", "X14"), **kw)
    make_config(conds, 16, design="lhs", parameters=("X13", "X14"), **kw)  # their design
    make_config(conds, 16, design="sobol", parameters=("X13", "X14"))


@pytest.mark.parametrize("n", [2, 4, 8])
def test_a_saltelli_design_too_small_for_its_analysis_is_refused_when_made(n):
    """N = 2, 4, 8 base samples were accepted, simulated, and refused only by the analysis
    after the runs were spent."""
    with pytest.raises(CampaignError, match=f"samples {n}: .*needs N >= {MIN_DIRECT_BASE}"):
        make_config(SHORT, n, design="sobol", parameters=("X13", "X14"))
    assert make_config(SHORT, MIN_DIRECT_BASE, design="sobol").samples == MIN_DIRECT_BASE
    make_config(SHORT, n, design="lhs", parameters=("X13", "X14"))  # an LHS of n: its own rule


def test_a_stored_saltelli_campaign_with_per_row_tracks_is_refused_by_the_analysis(tmp_path):
    """A Saltelli campaign on a track per run, stored before make_config refused it, was
    analysed directly and its noisy total indices taken as key."""
    cfg = stored_config(16, design="sobol", independent_seeds=True, parameters=("X13", "X14"))
    run_campaign(cfg, tmp_path / "sob")
    with pytest.raises(ValueError, match="design sobol with independent_seeds"):
        analyse(tmp_path / "sob")
    assert not (tmp_path / "sob" / "sensitivity").exists()


# ------------------------------------------------------------ 2. metamodels that do not fit
def indices(r2: dict[str, float], method: str = "metamodel") -> pd.DataFrame:
    """Two features over X13..X16: 'curve Y mean' (X13 key) and 'straight Y mean', whose
    indices put X16 at ST 0.9; each feature's held-out R^2 from ``r2``."""
    rows = []
    for cond, st in (("curve", (0.8, 0.02, 0.01, 0.01)), ("straight", (0.02, 0.03, 0.02, 0.9))):
        for p, v in zip(("X13", "X14", "X15", "X16"), st, strict=True):
            rows.append(
                {
                    "condition": cond,
                    "quantity": "Y",
                    "statistic": "mean",
                    "parameter": p,
                    "S1": v,
                    "S1_conf": 0.01,
                    "ST": v,
                    "ST_conf": 0.01,
                    "method": method,
                    "cv": 0.1,
                    "r2_holdout": r2[cond],
                }
            )
    return pd.DataFrame(rows)


@pytest.mark.parametrize("poor", [0.1, float("nan")])
def test_a_feature_whose_metamodel_does_not_fit_chooses_no_key(poor):
    """Sobol indices of a GP mean are normalised by that mean's variance: a feature the GP
    cannot explain (held-out R^2 0.1, or NaN: not scored) made X16 key at ST 0.9."""
    with pytest.warns(UserWarning, match="left out of the key rule.*straight Y mean"):
        sel = select_key_parameters(indices({"curve": 0.95, "straight": poor}))
    assert sel.keys == ["X13"]
    assert sel.unfitted == ["straight Y mean"]
    assert sel.max_st["X16"] == pytest.approx(0.01) and sel.where["X16"] == "curve Y mean"
    d = sel.to_dict()
    assert d["min_r2"] == MIN_METAMODEL_R2 and d["unfitted_features"] == ["straight Y mean"]
    assert f"held-out R^2 below {MIN_METAMODEL_R2:g}" in d["rule"]
    # the direct route has no metamodel: its rows are never left out, its rule says nothing
    direct = select_key_parameters(indices({"curve": np.nan, "straight": np.nan}, "direct"))
    assert direct.keys == ["X13", "X16"] and direct.min_r2 is None
    assert "R^2" not in direct.rule()


def test_when_no_metamodel_fits_the_key_selection_is_refused():
    """Every feature unexplained: keys were chosen from noise all the same."""
    with pytest.raises(ValueError, match=r"no feature's Gaussian-process metamodel fits"):
        select_key_parameters(indices({"curve": -0.3, "straight": np.nan}))


def test_pure_noise_features_are_refused_not_made_keys(lhs_runs, tmp_path):
    """Features of pure noise (12 runs: under the single hold-out's 50) gave every
    parameter ST about 0.5 and all of them as keys, the R^2 of two held-out points not
    looked at."""
    run = tmp_path / "noise"
    shutil.copytree(lhs_runs[0], run)
    feats = pd.read_parquet(run / "features.parquet")
    rng = np.random.default_rng(0)
    feats["value"] = rng.normal(100.0, 10.0, len(feats))
    write_parquet(run / "features.parquet", feats)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ValueError, match="no feature's Gaussian-process metamodel fits"):
            analyse(run, base_samples=64)
    assert not (run / "sensitivity" / "key_parameters.json").exists()


def test_a_small_campaigns_metamodels_are_scored(tmp_path):
    """With 5-9 runs one point was held out and every R^2 was NaN (the CLI's `r2 < 0.8`
    warning never printed); now a 5-fold cross-validation scores them, and the smooth mean
    lateral force fits."""
    cfg = make_config(SHORT, 8, batch_size=8, seed=1, parameters=("X13", "X14"))
    run_campaign(cfg, tmp_path / "lhs8")
    idx, fits = sobol_metamodel(load_campaign(tmp_path / "lhs8"), ("mean",), base_samples=64)
    assert all(np.isfinite(f.r2_holdout) for f in fits)
    y_mean = next(f for f in fits if f.quantity == "Y")
    assert y_mean.r2_holdout > 0.9
    assert set(idx.r2_holdout) == {f.r2_holdout for f in fits}


def test_an_analysis_killed_while_writing_leaves_no_temporary_after_the_next(lhs_runs, tmp_path):
    """A kill while an output was written left ``.indices.csv.XXXXXXXX.tmp`` in
    ``sensitivity/`` for good; the next analysis removes it (other hidden files stay)."""
    run = tmp_path / "run"
    shutil.copytree(lhs_runs[0], run)
    (run / "sensitivity").mkdir(exist_ok=True)
    stale = run / "sensitivity" / ".indices.csv.k3j9x0qa.tmp"
    stale.write_text("parameter,")
    kept = run / "sensitivity" / ".notes"
    kept.write_text("mine")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analyse(run, statistics=("mean",), key_statistics=("mean",), base_samples=64)
    assert not stale.exists() and kept.exists()
    assert (run / "sensitivity" / "key_parameters.json").exists()


# ---------------------------------------------------------------- 3. --compare campaigns
def test_an_unfinished_comparison_campaign_is_refused(lhs_runs):
    """analyse(run, compare=PART) compared an unfinished campaign on the batches it had,
    silently."""
    full, part = lhs_runs
    with pytest.raises(CampaignError, match="the campaign is incomplete"):
        analyse(full, base_samples=64, compare=part)
    assert not (full / "sensitivity" / "agreement.csv").exists()


def test_a_comparison_campaign_of_other_force_laws_is_refused(lhs_runs, tmp_path):
    """The comparison campaign's force-law revision was not checked, the main one's was."""
    other = tmp_path / "other"
    shutil.copytree(lhs_runs[0], other)
    meta = json.loads((other / "campaign.json").read_text())
    meta["model_revision"] = "1999-01-01.0"
    (other / "campaign.json").write_text(json.dumps(meta))
    with pytest.raises(CampaignError, match="force-law revision 1999-01-01.0"):
        analyse(lhs_runs[0], base_samples=64, compare=other)


# --------------------------------------------------------------- 4. key statistics
def test_key_statistics_not_analysed_are_refused():
    """key_statistics p99 with statistics mean: p99 had no indices, the keys rested on the
    mean alone, and key_parameters.json's rule said mean/p99."""
    with pytest.raises(RailsuspInputError, match=r"^key_statistics p99: accepted only"):
        check_settings(("mean",), 0.05, ("mean", "p99"), 6, 0.005, 64, 0)
    check_settings(("mean", "p99"), 0.05, ("p99",), 6, 0.005, 64, 0)


# --------------------------------------------------------------- 5. a repeated index
def test_a_repeated_index_gives_each_parameters_own_largest_st():
    """Tables concatenated without ignore_index (index 0, 1, 0, 1): idxmax's labels read
    back with .loc took every row of a label, and X14's largest ST came out as the 0.9 of
    X13's row."""
    a = indices({"curve": 0.9, "straight": 0.9})
    tab = pd.concat([a[a.condition == "curve"], a[a.condition == "straight"]])
    tab.index = np.tile(np.arange(4), 2)
    sel = select_key_parameters(tab)
    assert sel.max_st == pytest.approx({"X13": 0.8, "X14": 0.03, "X15": 0.02, "X16": 0.9})
    assert sel.where["X14"] == "straight Y mean" and sel.where["X13"] == "curve Y mean"


# ------------------------------------------------------------ 6. the EN 14363 filter's text
def test_the_report_states_the_zero_phase_filters_response(tmp_path):
    """The report called the filter a "4th-order Butterworth"; run forwards and backwards
    its amplitude response is that filter's squared, half (-6 dB) at the 20 Hz cut-off."""
    from railsusp.en14363 import lowpass
    from railsusp.report_doc import Doc
    from railsusp.report_en14363 import EN14363_CSV, en14363_section

    fs, n = 500.0, 5000
    t = np.arange(n) / fs
    x = np.sin(2 * np.pi * 20.0 * t)
    gain = np.std(lowpass(x, fs)[1000:-1000]) / np.std(x[1000:-1000])
    assert gain == pytest.approx(0.5, abs=0.01)  # -6 dB at the cut-off, as the text says
    field = tmp_path / "field"
    field.mkdir()
    (field / "index.json").write_text("{}")
    pd.DataFrame({"section": ["s"], "wheel": ["w1L"], "force": ["Y"], "p99.85_kN": [1.0]}).to_csv(
        field / EN14363_CSV, index=False
    )
    doc = Doc(tmp_path)
    en14363_section(doc, tmp_path)
    text = "\n".join(doc.md)
    assert "-6 dB (half amplitude) at 20 Hz" in text and "1/(1 + (f/20 Hz)^8)" in text
    assert "8th-order roll-off" in text


def test_failed_runs_left_out_of_the_metamodels_are_said_and_recorded(lhs_runs, monkeypatch):
    """The metamodel route dropped failed (derailed) runs without a word: its Gaussian
    processes were fitted on the survivors and its indices taken over the whole ranges,
    where the wagon derails too, with a smaller n_train the only trace (stop 78's hunt).
    Now a warning per condition, and key_parameters.json's failed_runs."""
    import railsusp.sensitivity_metamodel as sm

    real = sm.analysed_features

    def two_failed(*args, **kwargs):
        for cond, q, st, y in real(*args, **kwargs):
            y = y.copy()
            y.iloc[[3, 7]] = np.nan
            yield cond, q, st, y

    monkeypatch.setattr(sm, "analysed_features", two_failed)
    with pytest.warns(UserWarning, match=r"condition 'short': 2 of 12 simulations failed"):
        summary = analyse(lhs_runs[0], base_samples=64)
    assert summary["failed_runs"] == {"short": 2}
    assert {f["n_failed"] for f in summary["metamodel_r2"]} == {2}
    stored = json.loads((lhs_runs[0] / "sensitivity" / "key_parameters.json").read_text())
    assert stored["failed_runs"] == {"short": 2}


def test_a_comparison_with_no_condition_in_common_is_refused(lhs_runs, tmp_path):
    """``sensitivity --compare`` with no condition of the same name wrote an empty
    agreement and exited 0; one of the same name defined otherwise (1 s against 2 s) was
    compared as the same features without a note (stop 78's hunt)."""
    other = make_config(
        [SHORT[0].with_changes(name="other")], 12, batch_size=4, seed=1, parameters=("X13", "X14")
    )
    run_campaign(other, tmp_path / "other")
    with pytest.raises(RailsuspInputError, match=r"compare .*other: no condition in common"):
        analyse(lhs_runs[0], base_samples=64, compare=tmp_path / "other")
    assert not (lhs_runs[0] / "sensitivity" / "agreement.csv").exists()
    longer = make_config(
        [SHORT[0].with_duration(2.0)], 12, batch_size=4, seed=1, parameters=("X13", "X14")
    )
    run_campaign(longer, tmp_path / "longer")
    with pytest.warns(UserWarning, match=r"condition 'short' is defined otherwise there \("):
        summary = analyse(lhs_runs[0], base_samples=64, compare=tmp_path / "longer")
    assert summary["agreement"]


def test_total_indices_above_one_are_said_as_the_estimators_noise(lhs_runs, monkeypatch):
    """A 16-run campaign's metamodels at N = 64 gave ST 1.087, and --threshold 0.99 kept it
    as a key without a word (stop 78's hunt). A share of the variance cannot exceed 1: the
    analysis says the estimate is that noisy and what narrows it."""
    import railsusp.sensitivity as sens

    real = sens.sobol_metamodel

    def noisy(*args, **kwargs):
        idx, fits = real(*args, **kwargs)
        idx = idx.copy()
        idx.loc[idx.index[0], "ST"] = 1.087
        return idx, fits

    monkeypatch.setattr(sens, "sobol_metamodel", noisy)
    with pytest.warns(UserWarning, match=r"1 total Sobol index\(es\) above 1, up to 1\.087 \("):
        analyse(lhs_runs[0], base_samples=64)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # none at the real indices
        monkeypatch.setattr(sens, "sobol_metamodel", real)
        idx = sens.sobol_metamodel(load_campaign(lhs_runs[0]), base_samples=64)[0]
        sens._warn_beyond_one(idx.assign(ST=idx.ST.clip(upper=1.0)), 64)
