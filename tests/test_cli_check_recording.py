"""check-recording's summary of the forces: Y's sign shown (the mean and maximum of |Y|
alone printed a sign-flipped Y as the right one), and a long run's statistics over its
measured samples only (the samples filled across a NaN gap counted in them before)."""

import numpy as np
import pandas as pd
from typer.testing import CliRunner

from railsusp.cli import app
from test_measured import make_recording

runner = CliRunner()


def rows_of(output: str) -> dict[str, list[str]]:
    """The summary table's rows by wheel, their cells as printed."""
    out = {}
    for line in output.splitlines():
        cells = [c.strip() for c in line.replace("┃", "│").split("│") if c.strip()]
        if cells and cells[0] in ("w1L", "w1R"):
            out[cells[0]] = cells[1:]
    return out


def test_the_sign_of_y_is_in_the_summary(tmp_path):
    rec = make_recording(100, 50.0)
    rec.Y = {"w1L": -rec.Y["w1L"]}  # a channel + towards the track centre
    rec.write(tmp_path / "flip.csv")
    result = runner.invoke(app, ["check-recording", str(tmp_path / "flip.csv")], terminal_width=160)
    assert result.exit_code == 0, result.output
    assert "Y mean kN" in result.output and "|Y| mean kN" in result.output
    signed, mean_abs, max_abs = rows_of(result.output)["w1L"][:3]
    y = rec.Y["w1L"]
    assert float(signed) == round(float(np.mean(y)), 2) < 0
    assert float(mean_abs) == round(float(np.mean(np.abs(y))), 2)
    assert float(max_abs) == round(float(np.max(np.abs(y))), 2)
    assert "+ towards the field side" in result.output


def test_a_long_runs_summary_leaves_out_the_samples_filled_across_a_gap(tmp_path):
    """Q of w1R missing over 3000 samples between two readings of 200 kN: filled across,
    they took its mean from 120 to 140 kN."""
    rate, n = 200.0, 12000
    t = np.arange(n) / rate
    rng = np.random.default_rng(3)
    q = 120.0 + rng.standard_normal(n)
    q[999] = q[4000] = 200.0
    q[1000:4000] = np.nan
    pd.DataFrame(
        {
            "time_s": t,
            "Y_R": 5.0 + rng.standard_normal(n),
            "Q_R": q,
            "v": np.full(n, 54.0),
            "s": 15.0 * t,
        }
    ).to_csv(tmp_path / "run.csv", index=False)
    (tmp_path / "map.toml").write_text(
        'speed = "v"\nposition = "s"\ntime = "time_s"\n[wheels.w1R]\nY = "Y_R"\nQ = "Q_R"\n'
        '[units]\nv = "km/h"\ns = "m"\nY_R = "kN"\nQ_R = "kN"\n'
    )
    result = runner.invoke(
        app,
        ["check-recording", str(tmp_path / "run.csv"), "--map", str(tmp_path / "map.toml")],
        terminal_width=200,
    )
    assert result.exit_code == 0, result.output
    q_mean = float(rows_of(result.output)["w1R"][3])
    assert q_mean == round(float(np.nanmean(q)), 2)  # 120.03, not 140
    assert "filled across NaN gaps: 3000 of Q w1R" in " ".join(result.output.split())


def test_synth_field_names_the_wagon_option(tmp_path):
    result = runner.invoke(app, ["synth-field", "--out", str(tmp_path / "f"), "--wagon", "nosuch"])
    assert result.exit_code == 2
    assert "--wagon: wagon file nosuch does not exist" in " ".join(result.output.split())
