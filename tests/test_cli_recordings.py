"""`railsusp sections`, `check-recording --map` and `example-recording` on the command
line: the cut printed and written, bad input one line and exit status 2."""

import json

import numpy as np
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.run_lock import LOCK_NAME

runner = CliRunner()


def example(tmp_path):
    result = runner.invoke(app, ["example-recording", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    return tmp_path / "example_run.mf4", tmp_path / "example_run.map.toml"


def test_sections_from_a_user_table_are_written_by_their_names(tmp_path):
    run, cmap = example(tmp_path)
    table = tmp_path / "sections.csv"
    table.write_text("start_m,end_m,name\n50,500,level-65\n800,1150,curve-600\n")
    out = tmp_path / "field"
    result = runner.invoke(
        app, ["sections", str(run), "--map", str(cmap), "--table", str(table), "--write", str(out)]
    )
    assert result.exit_code == 0, result.output
    index = json.loads((out / "index.json").read_text())
    assert index["recordings"] == ["level-65.csv", "curve-600.csv"]
    side = json.loads((out / "curve-600.json").read_text())
    assert side["condition"]["curve_radius_m"] == 600.0
    assert side["condition"]["speed_kmh"] == 55.0
    t = np.loadtxt(out / "curve-600.csv", delimiter=",", skiprows=1)[:, 0]
    np.testing.assert_allclose(np.diff(t), 0.02, rtol=1e-6)  # written at 50 Hz
    assert abs(t[-1] - 350 / (55 / 3.6)) < 0.1  # 350 m at 55 km/h


def test_a_section_name_that_would_leave_the_folder_is_refused(tmp_path):
    run, cmap = example(tmp_path)
    table = tmp_path / "sections.csv"
    for name in ("../../x", "/etc/x", ".hidden"):
        table.write_text(f"start_m,end_m,name\n50,500,{name}\n")
        result = runner.invoke(
            app, ["sections", str(run), "--map", str(cmap), "--table", str(table)]
        )
        assert result.exit_code == 2 and "row 2: name" in result.output


def test_bad_runs_and_maps_are_one_line_errors(tmp_path):
    run, cmap = example(tmp_path)
    bad_map = tmp_path / "bad.toml"
    bad_map.write_text('speed = "v_train"\n[wheels.w1R]\nY = "WS1_Y_R"\nQ = "WS1_Q_X"\n')
    result = runner.invoke(app, ["sections", str(run), "--map", str(bad_map)])
    assert result.exit_code == 2
    assert "channel 'WS1_Q_X' of the" in result.output and "did you mean 'WS1_Q_R'" in result.output
    garbage = tmp_path / "garbage.mf4"
    garbage.write_bytes(b"\x00\x01 not an MDF file")
    result = runner.invoke(app, ["check-recording", str(garbage), "--map", str(cmap)])
    assert result.exit_code == 2 and "not a readable MDF file" in result.output
    result = runner.invoke(app, ["sections", str(run), "--map", str(cmap), "--rate", "0"])
    assert result.exit_code == 2 and "--rate 0: accepted 50 to 5000 Hz" in result.output
    # 10-49 Hz wrote a field folder that every estimation command refused
    result = runner.invoke(app, ["sections", str(run), "--map", str(cmap), "--rate", "20"])
    assert result.exit_code == 2 and "--rate 20: accepted 50 to 5000 Hz" in result.output
    result = runner.invoke(
        app, ["sections", str(run), "--map", str(cmap), "--speed-tolerance", "-1"]
    )
    assert result.exit_code == 2 and "--speed-tolerance -1: accepted 0 to 1" in result.output
    assert "Traceback" not in result.output


def test_sections_write_replaces_the_folder_whole(tmp_path, monkeypatch):
    """The kill/resume pass (stop 54): a rewrite killed midway left new recordings beside
    the old index and sidecars. Now the folder is swapped in at once: a failure leaves the
    old one as it was; other files of the folder are carried over."""
    import railsusp.measured.sections_out as sections_out

    run, cmap = example(tmp_path)
    table = tmp_path / "sections.csv"
    table.write_text("start_m,end_m,name\n50,500,level-65\n800,1150,curve-600\n")
    out = tmp_path / "field"
    args = ["sections", str(run), "--map", str(cmap), "--table", str(table), "--write", str(out)]
    assert runner.invoke(app, args).exit_code == 0
    (out / "notes.txt").write_text("mine")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    real, calls = sections_out.section_recording, []

    def dies_second(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("killed")
        return real(*a, **k)

    monkeypatch.setattr(sections_out, "section_recording", dies_second)
    result = runner.invoke(app, [*args, "--rate", "100"])
    assert result.exit_code != 0
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert not list(tmp_path.glob(".field.*"))
    monkeypatch.setattr(sections_out, "section_recording", real)
    assert runner.invoke(app, [*args, "--rate", "100"]).exit_code == 0
    assert (out / "notes.txt").read_text() == "mine"
    t = np.loadtxt(out / "curve-600.csv", delimiter=",", skiprows=1)[:, 0]
    np.testing.assert_allclose(np.diff(t), 0.01, rtol=1e-6)


def test_neither_writer_replaces_a_field_folder_it_did_not_write(tmp_path):
    """Before stop 57 `synth-field --out` into the sections of a measured run replaced the
    measured recordings with synthetic ones (exit 0), and `sections --write` replaced the
    index of a synthetic field, leaving its truth.json beside the measured sections."""
    run, cmap = example(tmp_path)
    table = tmp_path / "sections.csv"
    table.write_text("start_m,end_m,name\n50,500,level-65\n")
    cut = tmp_path / "cut"
    args = ["sections", str(run), "--map", str(cmap), "--table", str(table), "--write"]
    assert runner.invoke(app, [*args, str(cut)]).exit_code == 0
    assert runner.invoke(app, [*args, str(cut)]).exit_code == 0  # its own folder again
    before = {p.name: p.read_bytes() for p in cut.iterdir()}
    conditions = tmp_path / "c.toml"
    conditions.write_text('[[condition]]\nname = "level-65"\nduration_s = 1.0\nn_steps = 50\n')
    synth = ["synth-field", "--conditions", str(conditions), "--duration", "1", "--out"]
    result = runner.invoke(app, [*synth, str(cut)])
    assert result.exit_code == 2, result.output
    (line,) = result.output.strip().splitlines()
    assert line == (
        f"error: --out {cut} holds a field folder written by sections --write; synth-field "
        "would replace them: accepted a new or empty folder, or one synth-field wrote"
    )
    assert {p.name: p.read_bytes() for p in cut.iterdir()} == before  # nothing lost
    field = tmp_path / "synthetic"
    assert runner.invoke(app, [*synth, str(field)]).exit_code == 0
    assert runner.invoke(app, [*synth, str(field)]).exit_code == 0  # its own folder again
    result = runner.invoke(app, [*args, str(field)])
    assert result.exit_code == 2 and "holds a field folder written by synth-field" in result.output
    assert (field / "truth.json").is_file()
    # a user's measured folder whose index has a "source" of its own (docs/data-format.md)
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "index.json").write_text('{"recordings": ["a.csv"], "source": "logger B"}')
    result = runner.invoke(app, [*args, str(mine)])
    assert result.exit_code == 2 and "files of another kind" in result.output
    assert json.loads((mine / "index.json").read_text())["source"] == "logger B"
    # the sections of another run are not replaced by this one's (told by the contents,
    # stop 63: a byte copy under another name is the same run)
    other = tmp_path / "other.mf4"
    other.write_bytes(run.read_bytes() + b"\0")
    again = ["sections", str(other), "--map", str(cmap), "--table", str(table), "--write"]
    result = runner.invoke(app, [*again, str(cut)])
    assert result.exit_code == 2, result.output
    assert f"holds the sections of another run ({run.name})" in result.output
    other.write_bytes(run.read_bytes())
    assert runner.invoke(app, [*again, str(cut)]).exit_code == 0
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "a.txt").write_text("mine")
    result = runner.invoke(app, [*synth, str(tmp_path / "notes")])
    assert result.exit_code == 2 and "files of another kind" in result.output
    assert (tmp_path / "notes" / "a.txt").read_text() == "mine"


def test_check_recording_takes_the_wagon_whose_wheel_loads_it_checks(tmp_path):
    """A tare C80's recording (24.5 kN static wheel load) was refused against the loaded
    C80's 121.9 kN whatever the wagon: check-recording and sections had no --wagon."""
    from test_measured import make_recording

    rec = make_recording(100, 50.0)
    rec.Q = {"w1L": 24.5 + 2 * np.cos(rec.time)}
    rec.write(tmp_path / "tare.csv")
    loaded = runner.invoke(app, ["check-recording", str(tmp_path / "tare.csv")])
    assert loaded.exit_code == 2 and "static wheel load 121.9 kN" in loaded.output
    tare = runner.invoke(app, ["check-recording", str(tmp_path / "tare.csv"), "--wagon", "tare"])
    assert tare.exit_code == 0, tare.output
    bad = runner.invoke(app, ["check-recording", str(tmp_path / "tare.csv"), "--wagon", "nope"])
    assert bad.exit_code == 2 and "--wagon" in bad.output and "Traceback" not in bad.output


def test_sections_of_a_tare_wagons_run_are_written_and_digested_as_its(tmp_path):
    """sections --wagon tare --write read its sections back for the index's digest as
    recordings of the loaded C80 and refused them (24.5 kN against 121.9 kN, naming its
    temporary folder; the review of stop 76): the run's wagon reads them now."""
    import pandas as pd

    n = 12000
    t = np.arange(n) / 200.0
    rng = np.random.default_rng(4)
    forces = {"Y_R": 2.0 + rng.standard_normal(n), "Q_R": 24.5 + rng.standard_normal(n)}
    table = {"time_s": t, **forces, "v": np.full(n, 54.0), "s": 15.0 * t}
    pd.DataFrame(table).to_csv(tmp_path / "run.csv", index=False)
    (tmp_path / "map.toml").write_text(
        'speed = "v"\nposition = "s"\ntime = "time_s"\n[wheels.w1R]\nY = "Y_R"\n'
        'Q = "Q_R"\n[units]\nv = "km/h"\ns = "m"\nY_R = "kN"\nQ_R = "kN"\n'
    )
    cut = tmp_path / "cut"
    args = ["sections", str(tmp_path / "run.csv"), "--map", str(tmp_path / "map.toml")]
    result = runner.invoke(app, [*args, "--wagon", "tare", "--write", str(cut)])
    assert result.exit_code == 0, result.output
    from railsusp.measured import read_field
    from railsusp.measured.recording import same_recordings
    from railsusp.vehicle.wagon import load_wagon

    index = json.loads((cut / "index.json").read_text())
    recs = read_field(cut, wagon=load_wagon("tare"))
    assert same_recordings(recs, index["recordings_digest"])


def test_example_recording_does_not_write_over_an_edited_file(tmp_path):
    """The tutorial has the user edit the example's configuration: copying the example
    again replaced it silently (command-line audit of stop 60). Unchanged copies are fine."""
    example(tmp_path)
    stamps = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir() if p.name != LOCK_NAME}
    example(tmp_path)  # the same files again: nothing lost, nothing refused, none rewritten
    # (rewritten, the recording's new modification time made `railsusp run` redo its stages)
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir() if p.name != LOCK_NAME} == (
        stamps
    )
    config = tmp_path / "example_run.pipeline.toml"
    config.write_text(config.read_text() + "# my edit\n")
    shipped = (tmp_path / "example_run.mf4").read_bytes()
    (tmp_path / "example_run.mf4").unlink()  # deleted: restored beside the edited file
    result = runner.invoke(app, ["example-recording", "--out", str(tmp_path)])
    # beside an edited file it wrote nothing (exit 2): the deleted recording stayed lost
    assert result.exit_code == 0, result.output
    assert config.read_text().endswith("# my edit\n")
    assert (tmp_path / "example_run.mf4").read_bytes() == shipped
    out = " ".join(result.output.split())
    assert f"wrote example_run.mf4 to {tmp_path}; already there as shipped: " in out
    assert (
        f"--out {tmp_path}: left as they are, not the shipped files (edited?): "
        "example_run.pipeline.toml; move them away, or give a new --out, for fresh copies"
    ) in out
    result = runner.invoke(app, ["example-recording", "--out", str(tmp_path)])
    assert f"nothing written to {tmp_path}; already there as shipped" in " ".join(
        result.output.split()
    )  # it said "wrote" every file while it wrote none


