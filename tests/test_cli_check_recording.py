"""check-recording's summary of the forces: Y's sign shown (the mean and maximum of |Y|
alone printed a sign-flipped Y as the right one), and a long run's statistics over its
measured samples only (the samples interpolated across missing values counted in them
before); a long run's table read with a recording's checks, and refused where too much of
a force channel is interpolated."""

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
    said = " ".join(result.output.split())
    assert "left out, interpolated across missing values: 3000 of Q w1R" in said


def long_run(tmp_path, q, name="run.csv"):
    """A 200 Hz long run of one wheel with ``q`` as its Q, and its channel map."""
    n = q.size
    t = np.arange(n) / 200.0
    rng = np.random.default_rng(4)
    frame = {"time_s": t, "Y_R": 5.0 + rng.standard_normal(n), "Q_R": q}
    frame.update(v=np.full(n, 54.0), s=15.0 * t)
    pd.DataFrame(frame).to_csv(tmp_path / name, index=False)
    (tmp_path / "map.toml").write_text(
        'speed = "v"\nposition = "s"\ntime = "time_s"\n[wheels.w1R]\nY = "Y_R"\nQ = "Q_R"\n'
        '[units]\nv = "km/h"\ns = "m"\nY_R = "kN"\nQ_R = "kN"\n'
    )
    return tmp_path / name, tmp_path / "map.toml"


def test_a_long_runs_summary_leaves_out_every_interpolated_sample(tmp_path):
    """Only the samples of gaps over 5 were left out (the docs said every filled one): 298
    single samples missing between readings of 200 kN took Q's mean from 120 to 124 kN."""
    q = 120.0 + np.random.default_rng(5).standard_normal(12000)
    at = np.arange(100, 12000, 40)  # 298, 2.5 %: within the 5 % interpolated
    q[at - 1] = q[at + 1] = 200.0
    q[at] = np.nan
    path, cmap = long_run(tmp_path, q)
    result = runner.invoke(app, ["check-recording", str(path), "--map", str(cmap)],
                           terminal_width=200)  # fmt: skip
    assert result.exit_code == 0, result.output
    assert float(rows_of(result.output)["w1R"][3]) == round(float(np.nanmean(q)), 2)
    said = " ".join(result.output.split())
    assert "left out, interpolated across missing values: 298 of Q w1R" in said


def test_a_long_run_with_a_fifth_of_its_forces_missing_is_refused_by_sections(tmp_path):
    """20 % of Q missing one sample at a time was read with a note, and sections --write
    wrote the interpolated values as measured sections that check-recording accepted."""
    q = 120.0 + np.random.default_rng(6).standard_normal(12000)
    q[np.arange(2, 12000, 5)] = np.nan
    path, cmap = long_run(tmp_path, q)
    out = tmp_path / "field"
    result = runner.invoke(
        app, ["sections", str(path), "--map", str(cmap), "--write", str(out)], terminal_width=200
    )
    assert result.exit_code == 2 and not (out / "index.json").exists()
    assert (
        "channel 'Q_R': 2400 of its 12000 samples (20 %) missing (NaN), in gaps of up to 5 "
        "samples; accepted at most 5 %"
    ) in " ".join(result.output.split())


def test_a_long_runs_table_gets_the_checks_of_a_recordings_table(tmp_path):
    """A long run's CSV was read by another reader: separated by ';' it said "no time
    column", a column named twice was read as 'Q_R.1', a line not UTF-8 had no number."""
    path, cmap = long_run(tmp_path, 120.0 + np.zeros(2000) + np.arange(2000) % 7)
    lines = path.read_text().splitlines()

    def said(text: str | bytes) -> str:
        path.write_bytes(text if isinstance(text, bytes) else text.encode())
        result = runner.invoke(app, ["check-recording", str(path), "--map", str(cmap)],
                               terminal_width=300)  # fmt: skip
        assert result.exit_code == 2, result.output
        return " ".join(result.output.split())

    semi = "\n".join(line.replace(",", ";") for line in lines) + "\n"
    assert "its cells are separated by ';'; accepted a comma-separated table" in said(semi)
    header = lines[0] + ",Q_R"
    twice = "\n".join([header, *(line + ",1" for line in lines[1:])]) + "\n"
    assert "column 'Q_R' appears 2 times in the header (columns 3, 6)" in said(twice)
    raw = ("\n".join(lines) + "\n").encode().split(b"\n")
    raw[40] += b"\xe9"
    assert "line 41: not UTF-8 text (byte 0xe9)" in said(b"\n".join(raw))
    longer = "\n".join([*lines[:9], lines[9] + ",7", *lines[10:]]) + "\n"
    assert "line 10: more cells than the header's 5" in said(longer)


def test_every_command_names_the_wagon_option(tmp_path):
    path, cmap = long_run(tmp_path, 120.0 + np.arange(2000) % 7)
    for args in (
        ["check-recording", str(path), "--map", str(cmap)],
        ["sections", str(path), "--map", str(cmap)],
    ):
        result = runner.invoke(app, [*args, "--wagon", "nosuch"])
        assert result.exit_code == 2
        assert "--wagon: wagon file nosuch does not exist" in " ".join(result.output.split())


def test_synth_field_names_the_wagon_option(tmp_path):
    result = runner.invoke(app, ["synth-field", "--out", str(tmp_path / "f"), "--wagon", "nosuch"])
    assert result.exit_code == 2
    assert "--wagon: wagon file nosuch does not exist" in " ".join(result.output.split())
