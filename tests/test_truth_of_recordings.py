"""A synthetic field's truth is told to belong to the recordings it is scored against
(measured/truth.py): by the SHA-256 of their tables, or of the run their sections were cut
from, wherever the truth file lies."""

import json
import shutil
from importlib import resources

import pytest

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured import check_truth_of, read_truth, synthesise_field
from railsusp.measured.field_folder import source_fingerprint
from railsusp.params import ParameterSet
from railsusp.store import file_hash


@pytest.fixture(scope="module")
def fields(tmp_path_factory):
    root = tmp_path_factory.mktemp("truths")
    cond = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=30.0)
    a = synthesise_field(ParameterSet({"X13": 18.0}, units="display"), [cond], root / "a")
    b = synthesise_field(ParameterSet({"X13": 9.0}, units="display"), [cond], root / "b", seed=8)
    return a, b


def test_synth_field_records_its_tables_by_content(fields):
    a, _ = fields
    doc = json.loads((a / "truth.json").read_text())
    assert doc["recording_files"] == {"straight.csv": file_hash(a / "straight.csv")}
    check_truth_of(a / "truth.json", a)  # its own recordings: accepted


def test_a_truth_kept_elsewhere_is_still_the_truth_of_its_recordings(fields, tmp_path):
    a, _ = fields
    kept = tmp_path / "blind" / "truth.json"  # a blind test keeps the truth away
    kept.parent.mkdir()
    shutil.copy(a / "truth.json", kept)
    check_truth_of(kept, a)


def test_the_truth_of_another_field_is_refused_naming_the_table(fields):
    a, b = fields
    with pytest.raises(RailsuspInputError) as exc:
        check_truth_of(b / "truth.json", a, "--truth")
    msg = str(exc.value)
    assert msg.startswith(f"--truth {b / 'truth.json'}: the truth of other recordings")
    assert "straight.csv is none of the tables" in msg and "\n" not in msg


def test_an_edited_recording_is_no_longer_the_truths(fields, tmp_path):
    a, _ = fields
    copy = shutil.copytree(a, tmp_path / "edited")
    table = copy / "straight.csv"
    table.write_text(table.read_text().replace("\n", "\r\n", 1))  # one byte more
    with pytest.raises(RailsuspInputError, match="straight.csv is none of the tables"):
        check_truth_of(copy / "truth.json", copy)


def test_sections_of_a_run_belong_to_its_truth(fields, tmp_path):
    a, b = fields
    sections = tmp_path / "sections"
    sections.mkdir()
    # the index sections --write writes: the cut run's name, size and SHA-256
    index = {"recordings": ["s1.csv"], **source_fingerprint(a / "straight.csv")}
    (sections / "index.json").write_text(json.dumps(index))
    (sections / "s1.csv").write_text("a section's table, not one of the field's\n")
    _cut_table(sections, "s1")
    check_truth_of(a / "truth.json", sections)
    with pytest.raises(RailsuspInputError, match="s1.csv is none of the tables"):
        check_truth_of(b / "truth.json", sections)
    # a recording added to the sections' index is none of the run's sections (the review
    # of stop 74: the run's hash let every table of the folder through)
    shutil.copy(b / "straight.csv", sections / "other.csv")
    index["recordings"].append("other.csv")
    (sections / "index.json").write_text(json.dumps(index))
    with pytest.raises(RailsuspInputError, match=r"\(other.csv is none of the tables"):
        check_truth_of(a / "truth.json", sections)


def _cut_table(folder, *kept):
    """The sections.csv sections --write writes beside its index, these sections kept."""
    head = "section,kind,from_m,to_m,length_m,speed_kmh,speed_spread_pct,cant_mm,"
    rows = [head + "grade_permille,kept,reason"]
    rows += [f"{name},tangent,0,500,500,60,0,0,0,yes," for name in kept]
    rows.append("-,tangent,500,700,200,60,16.7,0,0,no,speed not steady")
    (folder / "sections.csv").write_text("\n".join(rows) + "\n")


