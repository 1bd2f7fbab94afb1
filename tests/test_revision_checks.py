"""Artefacts of older force laws opened by this railsusp (the upgrade audit, H2 and M3).

H2: ``estimate --surrogate`` opened, without a word, surrogates that record no force-law
revision (trained before revisions were recorded, so on older force laws), while it refused
one that records an older revision and the posterior refused the same case. M3: ``train``,
``sensitivity`` and a resumed ``campaign`` on a campaign of revision 2026-11-30.1 said "its
configuration is not the one its batches were simulated with ... edited by hand?": that
revision's wagon data lacked fields added (with defaults) in 2026-11-30.2, so the stored
configuration's hash changed, and that check ran before the revision's. A campaign that
records no revision was only warned of.

The old artefacts are made cheaply: a small fresh campaign (or a random-weight bundle) with
its record edited as the older railsusp wrote it (its revision, and for 2026-11-30.1 its
wagon data without the later fields and the hash of that configuration, on campaign.json
and on every batch file)."""

import json
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy.stats import qmc
from typer.testing import CliRunner

from railsusp.campaign import (
    CampaignError,
    load_campaign,
    make_config,
    require_complete,
    run_campaign,
)
from railsusp.campaign.batch_files import REVISION_KEY, STAMP_KEY
from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import SurrogateForces
from railsusp.estimate.statistics_forces import StatisticsForces
from railsusp.params import bounds
from railsusp.store import content_hash
from railsusp.surrogate.baselines import StatisticsGP
from railsusp.surrogate.data import SeriesData
from railsusp.surrogate.features import FeatureSpec
from railsusp.surrogate.statistics import StatisticsSurrogate
from railsusp.vehicle import MODEL_REVISION
from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_11_30_2
from test_estimate_aligned import tiny_surrogate

runner = CliRunner()
OLD = "2026-11-30.1"  # the revision before this one (the audit's r100 and camp_old100)
SHORT = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)


