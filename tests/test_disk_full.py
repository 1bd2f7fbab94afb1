"""A full disk, a quota, an I/O error (the disk audit): an interrupted sensitivity analysis
leaves the old one whole, example-recording exits 1 for the machine's errors, an I/O error
flushing a folder is no success, and the full-disk message names the file. Each test failed
on the code before, as its docstring says."""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

import railsusp.atomic_files as atomic_files
import railsusp.report
import railsusp.sensitivity
import railsusp.store as store
from railsusp.campaign import make_config, run_campaign
from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.sensitivity import analyse

runner = CliRunner()

SHORT = [get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0, name="short")]


def enospc(*_args, **_kw):
    """A write the full disk refused, as pyarrow and a bare ``write`` raise it: no file."""
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too), by its path relative to it."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def analysed(tmp_path_factory) -> Path:
    """A complete 12-run LHS campaign with a finished analysis (figures of mean and p99)."""
    run = tmp_path_factory.mktemp("disk") / "camp"
    cfg = make_config(SHORT, 12, batch_size=4, seed=1, parameters=("X13", "X14"))
    run_campaign(cfg, run)
    analyse(run, base_samples=64)
    assert {"sobol-mean.png", "sobol-p99.png", "key_parameters.json"} <= set(
        snapshot(run / "sensitivity")
    )
    return run


@pytest.fixture
def campaign(analysed, tmp_path) -> Path:
    """A copy of :func:`analysed` of the test's own (a failed test's leftovers not seen by
    the next)."""
    return Path(shutil.copytree(analysed, tmp_path / "camp"))


# ---------------------------------------------------------------- 1. sensitivity as one
@pytest.mark.parametrize("where", ["figure", "key_parameters"])
def test_a_sensitivity_rerun_that_fails_part_way_leaves_the_old_analysis_whole(
    campaign, monkeypatch, where
):
    """A re-run that met a full disk on its last file replaced the files one by one: new
    indices beside the old key_parameters.json, or the new key parameters beside the old
    analysis's figures (sobol-p99.png removed), and the folder read as one finished
    analysis. Now the folder is written as one artefact: every file of the old analysis is
    byte-identical afterwards, and no temporary is left."""
    before = snapshot(campaign)
    if where == "figure":
        monkeypatch.setattr(railsusp.report, "plot_sobol", enospc)
    else:
        write_json = railsusp.sensitivity.write_json

        def refusing(path, obj):
            if Path(path).name == "key_parameters.json":
                enospc()
            return write_json(path, obj)

        monkeypatch.setattr(railsusp.sensitivity, "write_json", refusing)
    with pytest.raises(OSError) as caught:
        analyse(
            campaign,
            statistics=("mean",),
            key_statistics=("mean",),
            threshold=0.5,
            max_keys=1,
            base_samples=128,
        )
    assert caught.value.errno == errno.ENOSPC
    assert snapshot(campaign) == before
    assert not [p.name for p in campaign.iterdir() if p.name.startswith(".sensitivity.")]


def test_a_sensitivity_rerun_drops_an_earlier_analysis_figures_and_comparison(campaign):
    """As before: figures of statistics no longer analysed, and an earlier comparison, are
    not carried into the new analysis; a file of the user's is."""
    (campaign / "sensitivity" / "agreement.csv").write_text("old comparison\n")
    (campaign / "sensitivity" / "notes.txt").write_text("the user's\n")
    analyse(campaign, statistics=("mean",), key_statistics=("mean",), base_samples=64)
    names = set(snapshot(campaign / "sensitivity"))
    assert "sobol-mean.png" in names and "notes.txt" in names
    assert "sobol-p99.png" not in names and "agreement.csv" not in names


# ---------------------------------------------------------------- 2. example-recording
def test_example_recording_on_a_full_disk_exits_1_naming_the_file(tmp_path, monkeypatch):
    """A full disk exited 2 (bad input) where every other command exits 1 (the machine),
    and the line named only the folder."""
    out = tmp_path / "ex"
    monkeypatch.setattr(atomic_files, "fsync_file", enospc)  # the content's flush refused
    result = runner.invoke(app, ["example-recording", "--out", str(out)])
    assert result.exit_code == 1, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert f"{out / 'example_run.mf4'}: No space left on device" in " ".join(lines)
    assert not list(tmp_path.rglob("*.tmp"))  # nothing left (the new folder removed too)


