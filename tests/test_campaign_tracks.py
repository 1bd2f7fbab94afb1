"""Many-track campaigns: track family and varied non-key parameters (railsusp.variation),
their validation, and that every sample runs on, and is stored with, its own track."""

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.campaign import CampaignError, load_campaign, make_config, make_design, run_campaign
from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.params import spec
from railsusp.surrogate.data import load_series
from railsusp.surrogate.features import FeatureSpec
from railsusp.variation import (
    assumed_parameters,
    full_ranges,
    parse_priors,
    parse_range,
    sample_condition,
)
from railsusp.vehicle.simulate import simulate_batch

KEYS = ("X13", "X14", "X15")
CURVE = get_condition("curve", duration_s=2.0, n_steps=100)  # in the arc (spiral ends at 80 m)
STRAIGHT = get_condition("straight", duration_s=2.0, n_steps=100, lead_in_m=30.0)
FAMILY = {"irregularity_classes": (4, 6), "curve_radius_m": (250.0, 400.0), "cant_mm": (0, 100)}
X19 = (20e6, 40e6)  # a prior narrower than Table 2's 15-45 MN/m


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        (
            {"independent_seeds": True, "track_family": {"curve_radius_m": (10, 400)}},
            r"track_family: curve_radius_m = 10-400 m: accepted a range lo <= hi within "
            r"\[50, 100000\] m",
        ),
        (
            {"independent_seeds": True, "track_family": {"cant_mm": (80, 20)}},
            r"cant_mm = 80-20 mm: accepted a range lo <= hi within \[0, 200\] mm",
        ),
        (
            {"independent_seeds": True, "track_family": {"irregularity_classes": (0, 5)}},
            r"irregularity_classes = 0-5: accepted a range lo <= hi within \[1, 6\]",
        ),
        (
            {"track_family": {"irregularity_classes": (4, 6)}},
            "track_family needs independent_seeds",
        ),
        (
            {"independent_seeds": True, "track_family": {"speed": (1, 2)}},
            "track_family.speed: Extra inputs are not permitted",
        ),
        (
            {"other_parameters": {"X19": (1e6, 40e6)}},
            r"other_parameters: X19 range 1000-40000 kN/m: accepted lo <= hi within "
            r"\[15000, 45000\] kN/m",
        ),
        ({"other_parameters": {"X13": X19}}, "X13 is sampled as a key parameter already"),
        ({"other_parameters": {"X3": (1, 2)}}, "X3 is a fixed parameter"),
    ],
)
def test_bad_variation_is_one_line_naming_field_and_range(kw, message):
    with pytest.raises(CampaignError, match=message) as exc:
        make_config([CURVE], 4, parameters=KEYS, **kw)
    assert "\n" not in str(exc.value)


def test_radius_family_needs_a_curve_condition():
    with pytest.raises(CampaignError, match="need a curve condition"):
        make_config(
            [STRAIGHT],
            4,
            independent_seeds=True,
            track_family={"curve_radius_m": (250, 400)},
        )


def test_unset_variation_keeps_old_configuration_hashes():
    """Campaigns made before track families existed keep their hash (their run
    directories still resume): the new fields are left out of the dump when unset."""
    cfg = make_config([CURVE], 4, parameters=KEYS)
    dump = cfg.model_dump(mode="json")
    assert "track_family" not in dump and "other_parameters" not in dump
    fam = make_config([CURVE], 4, parameters=KEYS, independent_seeds=True, track_family=FAMILY)
    assert fam.hash() != make_config([CURVE], 4, parameters=KEYS, independent_seeds=True).hash()


def test_other_parameters_are_their_own_hypercube_and_leave_keys_unchanged():
    base = make_design(make_config([CURVE], 40, parameters=KEYS, seed=2))
    cfg = make_config([CURVE], 40, parameters=KEYS, seed=2, other_parameters={"X19": X19})
    d = make_design(cfg)
    np.testing.assert_array_equal(d[list(KEYS)].to_numpy(), base[list(KEYS)].to_numpy())
    u = (d["X19"].to_numpy() - X19[0]) / (X19[1] - X19[0])
    assert sorted(np.floor(u * 40).astype(int)) == list(range(40))  # stratified in the prior


@pytest.fixture(scope="module")
def family_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("family") / "run"
    cfg = make_config(
        [CURVE, STRAIGHT],
        6,
        parameters=KEYS,
        seed=7,
        batch_size=3,
        independent_seeds=True,
        track_family=FAMILY,
        other_parameters={"X19": X19},
    )
    run_campaign(cfg, out)
    return out


def test_family_samples_are_drawn_within_their_ranges(family_run):
    camp = load_campaign(family_run)
    t = camp.tracks("curve")
    assert t.seed.nunique() == 6
    assert t.irregularity_class.between(4, 6).all()
    assert t.curve_radius_m.between(250, 400).all() and t.curve_radius_m.nunique() == 6
    assert t.cant_mm.between(0, 100).all()
    s = camp.tracks("straight")  # tangent: only the class and seed vary
    assert s.curve_radius_m.isna().all() and (s.cant_mm == 0).all()
    assert not set(s.seed) & set(t.seed)
    stored = __import__("pandas").read_parquet(family_run / "tracks.parquet")
    assert len(stored) == 12 and set(stored.condition) == {"curve", "straight"}