def one_line_error(args: list) -> str:
    """The CLI run in-process: exit status 2 and one ``error:`` line, returned."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    errors = [line for line in result.output.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "Traceback" not in result.output, result.output
    return errors[0].removeprefix("error: ")


# ------------------------------------------------------------------ H2: surrogate bundles
def _stamp_bundle(path, revision):
    """The bundle description ``path`` as recording ``revision`` (None: none, as a bundle
    trained before revisions were recorded)."""
    doc = json.loads(path.read_text())
    doc["meta"].pop("model_revision", None)
    if revision is not None:
        doc["meta"]["model_revision"] = revision
    path.write_text(json.dumps(doc))


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    """One second of synthetic recordings of 'straight' (the estimate's --measured)."""
    root = tmp_path_factory.mktemp("field")
    cond = root / "c.toml"
    cond.write_text(
        '[[condition]]\nname = "straight"\nduration_s = 1.0\nn_steps = 50\nlead_in_m = 20.0\n'
    )
    result = runner.invoke(
        app, ["synth-field", "--truth", "X13=16.1", "--conditions", str(cond), "--out",
              str(root / "f")],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    return root / "f"


def test_estimate_refuses_a_window_surrogate_that_records_no_force_law_revision(tmp_path, field):
    """The audit's r24 bundle (revision 2026-11-24.2, none recorded) was used by `estimate`
    at exit 0, one of 2026-11-30.1 refused: both are refused now, naming the bundle and what
    to do; one of this revision opens."""
    folder = tiny_surrogate(tmp_path / "s")
    described = folder / "straight" / "surrogate.json"
    _stamp_bundle(described, MODEL_REVISION)
    assert SurrogateForces(folder).conditions == ["straight"]
    _stamp_bundle(described, None)
    with pytest.raises(RailsuspInputError) as err:
        SurrogateForces(folder)
    text = str(err.value)
    assert text.startswith(
        f"{folder / 'straight'}: trained on a campaign simulated with force laws older than "
        "any recorded force-law revision (it records none"
    )
    assert f"this railsusp's is {MODEL_REVISION}" in text and "\n" not in text
    assert "`railsusp train`" in text and "`railsusp run`" in text
    out = tmp_path / "e"
    line = one_line_error(["estimate", "--measured", field, "--surrogate", folder, "--out", out])
    assert line == text and not out.exists()
    _stamp_bundle(described, OLD)  # a recorded older revision: as before, same remedy
    line = one_line_error(["estimate", "--measured", field, "--surrogate", folder, "--out", out])
    assert f"force-law revision {OLD}, older than this railsusp's {MODEL_REVISION}" in line
    assert "`railsusp train`" in line


def test_estimate_refuses_statistics_surrogates_that_record_no_force_law_revision(tmp_path):
    """The statistics GPs (gp-stats) of a campaign before revisions were recorded: the same
    refusal (the audit's r24 gp-stats bundle)."""
    cond = get_condition("straight", duration_s=2.0, n_steps=100)
    params = ("X13", "X14")
    lo, hi = bounds(params)
    unit = qmc.LatinHypercube(d=2, seed=3).random(12)
    x = lo + unit * (hi - lo)
    t = np.linspace(0.0, 1.0, 100)[None, :]
    lateral = x[:, :1] / 1e6 + np.sin(6.0 * t)  # kN: any smooth function of the parameters
    vertical = 100.0 + x[:, 1:] / 1e6 + 0.0 * t
    targets = np.stack([lateral, vertical], axis=-1).astype(np.float32)  # (12, 100, 2)
    data = SeriesData(np.arange(12), unit, np.zeros((1, 100, 15)), targets, cond, np.zeros(12))
    gp = StatisticsGP(FeatureSpec(parameters=params), statistics=("mean",)).fit(data)
    StatisticsSurrogate(gp, cond, {"model_revision": MODEL_REVISION}).save(
        tmp_path / "gp" / "straight"
    )
    assert StatisticsForces(tmp_path / "gp").parameters == params
    StatisticsSurrogate(gp, cond, {"n_train": 12}).save(tmp_path / "old" / "straight")
    with pytest.raises(RailsuspInputError, match=r"straight: .*\(it records none"):
        StatisticsForces(tmp_path / "old")


# ----------------------------------------------------------------------- M3: campaigns
@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A small finished campaign of this railsusp, and its configuration."""
    out = tmp_path_factory.mktemp("campaign") / "c"
    cfg = make_config([SHORT], 4, batch_size=2, seed=3, parameters=("X13", "X14"))
    run_campaign(cfg, out)
    return cfg, out


def _edit_meta(run, change) -> dict:
    """Apply ``change`` to ``run``'s campaign.json and return the new record."""
    path = run / "campaign.json"
    meta = json.loads(path.read_text())
    change(meta)
    path.write_text(json.dumps(meta))
    return meta


def _as_older_railsusp(run, revision):
    """``run`` as a railsusp of force-law revision ``revision`` (None: one that recorded
    none) wrote it: the wagon data without the fields that 2026-11-30.2 and 2026-12-02.1
    added (with defaults; FORCE_LAWS_BEFORE_2026_11_30_2 holds both), the hash of that
    configuration on campaign.json and every batch file, and the revision (if any) on both."""

    def change(meta):
        for dotted in FORCE_LAWS_BEFORE_2026_11_30_2:
            group, name = dotted.split(".")
            del meta["config"]["wagon"][group][name]
        meta["config_hash"] = content_hash(meta["config"])
        meta.pop("model_revision", None)
        if revision is not None:
            meta["model_revision"] = revision

    meta = _edit_meta(run, change)
    for path in (run / "batches").rglob("batch-*.parquet"):
        table = pq.read_table(path)
        stamps = dict(table.schema.metadata or {})
        stamps[STAMP_KEY.encode()] = meta["config_hash"].encode()
        stamps.pop(REVISION_KEY.encode(), None)
        if revision is not None:
            stamps[REVISION_KEY.encode()] = revision.encode()
        pq.write_table(table.replace_schema_metadata(stamps), path)


def _copy(campaign, tmp_path, name="old"):
    copy = tmp_path / name
    shutil.copytree(campaign[1], copy)
    return copy


def test_train_and_sensitivity_name_an_older_campaigns_revision(campaign, tmp_path):
    """The audit's r100 campaign (2026-11-30.1): "edited by hand?" before; now both
    revisions and the remedy, exit 2, and nothing written."""
    old = _copy(campaign, tmp_path)
    _as_older_railsusp(old, OLD)
    said = (
        f"{old / 'campaign.json'} was simulated with force-law revision {OLD}, older than this "
        f"railsusp's {MODEL_REVISION}: run the campaign again into a new --out (or with --force)"
    )
    for args in (["train", old, "--model", "gp-stats"], ["sensitivity", old]):
        line = one_line_error(args)
        assert line.startswith(said) and "edited by hand" not in line, line
    assert not (old / "surrogates").exists() and not (old / "sensitivity").exists()
    with pytest.raises(CampaignError, match="force-law revision 2026-11-30.1, older than"):
        require_complete(load_campaign(old))


def test_resuming_an_older_campaign_names_its_revision_and_keeps_its_batches(campaign, tmp_path):
    """``railsusp campaign`` resumed into the audit's camp_old100: its revision named, its
    batches left alone; ``--force`` starts it again with this revision."""
    cfg, _ = campaign
    old = _copy(campaign, tmp_path)
    _as_older_railsusp(old, OLD)
    batches = sorted(p.name for p in (old / "batches").rglob("*.parquet"))
    with pytest.raises(CampaignError) as err:
        run_campaign(cfg, old)
    text = str(err.value)
    assert f"force-law revision {OLD}, older than this railsusp's {MODEL_REVISION}" in text
    assert "edited by hand" not in text and "\n" not in text
    assert sorted(p.name for p in (old / "batches").rglob("*.parquet")) == batches
    run_campaign(cfg, old, force=True, max_batches=0)
    assert json.loads((old / "campaign.json").read_text())["model_revision"] == MODEL_REVISION


def test_a_campaign_that_records_no_revision_is_refused(campaign, tmp_path):
    """A campaign made before revisions were recorded (the audit's r24): refused, saying
    that none is recorded, whether its configuration's hash changed since (as every real
    one's did) or not (it was warned of, and trained on: the surrogates would record none,
    which the estimate refuses)."""
    old = _copy(campaign, tmp_path)
    _as_older_railsusp(old, None)
    line = one_line_error(["sensitivity", old])
    assert line.startswith(
        f"{old / 'campaign.json'} was simulated with force laws older than any recorded "
        "force-law revision (it records none"
    )
    assert f"this railsusp's is {MODEL_REVISION}" in line
    assert "run the campaign again into a new --out" in line
    unrecorded = _copy(campaign, tmp_path, "unrecorded")
    _edit_meta(unrecorded, lambda meta: meta.pop("model_revision"))
    with pytest.raises(
        CampaignError, match=r"it records none: made before revisions were recorded"
    ):
        require_complete(load_campaign(unrecorded))


def test_the_revision_is_checked_before_completeness(campaign, tmp_path):
    """An unfinished campaign of older force laws was told to be finished, which the
    resumed campaign then refuses: its revision is said first."""
    cfg, _ = campaign
    part = tmp_path / "part"
    run_campaign(cfg, part, max_batches=1)
    _edit_meta(part, lambda meta: meta.update(model_revision=OLD))
    with pytest.raises(CampaignError, match=f"force-law revision {OLD}, older than"):
        require_complete(load_campaign(part))


def test_newer_and_hand_edited_campaigns_are_told_apart(campaign, tmp_path):
    """A changed hash is said as force laws only where the revision differs: a newer
    railsusp's campaign is not to be simulated again as outdated; one of this revision
    whose configuration was edited is still said to be so."""
    newer = _copy(campaign, tmp_path, "newer")
    _as_older_railsusp(newer, "2099-01-01.1")  # a configuration whose hash differs from ours
    with pytest.raises(CampaignError) as err:
        load_campaign(newer)
    assert f"2099-01-01.1, newer than this railsusp's {MODEL_REVISION}" in str(err.value)
    assert "run the campaign again" not in str(err.value)
    edited = _copy(campaign, tmp_path, "edited")
    _edit_meta(edited, lambda meta: meta["config"].update(seed=4))
    with pytest.raises(CampaignError, match="edited by hand"):
        load_campaign(edited)


def test_a_newer_railsusps_campaign_is_not_discarded_even_with_force(campaign, tmp_path):
    """``railsusp campaign --force`` into a newer railsusp's campaign discarded its batches
    (the pipeline refused the same folder since stop 65): refused with or without
    ``--force``, its batches left as they were, and the remedy is that railsusp."""
    cfg, _ = campaign
    newer = _copy(campaign, tmp_path, "newer")
    _edit_meta(newer, lambda meta: meta.update(model_revision="2099-01-01.1"))
    batches = sorted(p.name for p in (newer / "batches").rglob("*.parquet"))
    for force in (False, True):
        with pytest.raises(CampaignError) as err:
            run_campaign(cfg, newer, force=force, max_batches=0)
        text = str(err.value)
        assert f"2099-01-01.1, newer than this railsusp's {MODEL_REVISION}: use it with" in text
        assert "--force to discard" not in text and "\n" not in text
    assert sorted(p.name for p in (newer / "batches").rglob("*.parquet")) == batches
    assert json.loads((newer / "campaign.json").read_text())["model_revision"] == "2099-01-01.1"