def test_the_shipped_example_truth_is_that_of_the_shipped_run(tmp_path):
    data = resources.files("railsusp") / "data"
    truth = tmp_path / "example_run.truth.json"
    truth.write_bytes((data / "example_run.truth.json").read_bytes())
    run = tmp_path / "example_run.mf4"
    run.write_bytes((data / "example_run.mf4").read_bytes())
    sections = tmp_path / "sections"
    sections.mkdir()
    index = {"recordings": ["s1.csv"], **source_fingerprint(run)}
    (sections / "index.json").write_text(json.dumps(index))
    _cut_table(sections, "s1")
    check_truth_of(truth, sections)
    assert read_truth(truth)["X14"] == pytest.approx(8.3e6)  # SI inside


def test_a_truth_without_recording_files_is_taken_as_it_is(fields, tmp_path):
    _, b = fields
    doc = json.loads((b / "truth.json").read_text())
    del doc["recording_files"]  # written before stop 74
    old = tmp_path / "truth.json"
    old.write_text(json.dumps(doc))
    check_truth_of(old, fields[0])


@pytest.mark.parametrize("bad", [["straight.csv"], {"straight.csv": 3}, "abc"])
def test_recording_files_not_a_table_of_hashes_is_refused(fields, tmp_path, bad):
    a, _ = fields
    doc = json.loads((a / "truth.json").read_text())
    doc["recording_files"] = bad
    path = tmp_path / "truth.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(RailsuspInputError, match="'recording_files' is not a table of file"):
        check_truth_of(path, a)


def test_a_copy_in_other_bytes_that_reads_the_same_is_still_the_truths(fields, tmp_path):
    """A field checked out with CRLF line endings (git's autocrlf) holds the same
    recordings in other bytes: its truth was refused, and the pipeline dropped it (the
    review of stop 74). The recordings as read are compared too (recordings_digest)."""
    from railsusp.measured import read_field

    a, _ = fields
    copy = shutil.copytree(a, tmp_path / "crlf")
    table = copy / "straight.csv"
    table.write_bytes(table.read_bytes().replace(b"\n", b"\r\n"))
    check_truth_of(copy / "truth.json", copy, recordings=read_field(copy))
    with pytest.raises(RailsuspInputError, match="nor read as the same recordings"):
        check_truth_of(copy / "truth.json", copy)  # the bytes alone: not the same
    lines = table.read_text().splitlines()
    cells = lines[1].split(",")
    cells[1] = f"{float(cells[1]) + 0.5:.6g}"  # one force changed: other recordings
    table.write_text("\n".join([lines[0], ",".join(cells), *lines[2:]]) + "\n")
    with pytest.raises(RailsuspInputError, match="straight.csv is none of the tables"):
        check_truth_of(copy / "truth.json", copy, recordings=read_field(copy))


@pytest.fixture(scope="module")
def tracked(tmp_path_factory):
    """A field whose recording carries its measured track geometry (with_track)."""
    cond = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=30.0)
    root = tmp_path_factory.mktemp("tracked")
    return synthesise_field(
        ParameterSet({"X13": 18.0}, units="display"), [cond], root / "a", with_track=True
    )


def test_a_geometry_in_other_bytes_that_reads_the_same_is_still_the_truths(tracked, tmp_path):
    """The truth's digest of a field on measured track hashed the geometry file's bytes: the
    field checked out with CRLF line endings (recordings and geometry) was refused as other
    recordings. Digest version 2 hashes the geometry as read; a changed geometry value is
    still other recordings."""
    from railsusp.measured import read_field

    copy = shutil.copytree(tracked, tmp_path / "crlf")
    for name in ("straight.csv", "straight.track.csv"):
        f = copy / name
        f.write_bytes(f.read_bytes().replace(b"\n", b"\r\n"))
    check_truth_of(copy / "truth.json", copy, recordings=read_field(copy))
    geometry = copy / "straight.track.csv"
    lines = geometry.read_text().splitlines()
    cells = lines[5].split(",")
    cells[1] = f"{float(cells[1]) + 0.25:.9g}"  # one vertical irregularity moved 0.25 mm
    geometry.write_text("\n".join([*lines[:5], ",".join(cells), *lines[6:]]) + "\n")
    with pytest.raises(RailsuspInputError, match="nor read as the same recordings"):
        check_truth_of(copy / "truth.json", copy, recordings=read_field(copy))


