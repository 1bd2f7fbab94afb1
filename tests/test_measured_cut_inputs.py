"""What the cut of a long run took silently or said without the accepted range (the
suspected items of the audit of stop 63): a line description read from km 0 on a run
without a position channel, a section-table row only partly on the run kept under its
name, messages of the line and section tables and of --write, a channel map naming
another recording, and the cut's cache keeping whole runs alive."""

import gc
import weakref

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.measured.channels import channel_map_from, read_channel_map
from railsusp.measured.line import read_line, read_section_table
from railsusp.measured.run import read_run
from railsusp.measured.sections import cut_sections, sections_table
from railsusp.measured.sections_out import write_sections
from test_measured_run import MAP, track_run, write_mdf


def _table_run(path, *, position=True):
    """60 s at 54 km/h, both leading wheels, forces at 100 Hz; with or without a position
    channel."""
    rng = np.random.default_rng(7)
    t = np.arange(6000) / 100.0
    frame = {"time_s": t, "speed_kmh": np.full(t.size, 54.0)}
    if position:
        frame["distance_m"] = 15.0 * t
    for w in ("w1R", "w1L"):
        frame[f"Y_{w}_kN"] = 5.0 + rng.standard_normal(t.size)
        frame[f"Q_{w}_kN"] = 120.0 + rng.standard_normal(t.size)
    pd.DataFrame(frame).to_csv(path, index=False)
    return path


def test_a_line_description_on_a_run_without_a_position_channel_says_it_starts_at_km_0(tmp_path):
    """The position is the integrated speed from 0: the line's km 0 is where the run starts,
    which was taken silently; a note (warned of by the pipeline) says so. With a position
    channel, nothing."""
    from railsusp.measured.sections import LINE_FROM_ZERO_NOTE

    line = tmp_path / "line.csv"
    line.write_text(
        "km_start,km_end,radius_m,direction,cant_mm,grade_permille\n0,0.4,,,0,0\n"
        "0.4,2,800,left,50,0\n"
    )
    run = read_run(_table_run(tmp_path / "a.csv", position=False))
    assert run.position_from_speed
    cut_sections(run)  # no line: nothing to say
    assert LINE_FROM_ZERO_NOTE not in run.notes
    cut_sections(run, line=read_line(line))
    cut_sections(run, line=read_line(line))
    assert run.notes.count(LINE_FROM_ZERO_NOTE) == 1 and LINE_FROM_ZERO_NOTE in run.data_notes
    assert LINE_FROM_ZERO_NOTE.startswith("no position channel: the position is the speed ")
    located = read_run(_table_run(tmp_path / "b.csv"))
    cut_sections(located, line=read_line(line))
    assert not located.position_from_speed and LINE_FROM_ZERO_NOTE not in located.notes


def test_a_section_table_row_only_partly_on_the_run_says_so(tmp_path):
    """A row reaching beyond the run's end (or before its start) is kept over what the run
    passes, its reason giving both ranges; a row wholly on the run has no reason."""
    run = track_run(rate=50.0)  # 0 to 2100 m
    table = tmp_path / "t.csv"
    table.write_text(
        "start_m,end_m,name,radius_m,direction\n-100,300,head,,\n800,1300,curve,600,left\n"
        "1800,2400,tail,,\n"
    )
    secs = cut_sections(run, table=read_section_table(table))
    reasons = {s.name: s.reason for s in secs if s.kept}
    assert reasons == {
        "head": "kept, 0-300 m of -100 to 300 m on the run (row 2 of the table)",
        "curve": "",
        "tail": "kept, 1800-2100 m of 1800-2400 m on the run (row 4 of the table)",
    }
    shown = sections_table(secs).set_index("section")
    assert shown.loc["tail", "kept"] == "yes" and shown.loc["tail", "reason"].startswith("kept, ")


@pytest.mark.parametrize(
    ("text", "said"),
    [
        (
            "km_start,km_end,radius_m,cant_mm,grade_permille\n1,0.5,,0,0\n",
            "row 2: km_end = 0.5 is not above km_start = 1: accepted km_end > km_start (a row "
            "from its lower position to its higher one, also for a run towards falling ones)",
        ),
        (
            "km_start,km_end,radius_m,cant_mm,grade_permille\n0,x,,0,0\n",
            "row 2: km_end = 'x' not a number: accepted a finite number",
        ),
        (
            "km_start,km_end,radius_m,cant_mm,grade_permille\n0,1,abc,0,0\n",
            "row 2: radius_m = 'abc' not a number: accepted a finite number, or an empty cell",
        ),
        (
            "km_start,km_end,radius_m,cant_mm,grade_permille\ninf,1,,0,0\n",
            "row 2: km_start = inf: accepted a finite number",  # (empty is refused there)
        ),
        (
            "km_start,km_end,radius_m,cant_mm,grade_permille\n0,,,0,0\n",
            "row 2: km_end = nan (or empty): accepted a finite number in every row (a row's "
            "two ends)",
        ),
        (
            "km_start,km_end,radius_m\n0,1,\n",
            ": no column cant_mm, grade_permille; accepted a table with the columns km_start, "
            "km_end, radius_m, cant_mm, grade_permille and at least one row",
        ),
    ],
)
def test_a_bad_line_description_names_the_field_and_what_is_accepted(tmp_path, text, said):
    line = tmp_path / "line.csv"
    line.write_text(text)
    with pytest.raises(RailsuspInputError) as info:
        read_line(line)
    assert str(info.value) == f"line description {line}{'' if said[0] == ':' else ', '}{said}"


