"""Whether a run directory's files read (railsusp.integrity): each format's check finds a
copy cut short, and a file's recorded size finds a cut that its format cannot show."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch

from railsusp.integrity import (
    changed_files,
    csv_last_line_cut,
    file_readable,
    file_sizes,
    files_under,
    unreadable_files,
)
from railsusp.store import write_json, write_parquet


def _cut(path, keep: int | None = None) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2 if keep is None else keep])


@pytest.fixture()
def files(tmp_path):
    df = pd.DataFrame({"a": np.arange(50.0), "b": np.arange(50.0) ** 2})
    paths = {
        "parquet": write_parquet(tmp_path / "t.parquet", df),
        "json": write_json(tmp_path / "t.json", {"x": list(range(50))}),
        "csv": tmp_path / "t.csv",
        "pt": tmp_path / "model.pt",
        "npz": tmp_path / "t.npz",
    }
    df.to_csv(paths["csv"], index=False)
    torch.save({"w": torch.arange(1000.0)}, paths["pt"])
    np.savez(paths["npz"], x=np.arange(1000.0))
    return paths


@pytest.mark.parametrize("kind", ["parquet", "json", "csv", "pt", "npz"])
def test_each_format_reads_whole_and_not_cut_short(files, kind):
    path = files[kind]
    assert file_readable(path)
    # a CSV cut inside its last line's first number (a cut after its last comma is the
    # size record's to find, below)
    _cut(path, len(path.read_bytes()) - len(b"0,2401.0\n") if kind == "csv" else None)
    assert not file_readable(path)


def test_a_zip_with_a_flipped_byte_fails_its_checksum(files):
    """A damaged network file is found even where its length is intact."""
    path = files["pt"]
    data = bytearray(path.read_bytes())
    i = data.find(b"\x00\x00\x80?")  # inside the stored tensor (1.0 as float32)
    assert i > 0
    data[i + 3] ^= 0x01
    path.write_bytes(bytes(data))
    assert not file_readable(path)


def test_other_files_need_only_exist(tmp_path):
    fig = tmp_path / "figure.png"
    fig.write_bytes(b"\x89PNG cut")
    assert file_readable(fig)
    assert not file_readable(tmp_path / "gone.png")
    assert not file_readable(tmp_path)  # a folder is not a file


def test_a_csv_cut_inside_its_last_number_passes_the_format_check_but_not_its_size(files):
    """The limit of reading a CSV's format: every cell is still there. The size recorded
    when the file was written finds it."""
    path = files["csv"]
    sizes = file_sizes([path], path.parent)
    assert changed_files(sizes, path.parent) == []
    path.write_bytes(path.read_bytes()[:-3])  # '2401.0\n' -> '2401'
    assert file_readable(path)
    assert changed_files(sizes, path.parent) == [path]
    path.unlink()
    assert changed_files(sizes, path.parent) == [path]


def test_an_edit_that_keeps_the_size_is_found_by_the_recorded_hash(files):
    """The run-directory store audit: the sizes alone passed a same-size edit (15.917 made
    25.917 in an estimate.json). The SHA-256 recorded beside them finds it; a record without
    hashes (a run made before they were) is compared by size, as it was."""
    from railsusp.integrity import file_hashes

    path = files["json"]
    sizes, hashes = file_sizes([path], path.parent), file_hashes([path], path.parent)
    assert changed_files(sizes, path.parent, hashes) == []
    data = path.read_bytes()
    digit = next(i for i, c in enumerate(data) if chr(c).isdigit())
    path.write_bytes(data[:digit] + (b"7" if data[digit] != ord("7") else b"8") + data[digit + 1 :])
    assert file_readable(path) and path.stat().st_size == len(data)
    assert changed_files(sizes, path.parent, hashes) == [path]
    assert changed_files(sizes, path.parent) == []  # by size alone: unseen


def test_csv_last_line_rules(tmp_path):
    path = tmp_path / "r.csv"
    path.write_bytes(b"t,y,q\n0,1,2\n1,2")
    assert csv_last_line_cut(path, 3)
    path.write_bytes(b"t,y,q\n0,1,2\n1,2,3")  # only the last line end missing
    assert not csv_last_line_cut(path, 3)
    path.write_bytes(b"")
    assert not file_readable(path)  # no header


def test_files_under_leaves_out_hidden_files_other_stages_folders_and_named_files(tmp_path):
    (tmp_path / "own" / "deep").mkdir(parents=True)
    (tmp_path / "other").mkdir()
    for rel in ("a.json", "own/deep/b.csv", "other/c.json", ".a.json.tmp", "own/checkpoint.pt"):
        (tmp_path / rel).write_text("t,y\n1" if rel.endswith(".csv") else "{}")
    (tmp_path / ".hidden").mkdir()
    (tmp_path / ".hidden" / "d.json").write_text("{")
    found = files_under(tmp_path, skip_folders=("other",), skip_names=("checkpoint.pt",))
    assert [p.relative_to(tmp_path).as_posix() for p in found] == ["a.json", "own/deep/b.csv"]
    assert files_under(tmp_path / "missing") == []
    assert unreadable_files(found) == [tmp_path / "own/deep/b.csv"]  # its last line lacks a cell


def test_what_a_users_copied_folder_may_hold_reads(tmp_path):
    """A reviewer's finds: the field stage copies a user's measured folder, and a CSV with a
    quoted comma and no last line end, or a JSON file with a byte-order mark (Windows
    editors), read as they are; before, they were called damaged on every run, which ran
    the field stage and every stage after it again each time."""
    table = tmp_path / "log.csv"
    table.write_bytes(b'id,"where, when",x\n1,"Pinsk, 09:00",2')
    assert file_readable(table)
    table.write_bytes(b'id,"where, when",x\n1,"Pinsk, 09:00"')  # a cell short: cut
    assert not file_readable(table)
    notes = tmp_path / "notes.json"
    notes.write_bytes(b'\xef\xbb\xbf{"line": "Kola"}')
    assert file_readable(notes)


def test_a_damaged_compressed_archive_is_unreadable_not_an_error(tmp_path):
    """zlib's own error, from a compressed member that does not inflate, was let through
    (a traceback that ended the run)."""
    path = tmp_path / "t.npz"
    np.savez_compressed(path, x=np.random.default_rng(0).random(5000))
    data = bytearray(path.read_bytes())
    for i in range(60, 68):  # the start of the deflate stream: "invalid code lengths set"
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))
    assert not file_readable(path)


@pytest.mark.parametrize(
    ("content", "reads"),
    [
        (b"a,b\r1,2\r3,4", True),  # old Mac Excel: bare CR line ends, no last one
        (b"a,b\r1,2\r3", False),  # the same cut inside its last line
        (b"a,b\n1,2\r3,4", True),  # a stray CR inside the last line
        (b'id,x\n1,"unterminated', True),  # a stray quote: counted by commas
        (b"9" * 300_000, True),  # one line, a cell beyond the csv module's field size limit
        (b"\x00" * 4096, False),  # zeroed by a crash, size intact
        (b"a,b\n1,2\n" + b"\x00" * 64, False),
    ],
)
def test_a_csv_that_the_csv_module_cannot_parse_is_judged_not_raised(tmp_path, content, reads):
    """A second review's finds: these raised csv.Error (a traceback from check-recording,
    and a run directory that could no longer resume); a file of NUL bytes passed."""
    path = tmp_path / "t.csv"
    path.write_bytes(content)
    assert file_readable(path) is reads


@pytest.mark.parametrize("nul", [True, False])
def test_random_bytes_named_as_a_table_are_unreadable_not_an_error(tmp_path, nul):
    """Bytes of no format are judged, never raised. As CSV, bytes without a NUL (one line of
    text to the format check, its size the recorded size's to judge) read, and with one do
    not; 5000 random bytes hold a NUL almost surely, so each case is made deterministic (the
    second had never run)."""
    data = np.random.default_rng(1).integers(1, 256, 5000, dtype=np.uint8).tobytes()
    data = data.replace(b"\r", b"").replace(b"\n", b"")  # one line: a header, no last line
    if nul:
        data = data[:2500] + b"\x00" + data[2500:]
    assert (b"\x00" in data) is nul
    for name in ("t.csv", "t.json", "t.parquet", "t.pt"):
        (tmp_path / name).write_bytes(data)
        assert file_readable(tmp_path / name) is (name == "t.csv" and not nul), name


def test_json_with_a_byte_order_mark_reads_where_railsusp_reads_it(tmp_path):
    """The check accepted a BOM that read_json refused (a split file with one passed the
    check, then failed as 'corrupt split')."""
    from railsusp.store import read_json

    path = tmp_path / "split.json"
    path.write_bytes(b'\xef\xbb\xbf{"seed": 0}')
    assert file_readable(path)
    assert read_json(path) == {"seed": 0}


def test_json_nested_deeper_than_python_can_parse_is_unreadable_not_an_error(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    assert not file_readable(path)


def test_a_modified_source_tree_is_recorded_and_the_report_says_which_code_made_each_stage(
    monkeypatch,
):
    """Stop 61's report audit: provenance held ``git rev-parse HEAD`` alone, so a run from
    modified code showed the commit's SHA, and a run whose stages two commits made showed
    one."""
    from railsusp import provenance
    from railsusp.report_provenance import _made_by

    monkeypatch.setattr(provenance, "_git", lambda *a: " M src/railsusp/x.py\n")
    assert provenance.git_dirty() is True
    monkeypatch.setattr(provenance, "_git", lambda *a: "")
    assert provenance.git_dirty() is False
    monkeypatch.setattr(provenance, "_git", lambda *a: None)
    assert provenance.git_dirty() is None and provenance.git_sha() is None
    made = {"railsusp": "1.0", "git_sha": "0123456789abcdef", "git_dirty": True}
    assert _made_by(made) == "1.0 0123456+modified" and _made_by(None) == ""


def _user_repository(root):
    """A git repository of a user's, with one commit; its HEAD."""
    import subprocess

    root.mkdir(parents=True, exist_ok=True)
    git = ["git", "-c", "user.email=u@example.org", "-c", "user.name=u", "-C", str(root)]
    subprocess.run([*git, "init", "-q"], check=True)
    (root / "notes.txt").write_text("mine")
    subprocess.run([*git, "add", "notes.txt"], check=True)
    subprocess.run([*git, "commit", "-q", "-m", "mine"], check=True)
    out = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True, check=True)
    return out.stdout.strip()


def test_an_installed_package_inside_a_users_repository_records_no_commit(tmp_path, monkeypatch):
    """railsusp installed in a project's .venv: git found the project's repository around
    site-packages and its commit was recorded as railsusp's, clean (the packaging audit of
    stop 65). A checkout of railsusp (the package at src/railsusp) still records its own."""
    from railsusp import provenance

    head = _user_repository(tmp_path / "project")
    installed = tmp_path / "project" / ".venv" / "lib" / "site-packages" / "railsusp"
    installed.mkdir(parents=True)
    monkeypatch.setattr(provenance, "__file__", str(installed / "provenance.py"))
    assert provenance.git_sha() is None and provenance.git_dirty() is None
    checkout = tmp_path / "checkout"
    head = _user_repository(checkout)
    (checkout / "src" / "railsusp").mkdir(parents=True)
    monkeypatch.setattr(
        provenance, "__file__", str(checkout / "src" / "railsusp" / "provenance.py")
    )
    assert provenance.git_sha() == head and provenance.git_dirty() is False