def test_example_recording_exits_1_for_enospc_and_2_for_a_read_only_folder(tmp_path, monkeypatch):
    """ENOSPC from atomic_write_bytes exits 1; EROFS (the folder not writable) stays 2."""
    for code, expected in ((errno.ENOSPC, 1), (errno.EDQUOT, 1), (errno.EIO, 1), (errno.EROFS, 2)):

        def refused(path, data, code=code):
            raise OSError(code, os.strerror(code), str(path))

        monkeypatch.setattr(store, "atomic_write_bytes", refused)
        result = runner.invoke(app, ["example-recording", "--out", str(tmp_path / f"e{code}")])
        assert result.exit_code == expected, (code, result.output)
        assert "cannot write there" in result.output


# ---------------------------------------------------------------- 3. fsync of a folder
def test_an_io_error_flushing_a_folder_is_raised(tmp_path, monkeypatch):
    """fsync_dir swallowed every OSError, EIO included: a rename perhaps never on disk was
    reported as written. Only "not supported" errors are ignored now."""
    monkeypatch.setattr(os, "fsync", lambda fd: (_ for _ in ()).throw(OSError(errno.EIO, "I/O")))
    with pytest.raises(OSError) as caught:
        atomic_files.fsync_dir(tmp_path)
    assert caught.value.errno == errno.EIO
    for unsupported in (errno.EINVAL, errno.ENOTSUP, errno.EBADF):
        monkeypatch.setattr(
            os, "fsync", lambda fd, e=unsupported: (_ for _ in ()).throw(OSError(e, "no"))
        )
        atomic_files.fsync_dir(tmp_path)  # ignored


def test_an_io_error_flushing_the_folder_fails_the_write(tmp_path, monkeypatch):
    """Through a write: the content flushed, the folder's flush EIO: the write fails with
    EIO, naming the file."""
    monkeypatch.setattr(atomic_files, "fsync_file", lambda path: None)
    monkeypatch.setattr(os, "fsync", lambda fd: (_ for _ in ()).throw(OSError(errno.EIO, "I/O")))
    with pytest.raises(OSError) as caught:
        store.atomic_write_text(tmp_path / "a.txt", "x")
    assert caught.value.errno == errno.EIO
    assert caught.value.filename == str(tmp_path / "a.txt")


# ---------------------------------------------------------------- 4. the file named
def test_a_write_error_naming_no_file_names_the_target(tmp_path, monkeypatch):
    """A bare write error (no filename) was shown as "No space left on device", naming
    nothing; pyarrow's errno-28 error likewise. Both name the target now, errno kept."""
    monkeypatch.setattr(atomic_files, "fsync_file", enospc)
    with pytest.raises(OSError) as caught:
        store.atomic_write_bytes(tmp_path / "a.bin", b"x")
    assert (caught.value.errno, caught.value.filename) == (errno.ENOSPC, str(tmp_path / "a.bin"))
    assert caught.value.strerror == os.strerror(errno.ENOSPC)
    monkeypatch.undo()

    def arrow_full(*_args, **_kw):
        exc = OSError("Error writing bytes to file. Detail: [errno 28] No space left on device")
        exc.errno = errno.ENOSPC
        raise exc

    monkeypatch.setattr(store.pq, "write_table", arrow_full)
    with pytest.raises(OSError) as caught:
        store.write_parquet(tmp_path / "t.parquet", pd.DataFrame({"a": [1]}))
    assert (caught.value.errno, caught.value.filename) == (
        errno.ENOSPC,
        str(tmp_path / "t.parquet"),
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no temporary left


def test_a_write_error_naming_the_temporary_names_the_target(tmp_path, monkeypatch):
    """An error naming the hidden ``.NAME.XXXXXXXX.tmp`` (the rename refused) showed that
    name; it names the target now. One naming another file is left as it is."""
    target = tmp_path / "a.json"

    def refused(src, dst):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), src, dst)

    monkeypatch.setattr(store.os, "replace", refused)
    with pytest.raises(OSError) as caught:
        store.write_json(target, {"a": 1})
    assert (caught.value.errno, caught.value.filename) == (errno.EROFS, str(target))
    other = str(tmp_path / "elsewhere")
    monkeypatch.setattr(
        store.os, "replace", lambda s, d: (_ for _ in ()).throw(OSError(errno.EIO, "I/O", other))
    )
    with pytest.raises(OSError) as caught:
        store.write_json(target, {"a": 1})
    assert caught.value.filename == other


def test_a_file_of_an_atomic_folder_is_named_inside_its_target(tmp_path, monkeypatch):
    """A file written inside atomic_folder's hidden ``.NAME.new-*`` folder is named as the
    file it was to become."""
    monkeypatch.setattr(atomic_files, "fsync_file", enospc)
    with pytest.raises(OSError) as caught, store.atomic_folder(tmp_path / "est") as tmp:
        store.write_json(tmp / "estimate.json", {})
    assert caught.value.filename == str(tmp_path / "est" / "estimate.json")
    assert caught.value.errno == errno.ENOSPC
