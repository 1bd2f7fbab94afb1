"""A pipeline on another wagon's data simulates that wagon in every stage (the user-journey
audit of stop 59: the synthetic recordings, the validation's and the refinement's
simulations took the packaged C80 whatever ``wagon =`` said, and recordings of a tare
wagon were refused for their wheel loads)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

import railsusp
from railsusp.vehicle.setup import static_wheel_load
from railsusp.vehicle.wagon import load_wagon

TINY = Path(__file__).resolve().parents[1] / "examples" / "tiny.toml"
#: a 1 s straight condition on a 20 m lead-in, as a condition file
SHORT = (
    '[[condition]]\nbase = "straight"\nname = "short"\nduration_s = 1.0\nn_steps = 50\n'
    "lead_in_m = 20.0\n"
)


def tare_field(runner, tmp_path: Path, *options: str) -> Path:
    """``synth-field --wagon tare`` of the :data:`SHORT` condition into tmp_path/field."""
    from railsusp.cli import app

    cond, field = tmp_path / "short.toml", tmp_path / "field"
    cond.write_text(SHORT)
    done = runner.invoke(app, ["synth-field", "--out", str(field), "--conditions", str(cond),
                               "--wagon", "tare", *options])  # fmt: skip
    assert done.exit_code == 0, done.output
    return field


def short_wagon_field(folder: Path):
    """A wagon 3.2 m shorter between bogie centres than the C80 (its data as a document and
    as WagonData), and its synthetic recording of a 1 s straight on a 13 m lead-in with its
    track geometry, in ``folder``: a lead-in its axles cover and the C80's do not."""
    from railsusp.conditions import get_condition
    from railsusp.measured import synthesise_field
    from railsusp.params import ParameterSet
    from railsusp.vehicle.wagon import WagonData

    doc = load_wagon().model_dump(mode="json")
    doc["car_body"]["bogie_half_spacing"] -= 1.6
    short = WagonData.model_validate(doc)
    cond = get_condition("straight", duration_s=1.0, n_steps=50).with_changes(lead_in_m=13.0)
    synthesise_field(ParameterSet.nominal(), [cond], folder, with_track=True, wagon=short)
    return doc, short


def test_every_stage_simulates_the_configurations_wagon(tmp_path):
    tare = load_wagon("tare")
    config = tmp_path / "tare.toml"
    config.write_text('wagon = "tare"\n' + TINY.read_text())
    result = railsusp.run(config, out=tmp_path / "run")
    q = static_wheel_load(tare) / 1e3  # 24.5 kN
    field = pd.read_csv(tmp_path / "run" / "field" / "short.csv")
    assert field.filter(like="Q_").mean().iloc[0] == pytest.approx(q, rel=0.05)
    meta = json.loads((tmp_path / "run" / "field" / "short.json").read_text())
    assert meta["wagon"] == tare.name
    val = result.validation
    before = val[(val.force == "Q") & (val.statistic == "mean")].iloc[0]
    assert before.measured_kN == pytest.approx(q, rel=0.05)
    assert before.before_kN == pytest.approx(q, rel=0.05)  # the tare wagon, not 122 kN


def test_the_commands_take_the_wagon_and_validate_follows_the_estimates(tmp_path):
    """synth-field, estimate and validate simulated the packaged C80 whatever the wagon:
    they take --wagon now, and validate takes the estimate's by default."""
    from typer.testing import CliRunner

    from railsusp.cli import app

    runner = CliRunner()
    field, est = tare_field(runner, tmp_path, "--truth", "X13=16.1"), tmp_path / "est"
    q = static_wheel_load(load_wagon("tare")) / 1e3
    assert pd.read_csv(field / "short.csv").filter(like="Q_").mean().iloc[0] == pytest.approx(
        q, rel=0.05
    )
    done = runner.invoke(app, ["estimate", "--measured", str(field), "--out", str(est),
                               "--simulator", "--parameters", "X13", "--pop-size", "4",
                               "--n-gen", "1", "--wagon", "tare"])  # fmt: skip
    assert done.exit_code == 0, done.output
    assert json.loads((est / "estimate.json").read_text())["wagon"] == "tare"
    done = runner.invoke(app, ["validate", str(est)])
    assert done.exit_code == 0, done.output
    val = pd.read_csv(est / "validation" / "validation.csv")
    row = val[(val.force == "Q") & (val.statistic == "mean")].iloc[0]
    assert row.before_kN == pytest.approx(q, rel=0.05)


def test_simulate_shows_the_studys_figures_only_beside_the_studys_wagon():
    """`simulate --wagon tare` printed the study's loaded-C80 Y and Q as the reference."""
    from railsusp.cli.simulation import _force_table
    from railsusp.conditions import get_condition
    from railsusp.vehicle.simulate import simulate

    res = simulate(None, get_condition("straight", duration_s=1.0, n_steps=50))

    def study_column(study: bool) -> list:
        table = _force_table([res], "t", study=study)
        return list(next(c for c in table.columns if c.header == "study Y")._cells)

    assert study_column(True) != ["-"] and study_column(False) == ["-"]