def test_each_sample_is_simulated_on_its_own_track(family_run):
    """A sample of a batched, grouped call equals the same sample simulated alone on its
    own condition (class, radius, cant) and seed, with its varied X19."""
    camp = load_campaign(family_run)
    design = camp.design()
    ids, series = camp.series("curve")
    row = camp.tracks("curve").iloc[4]
    x = design.loc[design.sample_id == 4, [*KEYS, "X19"]].to_numpy()
    r = simulate_batch(
        x,
        sample_condition(CURVE, row),
        symbols=(*KEYS, "X19"),
        seeds=[int(row.seed)],
        wagon=camp.config.wagon,
        settings=camp.config.settings(),
    )
    w = list(ids).index(4)
    np.testing.assert_allclose(series[w, :8], r.Y[0], rtol=1e-5, atol=1.0)
    y_mean = camp.feature_matrix("curve", "Y", "mean")
    assert y_mean.loc[4] == pytest.approx(r.statistics("auto", set_index=None)["Y_mean"][0])


def test_a_batch_of_curve_layouts_is_one_parallel_call(family_run, integrator_calls):
    """Every sample of a curve batch has its own radius and cant (a layout each): the batch
    is one integrator call of 3 sets (one call per layout would run them one at a time, on
    one core), and its series are the stored ones."""
    from railsusp.campaign.batch_simulation import simulate_task
    from railsusp.campaign.design import track_seeds

    camp = load_campaign(family_run)
    cfg = camp.config
    design = camp.design()
    x = design[list(cfg.simulated_parameters)].to_numpy()[:3]
    ids = design.sample_id.to_numpy()[:3]
    res = simulate_task(cfg.model_dump_json(), 0, ids, x, track_seeds(cfg, CURVE)[:3])
    assert integrator_calls == [3]
    stored_ids, stored = camp.series("curve")
    rows = [list(stored_ids).index(i) for i in ids]
    np.testing.assert_array_equal(res["series"], stored[rows])


def test_window_inputs_carry_each_samples_track(family_run):
    """Different seeds give different irregularity inputs; the curvature channel at the
    leading axle is 1000 / R of the sample's own radius in the arc (1/km), and the cant
    channel its own cant (mm; its sign is that of the roll angle)."""
    camp = load_campaign(family_run)
    spec_ = FeatureSpec(parameters=KEYS, track_channels=("zL", "yL", "curvature", "cant"))
    data = load_series(camp, "curve", spec_)
    assert data.track.shape == (6, 100, 12)
    zl = data.track[:, :, 0]
    for i in range(6):
        for j in range(i + 1, 6):
            assert not np.allclose(zl[i], zl[j])
    t = camp.tracks("curve").set_index("sample_id").loc[data.sample_ids]
    np.testing.assert_allclose(data.track[:, -1, 2], 1e3 / t.curve_radius_m, rtol=1e-3)
    np.testing.assert_allclose(np.abs(data.track[:, -1, 3]), t.cant_mm, rtol=2e-3, atol=1e-3)
    assert data.other_names == ("X19",) and data.others.shape == (6, 1)
    assert ((data.others >= X19[0]) & (data.others <= X19[1])).all()


def test_assumed_parameters_list_varied_and_nominal():
    rows = {r["symbol"]: r for r in assumed_parameters(KEYS, {"X19": X19})}
    assert set(rows) == {"X11", "X12", "X16", "X17", "X18", "X19", "X20"}
    assert rows["X19"]["assumed"] == "varied" and rows["X19"]["low"] == pytest.approx(20000)
    assert (
        rows["X20"]["assumed"] == "nominal" and rows["X20"]["value"] == spec("X20").nominal_display
    )


def test_range_and_prior_parsing():
    assert parse_range("250:400", "--radius") == (250.0, 400.0)
    with pytest.raises(RailsuspInputError, match="--radius '250-400': accepted LO:HI"):
        parse_range("250-400", "--radius")
    with pytest.raises(RailsuspInputError, match="LO <= HI"):
        parse_range("400:250", "--radius")
    assert parse_priors("X19=20000:40000") == {"X19": pytest.approx((20e6, 40e6))}
    with pytest.raises(RailsuspInputError, match="SYMBOL=LO:HI"):
        parse_priors("X19")
    with pytest.raises(RailsuspInputError, match="X19 is given twice"):  # the last won
        parse_priors("X19=20000:40000,cross_brace_node_stiffness=20000:30000")
    others = full_ranges(KEYS, {"X19": X19})
    assert set(others) == {"X11", "X12", "X16", "X17", "X18", "X19", "X20"}
    assert others["X19"] == X19 and others["X20"] == spec("X20").bounds


def test_cli_campaign_options(tmp_path):
    runner = CliRunner()
    res = runner.invoke(
        app,
        ["campaign", "--out", str(tmp_path / "r"), "--conditions", "curve", "--radius", "10:400"],
    )
    assert res.exit_code == 2
    assert "curve_radius_m = 10-400 m" in res.output and "[50, 100000] m" in res.output
    res = runner.invoke(
        app,
        ["campaign", "--out", str(tmp_path / "r"), "--parameters", "X13", "--prior", "X13=10:20"],
    )
    assert res.exit_code == 2 and "sampled already" in res.output
    res = runner.invoke(
        app,
        [
            "campaign",
            "--out",
            str(tmp_path / "ok"),
            "--conditions",
            "curve",
            "--samples",
            "2",
            "--duration",
            "1",
            "--parameters",
            "X13",
            "--radius",
            "250:400",
            "--prior",
            "X19=20000:40000",
            "--vary-others",
            "--max-batches",
            "0",
        ],
    )
    assert res.exit_code == 0, res.output
    cfg = load_campaign(tmp_path / "ok").config
    assert cfg.independent_seeds and cfg.track_family.curve_radius_m == (250, 400)
    assert cfg.other_parameters["X19"] == pytest.approx(X19)
    assert len(cfg.other_parameters) == 9  # every other main-suspension parameter