def synthetic_run(path, seed):
    """A 120 s run at 54 km/h on tangent (1800 m, 50 Hz), the documented column names;
    ``seed`` makes another run of the same length."""
    import pandas as pd

    rng = np.random.default_rng(seed)
    t = np.arange(6000) / 50.0
    cols = {"time_s": t, "speed_kmh": np.full(t.size, 54.0)}
    for w in ("w1R", "w1L"):
        cols[f"Y_{w}_kN"] = 5.0 + rng.standard_normal(t.size)
        cols[f"Q_{w}_kN"] = 120.0 + rng.standard_normal(t.size)
    path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(cols).to_csv(path, index=False)
    return path


def test_sections_write_leaves_no_recording_of_the_earlier_cut(tmp_path):
    """A cut into four sections, then the same run cut into two: the earlier cut's third
    and fourth recordings (and sidecars) stayed beside the new index, which no longer
    listed them (the audit of stop 63). A file of the user's is still carried over."""
    run = synthetic_run(tmp_path / "run.csv", 0)
    out = tmp_path / "field"
    args = ["sections", str(run), "--write", str(out), "--max-duration"]
    assert runner.invoke(app, [*args, "30"]).exit_code == 0
    assert len(json.loads((out / "index.json").read_text())["recordings"]) == 4
    (out / "notes.txt").write_text("mine")
    result = runner.invoke(app, [*args, "60"])
    assert result.exit_code == 0, result.output
    listed = json.loads((out / "index.json").read_text())["recordings"]
    assert len(listed) == 2
    tables = sorted(p.name for p in out.glob("*.csv") if p.stem not in ("sections", "en14363"))
    assert tables == sorted(listed)
    sidecars = sorted(p.stem for p in out.glob("*.json") if p.name != "index.json")
    assert sidecars == sorted(n.removesuffix(".csv") for n in listed)
    assert (out / "notes.txt").read_text() == "mine"