def test_estimate_takes_the_surrogates_wagon_and_refuses_another(tmp_path, monkeypatch):
    """`estimate --surrogate` simulated (corrections, refinement) and checked the wheel
    loads with the packaged C80 whatever wagon the networks were trained on; it now takes
    theirs, and refuses a --wagon of another."""
    from types import SimpleNamespace

    from typer.testing import CliRunner

    import railsusp.estimate as estimate_package
    from railsusp.cli import app

    tare = load_wagon("tare")
    fake = SimpleNamespace(wagon=tare, parameters=("X13",))
    monkeypatch.setattr(estimate_package, "open_force_model", lambda folder, p: (fake, ("X13",)))
    (tmp_path / "sur").mkdir()
    result = CliRunner().invoke(app, ["estimate", "--measured", str(tmp_path / "none"),
                                      "--out", str(tmp_path / "est"), "--surrogate",
                                      str(tmp_path / "sur"), "--wagon", "loaded"])  # fmt: skip
    assert result.exit_code == 2
    assert "trained on another wagon (C80 / K6 tare)" in result.output


def test_align_track_takes_the_wagon(tmp_path):
    """align-track read a tare wagon's recordings against the loaded C80's wheel load and
    simulated the C80; it takes --wagon, and the refusal says so."""
    from typer.testing import CliRunner

    from railsusp.cli import app

    runner = CliRunner()
    cond = tmp_path / "short.toml"
    cond.write_text(
        '[[condition]]\nbase = "straight"\nname = "short"\nduration_s = 4.0\nn_steps = 200\n'
    )
    field = tmp_path / "field"
    done = runner.invoke(app, ["synth-field", "--out", str(field), "--conditions", str(cond),
                               "--with-track", "--wagon", "tare"])  # fmt: skip
    assert done.exit_code == 0, done.output
    refused = runner.invoke(app, ["align-track", str(field)])
    assert refused.exit_code == 2 and "another wagon? give its data (--wagon" in refused.output
    done = runner.invoke(app, ["align-track", str(field), "--wagon", "tare"])
    assert done.exit_code == 0, done.output


def test_the_standalone_campaign_simulates_the_wagon_on_its_recordings_track(tmp_path):
    """``railsusp campaign`` simulated the packaged C80 and read a field folder's recordings
    against its wheel load, so a tare wagon's recordings were refused (stop 59's "Left")."""
    from typer.testing import CliRunner

    from railsusp.campaign import load_campaign
    from railsusp.cli import app

    runner = CliRunner()
    field, run = tare_field(runner, tmp_path, "--with-track"), tmp_path / "run"
    args = ["campaign", "--out", str(run), "--samples", "2", "--conditions", str(field),
            "--parameters", "X14", "--batch-size", "2"]  # fmt: skip
    refused = runner.invoke(app, [*args, "--wagon", "nowhere.toml"])
    assert refused.exit_code == 2 and "nowhere.toml" in refused.output
    done = runner.invoke(app, [*args, "--wagon", "tare"])
    assert done.exit_code == 0, done.output
    camp = load_campaign(run)
    assert camp.config.wagon == load_wagon("tare")
    q = static_wheel_load(load_wagon("tare")) / 1e3
    f = camp.features()
    mean_q = f[(f.quantity == "Q") & (f.statistic == "mean")].value.to_numpy()  # kN
    assert mean_q.size == 2 and mean_q == pytest.approx(q, rel=0.05)


def test_a_recordings_measured_track_is_checked_against_its_own_wagons_axle_spread(tmp_path):
    """The reader checked a measured track's lead-in against the packaged C80's axle spread
    (10.03 m + 5 m) whatever the wagon: a shorter wagon's recording with a 13 m lead-in was
    refused, although its simulation accepts it (stop 59's "Left")."""
    from railsusp.errors import RailsuspInputError
    from railsusp.measured import read_field
    from railsusp.vehicle.setup import axle_spread

    field = tmp_path / "field"
    _, short = short_wagon_field(field)
    assert axle_spread(short) + 5.0 < 13.0 < axle_spread(load_wagon()) + 5.0
    with pytest.raises(RailsuspInputError, match=r"lead_in_m = 13 m .* accepted at least 15.03"):
        read_field(field)  # read as the packaged C80's
    (rec,) = read_field(field, wagon=short)
    assert rec.condition.lead_in_m == 13.0 and rec.condition.track_geometry is not None


def test_the_report_reads_the_field_as_the_runs_wagon(tmp_path):
    """The report (summary.field_recordings) read a run's field against the packaged C80's
    axle spread: a shorter wagon's recordings on a 13 m lead-in passed every stage and
    failed the report (the review of stop 60). pipeline.json now records the wagon."""
    from railsusp import summary
    from railsusp.store import write_json

    run = tmp_path / "run"
    doc, short = short_wagon_field(run / "field")
    write_json(run / "pipeline.json", {"static_wheel_load_N": static_wheel_load(short)})
    with pytest.raises(Exception, match="accepted at least 15.03"):  # as before: the C80's
        summary.field_recordings(run)
    write_json(
        run / "pipeline.json",
        {"static_wheel_load_N": static_wheel_load(short), "wagon_data": doc},
    )
    (rec,) = summary.field_recordings(run)
    assert rec.condition.lead_in_m == 13.0