def test_a_digest_stored_before_version_2_still_matches_its_recordings(tracked):
    """Estimates and truths written before the digest's version 2 hold a digest without a
    prefix (the geometry file's bytes): they are compared in their own version."""
    from railsusp.measured import read_field
    from railsusp.measured.recording import recordings_digest, same_recordings

    recs = read_field(tracked)
    old, new = recordings_digest(recs, version=1), recordings_digest(recs)
    assert new.startswith("v2:") and old != new.removeprefix("v2:")
    assert same_recordings(recs, old) and same_recordings(recs, new)
    assert not same_recordings(recs, "v9:" + old) and not same_recordings(recs, "v2:" + old)
    doc = json.loads((tracked / "truth.json").read_text())
    assert doc["recordings_digest"] == new


def test_the_same_geometry_as_parquet_is_the_same_recording(tracked, tmp_path):
    """Version 2 hashes the geometry as read: its CSV written again as Parquet reads the
    same; version 1 (the file's bytes) told them apart."""
    import pandas as pd

    from railsusp.measured import read_field
    from railsusp.measured.recording import recordings_digest

    (rec,) = read_field(tracked)
    parquet = tmp_path / "straight.track.parquet"
    pd.read_csv(rec.condition.track_geometry).to_parquet(parquet)
    moved = shutil.copy(rec.condition.track_geometry, tmp_path / "elsewhere.csv")
    twins = []
    for path in (parquet, moved):
        twin = read_field(tracked)[0]
        twin.condition = twin.condition.with_changes(track_geometry=str(path))
        twins.append(twin)
    assert recordings_digest(twins[:1]) == recordings_digest([rec])  # the parquet, as read
    assert recordings_digest(twins[1:]) == recordings_digest([rec])  # another place
    assert recordings_digest(twins[:1], version=1) != recordings_digest([rec], version=1)


@pytest.fixture(scope="module")
def example_sections(tmp_path_factory):
    """The shipped example run's sections as `sections --write` writes them, beside its
    truth."""
    from railsusp.measured.channels import read_channel_map
    from railsusp.measured.run import read_run
    from railsusp.measured.sections import cut_sections
    from railsusp.measured.sections_out import write_sections

    data = resources.files("railsusp") / "data"
    root = tmp_path_factory.mktemp("example")
    for name in ("example_run.mf4", "example_run.map.toml", "example_run.truth.json"):
        (root / name).write_bytes((data / name).read_bytes())
    run = read_run(root / "example_run.mf4", read_channel_map(root / "example_run.map.toml"))
    return root / "example_run.truth.json", write_sections(run, cut_sections(run), root / "cut")


def test_an_edited_section_is_no_longer_the_truths_of_its_run(example_sections, tmp_path):
    """A sections folder cut from the truth's run was told by its sections' names only: a
    section table edited after the cut (other forces) still took the run's truth. The index
    now records each section's SHA-256 and the sections' digest as read, so the folder in
    other bytes (CRLF) is still the run's, and an edited section is not."""
    from railsusp.measured import read_field

    truth, cut = example_sections
    index = json.loads((cut / "index.json").read_text())
    first = index["recordings"][0]
    assert index["recording_files"][first] == file_hash(cut / first)
    check_truth_of(truth, cut, recordings=read_field(cut))
    crlf = shutil.copytree(cut, tmp_path / "crlf")
    for name in index["recordings"]:
        (crlf / name).write_bytes((crlf / name).read_bytes().replace(b"\n", b"\r\n"))
    check_truth_of(truth, crlf, recordings=read_field(crlf))
    edited = shutil.copytree(cut, tmp_path / "edited")
    lines = (edited / first).read_text().splitlines()
    cells = lines[3].split(",")
    cells[1] = f"{float(cells[1]) + 1.0:.6g}"  # one lateral force 1 kN more
    (edited / first).write_text("\n".join([*lines[:3], ",".join(cells), *lines[4:]]) + "\n")
    with pytest.raises(RailsuspInputError, match=rf"\({first} is none of the tables"):
        check_truth_of(truth, edited, recordings=read_field(edited))