def test_sections_write_tells_another_run_of_the_same_name_by_its_contents(tmp_path):
    """day1/run.csv cut into a folder, then day2/run.csv, another run of the same file
    name: the folder's source was compared by name only, and the second day's sections
    silently replaced the first's (the audit of stop 63). A run moved or renamed is the
    same run; an index written before the fingerprint is compared by name."""
    day1 = synthetic_run(tmp_path / "day1" / "run.csv", 0)
    day2 = synthetic_run(tmp_path / "day2" / "run.csv", 1)
    out = tmp_path / "field"
    assert runner.invoke(app, ["sections", str(day1), "--write", str(out)]).exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    result = runner.invoke(app, ["sections", str(day2), "--write", str(out)])
    assert result.exit_code == 2, result.output
    (line,) = result.output.strip().splitlines()
    assert line.startswith(f"error: --write {out} holds the sections of another run (run.csv, ")
    assert "would replace them with those of run.csv, " in line and "SHA-256" in line
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # nothing lost
    moved = tmp_path / "archive" / "renamed.csv"
    moved.parent.mkdir()
    moved.write_bytes(day1.read_bytes())
    result = runner.invoke(app, ["sections", str(moved), "--write", str(out)])
    assert result.exit_code == 0, result.output  # the same run, elsewhere, by another name
    index = json.loads((out / "index.json").read_text())
    assert index["source"] == "renamed.csv" and index["source_bytes"] == moved.stat().st_size
    # an index of before stop 63, without the fingerprint: compared by name
    old = {k: v for k, v in index.items() if k not in ("source_bytes", "source_sha256")}
    (out / "index.json").write_text(json.dumps({**old, "source": "run.csv"}))
    assert runner.invoke(app, ["sections", str(day2), "--write", str(out)]).exit_code == 0
    assert "source_sha256" in json.loads((out / "index.json").read_text())
    result = runner.invoke(app, ["sections", str(moved), "--write", str(out)])
    assert result.exit_code == 2 and "holds the sections of another run (run.csv" in result.output


