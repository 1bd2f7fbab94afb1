"""A long run's line description and section table, checked where the command-line audit of
stop 60 found them taken silently: a radius of nan or inf read as a tangent, rows that
overlap (the later one won), cant on a tangent row (shown, then written as 0), and section
names that are the field folder's own files or repeat (one recording written over
another)."""

import warnings
from pathlib import Path

import pytest

from railsusp.errors import RailsuspInputError
from railsusp.measured.line import read_line, read_section_table

EXAMPLE_PATH = Path(__file__).resolve().parents[1] / "src/railsusp/data/example_line.csv"
EXAMPLE = EXAMPLE_PATH.read_text()


def _write(tmp_path, text: str, name: str = "t.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_example_line_reads():
    assert len(read_line(EXAMPLE_PATH)) >= 4


@pytest.mark.parametrize(
    ("old", "new", "said"),
    [
        ("0.7417,1.2000,600.0,", "0.7417,1.2000,nan,", "row 3: radius_m = 'nan' not a number"),
        ("0.7417,1.2000,600.0,", "0.7417,1.2000,inf,", "row 3: radius_m = inf: accepted a finite"),
        ("0.7417,1.2000,600.0,", "0.5000,1.2000,600.0,", "rows 2 and 3 overlap (km 0.5 to 0.5417)"),
        ("0.0000,0.5417,,left,0,0", "0.0000,0.5417,,left,50,0", "cant_mm = 50 on a tangent row"),
    ],
)
def test_a_bad_line_description_is_refused_in_one_line(tmp_path, old, new, said):
    assert old in EXAMPLE
    with pytest.raises(RailsuspInputError) as err:
        read_line(_write(tmp_path, EXAMPLE.replace(old, new, 1)))
    assert said in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("rows", "said"),
    [
        ("0,500,index\n800,1150,b\n", "row 2: name 'index' is the field folder's own file"),
        ("0,500,a\n800,1150,Sections\n", "row 3: name 'Sections' is the field folder's own"),
        # its truth.json beside the recordings read as a synthetic folder's truth sidecar
        ("0,500,truth\n800,1150,b\n", "row 2: name 'truth' is the field folder's own file"),
        ("0,500,a\n800,1150,A\n", "row 3: name 'A' is row 2's too"),
    ],
)
def test_a_section_table_whose_names_collide_is_refused(tmp_path, rows, said):
    with pytest.raises(RailsuspInputError, match=said):
        read_section_table(_write(tmp_path, "start_m,end_m,name\n" + rows))
    ok = read_section_table(_write(tmp_path, "start_m,end_m,name\n0,500,a\n800,1150,b\n"))
    assert list(ok.name) == ["a", "b"]


@pytest.mark.parametrize(
    ("columns", "row", "said"),
    [
        ("radius_m,direction", "30,left", "row 2: radius_m = 30: accepted 50 to 100000, or empty"),
        (
            "radius_m,direction",
            "600,up",
            "row 2: direction = 'up': accepted left or right \\(empty on a tangent row\\)",
        ),
        ("radius_m,cant_mm", ",50", "row 2: cant_mm = 50 on a tangent row"),
        ("grade_permille", "120", "row 2: grade_permille = 120: accepted -40 to 40"),
        ("direction", "left", "a direction column without radius_m; accepted radius_m"),
    ],
)
def test_a_section_tables_track_columns_are_checked_as_a_line_descriptions(
    tmp_path, columns, row, said
):
    """The audit of stop 63: a section table's rows take their track from its optional
    columns (radius_m, direction, cant_mm, grade_permille), where a run has no geometry
    channels; they are refused row by row outside a working condition's ranges as a line
    description's are (they were read as nothing at all)."""
    with pytest.raises(RailsuspInputError, match=said):
        read_section_table(_write(tmp_path, f"start_m,end_m,{columns}\n0,500,{row}\n"))


@pytest.mark.parametrize(
    ("rows", "said"),
    [
        ("0,500,\n", "section table .*t.csv, row 2: name is empty: accepted 1-60 letters"),
        ("0,500,a\n800,1150,\n", "row 3: name is empty"),
    ],
)
def test_an_empty_section_name_is_refused_in_one_line(tmp_path, rows, said):
    """QA: an empty name cell stayed NaN through ``astype(str)`` under pandas 3 (a
    TypeError's traceback; under pandas 2 a section named "nan")."""
    with pytest.raises(RailsuspInputError, match=said) as err:
        read_section_table(_write(tmp_path, "start_m,end_m,name\n" + rows))
    assert "\n" not in str(err.value)


def test_section_names_and_an_empty_direction_are_read_as_written(tmp_path):
    """Names that look like numbers stay as written ("01" was 1), and an empty direction
    cell on a tangent row is read, without pandas' warning on filling a float column; on a
    curve row it is refused (stop 72: it was taken as left)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # pandas' FutureWarning on filling a float column
        table = read_section_table(
            _write(
                tmp_path, "start_m,end_m,name,radius_m,direction\n0,500,01,,\n500,900,2,600,right\n"
            )
        )
    assert list(table.name) == ["01", "2"]
    with pytest.raises(RailsuspInputError, match=r"row 3: radius_m = 600 with no hand"):
        read_section_table(
            _write(tmp_path, "start_m,end_m,name,radius_m,direction\n0,500,a,,\n500,900,b,600,\n")
        )


@pytest.mark.parametrize(
    ("header", "row"),
    [
        ("start_m,end_m,name", "0,500," + "x" * 5000),
        ("start_m,end_m,radius_m,direction", "0,500,600," + "y" * 5000),
        ("start_m,end_m,radius_m", "0,500," + "z" * 5000),
    ],
)
def test_a_long_cell_is_quoted_cut_in_its_refusal(tmp_path, header, row):
    """The review of stop 72: a 5000-character name, direction or number cell was quoted
    whole (a refusal of 5100 characters)."""
    with pytest.raises(RailsuspInputError, match=r"row 2: .*\.\.\.") as err:
        read_section_table(_write(tmp_path, f"{header}\n{row}\n"))
    assert len(str(err.value)) < 400


def test_a_curve_row_of_a_table_given_as_a_data_frame_states_its_hand():
    """The review of stop 72: a section table passed as a DataFrame (not read by
    read_section_table) took a curve without a direction column as left."""
    import numpy as np
    import pandas as pd

    from railsusp.measured.line import geometry_from_table

    rows = pd.DataFrame({"start_m": [0.0], "end_m": [500.0], "radius_m": [600.0]})
    with pytest.raises(RailsuspInputError, match="track row 1: radius_m = 600 with direction"):
        geometry_from_table(np.linspace(0.0, 400.0, 5), rows)
    right = geometry_from_table(np.linspace(0.0, 400.0, 5), rows.assign(direction="right"))
    assert np.allclose(right["curvature"], -1 / 600.0)