def test_a_section_table_ending_before_it_starts_names_the_fields(tmp_path):
    table = tmp_path / "t.csv"
    table.write_text("start_m,end_m\n500,500\n")
    with pytest.raises(RailsuspInputError) as info:
        read_section_table(table)
    assert str(info.value) == (
        f"section table {table}, row 2: end_m = 500 is not above start_m = 500: accepted "
        "end_m > start_m (a row from its lower position to its higher one, also for a run "
        "towards falling ones)"
    )


def test_writing_sections_onto_a_file_says_what_is_accepted(tmp_path):
    run = track_run(rate=50.0)
    secs = cut_sections(run)
    target = tmp_path / "field"
    target.write_text("a file")
    with pytest.raises(RailsuspInputError) as info:
        write_sections(run, secs, target)
    assert str(info.value) == (
        f"--write {target}: a file, not a folder; accepted a new folder or a field folder of "
        "sections written before (replaced whole)"
    )
    result = CliRunner().invoke(app, ["example-recording", "--out", str(target)])
    assert result.exit_code == 2
    assert " ".join(result.output.split()).endswith(
        "a file, not a folder; accepted a new folder or an existing one"
    )


def test_a_channel_map_naming_another_recording_is_refused(tmp_path):
    """``recording`` in a map was read and never compared with the file: a map written
    for one run read another. Refused in one line naming the key, the map and both file
    names, before the file is read; the file names alone are compared (case aside), the
    link's own or its target's. The folders were compared too, and a map beside the data
    (``../data/run.mf4``) or written on the logger's PC (``C:\\meas\\run.mf4``) was
    refused with 'run.mf4' on both sides."""
    (tmp_path / "day1").mkdir()
    path = write_mdf(tmp_path / "day1" / "run.mf4")
    link = tmp_path / "link.mf4"
    link.symlink_to(path)
    for named in ("run.mf4", "RUN.MF4", "day1/run.mf4", str(path), "../day1/run.mf4",
                  "C:\\meas\\day1\\run.mf4", "day2/run.mf4", "./run.mf4"):  # fmt: skip
        read_run(path, channel_map_from({**MAP, "recording": named}))
    for named in ("link.mf4", "run.mf4", "D:\\x\\Link.MF4"):
        read_run(link, channel_map_from({**MAP, "recording": named}))
    for named, file in (("other.mf4", ""), ("C:\\meas\\other.mf4", " names the file 'other.mf4'"),
                        ("../data/run", " names the file 'run'")):  # fmt: skip
        with pytest.raises(RailsuspInputError) as info:
            read_run(path, channel_map_from({**MAP, "recording": named}, "channel map m.toml"))
        assert str(info.value) == (
            f"channel map m.toml: recording = {named!r}{file}, but the file read through the "
            f"map is 'run.mf4' ({path}); accepted a recording of the file's name (folders and "
            "case aside), or a map without recording (one map for every run of a measuring "
            "system)"
        )
    with pytest.raises(
        RailsuspInputError, match=r"is 'link.mf4' \(.*link.mf4, a link to 'run.mf4'\)"
    ):
        read_run(link, channel_map_from({**MAP, "recording": "other.mf4"}))
    with pytest.raises(RailsuspInputError, match="recording = '': accepted the run's file name"):
        channel_map_from({**MAP, "recording": ""})
    mapping = tmp_path / "map.toml"
    mapping.write_text(
        'recording = "other.mf4"\nspeed = "v"\nposition = "s"\nignore = ["acc_bogie_y_g"]\n'
        '[wheels.w1R]\nY = "Y_R"\nQ = "Q_R"\n'
    )
    assert read_channel_map(mapping).recording == "other.mf4"
    result = CliRunner().invoke(app, ["check-recording", str(path), "--map", str(mapping)])
    assert result.exit_code == 2
    assert "recording = 'other.mf4', but the file read through the map is 'run.mf4'" in " ".join(
        result.output.split()
    )


def test_the_cut_is_let_go_after_the_field_stage_its_conditions_kept(tmp_path, monkeypatch):
    """The cache kept up to four whole runs (0.5 GB each for 2 h at 1 kHz) for the
    pipeline's life. One cut is kept, and none once the field folder is written; the
    sections' conditions, which the later stages ask for, are not read again."""
    import railsusp.measured.cut as cut

    path = write_mdf(tmp_path / "run.mf4")
    mapping = tmp_path / "map.toml"
    mapping.write_text(
        'speed = "v"\nposition = "s"\nignore = ["acc_bogie_y_g"]\n[wheels.w1R]\nY = "Y_R"\n'
        'Q = "Q_R"\n'
    )
    source = cut.RunSource(path, mapping)
    reads = []
    real = cut.read_run
    monkeypatch.setattr(cut, "read_run", lambda *a, **k: reads.append(1) or real(*a, **k))
    conditions = cut.section_conditions(source)  # the configuration check
    run, _ = cut.cut_run(source)
    assert cut.cut_run(source)[0] is run and len(reads) == 1
    alive = weakref.ref(run)
    del run
    with pytest.warns(UserWarning, match="no curvature channel"):
        cut.write_run_field(source, tmp_path / "field")
    gc.collect()
    assert alive() is None  # the run is let go
    assert cut.section_conditions(source) == conditions and len(reads) == 1