def test_sections_of_a_table_are_one_recording_each_whatever_their_names(tmp_path):
    """The audit of stop 63 (defect 3): a row "a" split in two by the 120 s maximum was
    numbered a-1, a-2 beside a row named "a-1" (which of them kept the name hung on Python's
    hash seed), and "km0.5" and "km0.7" were both written as km0.csv: one recording over
    another, exit 0. A split row's numbers skip those taken, in table order; a dot stays."""
    import pandas as pd

    t = np.arange(12000) / 50.0  # 240 s at 54 km/h: 3600 m of tangent
    rng = np.random.default_rng(0)
    cols = {"time_s": t, "speed_kmh": np.full(t.size, 54.0), "curvature_1_per_km": 0.0 * t}
    for w in ("w1R", "w1L"):
        cols[f"Y_{w}_kN"] = 5.0 + rng.standard_normal(t.size)
        cols[f"Q_{w}_kN"] = 120.0 + rng.standard_normal(t.size)
    pd.DataFrame(cols).to_csv(tmp_path / "run.csv", index=False)
    table = tmp_path / "table.csv"
    table.write_text(
        "start_m,end_m,name\n0,2400,a\n2500,2900,a-1\n3000,3250,km0.5\n3300,3550,km0.7\n"
    )
    out = tmp_path / "field"
    args = ["sections", str(tmp_path / "run.csv"), "--table", str(table), "--write", str(out)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    listed = json.loads((out / "index.json").read_text())["recordings"]
    assert listed == ["a-2.csv", "a-3.csv", "a-1.csv", "km0.5.csv", "km0.7.csv"]
    for name in listed:
        assert (out / name).is_file() and (out / name).with_suffix(".json").is_file()
    from railsusp.measured import read_field

    assert [r.condition.name for r in read_field(out)] == [n[:-4] for n in listed]


def test_a_tables_curve_against_the_runs_own_is_said(tmp_path):
    """QA of stop 73: a section table's R350 right over a stretch the run's curvature channel
    gives as R600 left was cut and written without a word (its sections carry no curvature,
    so nothing after the cut can catch a typed hand that makes the inner wheel the compared
    one). Said now, naming the row and both; a row that agrees is not."""
    run, cmap = example(tmp_path)
    table = tmp_path / "sections.csv"
    header = "start_m,end_m,name,radius_m,direction,cant_mm,grade_permille\n"
    for row, said in [
        ("800,1150,c,350,right,100,0", "it states R 350 m right, the run's curvature channel "
         "gives R 600 m left there"),
        ("800,1150,c,600,right,100,0", "it states R 600 m right, the run's curvature channel "
         "gives R 600 m left there"),
        ("800,1150,c,,,,0", "it states tangent, the run's curvature channel gives R 600 m left"),
        ("800,1150,c,600,left,100,0", None),
        ("50,500,c,,,,0", None),
    ]:  # fmt: skip
        table.write_text(header + row + "\n")
        result = runner.invoke(
            app, ["sections", str(run), "--map", str(cmap), "--table", str(table)]
        )
        assert result.exit_code == 0, result.output
        out = " ".join(result.output.split())
        if said is None:
            assert "averaged over the row" not in out, row
        else:
            assert f"row 2: {said}" in out and "check its radius_m and direction" in out, row


def test_example_recording_is_not_written_among_recordings(tmp_path):
    """example-recording wrote its five files into a field folder, beside the recordings
    (the QA of stop 73); refused now in one line, as every command writing results is."""
    field = tmp_path / "field"
    field.mkdir()
    (field / "index.json").write_text('{"recordings": ["straight.csv"]}')
    result = runner.invoke(app, ["example-recording", "--out", str(field)])
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    assert f"--out {field} is a field folder of recordings (index.json)" in text
    assert sorted(p.name for p in field.iterdir()) == ["index.json"]  # nothing written


def test_an_earlier_railsusps_example_truth_is_replaced_not_called_edited(tmp_path):
    """The example truth gained its run's SHA-256 in stop 74: a copy an earlier railsusp
    wrote was called edited and kept (the review of stop 74). It is replaced by this one's;
    a user's edit is still kept."""
    import hashlib

    from railsusp.cli.recordings import EARLIER_SHIPPED

    example(tmp_path)
    older = (
        json.dumps(
            {
                "parameters_display": {"X13": 16.1, "X14": 8.3, "X15": 164.0},
                "note": "hidden truth of example_run.mf4; the estimator never reads it",
            },
            indent=1,
        ).encode()
        + b"\n"
    )  # as railsusp shipped it until stop 73
    assert hashlib.sha256(older).hexdigest() in EARLIER_SHIPPED["example_run.truth.json"]
    truth = tmp_path / "example_run.truth.json"
    shipped = truth.read_bytes()
    truth.write_bytes(older)
    result = runner.invoke(app, ["example-recording", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "edited" not in result.output and truth.read_bytes() == shipped
    truth.write_bytes(shipped.replace(b"16.1", b"16.2"))  # the user's own
    result = runner.invoke(app, ["example-recording", "--out", str(tmp_path)])
    assert "(edited?): example_run.truth.json" in " ".join(result.output.split())
