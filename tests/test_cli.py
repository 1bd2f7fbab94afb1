"""Command line: the catalogue, conditions and track commands, and one-line input errors."""

import json
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from railsusp.cli import app

runner = CliRunner()


def test_params_prints_catalogue_with_override():
    result = runner.invoke(app, ["params", "--set", "X13=16.1"])
    assert result.exit_code == 0, result.output
    assert "X20" in result.output and "16.1" in result.output
    assert "primary longitudinal" in result.output


def test_conditions_prints_the_three():
    result = runner.invoke(app, ["conditions"])
    assert result.exit_code == 0, result.output
    for name in ("straight", "curve", "uphill"):
        assert name in result.output
    assert "300" in result.output and "+12" in result.output


def test_track_writes_plot(tmp_path):
    out = tmp_path / "t.png"
    result = runner.invoke(app, ["track", "--class", "5", "--length", "800", "--plot", str(out)])
    assert result.exit_code == 0, result.output
    assert out.stat().st_size > 10_000
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["params", "--set", "X99=1"], "unknown parameter 'X99'"),
        (["params", "--set", "X13=30"], "outside the accepted range [7, 21] MN/m"),
        (["conditions", "bogus"], "unknown condition 'bogus'"),
        (["track", "--class", "9"], "--class 9: accepted range [1, 6]"),
        (["track", "--length", "-1"], "--length"),
    ],
)
def test_bad_input_is_one_line_with_status_2(args, needle):
    # a real process, so that stderr, exit status and the absence of a traceback are checked
    proc = subprocess.run(
        [sys.executable, "-m", "railsusp.cli", *args], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2, proc.stderr
    assert needle in proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_python_dash_m_railsusp_runs_the_command():
    """``python -m railsusp`` is the ``railsusp`` command (it failed: no __main__ module)."""
    proc = subprocess.run(
        [sys.executable, "-m", "railsusp", "params", "--set", "X99=1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2, proc.stderr
    assert "unknown parameter 'X99'" in proc.stderr
    ok = subprocess.run(
        [sys.executable, "-m", "railsusp", "--help"], capture_output=True, text=True, timeout=60
    )
    assert ok.returncode == 0, ok.stderr
    assert "demo" in ok.stdout


def test_demo_is_registered_with_the_embedded_default():
    result = runner.invoke(app, ["demo", "--help"])
    assert result.exit_code == 0 and "examples/quick.toml" in result.output


def test_simulate_prints_forces_and_writes_files(tmp_path):
    out = tmp_path / "f.parquet"
    png = tmp_path / "f.png"
    result = runner.invoke(
        app, ["simulate", "curve", "--set", "X13=16.1", "--out", str(out), "--plot", str(png)]
    )
    assert result.exit_code == 0, result.output
    assert "w1R" in result.output and "31.5" in result.output  # measured wheel, study value
    import pandas as pd

    df = pd.read_parquet(out)
    assert len(df) == 1000 and "Y_w1R_kN" in df.columns
    assert 20.0 < df["Y_w1R_kN"].mean() < 120.0  # the outer leading wheel flanges
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_simulate_tabulates_the_wheel_asked_for(tmp_path):
    """--wheel reached only the figure before stop 56: the table showed the leading wheel
    whatever was asked. The row's statistics are now the asked wheel's, equal to those of
    its series in the Parquet file."""
    import pandas as pd

    from railsusp.conditions import make_condition
    from railsusp.params import ParameterSet
    from railsusp.vehicle.simulate import simulate

    cond = tmp_path / "c.toml"  # named as the study's tangent, so Table 8 is beside it
    cond.write_text('[[condition]]\nname = "straight"\nduration_s = 2.0\nlead_in_m = 10.0\n')
    out = tmp_path / "f.parquet"

    def row(wheel: str) -> list[str]:
        args = ["simulate", str(cond), "--wheel", wheel, "--out", str(out)]
        result = runner.invoke(app, args, terminal_width=200)
        assert result.exit_code == 0, result.output
        line = next(x for x in result.output.splitlines() if "straight" in x)
        return [c.strip() for c in line.split("│") if c.strip()]

    cells = row("w2R")
    assert cells[:2] == ["straight", "w2R"]
    short = make_condition({"name": "straight", "duration_s": 2.0, "lead_in_m": 10.0})
    r = simulate(ParameterSet.nominal(), short)
    assert float(cells[2]) == pytest.approx(r.statistics("w2R")["Y_mean"], abs=0.051)
    # the asked wheel's row, not the leading wheel's: their Q means differ by 2.8 kN (the Y
    # means of w1L and w2R happen to agree to 0.05 kN since revision 2026-11-30.2)
    assert float(cells[7]) == pytest.approx(r.statistics("w2R")["Q_mean"], abs=0.051)
    assert float(cells[7]) != pytest.approx(r.statistics("w1L")["Q_mean"], abs=0.051)
    assert pd.read_parquet(out)["Y_w2R_kN"].abs().mean() == pytest.approx(
        float(cells[2]), abs=0.051
    )
    assert cells[6] == "-" and cells[10] == "-"  # the study's Table 8 is the leading wheel's
    assert row("w1L")[6] == "12.5"  # the wheel Table 8 measured: beside it again


def test_simulate_refuses_two_conditions_of_one_name_when_writing_files(tmp_path):
    """Both were written to f-a.parquet, the second over the first."""
    cond = tmp_path / "dup.toml"
    cond.write_text('[[condition]]\nname = "a"\n\n[[condition]]\nname = "a"\nseed = 2\n')
    result = runner.invoke(app, ["simulate", str(cond), "--out", str(tmp_path / "f.parquet")])
    assert result.exit_code == 2, result.output
    assert "conditions: a named more than once" in result.output
    cond.write_text('[[condition]]\nname = "A"\n\n[[condition]]\nname = "a"\nseed = 2\n')
    result = runner.invoke(app, ["simulate", str(cond), "--plot", str(tmp_path / "f.png")])
    assert result.exit_code == 2 and "conditions: A, a named more than once" in result.output
    assert not list(tmp_path.glob("f*"))


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["simulate", "straight", "--wheel", "w9"], "--wheel 'w9' unknown"),
        (["simulate", "straight", "--set", "X14=99"], "X14"),
        (["simulate", "loop"], "unknown condition 'loop'"),
    ],
)
def test_simulate_bad_input(args, needle):
    proc = subprocess.run(
        [sys.executable, "-m", "railsusp.cli", *args], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 2 and needle in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr


def short_campaign_args(tmp_path, samples: int, batch: int, parameters: str) -> list[str]:
    """`railsusp campaign` arguments for a tiny campaign in a 1 s condition, into
    tmp_path/run."""
    cond_file = tmp_path / "c.toml"
    cond_file.write_text(
        '[[condition]]\nname = "short"\nduration_s = 1.0\nn_steps = 50\nlead_in_m = 20.0\n'
    )
    return ["campaign", "--samples", str(samples), "--conditions", str(cond_file),
            "--out", str(tmp_path / "run"), "--batch-size", str(batch),
            "--parameters", parameters]  # fmt: skip


def test_campaign_sensitivity_train_compare_flow(tmp_path, monkeypatch):
    """The command-line chain on a tiny campaign: every step runs and writes its files."""
    run, cond_file = tmp_path / "run", tmp_path / "c.toml"
    base = short_campaign_args(tmp_path, 12, 6, "X13,X14,X17")
    result = runner.invoke(app, base)
    assert result.exit_code == 0, result.output
    assert (run / "features.parquet").exists()
    again = runner.invoke(app, [*base, "--seed", "1"])
    assert again.exit_code == 2 and "another configuration" in again.output
    result = runner.invoke(
        app, ["sensitivity", str(run), "--base-samples", "64", "--statistics", "mean"]
    )
    assert result.exit_code == 0, result.output
    assert "key parameters" in result.output and (run / "sensitivity" / "indices.csv").exists()
    # the surrogates' own campaign: only the keys sampled, the others nominal
    keys = json.loads((run / "sensitivity" / "key_parameters.json").read_text())
    keys = keys["key_parameters"]["keys"]
    own = tmp_path / "own"
    args = [a if a != str(run) else str(own) for a in base[:-2]]
    result = runner.invoke(app, [*args, "--keys-from", str(run)])
    assert result.exit_code == 0, result.output
    assert json.loads((own / "campaign.json").read_text())["config"]["parameters"] == keys
    both = runner.invoke(app, [*base, "--keys-from", str(run)])
    assert both.exit_code == 2 and "not both" in both.output
    none = runner.invoke(app, [*args, "--keys-from", str(tmp_path)])
    assert none.exit_code == 2 and f"run `railsusp sensitivity {tmp_path}` first" in none.output
    result = runner.invoke(
        app,
        [
            "train",
            str(run),
            "--model",
            "bp",
            "--epochs",
            "1",
            "--batches-per-epoch",
            "3",
            "--batch-size",
            "32",
        ],
    )
    assert result.exit_code == 0, result.output
    assert (run / "surrogates" / "bp" / "short" / "surrogate.json").exists()
    result = runner.invoke(
        app,
        [
            "compare",
            str(run),
            "--models",
            "bp,rbf,gp-stats",
            "--epochs",
            "1",
            "--batches-per-epoch",
            "3",
            "--batch-size",
            "32",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "gp-stats" in result.output and (run / "surrogates" / "compare.csv").exists()
    import pandas as pd

    tab = pd.read_csv(run / "surrogates" / "compare.csv")
    # 8 training runs: the MLP got a record correction, and its own error is reported too
    assert tab[tab.model == "bp"]["relative_error_of_mean_network_alone"].notna().all()
    assert tab[tab.model == "rbf"]["relative_error_of_mean_network_alone"].isna().all()
    bad = runner.invoke(app, ["compare", str(run), "--models", "svm"])
    assert bad.exit_code == 2 and "svm" in bad.output
    bp = ["--model", "bp", "--batches-per-epoch", "3", "--batch-size", "32"]  # compare's
    trained, again = (
        runner.invoke(app, ["train", str(run), *bp, "--epochs", n]) for n in ("1", "2")
    )
    assert trained.exit_code == 0 and again.exit_code == 0, trained.output + again.output
    held = tab[tab.model == "bp"]["test_tracks"].iloc[0]  # the docs audit of stop 58
    assert f"on {int(held)} distinct track(s)" in trained.output
    assert "replacing the network" not in trained.output  # compare's bp: the same settings
    assert "note: replacing the network in" in again.output and "epochs 1 -> 2" in again.output
    field = tmp_path / "field"
    result = runner.invoke(
        app,
        ["synth-field", "--truth", "X13=16.1", "--conditions", str(cond_file), "--out", str(field)],
    )
    assert result.exit_code == 0, result.output
    est = tmp_path / "est"
    result = runner.invoke(
        app,
        [
            "estimate",
            "--measured",
            str(field),
            "--surrogate",
            str(run / "surrogates" / "bp"),
            "--out",
            str(est),
            "--pop-size",
            "8",
            "--n-gen",
            "3",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "Table 5" in result.output and (est / "estimate.json").exists()
    result = runner.invoke(app, ["validate", str(est), "--truth", str(field / "truth.json")])
    assert result.exit_code == 0, result.output
    assert "Parameter recovery" in result.output and (est / "validation" / "recovery.csv").exists()
    # the kN columns' statistic as the report says it: a mean of |Y| was "Y mean" (QA, stop 73)
    assert "mean of |Y|" in result.output and "mean of Q" in result.output
    assert "Y mean" not in result.output
    result = runner.invoke(app, ["estimate", "--measured", str(field), "--out", str(est)])
    assert result.exit_code == 2 and "--surrogate FOLDER or --simulator" in result.output
    result = runner.invoke(app, ["train", str(run), "--model", "gp-stats"])
    assert result.exit_code == 0, result.output
    assert (run / "surrogates" / "gp-stats" / "short" / "statistics.json").exists()
    common = ["estimate", "--measured", str(field), "--pop-size", "8", "--n-gen", "3"]
    result = runner.invoke(
        app,
        [*common, "--surrogate", str(run / "surrogates" / "gp-stats"), "--out", str(est),
         "--statistic", "mean+std", "--weighting", "noise", "--per-condition"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert json.loads((est / "estimate.json").read_text())["config"]["weighting"] == "noise"
    # a full disk while the figures are drawn leaves the folder as it was (stop 57's audit
    # found estimate.json and the CSVs of the new estimate beside the old figures)
    from railsusp.estimate.result import CalibrationResult

    before = {p.relative_to(est): p.read_bytes() for p in est.rglob("*") if p.is_file()}
    real_save = CalibrationResult.save

    def disk_full(self, out, extra=None):
        real_save(self, out, extra)
        raise OSError(28, "No space left on device", str(out / "pareto.png"))

    monkeypatch.setattr(CalibrationResult, "save", disk_full)
    result = runner.invoke(
        app, [*common, "--surrogate", str(run / "surrogates" / "bp"), "--out", str(est)]
    )
    monkeypatch.undo()
    assert isinstance(result.exception, OSError)
    after = {p.relative_to(est): p.read_bytes() for p in est.rglob("*") if p.is_file()}
    assert after == before
    result = runner.invoke(
        app,
        [*common, "--surrogate", str(run / "surrogates" / "bp"), "--out", str(est),
         "--weighting", "noise"],
    )  # fmt: skip
    assert result.exit_code == 2 and "needs the predictive standard deviation" in result.output
    result = runner.invoke(
        app, [*common, "--simulator", "--out", str(est), "--statistic", "mean+median"]
    )
    assert result.exit_code == 2 and "mean, rms, p99, std" in result.output
    result = runner.invoke(app, [*common, "--simulator", "--out", str(est), "--channel-gains"])
    assert result.exit_code == 2
    assert "--channel-gains with statistic 'mean': accepted only with" in result.output
    for bad, needle in [
        (["--expected-draws", "4"], "--expected-draws 4 with statistic 'mean': accepted only"),
        (["--statistic", "aligned", "--expected-draws", "65"], "--expected-draws 65: accepted 0"),
        (["--statistic", "aligned+std", "--expected-draws", "8"], "accepted only with 'aligned'"),
        (["--statistic", "aligned+mean", "--expected-draws", "8"], "'aligned' alone"),
        (["--statistic", "aligned", "--expected-generations"], "needs --expected-draws 1 or more"),
    ]:
        result = runner.invoke(app, [*common, "--simulator", "--out", str(est), *bad])
        assert result.exit_code == 2 and needle in result.output, result.output


def test_synth_field_and_check_recording(tmp_path):
    out = tmp_path / "field"
    cond = tmp_path / "c.toml"
    cond.write_text('[[condition]]\nname = "short"\nduration_s = 2.0\nn_steps = 100\n')
    result = runner.invoke(
        app, ["synth-field", "--truth", "X13=16.1", "--conditions", str(cond), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert (out / "short.csv").exists() and (out / "truth.json").exists()
    result = runner.invoke(app, ["check-recording", str(out / "short.csv")])
    assert result.exit_code == 0 and "w1L" in result.output
    bad = runner.invoke(app, ["synth-field", "--truth", "X13=99", "--out", str(out)])
    assert bad.exit_code == 2 and "X13" in bad.output
    bad = runner.invoke(app, ["synth-field", "--duration", "0.5", "--out", str(out)])
    assert bad.exit_code == 2 and "--duration 0.5 s outside the accepted 1-600 s" in bad.output
    (out / "short.csv").write_text("time_s,Y_w1L_kN\n0,1\n")
    result = runner.invoke(app, ["check-recording", str(out / "short.csv")])
    assert result.exit_code == 2 and "Q_w1L_kN' missing" in result.output


def test_validate_command_bad_folder(tmp_path):
    result = runner.invoke(app, ["validate", str(tmp_path)])
    assert result.exit_code == 2 and "estimate.json" in result.output


def test_measured_track_flow(tmp_path):
    """synth-field --with-track, a campaign on the recordings' own track, gp-stats trained on
    it, NSGA-II, then the simulator's output-error refinement; validate scores the aligned
    mismatch."""
    cond = tmp_path / "c.toml"
    cond.write_text(
        '[[condition]]\nname = "short"\nduration_s = 2.0\nn_steps = 100\nlead_in_m = 20.0\n'
    )
    field, run, est = tmp_path / "field", tmp_path / "run", tmp_path / "est"
    result = runner.invoke(
        app,
        ["synth-field", "--truth", "X13=16.1", "--conditions", str(cond), "--out", str(field),
         "--with-track", "--track-noise", "0.1"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert (field / "short.track.csv").exists()
    result = runner.invoke(app, ["check-recording", str(field / "short.csv")])
    assert result.exit_code == 0 and "measured track geometry" in result.output
    result = runner.invoke(
        app,
        ["campaign", "--samples", "16", "--conditions", str(field), "--out", str(run),
         "--parameters", "X13,X14"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    camp = json.loads((run / "campaign.json").read_text())
    track = camp["config"]["conditions"][0]["track_geometry"]
    assert track == str((field / "short.track.csv").resolve())
    result = runner.invoke(app, ["train", str(run), "--model", "gp-stats"])
    assert result.exit_code == 0, result.output
    result = runner.invoke(
        app,
        ["estimate", "--measured", str(field), "--surrogate", str(run / "surrogates" / "gp-stats"),
         "--out", str(est), "--pop-size", "8", "--n-gen", "3", "--refine",
         "--refine-evaluations", "3", "--refine-screen", "4", "--refine-starts", "1",
         "--geometry-draws", "2", "--keep-geometry-bias", "--held-prior", "X15=150:190"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    doc = json.loads((est / "estimate.json").read_text())
    # --held-prior reaches the refined intervals and is recorded with what they assumed
    details = doc["intervals"]["details"]
    held = details["held_parameters_assumed"]
    assert held["X15"]["range"] == "prior" and held["X16"]["range"] == "Table 2"
    assert (held["X15"]["low_display"], held["X15"]["high_display"]) == (150.0, 190.0)
    assert details["held_prior_display"] == {"X15": [150.0, 190.0]}
    assert doc["refinement"]["n_evaluations"] <= 3 + 1
    # the recordings state 0.1 mm geometry accuracy: its error is in the standard errors
    ref = doc["refinement"]
    assert ref["geometry_draws"] == 2 and not ref["geometry_bias_removed"]
    assert ref["geometry_error_pct_range"]["X13"] > 0
    assert doc["estimate_display"] == ref["refined_display"]
    assert "standard_error_pct_range" in result.output or "standard" in result.output
    from railsusp.validate import validate

    v = validate(est, truth=field / "truth.json", statistic="mean+aligned")
    assert set(v.forces.statistic) == {"mean", "aligned"}
    # expected forces: NSGA-II's choice polished on them, the refinement compares them too
    result = runner.invoke(
        app,
        ["estimate", "--measured", str(field), "--simulator", "--parameters", "X13",
         "--statistic", "aligned", "--expected-draws", "2", "--out", str(tmp_path / "exp"),
         "--pop-size", "4", "--n-gen", "2", "--refine", "--refine-evaluations", "2",
         "--refine-screen", "2", "--refine-starts", "1"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    doc = json.loads((tmp_path / "exp" / "estimate.json").read_text())
    assert doc["expected_polish"]["draws"] == 2 and doc["expected_polish"]["n_jacobians"] >= 1
    assert doc["nsga_estimate_display"] == doc["expected_polish"]["polished_display"]
    assert doc["estimate_display"] == doc["nsga_estimate_display"]
    assert doc["nsga_geometry"]["draws"] == 0  # no SIMEX step beside the polish
    assert "polished by the same model's time-aligned least squares" in doc["route"]
    assert doc["refinement"]["geometry_draws"] == 0  # the error is in the comparison
    assert doc["route"].endswith(
        "the simulator's output-error refinement on its mean over 2 draws of the true track "
        "geometry is a polish beside it"
    )
    slopes_alone = runner.invoke(
        app,
        ["estimate", "--measured", str(field), "--simulator", "--out", str(tmp_path / "x"),
         "--correction-slopes", "--n-gen", "1", "--pop-size", "4"],
    )  # fmt: skip
    assert slopes_alone.exit_code == 2
    assert "--correction-slopes makes each simulator correction first order" in (
        slopes_alone.output
    )
    for update, needle in (
        ("broyden", "--slope-update 'broyden' updates the slopes of first-order corrections"),
        ("newton", "--slope-update 'newton': accepted 'simulated', 'broyden'"),
    ):
        bad = runner.invoke(
            app,
            ["estimate", "--measured", str(field), "--simulator", "--out", str(tmp_path / "x"),
             "--slope-update", update, "--n-gen", "1", "--pop-size", "4"],
        )  # fmt: skip
        assert bad.exit_code == 2 and needle in bad.output, bad.output
    for extra, needle in (
        ([], "--simulator-corrections corrects the time-aligned least squares"),
        (["--statistic", "aligned"], "the force model is the simulator itself"),
    ):
        bad = runner.invoke(
            app,
            ["estimate", "--measured", str(field), "--simulator", "--out", str(tmp_path / "x"),
             "--simulator-corrections", "1", "--n-gen", "1", "--pop-size", "4", *extra],
        )  # fmt: skip
        assert bad.exit_code == 2 and needle in bad.output, bad.output
    assert doc["polished_display"] == doc["refinement"]["refined_display"]
    for option, value, accepted in (
        ("--refine-evaluations", "0", "1 to 500"),
        ("--geometry-draws", "101", "0 to 100"),
    ):
        bad = runner.invoke(
            app,
            ["estimate", "--measured", str(field), "--simulator", "--out", str(est),
             option, value, "--refine", "--n-gen", "1", "--pop-size", "4"],
        )  # fmt: skip
        assert bad.exit_code == 2 and f"{option} {value}: accepted {accepted}" in bad.output


def test_align_track_finds_and_writes_a_misregistration(tmp_path):
    """A track file whose distances are off by 2 m: align-track finds -2 m, --write stores
    it in the sidecar, and the reader then applies it (correlation back to its best)."""
    import pandas as pd

    from railsusp.estimate import align_track
    from railsusp.measured import read_field

    cond = tmp_path / "c.toml"
    cond.write_text(
        '[[condition]]\nname = "short"\nduration_s = 4.0\nn_steps = 200\nlead_in_m = 20.0\n'
    )
    field = tmp_path / "field"
    result = runner.invoke(
        app, ["synth-field", "--conditions", str(cond), "--out", str(field), "--with-track"]
    )
    assert result.exit_code == 0, result.output
    (rec,) = read_field(field)
    assert abs(align_track(rec).shift_m) < 0.1  # registered already
    track = pd.read_csv(field / "short.track.csv")
    track["distance_m"] += 2.0
    track.to_csv(field / "short.track.csv", index=False, float_format="%.9g")
    result = runner.invoke(app, ["align-track", str(field), "--write"])
    assert result.exit_code == 0, result.output
    assert "Track geometry alignment" in result.output and "short" in result.output
    side = json.loads((field / "short.json").read_text())
    assert side["condition"]["track_offset_m"] == pytest.approx(-2.0, abs=0.1)
    (rec,) = read_field(field)
    after = align_track(rec)
    assert abs(after.shift_m) < 0.1 and after.correlation > 0.9
    assert "(offset -" in rec.condition.describe()
    bad = runner.invoke(app, ["align-track", str(field), "--max-shift", "0"])
    assert bad.exit_code == 2 and "--max-shift 0: accepted (0, 200] m" in bad.output


def test_campaign_duration_keeps_the_sampling_interval(tmp_path):
    run = tmp_path / "run"
    base = short_campaign_args(tmp_path, 2, 2, "X13")
    result = runner.invoke(app, [*base, "--duration", "2"])
    assert result.exit_code == 0, result.output
    (cond,) = json.loads((run / "campaign.json").read_text())["config"]["conditions"]
    assert cond["duration_s"] == 2.0 and cond["n_steps"] == 100
    bad = runner.invoke(app, [*base, "--duration", "700", "--out", str(tmp_path / "x")])
    # named as the option typed, not as the condition's field (duration_s)
    assert bad.exit_code == 2 and "--duration 700" in bad.output and "600" in bad.output
